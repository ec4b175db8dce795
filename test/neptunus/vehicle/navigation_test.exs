defmodule Neptunus.Vehicle.NavigationTest do
  use ExUnit.Case, async: true

  @moduletag :capture_log

  alias Neptunus.{Allocation, Fleet}
  alias Neptunus.Vehicle.{Board, Control, Navigation, Telemetry}

  @m %{depth: 1.0, heading: 0.5, roll: 0.01, pitch: -0.01, voltage: 12.4, current: 0.4}

  defp id, do: "nav-#{System.unique_integer([:positive])}"

  describe "alone, the test process standing in for telemetry and control" do
    setup do
      id = id()
      {:ok, _} = Registry.register(Fleet.Registry, {Telemetry, id}, nil)
      {:ok, _} = Registry.register(Fleet.Registry, {Control, id}, nil)
      start_supervised!({Navigation, id: id})
      {:ok, id: id}
    end

    test "a sample goes on to telemetry filtered and estimated, the estimate to control",
         %{id: id} do
      truth = %{x: 3.0, y: -2.0, z: 1.0, psi: 0.5}
      Navigation.sample(id, %{t: 1.0, measurement: @m, sim: truth})

      # no first reading is trusted: initialising, no numbers
      assert_receive {:"$gen_cast", {:sample, sample}}
      assert %{t: 1.0, sim: ^truth} = sample
      assert sample.measurement |> Map.values() |> Enum.all?(&is_nil/1)
      assert sample.measurement_state |> Map.values() |> Enum.all?(&(&1 == "initialising"))

      assert sample.estimate == %{
               depth: nil,
               depth_rate: nil,
               heading: nil,
               yaw_rate: nil,
               roll: nil,
               roll_rate: nil,
               pitch: nil,
               pitch_rate: nil
             }

      assert_receive {:"$gen_cast", {:estimate, estimate}}
      # the simulator's truth is no position source: the simulated DVL and USBL are
      assert %{depth: nil, heading: nil, position: %{valid: false, north: nil}} = estimate
      assert estimate.position.reason == "no position source"
      assert estimate.measurement_state == %{depth: :initialising, heading: :initialising}

      # the readings agree past the settle time: valid
      warm(id, 1.05, truth)
      sample = last_cast(:sample)
      assert %{measurement: @m, sim: ^truth} = sample
      assert sample.measurement_state |> Map.values() |> Enum.all?(&(&1 == "valid"))
      # (the model's net buoyancy lifts it a little between the held readings)
      assert %{depth: depth, heading: 0.5, yaw_rate: 0.0} = sample.estimate
      assert_in_delta depth, 1.0, 1.0e-3

      assert %{total: 0, by_field: %{depth: 0}, by_reason: %{}, reacquired: 0} =
               sample.wild_points

      assert %{
               heading: 0.5,
               yaw_rate: 0.0,
               position: %{valid: false, reason: "no position source"},
               measurement_state: %{depth: :valid, heading: :valid}
             } = last_cast(:estimate)
    end

    test "wild points are counted and never passed on", %{id: id} do
      warm(id, 1.0, nil)
      flush_casts()
      Navigation.sample(id, %{t: 2.5, measurement: %{@m | depth: 10.0, heading: 50.0}, sim: nil})

      assert_receive {:"$gen_cast", {:sample, %{t: 2.5} = sample}}
      assert sample.measurement.depth == 1.0 and sample.measurement.heading == 0.5
      assert_in_delta sample.estimate.depth, 1.0, 1.0e-4
      assert %{total: 2, by_field: %{depth: 1, heading: 1}} = sample.wild_points

      assert %{wild_points: %{total: 2}, measurement: %{depth: 1.0}} = Navigation.status(id)
    end

    test "board_reset/2: every measurement initialising again, control told at once",
         %{id: id} do
      warm(id, 1.0, nil)
      assert %{measurement_state: %{depth: :valid}} = Navigation.status(id)
      flush_casts()

      Navigation.board_reset(id, "link up")
      assert_receive {:"$gen_cast", {:estimate, estimate}}
      assert %{depth: nil, heading: nil} = estimate
      assert estimate.measurement_state == %{depth: :initialising, heading: :initialising}

      assert %{board_resets: 1, measurement: %{depth: nil}, measurement_state: states} =
               Navigation.status(id)

      assert states |> Map.values() |> Enum.all?(&(&1 == :initialising))

      # the settle time starts again at the next sample
      Navigation.sample(id, %{t: 3.0, measurement: @m, sim: nil})
      assert_receive {:"$gen_cast", {:sample, %{t: 3.0} = sample}}
      assert sample.measurement_state.depth == "initialising" and sample.measurement.depth == nil
      warm(id, 3.05, nil)
      assert last_cast(:sample).measurement_state.depth == "valid"
    end

    test "the board's clock going back (a board reset) re-initialises", %{id: id} do
      for i <- 0..29 do
        Navigation.sample(id, %{
          t: 1.0 + i * 0.05,
          measurement: @m,
          sim: nil,
          board: %{board_time: 10.0 + i * 0.05}
        })
      end

      assert %{measurement_state: %{depth: :valid}, board_resets: 0} = Navigation.status(id)
      Navigation.sample(id, %{t: 2.6, measurement: @m, sim: nil, board: %{board_time: 0.1}})

      assert %{measurement_state: %{depth: :initialising}, board_resets: 1} =
               Navigation.status(id)
    end

    test "until depth and heading are valid, control's estimate has no numbers", %{id: id} do
      Navigation.sample(id, %{t: 1.0, measurement: %{@m | heading: 9.0}, sim: nil})
      assert_receive {:"$gen_cast", {:estimate, %{depth: nil, heading: nil} = estimate}}
      assert estimate.measurement_state == %{depth: :initialising, heading: :initialising}
    end

    test "an ArduSub board's position (LOCAL_POSITION_NED) is a position source", %{id: id} do
      # a new position is one with a new time_boot_ms; the first one starts the filter on
      # it, a second that agrees makes it valid
      Navigation.sample(id, %{
        t: 1.0,
        measurement: @m,
        sim: nil,
        board: %{position: %{x: 1.0, y: 2.0, time_boot_ms: 1000}}
      })

      assert_receive {:"$gen_cast", {:estimate, %{position: first}}}
      assert %{valid: false, frame: :ardusub, north: n, east: e} = first
      assert_in_delta n, 1.0, 1.0e-6
      assert_in_delta e, 2.0, 1.0e-6
      assert first.reason =~ "second fix"

      Navigation.sample(id, %{
        t: 1.05,
        measurement: @m,
        sim: nil,
        board: %{position: %{x: 1.0, y: 2.0, time_boot_ms: 1050}}
      })

      assert_receive {:"$gen_cast", {:estimate, %{t: 1.05, position: %{valid: true} = second}}}
      assert_in_delta second.north, 1.0, 0.05
      assert_in_delta second.east, 2.0, 0.05

      assert %{position: %{valid: true, sources: [%{name: "ardusub", accepted: 2}]}} =
               Navigation.status(id)
    end

    test "without a position source the position is not valid, and says so", %{id: id} do
      Navigation.sample(id, %{t: 1.0, measurement: @m, sim: nil, board: %{yaw: 0.1}})

      assert_receive {:"$gen_cast",
                      {:estimate, %{position: %{valid: false, reason: "no position source"}}}}
    end

    test "commands drive the filter's model", %{id: id} do
      Navigation.command(id, %{port: 0.2, vertical: 1.0, starboard: 0.2})
      assert %{command: %{vertical: 1.0, port: 0.2}} = Navigation.status(id)
    end
  end

  describe "in the vehicle" do
    setup do
      id = id()

      start_supervised!(
        {Neptunus.Vehicle.Supervisor, %{id: id, board: Board.Test, report_to: self()}}
      )

      {:ok, id: id}
    end

    test "board samples reach telemetry through navigation", %{id: id} do
      Board.Test.sample(id, %{t: 1.0, measurement: @m, sim: nil})

      assert %{measurement: %{depth: nil}, measurement_state: %{depth: "initialising"}} =
               Telemetry.latest(id)

      for i <- 1..30, do: Board.Test.sample(id, %{t: 1.0 + i * 0.05, measurement: @m, sim: nil})
      Board.Test.sample(id, %{t: 2.55, measurement: %{@m | depth: 100.0}, sim: nil})

      assert %{
               t: 2.55,
               measurement_state: %{depth: "valid", heading: "valid"},
               measurement: %{depth: 1.0},
               estimate: %{depth: depth, heading: 0.5},
               wild_points: %{total: 1, by_field: %{depth: 1}}
             } = Telemetry.latest(id)

      assert_in_delta depth, 1.0, 1.0e-4
    end

    test "autopilots refuse to engage on an initialising measurement, with the reason", %{id: id} do
      Board.Test.sample(id, %{t: 1.0, measurement: @m, sim: nil})
      _ = Navigation.status(id)

      assert Control.command(id, "autopilot", %{"depth" => "hold"}) ==
               {:error,
                "depth hold: depth is initialising (the board's depth sensor has not given " <>
                  "consistent readings yet)"}

      for i <- 1..30, do: Board.Test.sample(id, %{t: 1.0 + i * 0.05, measurement: @m, sim: nil})
      _ = Navigation.status(id)

      assert {:ok, %{control: %{autopilot: %{depth: depth}}}} =
               Control.command(id, "autopilot", %{"depth" => "hold"})

      assert_in_delta depth, 1.0, 1.0e-3

      # a board reset: initialising again, and the reason is back
      Navigation.board_reset(id, "test")
      _ = Navigation.status(id)

      assert {:error, "heading hold: heading is initialising" <> _} =
               Control.command(id, "autopilot", %{"heading" => "hold"})
    end

    test "thruster commands reach navigation with the board", %{id: id} do
      Board.go(id, %{port: 0.5, vertical: -0.5, starboard: 0.5})
      assert_receive {:board, ^id, {:go, %{vertical: -0.5}}}
      assert %{command: %{port: 0.5, vertical: -0.5, starboard: 0.5}} = Navigation.status(id)
    end

    test "a crash of navigation restarts what comes after it, not the board", %{id: id} do
      neutral = Allocation.neutral()
      assert_receive {:board, ^id, {:started, ^neutral}}
      Board.Test.sample(id, %{t: 1.0, measurement: @m, sim: nil})
      flush_gos(id)
      board = Fleet.whereis(Board, id)
      control = Fleet.whereis(Control, id)

      Process.exit(Fleet.whereis(Navigation, id), :kill)
      # control restarts, and drives the thrusters neutral; the board stays
      assert_receive {:board, ^id, {:go, ^neutral}}
      refute_received {:board, ^id, {:started, _}}
      assert Fleet.whereis(Board, id) == board
      assert Fleet.whereis(Control, id) != control
      assert %{samples: 0} = Navigation.status(id)
    end
  end

  # samples of @m at 20 Hz from t0 for 1.5 s (valid after the settle time), then let them
  # all arrive
  defp warm(id, t0, sim) do
    for i <- 0..29, do: Navigation.sample(id, %{t: t0 + i * 0.05, measurement: @m, sim: sim})
    _ = Navigation.status(id)
  end

  # the last cast of `kind` that arrived
  defp last_cast(kind, last \\ nil) do
    receive do
      {:"$gen_cast", {^kind, value}} -> last_cast(kind, value)
    after
      0 -> last
    end
  end

  defp flush_casts do
    receive do
      {:"$gen_cast", _} -> flush_casts()
    after
      0 -> :ok
    end
  end

  defp flush_gos(id) do
    receive do
      {:board, ^id, {:go, _}} -> flush_gos(id)
    after
      100 -> :ok
    end
  end

  test "on a simulated vehicle the estimate follows the simulator's truth" do
    id = id()
    start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}})

    wait = fn wait, n ->
      case Telemetry.latest(id) do
        %{t: t} = latest when t > 1.8 -> latest
        _ when n > 0 -> Process.sleep(50) && wait.(wait, n - 1)
      end
    end

    latest = wait.(wait, 100)
    assert_in_delta latest.estimate.depth, latest.sim.z, 0.05
    heading_error = Neptunus.Dynamics.wrap_pi(latest.estimate.heading - latest.sim.psi)
    assert_in_delta heading_error, 0.0, 0.05
    assert is_float(latest.estimate.depth_rate) and is_float(latest.estimate.yaw_rate)
  end
end
