defmodule Neptunus.GCS.IntentsTest do
  # A ground station's `autopilot` goes where the vehicle's capabilities say its autopilots
  # are — Neptunus' own (control) or the vehicle's (its board) —, never by board type.
  use ExUnit.Case, async: true

  alias Neptunus.GCS.Intents
  alias Neptunus.Vehicle.{Board, Control, Helm}

  @moduletag :capture_log

  defp vehicle!(capabilities) do
    id = "intents-#{System.unique_integer([:positive])}"
    vehicle = %{id: id, board: Board.Test, report_to: self(), capabilities: capabilities}
    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})
    assert_receive {:board, ^id, {:started, _}}
    vehicle
  end

  defp pilot!(id) do
    test = self()

    party = %{
      id: "gcs-#{System.unique_integer([:positive])}",
      name: "gcs",
      role: :pilot,
      pid: spawn(fn -> receive do: (:die -> :ok) end),
      notify: fn event, payload -> send(test, {:notify, event, payload}) end
    }

    assert {:ok, %{status: "granted"}} = Helm.request_control(id, party)
    party
  end

  test "on a vehicle whose autopilots are Neptunus' own, control gets the command" do
    vehicle = vehicle!(%{})
    party = pilot!(vehicle.id)

    # control's own refusal (the test board sent no samples) shows it was asked
    assert {:error, "no current estimate of depth and heading" <> _} =
             Intents.run({:commands, [{"autopilot", %{"depth" => 2.0}}]}, vehicle, party)
  end

  test "on a vehicle whose autopilots are its own, the board gets the command" do
    vehicle = vehicle!(%{autopilots: :vehicle})
    party = pilot!(vehicle.id)

    # the test board has no vehicle commands: Board.command/3's refusal shows it was asked
    assert {:error, "this vehicle's autopilots are Neptunus' own"} =
             Intents.run({:commands, [{"autopilot", %{"depth" => 2.0}}]}, vehicle, party)

    assert %{autopilot: %{depth: nil}} = Control.status(vehicle.id)

    # a bad payload is refused with the reason before the board is asked
    assert {:error, "depth" <> _} =
             Intents.run({:commands, [{"autopilot", %{"depth" => "deep"}}]}, vehicle, party)
  end
end
