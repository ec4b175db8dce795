defmodule NeptunusWeb.FleetCameraRelayTest do
  # A node's relay of a camera (NeptunusWeb.CameraRelay) on its own: one subscription of the
  # camera's topic, every viewer served, stopped after the last viewer.
  use ExUnit.Case, async: false

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.Camera
  alias NeptunusWeb.CameraRelay

  defp viewer(id, test) do
    spawn(fn ->
      ref = CameraRelay.subscribe(id)
      send(test, {:subscribed, self(), ref})

      receive_loop = fn loop ->
        receive do
          {:pubsub, _, "frame", %{jpeg: jpeg}} ->
            send(test, {:frame, self(), jpeg})
            loop.(loop)

          :stop ->
            :ok
        end
      end

      receive_loop.(receive_loop)
    end)
  end

  test "one subscription of the topic serves every viewer; the relay stops after the last" do
    id = "relay-#{System.unique_integer([:positive])}"
    topic = Camera.topic(id)
    a = viewer(id, self())
    b = viewer(id, self())
    assert_receive {:subscribed, ^a, _}
    assert_receive {:subscribed, ^b, _}

    relay = CameraRelay.whereis(id)
    assert is_pid(relay)
    assert PubSub.subscriber_count(topic) == 1

    :ok = PubSub.broadcast(topic, "frame", %{jpeg: "jpeg-1"})
    assert_receive {:frame, ^a, "jpeg-1"}
    assert_receive {:frame, ^b, "jpeg-1"}

    ref = Process.monitor(relay)
    send(a, :stop)
    :ok = PubSub.broadcast(topic, "frame", %{jpeg: "jpeg-2"})
    assert_receive {:frame, ^b, "jpeg-2"}
    refute_received {:DOWN, ^ref, _, _, _}

    send(b, :stop)
    assert_receive {:DOWN, ^ref, :process, ^relay, :normal}
    # the registry drops a dead process's name on its own monitor message, just after
    Neptunus.Test.Cluster.wait!(fn -> CameraRelay.whereis(id) == nil end, "relay unregistered")
    Neptunus.Test.Cluster.wait!(fn -> PubSub.subscriber_count(topic) == 0 end, "no subscriber")
  end

  test "a relay that dies: its viewers see it go and subscribe again" do
    id = "relay-#{System.unique_integer([:positive])}"
    ref = CameraRelay.subscribe(id)
    relay = CameraRelay.whereis(id)
    Process.exit(relay, :kill)
    assert_receive {:DOWN, ^ref, :process, ^relay, :killed}

    _ref = CameraRelay.subscribe(id)
    assert is_pid(CameraRelay.whereis(id)) and CameraRelay.whereis(id) != relay
    :ok = PubSub.broadcast(Camera.topic(id), "frame", %{jpeg: "again"})
    assert_receive {:pubsub, _, "frame", %{jpeg: "again"}}
  end
end
