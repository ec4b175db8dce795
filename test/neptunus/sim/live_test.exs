defmodule Neptunus.Sim.LiveTest do
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias Neptunus.Sim.Live
  alias Neptunus.Vehicle.{Board, Telemetry}

  doctest Neptunus.Sim.Live

  @moduletag :capture_log

  describe "validate/2" do
    test "sim_reset takes an empty payload" do
      assert Live.validate("sim_reset", %{}) == {:ok, :reset}

      assert Live.validate("sim_reset", %{"hard" => true}) ==
               {:error, "unknown field: hard (no fields expected)"}

      assert Live.validate("sim_reset", "now") ==
               {:error, ~s(the document must be an object, got "now")}
    end

    test "sim_set takes paused, current and tether_length" do
      assert Live.validate("sim_set", %{"paused" => false, "tether_length" => 20}) ==
               {:ok, {:set, %{paused: false, tether_length: 20.0}}}

      for {payload, reason} <- [
            {%{}, "sim_set needs at least one of: current, paused, tether_length"},
            {%{"speed" => 1},
             "unknown field: speed (expected one of: current, paused, tether_length)"},
            {%{"paused" => "yes"}, ~s(paused must be true or false, got "yes")},
            {%{"current" => [1, 2]}, "current must be a list of 3 numbers, got [1,2]"},
            {%{"current" => [0, 0, 6]}, "current[2] must be a number in [-5, 5], got 6"},
            {%{"tether_length" => -1}, "tether_length must be a number in [0, 1000], got -1"}
          ] do
        assert Live.validate("sim_set", payload) == {:error, reason}
      end
    end
  end

  describe "command/3" do
    defp start!(board) do
      id = "live-#{System.unique_integer([:positive])}"
      PubSub.subscribe(Telemetry.topic(id))
      start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: board, report_to: self()}})
      id
    end

    test "reset stops the thrusters first and puts the vehicle back" do
      id = start!(:simulated)
      assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
      Process.sleep(50)

      assert {:ok, %{sim: %{t: +0.0, vehicle: "neptunus", paused: false}}} =
               Live.command(id, "sim_reset", %{})

      assert_receive {:pubsub, _, "stopped", %{reason: "sim_reset"}}
    end

    test "set changes the simulation; a bad payload changes nothing" do
      id = start!(:simulated)

      assert {:ok, %{sim: %{current: [0.0, 0.2, 0.0]}}} =
               Live.command(id, "sim_set", %{"current" => [0, 0.2, 0]})

      assert {:error, _} = Live.command(id, "sim_set", %{"current" => [0, 9, 0]})
      assert Board.Simulated.state(id).sim |> Neptunus.Sim.current() == {0.0, 0.2, 0.0}
    end

    test "refused on a board that is not the built-in simulator" do
      id = start!(Neptunus.Vehicle.Board.Test)

      assert Live.command(id, "sim_reset", %{}) ==
               {:error,
                "sim_reset is only available on a simulated vehicle (board: Neptunus.Vehicle.Board.Test)"}

      assert {:error, "sim_set is only available on a simulated vehicle" <> _} =
               Live.command(id, "sim_set", %{"paused" => true})

      assert Live.command("nope", "sim_set", %{"paused" => true}) ==
               {:error, "unknown vehicle: nope"}
    end
  end
end
