defmodule Neptunus.PubSubTest do
  use ExUnit.Case, async: true

  alias Neptunus.PubSub

  doctest Neptunus.PubSub

  defmodule Encoder do
    # counts encodings in the calling process, so "encoded once" can be checked
    def encode_broadcast(topic, event, payload) do
      Process.put(:encodings, Process.get(:encodings, 0) + 1)
      "#{topic}|#{event}|#{payload.n}"
    end
  end

  defp topic, do: "test:#{System.unique_integer([:positive])}"

  # A fastlane subscriber: reports every frame to the test as {:frame, name, frame, ms}.
  defp subscriber(topic, name, opts \\ []) do
    test = self()

    pid =
      spawn_link(fn ->
        PubSub.subscribe_fastlane(topic)
        if opts[:first], do: PubSub.prioritize(topic, true)
        send(test, {:subscribed, name})
        forward(test, name)
      end)

    assert_receive {:subscribed, ^name}
    pid
  end

  defp forward(test, name) do
    receive do
      {:pubsub_frame, _topic, _event, frame} ->
        send(test, {:frame, name, frame, System.monotonic_time(:millisecond)})
        forward(test, name)

      {:run, fun} ->
        fun.()
        send(test, {:ran, name})
        forward(test, name)
    end
  end

  defp run(pid, name, fun) do
    send(pid, {:run, fun})
    assert_receive {:ran, ^name}
  end

  test "broadcast: term subscribers get the payload, fastlane subscribers one shared frame" do
    t = topic()
    PubSub.subscribe(t)
    subscriber(t, :a)
    subscriber(t, :b, first: true)

    assert :ok = PubSub.broadcast(t, "ev", %{n: 1}, Encoder)
    assert_receive {:pubsub, ^t, "ev", %{n: 1}}
    assert_receive {:frame, :a, frame, _}
    assert_receive {:frame, :b, ^frame, _}
    assert frame == "#{t}|ev|1"
    assert Process.get(:encodings) == 1
    assert PubSub.subscriber_count(t) == 3
  end

  test "no fastlane subscriber: nothing is encoded" do
    t = topic()
    PubSub.subscribe(t)
    assert :ok = PubSub.broadcast_paced(t, "ev", %{n: 1}, pace(1, 1, 10), Encoder)
    assert :ok = PubSub.broadcast(t, "ev", %{n: 2}, Encoder)
    assert_receive {:pubsub, ^t, "ev", %{n: 1}}
    assert_receive {:pubsub, ^t, "ev", %{n: 2}}
    assert Process.get(:encodings) == nil
  end

  defp pace(slice, gap_ms, spread_ms), do: %{slice: slice, gap_ms: gap_ms, spread_ms: spread_ms}

  test "broadcast_paced: prioritized and the first slice now, the rest from the caller's timers" do
    t = topic()
    PubSub.subscribe(t)
    for name <- 1..5, do: subscriber(t, name)
    subscriber(t, :pilot, first: true)

    assert :ok = PubSub.broadcast_paced(t, "ev", %{n: 7}, pace(2, 20, 1_000), Encoder)
    sent = System.monotonic_time(:millisecond)
    assert_receive {:pubsub, ^t, "ev", %{n: 7}}
    assert_receive {:frame, :pilot, frame, _}
    assert frame == "#{t}|ev|7"

    # one slice of two now; the other three subscribers are in two later slices
    now = for _ <- 1..2, do: assert_receive({:frame, name, ^frame, _}) && name
    refute_received {:frame, _, _, _}

    slices =
      for k <- 1..2 do
        assert_receive {PubSub, :slice, ^t, "ev", ^frame, pids} = slice
        assert System.monotonic_time(:millisecond) - sent >= k * 20
        assert :ok = PubSub.deliver_slice(slice)
        pids
      end

    assert Enum.map(slices, &length/1) == [2, 1]
    later = for _ <- 1..3, do: assert_receive({:frame, name, ^frame, _}) && name
    assert Enum.sort(now ++ later) == [1, 2, 3, 4, 5]
    refute_receive {PubSub, :slice, _, _, _, _}, 50
    assert Process.get(:encodings) == 1
  end

  test "broadcast_paced: without a prioritized subscriber, everyone at once" do
    t = topic()
    for name <- 1..5, do: subscriber(t, name)
    assert :ok = PubSub.broadcast_paced(t, "ev", %{n: 1}, pace(2, 1, 100), Encoder)
    for _ <- 1..5, do: assert_receive({:frame, _, _, _})
    refute_receive {PubSub, :slice, _, _, _, _}, 20
  end

  test "broadcast_paced: no more others than one slice, everyone at once" do
    t = topic()
    for name <- 1..3, do: subscriber(t, name)
    subscriber(t, :pilot, first: true)
    assert :ok = PubSub.broadcast_paced(t, "ev", %{n: 1}, pace(3, 1, 0), Encoder)
    for _ <- 1..4, do: assert_receive({:frame, _, _, _})
    refute_receive {PubSub, :slice, _, _, _, _}, 20
  end

  test "prioritize moves a subscriber between the groups, and only a subscriber" do
    t = topic()
    pid = subscriber(t, :a)
    first = {:fastlane_first, t}
    others = {:fastlane, t}

    run(pid, :a, fn -> PubSub.prioritize(t, true) end)
    assert :pg.get_members(PubSub, first) == [pid] and :pg.get_members(PubSub, others) == []
    run(pid, :a, fn -> PubSub.prioritize(t, true) end)
    assert :pg.get_members(PubSub, first) == [pid]
    run(pid, :a, fn -> PubSub.prioritize(t, false) end)
    assert :pg.get_members(PubSub, first) == [] and :pg.get_members(PubSub, others) == [pid]

    # not subscribed: no effect
    assert :ok = PubSub.prioritize(t, true)
    assert :pg.get_members(PubSub, first) == []

    run(pid, :a, fn -> PubSub.prioritize(t, true) end)
    run(pid, :a, fn -> PubSub.unsubscribe(t) end)
    assert PubSub.subscriber_count(t) == 0
  end

  test "subscribing twice subscribes once, a prioritized subscriber stays first" do
    t = topic()
    assert :ok = PubSub.subscribe(t)
    assert :ok = PubSub.subscribe(t)
    PubSub.broadcast(t, "ev", %{n: 1}, Encoder)
    assert_receive {:pubsub, ^t, "ev", %{n: 1}}
    refute_receive {:pubsub, ^t, "ev", _}, 20

    pid = subscriber(t, :a, first: true)
    run(pid, :a, fn -> :ok = PubSub.subscribe_fastlane(t) end)
    assert :pg.get_members(PubSub, {:fastlane_first, t}) == [pid]
    assert :pg.get_members(PubSub, {:fastlane, t}) == []
    assert PubSub.subscriber_count(t) == 2
  end

  test "monitor/0 watches the scope process" do
    assert {:ok, ref} = PubSub.monitor()
    assert is_reference(ref)
    scope = Process.whereis(PubSub)
    assert {:monitored_by, watchers} = Process.info(scope, :monitored_by)
    assert self() in watchers
  end

  test "plan: slices grow to keep the spread, never below the configured size" do
    for count <- [0, 1, 49, 50, 51, 999, 1_000, 1_001, 10_000],
        slice <- [1, 7, 50],
        gap <- [1, 2, 5],
        spread <- [0, 1, 10, 40] do
      {size, ^gap} = PubSub.plan(count, pace(slice, gap, spread))
      assert size >= slice
      slices = if count == 0, do: 0, else: div(count + size - 1, size)
      # the last slice leaves within the spread
      assert max(slices - 1, 0) * gap <= spread
      # and the slices are no larger than needed for it
      assert size == slice or div(count + size - 2, size - 1) - 1 > div(spread, gap)
    end
  end
end
