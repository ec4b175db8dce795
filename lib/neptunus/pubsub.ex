defmodule Neptunus.PubSub do
  @moduledoc """
  Topic fan-out on an `:pg` scope, local or across a cluster of nodes.

  There are two kinds of subscriber:

    * **term subscribers** (`subscribe/1`) receive `{:pubsub, topic, event, payload}` — for
      Elixir processes (recorder, tests, other vehicles' processes);
    * **fastlane subscribers** (`subscribe_fastlane/1`) receive `{:pubsub_frame, topic, frame}`
      where `frame` is the wire frame (a binary) for that broadcast, **encoded once per
      broadcast** with `encoder.encode_broadcast(topic, event, payload)` and the same binary
      sent to every fastlane subscriber (binaries over 64 bytes are shared, not copied, on
      the local node). WebSocket connection processes use this.

  Subscriptions end when the subscriber exits (`:pg` monitors members).
  """

  @scope __MODULE__
  @default_encoder NeptunusWeb.Channels.Wire

  @type topic :: String.t()
  @type event :: String.t()

  @doc "Child spec: the `:pg` scope. Start it before anything that subscribes."
  @spec child_spec(term()) :: Supervisor.child_spec()
  def child_spec(_arg) do
    %{id: __MODULE__, start: {:pg, :start_link, [@scope]}, type: :worker}
  end

  @doc "Subscribes the calling process to `topic` as a term subscriber."
  @spec subscribe(topic()) :: :ok
  def subscribe(topic), do: :pg.join(@scope, {:term, topic}, self())

  @doc "Subscribes the calling process to pre-encoded frames of `topic`."
  @spec subscribe_fastlane(topic()) :: :ok
  def subscribe_fastlane(topic), do: :pg.join(@scope, {:fastlane, topic}, self())

  @doc "Removes the calling process' subscriptions (both kinds) to `topic`."
  @spec unsubscribe(topic()) :: :ok
  def unsubscribe(topic) do
    for group <- [{:term, topic}, {:fastlane, topic}] do
      if self() in :pg.get_local_members(@scope, group), do: :pg.leave(@scope, group, self())
    end

    :ok
  end

  @doc """
  Broadcasts `event` with `payload` on `topic` to every subscriber on every node.

  `encoder` is a module with `encode_broadcast(topic, event, payload) :: binary`; the frame is
  only encoded when there is at least one fastlane subscriber.
  """
  @spec broadcast(topic(), event(), map(), module()) :: :ok
  def broadcast(topic, event, payload, encoder \\ @default_encoder) do
    for pid <- :pg.get_members(@scope, {:term, topic}) do
      send(pid, {:pubsub, topic, event, payload})
    end

    case :pg.get_members(@scope, {:fastlane, topic}) do
      [] ->
        :ok

      pids ->
        frame = encoder.encode_broadcast(topic, event, payload)
        Enum.each(pids, &send(&1, {:pubsub_frame, topic, frame}))
    end
  end

  @doc "Number of subscribers (both kinds) of `topic` on all nodes."
  @spec subscriber_count(topic()) :: non_neg_integer()
  def subscriber_count(topic) do
    length(:pg.get_members(@scope, {:term, topic})) +
      length(:pg.get_members(@scope, {:fastlane, topic}))
  end
end
