defmodule Neptunus.Fleet.RelayTest do
  # The node's side of broadcasts across nodes (Neptunus.PubSub "Across nodes"): the relay
  # joins a topic's relay group while the node has fastlane subscribers of it, serves them a
  # frame from another node once each, and leaves when none is left; local broadcasts stay
  # on the node. (Across real nodes: NeptunusWeb.FleetClusterTest.)
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias Neptunus.PubSub.Relay

  defmodule Encoder do
    def encode_broadcast(topic, event, payload), do: "#{topic}|#{event}|#{payload.n}"
  end

  defp topic, do: "relay-test:#{System.unique_integer([:positive])}"

  defp relay_members(topic), do: :pg.get_local_members(PubSub.scope(), {:relay, topic})

  # a fastlane subscriber reporting its frames to the test
  defp subscriber(topic, opts \\ []) do
    test = self()

    pid =
      spawn_link(fn ->
        :ok = PubSub.subscribe_fastlane(topic)
        if opts[:first], do: PubSub.prioritize(topic, true)
        send(test, {:subscribed, self()})
        forward(test)
      end)

    assert_receive {:subscribed, ^pid}
    pid
  end

  defp forward(test) do
    receive do
      :stop ->
        :ok

      {:pubsub_frame, _topic, event, frame} ->
        send(test, {:frame, self(), event, frame}) && forward(test)
    end
  end

  defp await(fun) do
    Enum.reduce_while(1..div(Neptunus.Test.Patience.ms(), 20), false, fn _, _ ->
      if fun.(), do: {:halt, true}, else: Process.sleep(20) && {:cont, false}
    end)
  end

  test "a fastlane subscriber puts the node's relay in the topic's relay group, once" do
    topic = topic()
    subscriber(topic)
    subscriber(topic)
    relay = Process.whereis(Relay)
    assert await(fn -> relay_members(topic) == [relay] end)
  end

  test "a frame from another node reaches every local subscriber once, the prioritized first" do
    topic = topic()
    a = subscriber(topic)
    b = subscriber(topic, first: true)
    relay = Process.whereis(Relay)
    assert await(fn -> relay_members(topic) == [relay] end)

    send(relay, {Relay, topic, "telemetry", "frame-1"})
    assert_receive {:frame, ^b, "telemetry", "frame-1"}
    assert_receive {:frame, ^a, "telemetry", "frame-1"}
    refute_receive {:frame, _, _, _}, 50
  end

  test "a frame that finds no subscriber makes the relay leave the group; subscribing joins again" do
    topic = topic()
    sub = subscriber(topic)
    relay = Process.whereis(Relay)
    assert await(fn -> relay_members(topic) == [relay] end)

    ref = Process.monitor(sub)
    send(sub, :stop)
    assert_receive {:DOWN, ^ref, :process, _, _}
    assert await(fn -> PubSub.subscriber_count(topic) == 0 end)

    send(relay, {Relay, topic, "telemetry", "late"})
    assert await(fn -> relay_members(topic) == [] end)

    subscriber(topic)
    assert await(fn -> relay_members(topic) == [relay] end)
  end

  test "deliver_local says :none without a local subscriber" do
    assert PubSub.deliver_local(topic(), "telemetry", "frame") == :none
  end

  test "local_broadcast: this node's term and fastlane subscribers, encoded once" do
    topic = topic()
    sub = subscriber(topic)
    :ok = PubSub.subscribe(topic)
    :ok = PubSub.local_broadcast(topic, "unreachable", %{n: 7}, Encoder)
    assert_receive {:pubsub, ^topic, "unreachable", %{n: 7}}
    frame = "#{topic}|unreachable|7"
    assert_receive {:frame, ^sub, "unreachable", ^frame}
  end

  test "a broadcast on this node sends nothing to this node's relay (its own subscribers are served directly)" do
    topic = topic()
    sub = subscriber(topic)
    relay = Process.whereis(Relay)
    assert await(fn -> relay_members(topic) == [relay] end)
    :erlang.trace(relay, true, [:receive])
    PubSub.broadcast(topic, "telemetry", %{n: 1}, Encoder)
    frame = "#{topic}|telemetry|1"
    assert_receive {:frame, ^sub, "telemetry", ^frame}
    refute_receive {:trace, ^relay, :receive, {Relay, ^topic, _, _}}, 100
    :erlang.trace(relay, false, [:receive])
  end
end
