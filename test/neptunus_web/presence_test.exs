defmodule NeptunusWeb.PresenceTest do
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias NeptunusWeb.Presence

  defp meta(ref), do: %{phx_ref: ref}

  describe "fold_events/1 (one batch into one diff)" do
    test "joins and leaves of different metas are kept, grouped by key in order" do
      events = [
        {:join, "ada", meta("1")},
        {:join, "ada", meta("2")},
        {:leave, "bob", meta("3")}
      ]

      assert Presence.fold_events(events) ==
               {%{"ada" => %{metas: [meta("1"), meta("2")]}}, %{"bob" => %{metas: [meta("3")]}}}
    end

    test "a meta that joined and left within the batch is in neither" do
      events = [{:join, "ada", meta("1")}, {:join, "bob", meta("2")}, {:leave, "ada", meta("1")}]
      assert Presence.fold_events(events) == {%{"bob" => %{metas: [meta("2")]}}, %{}}
    end

    test "an empty batch is an empty diff" do
      assert Presence.fold_events([]) == {%{}, %{}}
    end
  end

  describe "the server" do
    setup do
      topic = "presence-test:#{System.unique_integer([:positive])}"
      PubSub.subscribe(topic)
      {:ok, topic: topic}
    end

    defp spawn_member, do: spawn(fn -> Process.sleep(:infinity) end)

    test "a crowd joining produces one batched diff, not one per join", %{topic: topic} do
      members = for i <- 1..50, do: {spawn_member(), "user#{i}"}
      for {pid, name} <- members, do: {:ok, _} = Presence.track(pid, topic, name, %{})

      assert_receive {:pubsub, ^topic, "presence_diff", %{joins: joins, leaves: %{}}}
      assert map_size(joins) == 50
      refute_receive {:pubsub, ^topic, "presence_diff", _}, 200
      assert map_size(Presence.list(topic)) == 50
    end

    test "a member that dies leaves", %{topic: topic} do
      pid = spawn_member()
      {:ok, %{phx_ref: ref}} = Presence.track(pid, topic, "ada", %{role: "observer"})
      assert %{"ada" => %{metas: [%{phx_ref: ^ref, role: "observer"}]}} = Presence.list(topic)
      assert_receive {:pubsub, ^topic, "presence_diff", %{joins: %{"ada" => _}}}
      Process.exit(pid, :kill)

      assert_receive {:pubsub, ^topic, "presence_diff",
                      %{leaves: %{"ada" => %{metas: [%{phx_ref: ^ref}]}}}}

      assert Presence.list(topic) == %{}
    end

    test "untrack and re-track; the same key may have several metas", %{topic: topic} do
      [a, b] = [spawn_member(), spawn_member()]
      {:ok, _} = Presence.track(a, topic, "ada", %{})
      {:ok, _} = Presence.track(b, topic, "ada", %{})
      assert %{"ada" => %{metas: [_, _]}} = Presence.list(topic)
      :ok = Presence.untrack(a, topic)
      assert %{"ada" => %{metas: [_]}} = Presence.list(topic)
      :ok = Presence.untrack(a, topic)
      # one transient meta (a) joined and left in the same batch: only b's join is announced
      assert_receive {:pubsub, ^topic, "presence_diff",
                      %{joins: %{"ada" => %{metas: [_]}}, leaves: leaves}}

      assert leaves == %{}
    end
  end
end
