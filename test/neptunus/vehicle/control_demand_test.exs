defmodule Neptunus.Vehicle.ControlDemandTest do
  # Vehicle.Control on a board whose vehicle allocates itself (the test board with ArduSub's
  # capabilities): what the board gets is the body-frame demand, from start to stop.
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  @moduletag :capture_log
  @zero %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
  @capabilities %{axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle}

  setup do
    id = "dem-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))

    vehicle = %{
      id: id,
      board: Board.Test,
      report_to: self(),
      capabilities: @capabilities,
      helm: [tick_ms: 3_600_000]
    }

    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    {:ok, id: id}
  end

  test "the vehicle's capabilities are everyone's", %{id: id} do
    assert %{axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle, real: true} =
             Board.capabilities(id)
  end

  test "neutral on start is a zero demand; thrust is the demand; a stop zero again", ctx do
    id = ctx.id
    assert_receive {:board, ^id, {:go, @zero}}
    refute_received {:board, ^id, {:go, %{port: _}}}

    payload = %{"mode" => "motion", "surge" => 0.4, "sway" => -1, "heave" => 0, "yaw" => 0.2}
    assert {:ok, %{command: %{sway: -1.0}}} = Control.thrust(id, payload)
    assert_receive {:board, ^id, {:go, %{surge: 0.2, sway: -0.5, heave: 0.0, yaw: 0.1}}}

    assert {:ok, _} = Control.stop(id, "pilot_stop")
    assert_receive {:board, ^id, {:go, @zero}}
  end

  test "the three-thruster vehicle refuses sway with a reason", %{id: _id} do
    id = "thr-#{System.unique_integer([:positive])}"
    vehicle = %{id: id, board: Board.Test, report_to: self(), helm: [tick_ms: 3_600_000]}
    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle}, id: :other)
    payload = %{"mode" => "motion", "surge" => 0, "sway" => 0.5, "heave" => 0, "yaw" => 0}

    assert {:error, "this vehicle has no sway" <> _} = Control.thrust(id, payload)
    assert {:ok, _} = Control.thrust(id, %{payload | "sway" => 0})
  end
end
