defmodule NeptunusWeb.SimWireTest do
  # sim_reset and sim_set over the wire: pilot only, refused with a reason otherwise.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  @moduletag :capture_log

  setup do
    {:ok, start_vehicle!("simwire")}
  end

  defp client(topic, name), do: client!(topic, %{"name" => name})

  defp push(c, event, payload \\ %{}), do: push_and_reply(c.ws, c.jr, c.topic, event, payload)

  test "only the pilot resets or changes the simulation", %{topic: topic} do
    ada = client(topic, "Ada")
    bob = client(topic, "Bob")

    # nobody pilots yet: refused like any command
    assert {"error", %{"reason" => "not_in_control"}} = push(ada, "sim_set", %{"paused" => true})

    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")

    assert {"ok",
            %{
              "sim" => %{
                "paused" => true,
                "vehicle" => "neptunus",
                "current" => [+0.0, +0.0, +0.0]
              }
            }} = push(ada, "sim_set", %{"paused" => true})

    assert {"ok", %{"sim" => %{"current" => [0.1, -0.1, +0.0], "paused" => true}}} =
             push(ada, "sim_set", %{"current" => [0.1, -0.1, 0]})

    assert {"error", %{"reason" => "not_in_control"}} = push(bob, "sim_reset")
    assert {"error", %{"reason" => "not_in_control"}} = push(bob, "sim_set", %{"paused" => false})

    assert {"ok", %{"sim" => %{"t" => +0.0}}} = push(ada, "sim_reset")
    assert %{"reason" => "sim_reset"} = event!(bob.ws, "stopped", &(&1["reason"] == "sim_reset"))

    assert {"error", %{"reason" => "current[0] must be a number in [-5, 5], got 7"}} =
             push(ada, "sim_set", %{"current" => [7, 0, 0]})

    assert {"error", %{"reason" => "unknown field: seed (no fields expected)"}} =
             push(ada, "sim_reset", %{"seed" => 1})
  end

  test "the strongest current on the longest tether keeps the vehicle running", %{
    id: id,
    topic: topic
  } do
    ada = client(topic, "Ada")
    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")
    board = GenServer.whereis(Neptunus.Vehicle.Board.via(id))

    assert {"ok", %{"sim" => %{"t" => t0, "tether_length" => 1000.0}}} =
             push(ada, "sim_set", %{"current" => [5, -5, 5], "tether_length" => 1000})

    # two simulated seconds later the same board still steps a finite vehicle
    assert %{"t" => _} = event!(ada.ws, "telemetry", &(&1["t"] >= t0 + 2.0), 15_000)
    assert GenServer.whereis(Neptunus.Vehicle.Board.via(id)) == board
    assert {"ok", _} = push(ada, "heartbeat")
  end
end
