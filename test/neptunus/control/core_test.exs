defmodule Neptunus.Control.CoreTest do
  use ExUnit.Case, async: true

  alias Neptunus.Allocation
  alias Neptunus.Control.Core

  @neutral %{port: 0.0, vertical: 0.0, starboard: 0.0}

  defp est(opts \\ []) do
    Map.merge(
      %{t: 1.0, depth: 2.0, depth_rate: 0.0, heading: 1.0, yaw_rate: 0.0, position: nil},
      Map.new(opts)
    )
  end

  # a core with a fresh estimate at t = 10 s
  defp core(opts \\ [], estimate \\ est()),
    do: opts |> Core.new() |> Core.estimate(estimate, 10.0)

  defp ok!(core, command, now \\ 10.0) do
    assert {:ok, core, actions} = Core.command(core, command, now)
    {core, actions}
  end

  defp motion(s, h, y), do: {:thrust, :motion, %{surge: s, heave: h, yaw: y}}
  defp manual(p, v, s), do: {:thrust, :manual, %{port: p, vertical: v, starboard: s}}

  defp ap(depth, heading \\ :unchanged),
    do: {:autopilot, %{depth: depth, heading: heading}}

  defp gos(actions), do: for({:go, thr} <- actions, do: thr)

  # a valid position estimate (Neptunus.Navigation.Position's) at rest
  defp pos(n, e),
    do: %{
      valid: true,
      reason: nil,
      north: n,
      east: e,
      velocity_north: 0.0,
      velocity_east: 0.0,
      velocity_measured: true,
      frame: :usbl,
      epoch: 1,
      shift: nil
    }

  # reference limits so high that a setpoint step reaches the PID whole at the next tick:
  # for tests of what the autopilot outputs do, not of how the reference moves
  @instant [
    reference: %{depth: [rate: 1.0e6, accel: 1.0e9], heading: [rate: 1.0e6, accel: 1.0e9]}
  ]

  # one control tick at 10.01 s (the reference reaches an instant setpoint)
  defp tick(core), do: elem(Core.tick(core, 0.02, 10.01), 0)

  test "at rest: motion, gain 0.5, neutral, nothing engaged" do
    core = Core.new()

    assert Core.status(core) == %{
             mode: "motion",
             gain: 0.5,
             lights: 0,
             laser: 0,
             tilt: 0.0,
             run_mode: "normal",
             dp_holds: nil,
             autopilot: %{depth: nil, heading: nil, position: nil},
             mission: nil,
             command: %{surge: 0.0, heave: 0.0, yaw: 0.0},
             thrusters: Allocation.with_us(@neutral)
           }

    assert Core.autopilot(core) == %{depth: nil, heading: nil, position: nil}
    refute Core.active?(core)
    assert Core.tick(core, 0.02, 0.0) == {core, []}
  end

  describe "thrust" do
    test "motion: the thesis' eq. 9.3 with the gain, exactly" do
      {core, actions} = ok!(core(), motion(1.0, -0.4, 0.5))
      expected = Allocation.motion(%{surge: 1.0, heave: -0.4, yaw: 0.5}, 0.5)
      assert gos(actions) == [expected]
      assert core.thrusters == expected
      assert Core.status(core).command == %{surge: 1.0, heave: -0.4, yaw: 0.5}
    end

    test "manual: each thruster times the gain, saturated" do
      {core, _} = ok!(core(gain: 1.0), {:set_control_mode, :manual})
      {core, actions} = ok!(core, manual(0.5, -1.0, 0.25))
      assert gos(actions) == [%{port: 0.5, vertical: -1.0, starboard: 0.25}]
      {core, actions} = ok!(core, {:set_gain, 0.5})
      assert gos(actions) == [%{port: 0.25, vertical: -0.5, starboard: 0.125}]
      assert Core.status(core).command == %{port: 0.5, vertical: -1.0, starboard: 0.25}
    end

    test "the thrust mode must be the control mode; nothing changes otherwise" do
      core = core()

      assert Core.command(core, manual(1, 1, 1), 10.0) ==
               {:error, "thrust mode manual does not match control mode motion"}

      {manual_core, _} = ok!(core, {:set_control_mode, :manual})

      assert Core.command(manual_core, motion(1, 0, 0), 10.0) ==
               {:error, "thrust mode motion does not match control mode manual"}
    end

    test "gain re-applies the command in force" do
      {core, _} = ok!(core(), motion(1.0, 0.0, 0.0))
      {core, actions} = ok!(core, {:set_gain, 1.0})
      assert gos(actions) == [%{port: 1.0, vertical: 0.0, starboard: 1.0}]
      assert Core.status(core).gain == 1.0
    end
  end

  test "lights, laser and tilt are set at once, never with a thrust" do
    {core, actions} = ok!(core(), {:set_lights, 200})
    assert actions == [{:lights, 200}]
    {core, actions} = ok!(core, {:set_laser, 5})
    assert actions == [{:laser, 5}]
    {core, actions} = ok!(core, {:set_tilt, -0.3})
    assert actions == [{:tilt, -0.3}]
    assert %{lights: 200, laser: 5, tilt: -0.3} = Core.status(core)
  end

  describe "control modes" do
    test "the same mode again changes nothing (no stop)" do
      core = core()
      assert Core.command(core, {:set_control_mode, :motion}, 10.0) == {:ok, core, []}
    end

    test "a change stops the thrusters first" do
      {core, _} = ok!(core(), motion(1, 1, 1))
      {core, actions} = ok!(core, {:set_control_mode, :manual})
      assert actions == [{:go, @neutral}, {:stopped, "control_mode_changed"}]
      assert core.thrusters == @neutral
      assert Core.status(core).command == %{port: 0.0, vertical: 0.0, starboard: 0.0}
    end

    test "manual disengages the autopilots; they are refused there" do
      {core, _} = ok!(core(), ap(:hold, :hold))
      {core, _} = ok!(core, {:set_control_mode, :manual})
      assert Core.status(core).autopilot == %{depth: nil, heading: nil, position: nil}
      refute Core.active?(core)

      assert Core.command(core, ap(1.0), 10.0) ==
               {:error, "autopilots are not available in manual mode: switch to motion or dp"}
    end

    test "dp without a position source holds depth and heading, and says so" do
      # (it was refused: "dp needs a position source: this vehicle has none")
      {core, actions} = ok!(core(@instant), {:set_control_mode, :dp})

      assert actions == [
               {:go, @neutral},
               {:stopped, "control_mode_changed"},
               {:notice,
                "dp: no valid position (no position source): holding depth and heading only"}
             ]

      assert %{mode: "dp", dp_holds: ["depth", "heading"]} = Core.status(core)
      assert %{autopilot: %{depth: 2.0, heading: 1.0, position: nil}} = Core.status(core)
      assert Core.active?(core)
      # pushed off its depth and heading, it pushes back, with no surge
      core = Core.estimate(core, est(depth: 2.2, heading: 1.1), 10.0)
      {core, _} = Core.tick(core, 0.02, 10.01)
      %{port: p, vertical: v, starboard: s} = core.thrusters
      assert v < 0 and p - s < 0
      assert_in_delta p + s, 0.0, 1.0e-12
      # pilot thrust is refused as in DP with a position
      assert {:error, "thrust mode motion does not match control mode dp"} =
               Core.command(core, motion(1.0, 0.0, 0.0), 10.0)

      # a safety stop ends it like DP
      {core, _} = Core.stop(core, "deadman")
      assert %{mode: "motion", dp_holds: nil, autopilot: %{depth: nil}} = Core.status(core)
    end

    test "dp needs a current estimate with valid depth and heading" do
      assert {:error, "dp needs a current estimate of depth and heading (no board samples)"} =
               Core.command(Core.new(), {:set_control_mode, :dp}, 10.0)

      stale = core([], est(position: pos(1.0, 2.0)))
      assert {:error, _} = Core.command(stale, {:set_control_mode, :dp}, 11.5)
    end

    test "dp holds position, depth and heading where it is engaged" do
      core = core([], est(position: pos(1.0, 2.0)))
      {core, actions} = ok!(core, {:set_control_mode, :dp})
      assert actions == [{:go, @neutral}, {:stopped, "control_mode_changed"}]

      assert %{mode: "dp", autopilot: %{depth: 2.0, heading: 1.0, position: %{x: 1.0, y: 2.0}}} =
               Core.status(core)

      assert Core.active?(core)

      assert %{position: %{x: 1.0, y: 2.0, phase: "hold"}, depth: %{setpoint: 2.0}} =
               Core.autopilot(core)

      # no pilot thrust in dp
      assert Core.command(core, motion(1, 0, 0), 10.0) ==
               {:error, "thrust mode motion does not match control mode dp"}

      # depth and heading cannot be released in dp
      assert Core.command(core, ap(nil), 10.0) ==
               {:error, "dp holds depth and heading: switch to motion to release them"}

      # ... but their setpoints can change; the heading is DP's held heading
      {core, _} = ok!(core, ap(3.0, 2.0))
      assert %{autopilot: %{depth: 3.0, heading: 2.0}} = Core.status(core)
      assert core.dp.heading == 2.0
    end

    test "dp keeps engaged setpoints; leaving dp for motion keeps them holding" do
      core = core([], est(position: pos(0.0, 0.0)))
      {core, _} = ok!(core, ap(5.0, 0.5))
      {core, _} = ok!(core, {:set_control_mode, :dp})
      assert %{autopilot: %{depth: 5.0, heading: 0.5}} = Core.status(core)
      {core, _} = ok!(core, {:set_control_mode, :motion})

      assert %{mode: "motion", autopilot: %{depth: 5.0, heading: 0.5, position: nil}} =
               Core.status(core)

      assert Core.active?(core)
    end
  end

  describe "autopilot commands" do
    test "need a current estimate" do
      msg = "no current estimate of depth and heading (no board samples): cannot engage"
      assert Core.command(Core.new(), ap(:hold), 10.0) == {:error, msg}
      assert Core.command(core(), ap(:hold), 11.5) == {:error, msg}
      # disengaging needs none
      assert {:ok, _, _} = Core.command(Core.new(), ap(nil, nil), 10.0)
    end

    test "hold, setpoints, null; each key on its own" do
      {core, actions} = ok!(core(@instant), ap(:hold))
      assert %{depth: 2.0, heading: nil} = Core.status(core).autopilot
      assert [_] = gos(actions)
      {core, _} = ok!(core, ap(:unchanged, 0.25))
      assert %{depth: 2.0, heading: 0.25} = Core.status(core).autopilot
      {core, _} = ok!(core, ap(nil))
      assert %{depth: nil, heading: 0.25} = Core.status(core).autopilot
      core = tick(core)

      assert %{depth: nil, heading: %{setpoint: 0.25, overridden: false, output: out}} =
               Core.autopilot(core)

      # heading 1.0 → 0.25: turn to port
      assert out < 0
    end

    test "engaged at the current depth there is no kick: neutral output" do
      {core, actions} = ok!(core(), ap(:hold))
      assert gos(actions) == [@neutral]
      {_core, actions} = Core.tick(core, 0.02, 10.01)
      assert actions == []
    end
  end

  describe "pilot override" do
    setup do
      {core, _} = ok!(core(gain: 1.0), ap(:hold, :hold))
      {:ok, core: core}
    end

    test "pilot heave overrides depth hold; release re-captures", %{core: core} do
      {core, actions} = ok!(core, motion(0.0, 0.6, 0.0))
      # the pilot's heave, times the gain, drives the vertical thruster
      assert [%{vertical: 0.6}] = gos(actions)
      assert %{depth: %{overridden: true}, heading: %{overridden: false}} = Core.autopilot(core)
      # the vehicle moved to 2.8 m
      core = Core.estimate(core, est(depth: 2.8), 10.5)
      {core, _} = ok!(core, motion(0.0, 0.0, 0.0), 10.5)
      assert %{depth: %{setpoint: 2.8, overridden: false}} = Core.autopilot(core)
      assert Core.status(core).autopilot.depth == 2.8
    end

    test "pilot yaw overrides heading hold, surge does not", %{core: core} do
      {core, _} = ok!(core, motion(0.5, 0.0, 0.0))
      assert %{heading: %{overridden: false}} = Core.autopilot(core)
      {core, actions} = ok!(core, motion(0.5, 0.0, 0.3))
      assert %{heading: %{overridden: true}} = Core.autopilot(core)
      assert gos(actions) == [Allocation.motion(%{surge: 0.5, heave: 0.0, yaw: 0.3}, 1.0)]
    end
  end

  describe "stops" do
    setup do
      core = core([gain: 1.0], est(position: pos(0.0, 0.0)))
      {core, _} = ok!(core, {:set_control_mode, :dp})
      {:ok, core: core}
    end

    test "a handover keeps the autopilots and DP holding", %{core: core} do
      for reason <- ["control_transferred", "main_station_takeover"] do
        {core2, actions} = Core.stop(core, reason)
        assert [{:go, _}, {:stopped, ^reason}] = actions
        assert Core.status(core2).mode == "dp"
        assert Core.active?(core2)
      end
    end

    test "a handover zeroes the pilot's thrust and re-captures an overridden axis" do
      {core, _} = ok!(core(gain: 1.0), ap(:hold))
      {core, _} = ok!(core, motion(0.2, 1.0, 0.0))
      core = Core.estimate(core, est(depth: 2.5), 10.2)
      {core, [{:go, thr}, _]} = Core.stop(core, "control_transferred")
      assert %{depth: %{setpoint: 2.5, overridden: false}} = Core.autopilot(core)
      assert Core.status(core).command == %{surge: 0.0, heave: 0.0, yaw: 0.0}
      assert thr.port == 0.0 and thr.starboard == 0.0
    end

    test "any other stop disengages everything and goes neutral; dp falls back to motion", %{
      core: core
    } do
      for reason <- ~w(deadman pilot_disconnected released pilot_stop helm_started sim_reset) do
        {core2, actions} = Core.stop(core, reason)
        assert actions == [{:go, @neutral}, {:stopped, reason}]

        assert %{mode: "motion", autopilot: %{depth: nil, heading: nil, position: nil}} =
                 Core.status(core2)

        refute Core.active?(core2)
        assert core2.thrusters == @neutral
      end
    end
  end

  describe "the control loop" do
    test "runs the autopilots on the estimate and commands the output" do
      {core, _} = ok!(core(@instant), ap(2.1))
      core = Core.estimate(core, est(depth: 2.0), 10.0)
      {core, actions} = Core.tick(core, 0.02, 10.01)
      assert [%{vertical: v}] = gos(actions)
      # deeper wanted: push down (positive)
      assert v > 0
      # the same output again: nothing to send
      core = %{core | depth: %{core.depth | pid: %{core.depth.pid | ki: 0.0}}}
      {core, _} = Core.tick(core, 0.02, 10.02)
      assert {_core, []} = Core.tick(core, 0.02, 10.03)
    end

    test "a stale estimate idles the outputs, keeping the setpoints" do
      {core, _} = ok!(core(), ap(2.5))
      {core, _} = Core.tick(core, 0.02, 10.01)
      {core, actions} = Core.tick(core, 0.02, 11.5)
      assert gos(actions) == [@neutral]
      assert Core.status(core).autopilot.depth == 2.5
      # estimates again: it acts again
      core = Core.estimate(core, est(depth: 2.0), 11.6)
      {_core, actions} = Core.tick(core, 0.02, 11.61)
      assert [%{vertical: v}] = gos(actions)
      assert v > 0
    end

    test "dp: surge towards the target along the heading" do
      core = core([], est(heading: 0.0, position: pos(0.0, 0.0)))
      {core, _} = ok!(core, {:set_control_mode, :dp})
      core = Core.estimate(core, est(heading: 0.0, position: pos(-1.0, 0.0)), 10.1)
      {core, actions} = Core.tick(core, 0.02, 10.1)
      assert [%{port: p, starboard: s}] = gos(actions)
      assert p > 0 and s > 0
      assert %{position: %{phase: "hold", distance: 1.0}} = Core.autopilot(core)
      # the position source gone: DP idles, depth and heading still held
      core = Core.estimate(core, est(heading: 0.0, position: nil), 10.2)
      {core, actions} = Core.tick(core, 0.02, 10.2)
      assert core.dp.demand.surge == 0.0
      assert [%{port: p, starboard: s}] = gos(actions)
      assert_in_delta p + s, 0.0, 1.0e-12

      assert {:notice,
              "dp: no valid position (no position source): holding depth and heading only"} in actions

      assert %{dp_holds: ["depth", "heading"]} = Core.status(core)
    end

    test "missions: only in dp, with a valid position; the autopilots are the mission's" do
      wp = [%{north: 5.0, east: 0.0, depth: 3.0, heading: nil, speed: 0.3, radius: 0.5}]

      assert Core.command(core(), {:mission, {:start, wp}}, 10.0) ==
               {:error, "missions run in control mode dp: switch to dp first"}

      {core, _} =
        ok!(core([], est(heading: 0.0, position: pos(0.0, 0.0))), {:set_control_mode, :dp})

      {core, actions} = ok!(core, {:mission, {:start, wp}})

      assert [
               {:mission, %{id: 1, state: "running", leg: 1, waypoints: ^wp}},
               {:notice, "mission 1: started, 1 waypoint"} | _
             ] = actions

      assert %{mission: %{id: 1, state: "running", leg: 1, count: 1}} = Core.status(core)

      assert Core.command(core, ap(4.0), 10.0) ==
               {:error,
                "a mission is running: it sets depth and heading (pause or abort it first)"}

      {core, _} = Core.tick(core, 0.02, 10.01)
      assert %{depth: %{setpoint: 3.0}, position: %{phase: "mission"}} = Core.autopilot(core)

      {core, actions} = ok!(core, {:mission, :pause})
      assert [{:mission, %{state: "paused"}} | _] = actions
      {core, _} = ok!(core, ap(4.0))
      {core, actions} = ok!(core, {:mission, :abort})
      assert [{:mission, nil} | _] = actions
      assert %{mission: nil, autopilot: %{position: %{x: 0.0, y: 0.0}}} = Core.status(core)

      # a handover stops a mission (DP holds position); a safety stop ends DP and it
      {core, _} = ok!(core, {:mission, {:start, wp}})
      {held, actions} = Core.stop(core, "control_transferred")
      assert {:mission, nil} in actions

      assert %{mode: "dp", mission: nil, dp_holds: ["depth", "heading", "position"]} =
               Core.status(held)

      {core, actions} = Core.stop(core, "deadman")
      assert {:mission, nil} in actions
      assert %{mode: "motion", mission: nil} = Core.status(core)
    end

    test "a mission without a valid position, or beyond reach, is refused with the reason" do
      wp = [%{north: 500.0, east: 0.0, depth: 3.0, heading: nil, speed: 0.3, radius: 0.5}]

      {core, _} =
        ok!(core([], est(heading: 0.0, position: pos(0.0, 0.0))), {:set_control_mode, :dp})

      assert Core.command(core, {:mission, {:start, wp}}, 10.0) ==
               {:error, "waypoint 1 is 500.0 m away: beyond the 200 m a mission may reach"}

      lost = %{
        valid: false,
        reason: "usbl: no report for 6.0 s",
        north: 0.0,
        east: 0.0,
        epoch: 1,
        shift: nil
      }

      core = Core.estimate(core, est(heading: 0.0, position: lost), 10.0)

      assert Core.command(core, {:mission, {:start, [%{hd(wp) | north: 5.0}]}}, 10.0) ==
               {:error, "a mission needs a valid position: usbl: no report for 6.0 s"}
    end
  end

  describe "measurement states (a board reset puts them back to initialising)" do
    defp states(depth, heading), do: %{depth: depth, heading: heading}

    defp initialising,
      do:
        est(
          depth: nil,
          depth_rate: nil,
          heading: nil,
          yaw_rate: nil,
          measurement_state: states(:initialising, :initialising)
        )

    test "engaging depth or heading hold on an initialising measurement is refused with the reason" do
      core = core([], initialising())

      assert Core.command(core, ap(:hold), 10.0) ==
               {:error,
                "depth hold: depth is initialising (the board's depth sensor has not given " <>
                  "consistent readings yet)"}

      assert Core.command(core, ap(:unchanged, 1.0), 10.0) ==
               {:error,
                "heading hold: heading is initialising (the board's compass has not given " <>
                  "consistent readings yet)"}

      # depth valid, heading still initialising: depth hold engages, heading hold does not
      core =
        Core.estimate(
          core,
          est(heading: nil, yaw_rate: nil, measurement_state: states(:valid, :initialising)),
          10.0
        )

      assert {:ok, _, _} = Core.command(core, ap(:hold), 10.0)

      assert {:error, "heading hold: heading is initialising" <> _} =
               Core.command(core, ap(:hold, :hold), 10.0)

      # releasing needs no measurement
      assert {:ok, _, _} = Core.command(core, ap(nil, nil), 10.0)

      core = Core.estimate(core, est(measurement_state: states(:stale, :valid)), 10.0)
      assert {:error, "depth hold: depth is stale" <> _} = Core.command(core, ap(2.0), 10.0)
    end

    test "dp is refused while depth or heading is initialising" do
      core = core([], %{initialising() | position: pos(0.0, 0.0)})

      assert {:error, "dp needs depth hold: depth is initialising" <> _} =
               Core.command(core, {:set_control_mode, :dp}, 10.0)
    end

    test "an engaged autopilot whose measurement goes back to initialising gives zero output, and the pilot is told" do
      {core, _} = ok!(core(), ap(2.5, 1.5))
      {core, _} = Core.tick(core, 0.02, 10.01)
      assert core.thrusters.vertical > 0 and Core.autopilot(core).depth.waiting == nil

      # the board resets: the estimate still comes, saying initialising
      core = Core.estimate(core, initialising(), 10.02)
      {core, actions} = Core.tick(core, 0.02, 10.03)
      assert gos(actions) == [@neutral]

      assert {:notice,
              "depth hold: depth is initialising (the board's depth sensor has not given " <>
                "consistent readings yet): output zero until it is valid"} in actions

      assert {:notice, "heading hold: heading is initialising" <> _} =
               Enum.find(actions, &match?({:notice, "heading" <> _}, &1))

      assert %{
               depth: %{
                 setpoint: 2.5,
                 output: 0.0,
                 waiting: "depth hold: depth is initialising" <> _
               }
             } = Core.autopilot(core)

      # told once
      {core, actions} = Core.tick(core, 0.02, 10.04)
      assert actions == []

      # valid again: it holds again
      core = Core.estimate(core, est(measurement_state: states(:valid, :valid)), 10.05)
      {core, actions} = Core.tick(core, 0.02, 10.06)
      assert [%{vertical: v}] = gos(actions)
      assert v > 0
      assert {:notice, "depth hold: depth valid again, holding"} in actions
      assert Core.autopilot(core).depth.waiting == nil
    end
  end

  describe "mixing" do
    test "the gain scales the pilot, not the autopilots" do
      {c1, _} = ok!(core([gain: 1.0] ++ @instant), ap(3.0))
      {c2, _} = ok!(core([gain: 0.2] ++ @instant), ap(3.0))
      {c1, c2} = {tick(c1), tick(c2)}
      assert c1.thrusters.vertical == c2.thrusters.vertical
      assert c1.thrusters.vertical == 1.0
    end

    test "heading first: surge gives way to the heading autopilot" do
      {core, _} = ok!(core([gain: 1.0] ++ @instant), ap(:unchanged, 1.0 + 0.2))
      {core, _} = ok!(tick(core), motion(1.0, 0.0, 0.0))
      %{port: p, starboard: s} = core.thrusters
      yaw = (p - s) / 2
      assert yaw > 0
      # no saturation: the difference is the heading's
      assert p <= 1.0 and abs(p + s) / 2 + abs(yaw) <= 1.0 + 1.0e-12
    end

    test "autopilot outputs skip the thrusters' deadband" do
      # kp 3 · 0.01 m = 0.03 → past the 5 % deadband
      {core, _} = ok!(core(@instant), ap(2.01))
      assert tick(core).thrusters.vertical > 0.05
      {core, _} = ok!(core([deadband: 0.0] ++ @instant), ap(2.01))
      core = tick(core)
      # (plus one tick of the integral: ki · 0.01 m · 0.02 s)
      assert_in_delta core.thrusters.vertical, 0.03, 1.0e-4
    end
  end

  describe "run mode" do
    test "a simulated board has only run mode normal" do
      core = core()
      assert Core.command(core, {:set_run_mode, :normal}, 10.0) == {:ok, core, []}

      assert Core.command(core, {:set_run_mode, :simulator}, 10.0) ==
               {:error,
                "run mode simulator needs a vehicle with a real board: this one is simulated " <>
                  "(its normal run mode is the simulator)"}
    end

    test "a change stops everything, seeds the simulator and re-applies lights, laser, tilt" do
      core = core(run_modes: [:normal, :simulator])
      {core, _} = ok!(core, {:set_lights, 9})
      {core, _} = ok!(core, ap(:hold, :hold))
      {core, actions} = ok!(core, {:set_run_mode, :simulator})

      assert actions == [
               {:go, @neutral},
               {:stopped, "run_mode_changed"},
               {:run_mode, :simulator, %{depth: 2.0, heading: 1.0}},
               {:lights, 9},
               {:laser, 0},
               {:tilt, 0.0}
             ]

      assert %{run_mode: "simulator", autopilot: %{depth: nil, heading: nil}} = Core.status(core)
      # the old vehicle's estimate is forgotten
      assert Core.fresh_estimate(core, 10.0) == nil
      {_core, actions} = ok!(core, {:set_run_mode, :normal})
      assert {:run_mode, :normal, nil} in actions
    end
  end

  describe "the vehicle's axes and allocation" do
    @sway_vehicle [axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle]
    @zero %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}

    defp strafe(s, w, h, y), do: {:thrust, :motion, %{surge: s, sway: w, heave: h, yaw: y}}

    test "the three-thruster vehicle: sway 0 may be sent and is left out, any other is refused" do
      {core, actions} = ok!(core(), strafe(0.5, 0.0, 0.0, 0.0))
      assert gos(actions) == [%{port: 0.25, vertical: 0.0, starboard: 0.25}]
      assert Core.status(core).command == %{surge: 0.5, heave: 0.0, yaw: 0.0}

      assert Core.command(core, strafe(0.5, 0.3, 0.0, 0.0), 10.0) ==
               {:error,
                "this vehicle has no sway (its axes: surge, heave, yaw): send 0 or leave it out"}
    end

    test "a vehicle that allocates itself gets the demand: the gain once, axes apart" do
      {core, actions} = ok!(core(@sway_vehicle), strafe(1.0, -0.6, 0.4, 1.0))
      # gain 0.5 on every axis; surge and yaw do not saturate each other
      assert gos(actions) == [%{surge: 0.5, sway: -0.3, heave: 0.2, yaw: 0.5}]
      assert Core.output(core) == %{surge: 0.5, sway: -0.3, heave: 0.2, yaw: 0.5}
      assert Core.status(core).command == %{surge: 1.0, sway: -0.6, heave: 0.4, yaw: 1.0}
      # the wire's thrusters stay the three-thruster view of the same demand
      assert %{port: 1.0, vertical: 0.2, starboard: 0.0} = Core.status(core).thrusters

      {core, actions} = ok!(core, {:set_gain, 1.0})
      assert gos(actions) == [%{surge: 1.0, sway: -0.6, heave: 0.4, yaw: 1.0}]

      # without sway in the command there is none
      {_core, actions} = ok!(core, motion(0.2, 0.0, 0.0))
      assert gos(actions) == [%{@zero | surge: 0.2}]
    end

    test "stops send a zero demand; handovers too" do
      core = core(@sway_vehicle)
      {core, _} = ok!(core, strafe(1.0, 1.0, 0.0, 0.0))
      assert {_core, [{:go, @zero}, {:stopped, "deadman"}]} = Core.stop(core, "deadman")

      assert {_core, [{:go, @zero}, {:stopped, "control_transferred"}]} =
               Core.stop(core, "control_transferred")

      assert {:ok, _core, [{:go, @zero}, {:stopped, "control_mode_changed"} | _]} =
               Core.command(core, {:set_control_mode, :dp}, 10.0)

      assert Core.neutral(core) == @zero
    end

    test "run mode simulator flies the three-thruster vehicle: thruster values, no sway" do
      core = core([run_modes: [:normal, :simulator]] ++ @sway_vehicle)
      {core, actions} = ok!(core, {:set_run_mode, :simulator})
      # the stop before the switch still went to the vehicle, as a demand
      assert [@zero | _] = gos(actions)
      assert Core.axes(core) == [:surge, :heave, :yaw]
      assert Core.neutral(core) == @neutral

      {core, actions} = ok!(core, motion(0.5, 0.0, 0.0))
      assert gos(actions) == [%{port: 0.25, vertical: 0.0, starboard: 0.25}]

      assert {:error, "this vehicle has no sway" <> _} =
               Core.command(core, strafe(0.0, 0.5, 0.0, 0.0), 10.0)

      {core, actions} = ok!(core, {:set_run_mode, :normal})
      assert [@neutral | _] = gos(actions)
      assert Core.axes(core) == [:surge, :sway, :heave, :yaw]
    end

    test "an autopilot's output joins the demand; the heading first, surge giving way" do
      core = core(@instant ++ @sway_vehicle)
      {core, _} = ok!(core, strafe(1.0, 0.5, 0.0, 0.0))
      {core, _} = ok!(core, ap(:unchanged, 2.0))
      %{surge: surge, sway: sway, yaw: yaw} = Core.output(tick(core))
      assert yaw > 0
      assert_in_delta abs(surge) + abs(yaw), 1.0, 1.0e-9
      assert sway == 0.25
    end

    test "the vehicle's axes change (an ArduSub's frame became known): sway offered, or taken away at once" do
      three = [axes: [:surge, :heave, :yaw], allocation: :vehicle]
      core = core(three)

      # until the frame is known there is no sway
      assert {:error, "this vehicle has no sway" <> _} =
               Core.command(core, strafe(0.0, 0.5, 0.0, 0.0), 10.0)

      {core, _} = ok!(core, motion(0.4, 0.0, 0.0))
      # a vectored frame: sway gained, the output as it was
      {core, actions} = Core.set_axes(core, [:surge, :sway, :heave, :yaw])
      assert actions == []
      assert Core.axes(core) == [:surge, :sway, :heave, :yaw]
      assert core.actuation == :full
      assert {core, []} == Core.set_axes(core, [:surge, :sway, :heave, :yaw])
      {core, actions} = ok!(core, strafe(0.4, 0.6, 0.0, 0.0))
      assert gos(actions) == [%{@zero | surge: 0.2, sway: 0.3}]

      # then a frame without lateral thrust: the sway in force goes at once, the rest flies on
      {core, actions} = Core.set_axes(core, [:surge, :heave, :yaw])
      assert gos(actions) == [%{@zero | surge: 0.2}]
      assert Core.status(core).command == %{surge: 0.4, heave: 0.0, yaw: 0.0}
      assert core.actuation == :surge

      assert {:error, "this vehicle has no sway" <> _} =
               Core.command(core, strafe(0.0, 0.5, 0.0, 0.0), 10.0)
    end

    test "the axes changing in manual mode leave the thruster command alone" do
      core = core(axes: [:surge, :sway, :heave, :yaw])
      {core, _} = ok!(core, {:set_control_mode, :manual})
      {core, _} = ok!(core, {:thrust, :manual, %{port: 0.5, vertical: 0.0, starboard: 0.5}})
      {core2, actions} = Core.set_axes(core, [:surge, :heave, :yaw])
      assert actions == []
      assert core2.pilot == core.pilot
    end
  end
end
