defmodule NeptunusWeb.Channels.LogChannelTest do
  # Topic `log:<id>` over the wire: real WebSocket clients against the running endpoint, each
  # test on its own simulated vehicle.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.Telemetry
  alias NeptunusWeb.Auth.{Password, Token}
  alias NeptunusWeb.Test.WSClient

  @moduletag :capture_log
  @secret String.duplicate("log-channel-secret-", 3)

  setup do
    id = "log-#{System.unique_integer([:positive])}"
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, id: id}
  end

  test "join, then every log entry of the vehicle arrives as a `log` event", %{id: id} do
    ws = connect!(%{"name" => "dev"})
    {jr, reply} = join!(ws, "log:" <> id)
    assert reply == %{"vehicle" => id}

    PubSub.broadcast(Telemetry.log_topic(id), "log", %{
      category: "gain",
      level: "info",
      message: "gain 0.7",
      at: 1
    })

    assert %{"category" => "gain", "message" => "gain 0.7", "at" => 1} = event!(ws, "log")

    # a safety stop by the pilot, seen on the log topic with its reason
    {vjr, _} = join!(ws, "vehicle:" <> id)

    {"ok", %{"status" => "granted"}} =
      push_and_reply(ws, vjr, "vehicle:" <> id, "request_control", %{})

    {"ok", _} =
      push_and_reply(ws, vjr, "vehicle:" <> id, "stop", %{"reason" => "window lost focus"})

    assert %{"category" => "safety", "level" => "warning", "reason" => "window lost focus"} =
             event!(ws, "log", &(&1["category"] == "safety"))

    # no client events
    assert {"error", %{"reason" => "unknown event on log: clear"}} =
             push_and_reply(ws, jr, "log:" <> id, "clear", %{})

    # leaving ends the entries
    ref = WSClient.unique_ref()
    WSClient.push(ws, jr, ref, "log:" <> id, "phx_leave", %{})
    WSClient.recv_until(ws, &match?([_, ^ref, _, "phx_reply", _], &1))
    PubSub.broadcast(Telemetry.log_topic(id), "log", %{category: "gain", message: "late", at: 2})
    no_event!(ws, "log", 200)
  end

  test "unknown vehicles are refused with a reason", %{id: _id} do
    ws = connect!(%{"name" => "dev"})
    assert {:error, %{"reason" => "unknown vehicle: nope"}} = WSClient.join(ws, "log:nope")
  end

  describe "secure mode" do
    setup do
      NeptunusWeb.Test.Wire.settings!(
        auth: %{
          mode: :secure,
          secret: @secret,
          users: %{
            "olga" => %{
              name: "olga",
              role: :observer,
              hash: Password.hash("pw", iterations: 1000)
            }
          },
          anonymous_observers: true,
          origins: []
        }
      )
    end

    test "observers and anonymous observers may read the log", %{id: id} do
      token = Token.sign("olga", @secret, System.os_time(:second), 600)

      for params <- [%{"token" => token}, %{}] do
        ws = connect!(params)
        {_jr, %{"vehicle" => ^id}} = join!(ws, "log:" <> id)

        PubSub.broadcast(Telemetry.log_topic(id), "log", %{category: "link", message: "up", at: 3})

        assert %{"category" => "link"} = event!(ws, "log")
      end
    end
  end
end
