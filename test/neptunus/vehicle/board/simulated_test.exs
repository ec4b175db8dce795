defmodule Neptunus.Vehicle.Board.SimulatedTest do
  # The live simulated board under the test's supervisor (vehicle processes included).
  use ExUnit.Case, async: true

  import Neptunus.Test.Pty, only: [wait_until: 2]

  alias Neptunus.{PubSub, Sim}
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  @moduletag :capture_log

  defp start!(extra \\ %{}) do
    id = "sim-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))

    start_supervised!(
      {Neptunus.Vehicle.Supervisor, Map.merge(%{id: id, board: :simulated}, extra)}
    )

    id
  end

  test "by default it simulates the neptunus set with realistic sensors" do
    id = start!()
    state = Board.Simulated.state(id)
    assert state.sim.params.name == "neptunus"
    assert state.sim.sensors != nil
    assert state.sim.dt == 0.01
    assert is_integer(Keyword.fetch!(state.sim.opts, :seed))

    assert_receive {:pubsub, _, "telemetry",
                    %{
                      measurement: m,
                      sim: truth,
                      measurement_state: %{depth: "valid", heading: "valid"}
                    }}

    assert Map.keys(truth) |> Enum.sort() == ~w(p phi psi q r theta u v w x y z)a
    assert is_float(m.depth) and is_float(m.heading)
  end

  test "the :sim option overrides any Sim option" do
    id = start!(%{sim: [vehicle: "thesis-4dof", noise: false, seed: 3], initial: [z: 4.0]})
    state = Board.Simulated.state(id)
    assert state.sim.params.name == "thesis-4dof"
    assert state.sim.sensors == nil
    assert Sim.status(state.sim).seed == 3

    assert_receive {:pubsub, _, "telemetry",
                    %{measurement: m, sim: truth, measurement_state: %{depth: "valid"}}}

    assert m.depth == truth.z
    assert_in_delta truth.z, 4.0, 0.01
  end

  test "pause freezes simulated time, resume continues; reset starts again" do
    id = start!(%{sim: [noise: false]})
    wait_until(fn -> Sim.time(Board.Simulated.state(id).sim) > 0 end, "simulated time")

    assert {:ok, %{paused: true, t: t0}} = Board.Simulated.command(id, {:set, %{paused: true}})
    # ticks keep coming while paused, each reporting the last sample again: telemetry at t0,
    # three times (at least two of them after the pause), and the simulation has not stepped
    for _ <- 1..3, do: assert_receive({:pubsub, _, "telemetry", %{t: ^t0}})
    assert Board.Simulated.state(id).sim.steps * 0.01 == t0
    assert Telemetry.latest(id).t == t0

    assert {:ok, %{paused: false}} = Board.Simulated.command(id, {:set, %{paused: false}})
    wait_until(fn -> Sim.time(Board.Simulated.state(id).sim) > t0 end, "time going on")

    assert {:ok, %{t: +0.0, paused: false}} = Board.Simulated.command(id, :reset)
  end

  test "current and tether length are set live and survive a reset" do
    id = start!()

    assert {:ok, %{current: [0.1, 0.0, 0.0], tether_length: 5.0}} =
             Board.Simulated.command(id, {:set, %{current: {0.1, 0.0, 0.0}, tether_length: 5}})

    assert {:ok, %{current: [0.1, 0.0, 0.0], tether_length: 5.0}} =
             Board.Simulated.command(id, :reset)
  end

  test "a reset keeps the thruster command Control set" do
    id = start!()
    {:ok, _} = Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})
    thrusters = Board.Simulated.state(id).sim.thrusters
    assert thrusters.port > 0
    {:ok, _} = Board.Simulated.command(id, :reset)
    assert Board.Simulated.state(id).sim.thrusters == thrusters
  end

  test "with stats: true it records each tick's lateness against its deadline" do
    id = start!(%{stats: true})
    assert Board.Simulated.stats(start!()) == nil
    wait_until(fn -> length(Board.Simulated.stats(id).lateness) >= 20 end, "20 ticks")
    %{lateness: lateness, work: work} = Board.Simulated.stats(id, reset: true)
    assert length(lateness) >= 20 and length(lateness) == length(work)
    assert Enum.all?(work, &(&1 >= 0))
    assert %{lateness: fresh} = Board.Simulated.stats(id)
    assert length(fresh) < length(lateness)
  end
end
