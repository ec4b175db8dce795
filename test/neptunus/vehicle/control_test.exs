defmodule Neptunus.Vehicle.ControlTest do
  # Vehicle.Control as a process, on the test board (which reports every command to the test
  # process). Estimates are sent by the test (Control.estimate/2), as navigation does.
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Fleet, PubSub}
  alias Neptunus.Vehicle.{Board, Control, Helm, Telemetry}

  @moduletag :capture_log
  @neutral %{port: 0.0, vertical: 0.0, starboard: 0.0}

  # a test's `@tag vehicle: %{...}` is merged into the vehicle (e.g. the board's capabilities)
  setup ctx do
    id = "ctl-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))

    vehicle = %{
      id: id,
      board: Board.Test,
      report_to: self(),
      control: [stale_after: 1.0, simulator: [sim: [noise: false]]],
      helm: [tick_ms: 3_600_000]
    }

    vehicle = Map.merge(vehicle, Map.get(ctx, :vehicle, %{}))

    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    flush_board(id)
    {:ok, id: id}
  end

  defp flush_board(id) do
    receive do
      {:board, ^id, _} -> flush_board(id)
    after
      50 -> :ok
    end
  end

  defp estimate(id, opts \\ []) do
    Control.estimate(
      id,
      Map.merge(
        %{t: 1.0, depth: 2.0, depth_rate: 0.0, heading: 1.0, yaw_rate: 0.0, position: nil},
        Map.new(opts)
      )
    )
  end

  defp command(id, event, payload), do: Control.command(id, event, payload)

  test "the control state: what the grant, replies and telemetry carry", %{id: id} do
    assert %{
             mode: "motion",
             gain: 0.5,
             lights: 0,
             laser: 0,
             tilt: 0.0,
             run_mode: "normal",
             autopilot: %{depth: nil, heading: nil, position: nil},
             command: %{surge: 0.0},
             thrusters: %{port_us: 1500}
           } = Control.status(id)

    assert Control.events() --
             ~w(set_control_mode set_gain set_lights set_laser set_tilt autopilot set_run_mode
                mission) ==
             []

    party = %{id: "p1", name: "ada", role: :pilot, pid: self(), notify: fn _, _ -> :ok end}
    assert {:ok, %{grant: %{control: control}}} = Helm.request_control(id, party)
    assert control == Control.status(id)
  end

  test "lights, laser and tilt reach the board at once, without a thrust", %{id: id} do
    assert {:ok, %{control: %{lights: 128}}} = command(id, "set_lights", %{"value" => 128})
    assert_receive {:board, ^id, {:lights, 128}}
    assert {:ok, %{control: %{laser: 3}}} = command(id, "set_laser", %{"value" => 3})
    assert_receive {:board, ^id, {:laser, 3}}
    assert {:ok, %{control: %{tilt: -0.5}}} = command(id, "set_tilt", %{"value" => -0.5})
    assert_receive {:board, ^id, {:tilt, -0.5}}
    refute_received {:board, ^id, {:go, _}}

    assert {:error, "value must be an integer in [0, 255], got 300"} =
             command(id, "set_lights", %{"value" => 300})

    assert Control.status(id).lights == 128
  end

  test "manual mode: stop first, then each thruster times the gain", %{id: id} do
    {:ok, _} = Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})
    assert_receive {:board, ^id, {:go, %{port: 0.5}}}

    assert {:ok, %{control: %{mode: "manual"}}} =
             command(id, "set_control_mode", %{"mode" => "manual"})

    assert_receive {:board, ^id, {:go, @neutral}}
    assert_receive {:pubsub, _, "stopped", %{reason: "control_mode_changed"}}

    assert {:ok, %{command: cmd, thrusters: thr, control: %{mode: "manual"}}} =
             Control.thrust(id, %{
               "mode" => "manual",
               "port" => 1,
               "vertical" => -0.5,
               "starboard" => 0
             })

    assert cmd == %{port: 1.0, vertical: -0.5, starboard: 0.0}
    assert %{port: 0.5, vertical: -0.25, starboard: +0.0, vertical_us: 1375} = thr
    assert_receive {:board, ^id, {:go, %{port: 0.5, vertical: -0.25, starboard: +0.0}}}

    assert {:error, "thrust mode motion does not match control mode manual"} =
             Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})
  end

  test "depth hold runs on the control loop and shows in telemetry", %{id: id} do
    assert {:error, "no current estimate" <> _} = command(id, "autopilot", %{"depth" => "hold"})
    estimate(id, depth: 2.0)

    assert {:ok, %{control: %{autopilot: %{depth: 2.1, heading: nil}}}} =
             command(id, "autopilot", %{"depth" => 2.1})

    # engaging starts from where the vehicle is (no jump), then the loop keeps commanding the
    # vertical thruster down towards 2.1 m, harder as the reference moves there
    assert_receive {:board, ^id, {:go, %{vertical: v0}}}
    assert v0 == 0.0
    assert_receive {:board, ^id, {:go, %{vertical: v1}}}
    assert_receive {:board, ^id, {:go, %{vertical: v2}}}
    assert v2 > v1 and v1 > 0

    Board.Test.sample(id, %{t: 1.0, measurement: measurement(), sim: nil})
    estimate(id, depth: 2.0)
    assert_receive {:pubsub, _, "telemetry", %{control: c, autopilot: ap}}
    assert %{mode: "motion", autopilot: %{depth: 2.1}} = c
    assert %{depth: %{setpoint: 2.1, output: out, overridden: false}, heading: nil} = ap
    assert out > 0

    # a deadman stop disengages it and goes neutral
    {:ok, _} = Control.stop(id, "deadman")
    assert Control.status(id).autopilot.depth == nil
    flush_board(id)
    estimate(id, depth: 2.0)
    refute_receive {:board, ^id, {:go, _}}, 100
  end

  test "estimates stop coming: outputs go neutral, setpoints stay", %{id: id} do
    estimate(id, depth: 2.0)
    {:ok, _} = command(id, "autopilot", %{"depth" => 3.0})
    assert_receive {:board, ^id, {:go, %{vertical: v}}} when v > 0
    # stale after 1 s (this test's setting)
    assert_receive {:board, ^id, {:go, @neutral}}
    assert Control.status(id).autopilot.depth == 3.0
  end

  test "dp: depth and heading only without a position source, position too with one", %{id: id} do
    estimate(id)
    PubSub.subscribe(Telemetry.log_topic(id))

    assert {:ok, %{control: %{mode: "dp", dp_holds: ["depth", "heading"]}}} =
             command(id, "set_control_mode", %{"mode" => "dp"})

    assert_receive {:pubsub, _, "log",
                    %{
                      category: "autopilot",
                      message: "dp: no valid position (no position source)" <> _
                    }}

    {:ok, _} = command(id, "set_control_mode", %{"mode" => "motion"})

    estimate(id,
      position: %{
        valid: true,
        reason: nil,
        north: 3.0,
        east: -1.0,
        velocity_north: 0.0,
        velocity_east: 0.0,
        velocity_measured: true,
        frame: :local,
        epoch: 0,
        shift: nil
      }
    )

    assert {:ok,
            %{
              control: %{
                mode: "dp",
                dp_holds: ["depth", "heading", "position"],
                autopilot: %{position: %{x: 3.0, y: -1.0}}
              }
            }} = command(id, "set_control_mode", %{"mode" => "dp"})

    assert {:error, "thrust mode motion does not match control mode dp"} =
             Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})

    # a handover keeps it holding
    {:ok, _} = Control.stop(id, "control_transferred")
    assert %{mode: "dp"} = Control.status(id)
  end

  describe "tuning" do
    test "gains apply at once, bumpless, are stored for the vehicle and applied at start", %{
      id: id
    } do
      on_exit(fn -> Neptunus.Settings.delete({:vehicle, id}, "tuning") end)
      estimate(id, depth: 2.0)
      {:ok, _} = command(id, "autopilot", %{"depth" => 2.2})
      Process.sleep(200)
      estimate(id, depth: 2.0)

      assert {:error, "depth.kp must be a number in [0, 20], got 25"} =
               Control.tune(id, %{"depth" => %{"kp" => 25}})

      PubSub.subscribe(Telemetry.log_topic(id))

      assert {:ok, %{tuning: %{"depth" => %{"kp" => 6.0, "ki" => 0.1, "kd" => 1.5}}}} =
               Control.tune(id, %{"depth" => %{"kp" => 6}})

      assert_receive {:pubsub, _, "log",
                      %{
                        category: "autopilot",
                        message:
                          "autopilot tuning: depth kp 6.0 ki 0.1 kd 1.5; heading kp 4.0" <> _
                      }}

      assert %{gains: %{"depth" => %{"kp" => 6.0}, "heading" => %{"kp" => 4.0}}} =
               Control.tuning(id)

      assert {:ok, %{"depth" => %{"kp" => 6.0}}} = Neptunus.Settings.get({:vehicle, id}, "tuning")

      # the vehicle restarts: its control comes back with the stored gains
      pid = GenServer.whereis(Fleet.via(Control, id))
      ref = Process.monitor(pid)
      Process.exit(pid, :kill)
      assert_receive {:DOWN, ^ref, _, _, _}

      wait = fn wait ->
        if GenServer.whereis(Fleet.via(Control, id)) in [nil, pid],
          do:
            (
              Process.sleep(20)
              wait.(wait)
            ),
          else: :ok
      end

      wait.(wait)
      assert %{gains: %{"depth" => %{"kp" => 6.0}}} = Control.tuning(id)
    end

    test "a step response runs on the vehicle's model with the proposed gains", %{id: id} do
      assert {:ok, %{axis: "depth", overshoot: o, settle: s, t: t, value: v}} =
               Control.step_response(id, %{"axis" => "depth", "step" => 1})

      assert o < 0.1 and s < 10 and length(t) == length(v)

      assert {:ok, %{settle: weak}} =
               Control.step_response(id, %{
                 "axis" => "depth",
                 "step" => 1,
                 "gains" => %{"depth" => %{"kp" => 0.3, "ki" => 0, "kd" => 0}}
               })

      assert weak == nil or weak > s
      # the vehicle's gains did not change
      assert %{gains: %{"depth" => %{"kp" => 3.0}}} = Control.tuning(id)
    end
  end

  describe "run mode simulator" do
    test "commands and samples move to a simulator seeded from the estimate, and back", %{
      id: id
    } do
      estimate(id, depth: 4.0, heading: :math.pi() / 2)
      {:ok, _} = command(id, "set_lights", %{"value" => 50})
      flush_board(id)

      assert {:ok, %{control: %{run_mode: "simulator"}}} =
               command(id, "set_run_mode", %{"mode" => "simulator"})

      assert_receive {:pubsub, _, "stopped", %{reason: "run_mode_changed"}}
      sim = Control.simulator(id)
      assert is_pid(sim)
      assert Control.sample_source(id) == :simulator

      # seeded at the estimated depth and heading
      %{sim: %{dyn: dyn}, devices: devices} = :sys.get_state(sim)
      assert_in_delta dyn.z, 4.0, 0.05
      assert_in_delta dyn.psi, :math.pi() / 2, 0.05
      assert devices.lights == 50

      # the real board stays neutral: thrust goes to the simulator
      {:ok, _} = Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})
      refute_receive {:board, ^id, {:go, %{port: 0.5}}}, 100
      assert %{port: 0.5} = :sys.get_state(sim).sim.thrusters
      # ... lights too
      {:ok, _} = command(id, "set_lights", %{"value" => 60})
      refute_receive {:board, ^id, {:lights, 60}}, 50
      assert :sys.get_state(sim).devices.lights == 60

      # the real board's samples are dropped; telemetry shows the simulator's
      Board.Test.sample(id, %{t: 99.0, measurement: measurement(), sim: nil})
      Process.sleep(50)
      assert %{sim: %{z: _}, t: t} = Telemetry.latest(id)
      assert t < 99.0

      # the real board is still kept alive
      assert_receive {:board, ^id, :keepalive}

      assert {:ok, %{control: %{run_mode: "normal"}}} =
               command(id, "set_run_mode", %{"mode" => "normal"})

      assert_receive {:board, ^id, {:lights, 60}}
      refute Process.alive?(sim)
      assert Control.simulator(id) == nil
      assert Control.sample_source(id) == :board
    end

    test "a simulated board has no other run mode" do
      id = "ctl-sim-#{System.unique_integer([:positive])}"
      start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}}, id: :sim)

      assert {:error, "run mode simulator needs a vehicle with a real board" <> _} =
               command(id, "set_run_mode", %{"mode" => "simulator"})

      assert {:ok, %{control: %{run_mode: "normal"}}} =
               command(id, "set_run_mode", %{"mode" => "normal"})
    end

    test "if the simulator dies, control restarts in run mode normal", %{id: id} do
      estimate(id)
      {:ok, _} = command(id, "set_run_mode", %{"mode" => "simulator"})
      control = Fleet.whereis(Control, id)
      Process.exit(Control.simulator(id), :kill)
      assert_receive {:board, ^id, {:go, @neutral}}
      wait_for(fn -> Fleet.whereis(Control, id) not in [nil, control] end)
      assert %{run_mode: "normal"} = Control.status(id)
      assert Control.sample_source(id) == :board
    end
  end

  test "the simulated board records lights, laser and tilt and reports them" do
    id = "ctl-dev-#{System.unique_integer([:positive])}"
    start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}}, id: :sim)
    Board.lights(id, 7)
    Board.laser(id, 8)
    Board.tilt(id, 0.25)
    assert %{devices: %{lights: 7, laser: 8, tilt: 0.25}} = Board.Simulated.state(id)
    assert Allocation.neutral() == Board.Simulated.state(id).sim.thrusters
  end

  test "a simulated neptunus-sway sways: sway in its axes, the pilot's sway on its lateral thruster" do
    id = "ctl-sway-#{System.unique_integer([:positive])}"

    start_supervised!(
      {Neptunus.Vehicle.Supervisor,
       %{id: id, board: :simulated, sim: [vehicle: "neptunus-sway", noise: false]}},
      id: :sway
    )

    assert %{axes: [:surge, :sway, :heave, :yaw], allocation: :thesis} = Board.capabilities(id)
    payload = %{"mode" => "motion", "surge" => 0.0, "sway" => 0.8, "heave" => 0.0, "yaw" => 0.0}
    assert {:ok, %{command: %{sway: 0.8}}} = Control.thrust(id, payload)
    # the gain (0.5) once, on the lateral thruster; the three-thruster allocation neutral
    wait_for(fn -> Board.Simulated.state(id).sim.thrusters[:lateral] == 0.4 end)

    assert %{port: +0.0, vertical: +0.0, starboard: +0.0} =
             Board.Simulated.state(id).sim.thrusters
  end

  defp measurement,
    do: %{depth: 1.0, heading: 0.5, roll: 0.0, pitch: 0.0, voltage: 12.0, current: 1.0}

  defp wait_for(fun, n \\ div(Neptunus.Test.Patience.ms(), 20)) do
    cond do
      fun.() -> :ok
      n == 0 -> flunk("timed out")
      true -> Process.sleep(20) && wait_for(fun, n - 1)
    end
  end

  describe "a vehicle that allocates itself (the test board with ArduSub's capabilities)" do
    @zero %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
    @sways %{capabilities: %{axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle}}

    @tag vehicle: @sways
    test "its capabilities are everyone's", %{id: id} do
      assert %{axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle, real: true} =
               Board.capabilities(id)
    end

    @tag vehicle: @sways
    test "the board gets the demand: thrust (gain once), then zero on a stop", %{id: id} do
      payload = %{"mode" => "motion", "surge" => 0.4, "sway" => -1, "heave" => 0, "yaw" => 0.2}
      assert {:ok, %{command: %{sway: -1.0}}} = Control.thrust(id, payload)
      assert_receive {:board, ^id, {:go, %{surge: 0.2, sway: -0.5, heave: 0.0, yaw: 0.1}}}
      refute_received {:board, ^id, {:go, %{port: _}}}

      assert {:ok, _} = Control.stop(id, "pilot_stop")
      assert_receive {:board, ^id, {:go, @zero}}
    end

    test "the three-thruster vehicle refuses sway with a reason, takes sway 0", %{id: id} do
      payload = %{"mode" => "motion", "surge" => 0, "sway" => 0.5, "heave" => 0, "yaw" => 0}
      assert {:error, "this vehicle has no sway" <> _} = Control.thrust(id, payload)
      assert {:ok, _} = Control.thrust(id, %{payload | "sway" => 0})
    end
  end
end
