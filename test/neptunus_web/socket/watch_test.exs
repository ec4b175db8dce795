defmodule NeptunusWeb.Socket.WatchTest do
  # The watch on the PubSub scope and the presence server, with both running. Their restarts
  # under live connections: test/neptunus_web/restart_test.exs.
  use ExUnit.Case, async: true

  alias NeptunusWeb.Socket.Watch

  test "the first join watches both; joined channels hear of a presence server watched anew" do
    assert {:ok, %Watch{pubsub: pubsub, presence: presence} = watch} =
             Watch.watch(Watch.new(), [])

    assert is_reference(pubsub) and is_reference(presence)
    refute_received {:channel_info, _, _}

    # watched already: nothing more
    assert Watch.watch(watch, ["vehicle:a"]) == {:ok, watch}
    refute_received {:channel_info, _, _}

    # the presence server was lost: watching again tells every joined channel
    assert {:ok, %Watch{pubsub: ^pubsub}} =
             Watch.watch(%{watch | presence: nil}, ["vehicle:a", "fleet"])

    assert_received {:channel_info, "vehicle:a", :presence_restarted}
    assert_received {:channel_info, "fleet", :presence_restarted}
  end

  test "a :DOWN says which stopped, and forgets that monitor" do
    {:ok, watch} = Watch.watch(Watch.new(), [])

    assert {:scope_stopped, %Watch{pubsub: nil, presence: presence}} =
             Watch.down(watch, watch.pubsub)

    assert presence == watch.presence

    assert {:presence_stopped, %Watch{pubsub: pubsub, presence: nil}} =
             Watch.down(watch, watch.presence)

    assert pubsub == watch.pubsub
    assert Watch.down(watch, make_ref()) == :other
    assert Watch.down(Watch.new(), make_ref()) == :other
  end

  test "the presence server back: watched, and the joined channels told; watched: nothing" do
    {:ok, watch} = Watch.watch(Watch.new(), [])
    {:presence_stopped, lost} = Watch.down(watch, watch.presence)

    assert %Watch{presence: ref} = Watch.presence_back(lost, ["vehicle:b"])
    assert is_reference(ref)
    assert_received {:channel_info, "vehicle:b", :presence_restarted}

    assert Watch.presence_back(watch, ["vehicle:b"]) == watch
    refute_received {:channel_info, _, _}
  end
end
