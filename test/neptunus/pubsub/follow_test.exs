defmodule Neptunus.PubSub.FollowTest do
  # The follow's decisions with the application's scope running. The scope killed and
  # restarted under a follower is in test/neptunus_web/restart_test.exs ("PubSub restart
  # under a follower"): killing the node's scope would take every async test's
  # subscriptions with it, so that test runs alone.
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias Neptunus.PubSub.Follow

  doctest Follow

  defp topic, do: "follow:#{System.unique_integer([:positive])}"

  defp scope_watchers do
    {:monitored_by, watchers} = Process.info(Process.whereis(PubSub), :monitored_by)
    watchers
  end

  describe "PubSub.follow/1" do
    test "watches the scope, then subscribes to every topic" do
      [a, b] = topics = [topic(), topic()]
      assert {:ok, ref} = PubSub.follow(topics)
      assert is_reference(ref)
      assert self() in scope_watchers()

      PubSub.broadcast(a, "ev", %{n: 1})
      PubSub.broadcast(b, "ev", %{n: 2})
      assert_receive {:pubsub, ^a, "ev", %{n: 1}}
      assert_receive {:pubsub, ^b, "ev", %{n: 2}}
    end

    test "no topic: only the watch" do
      assert {:ok, ref} = PubSub.follow([])
      assert is_reference(ref)
      assert self() in scope_watchers()
    end
  end

  describe "subscribe/1" do
    test "a new follow is not subscribed; subscribing subscribes to its topics" do
      t = topic()
      follow = Follow.new([t])
      refute Follow.subscribed?(follow)
      assert PubSub.subscriber_count(t) == 0

      assert {:subscribed, follow} = Follow.subscribe(follow)
      assert Follow.subscribed?(follow)
      assert PubSub.subscriber_count(t) == 1
      PubSub.broadcast(t, "ev", %{n: 1})
      assert_receive {:pubsub, ^t, "ev", %{n: 1}}
    end
  end

  describe "handle/2" do
    setup do
      t = topic()
      {:subscribed, follow} = Follow.subscribe(Follow.new([t]))
      {:ok, topic: t, follow: follow}
    end

    test "the scope's :DOWN: lost, and a retry at once that subscribes again",
         %{topic: t, follow: follow} do
      scope = Process.whereis(PubSub)

      assert {:lost, lost} =
               Follow.handle(follow, {:DOWN, follow.scope, :process, scope, :killed})

      refute Follow.subscribed?(lost)

      assert_receive {Follow, :retry, [^t]} = retry
      assert {:subscribed, again} = Follow.handle(lost, retry)
      assert Follow.subscribed?(again)
      refute again.scope == follow.scope
      # subscribing is idempotent: once, however many times
      assert PubSub.subscriber_count(t) == 1
    end

    test "another monitor's :DOWN is not the follow's, and changes nothing", %{follow: follow} do
      other = spawn(fn -> :ok end)
      ref = Process.monitor(other)
      assert_receive {:DOWN, ^ref, :process, ^other, _} = down
      assert {:other, ^follow} = Follow.handle(follow, down)
      refute_received {Follow, :retry, _}
    end

    test "a retry it does not need (subscribed), or another follow's, changes nothing",
         %{topic: t, follow: follow} do
      assert {:other, ^follow} = Follow.handle(follow, {Follow, :retry, [t]})

      {:lost, lost} = Follow.handle(follow, {:DOWN, follow.scope, :process, self(), :killed})
      assert_receive {Follow, :retry, [^t]}
      assert {:other, ^lost} = Follow.handle(lost, {Follow, :retry, [topic()]})
      refute Follow.subscribed?(lost)
    end

    test "unsubscribed: no topic, no watch, and a retry on its way changes nothing",
         %{topic: t, follow: follow} do
      {:lost, lost} = Follow.handle(follow, {:DOWN, follow.scope, :process, self(), :killed})
      assert_receive {Follow, :retry, [^t]} = retry
      Process.demonitor(follow.scope, [:flush])

      ended = Follow.unsubscribe(lost)
      refute Follow.subscribed?(ended)
      assert PubSub.subscriber_count(t) == 0
      assert {:other, ^ended} = Follow.handle(ended, retry)
      assert PubSub.subscriber_count(t) == 0

      # and it may follow again
      assert {:subscribed, again} = Follow.subscribe(ended)
      assert PubSub.subscriber_count(t) == 1
      _ended = Follow.unsubscribe(again)
      assert PubSub.subscriber_count(t) == 0
      refute self() in scope_watchers()
    end

    test "a new follow ignores retries: it follows once subscribed", %{topic: t} do
      assert {:other, _} = Follow.handle(Follow.new([t]), {Follow, :retry, [t]})
    end

    test "any other message is not the follow's", %{follow: follow} do
      assert {:other, ^follow} = Follow.handle(follow, {:pubsub, "t", "ev", %{}})
      assert {:other, ^follow} = Follow.handle(follow, :subscribe)
    end
  end
end
