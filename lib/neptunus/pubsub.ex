defmodule Neptunus.PubSub do
  @moduledoc """
  Topic fan-out on an `:pg` scope, local or across a cluster of nodes.

  There are two kinds of subscriber:

    * **term subscribers** (`subscribe/1`) receive `{:pubsub, topic, event, payload}` — for
      Elixir processes (recorder, tests, other vehicles' processes);
    * **fastlane subscribers** (`subscribe_fastlane/1`) receive
      `{:pubsub_frame, topic, event, frame}` where `frame` is the wire frame (a binary) for
      that broadcast, **encoded once per
      broadcast** with `encoder.encode_broadcast(topic, event, payload)` and the same binary
      sent to every fastlane subscriber (binaries over 64 bytes are shared, not copied, on
      the local node). WebSocket connection processes use this. A fastlane subscriber can
      ask to be served **first** (`prioritize/2`): the pilot's connection does, so its
      telemetry never waits behind the observers'.

  Subscriptions end when the subscriber exits (`:pg` monitors members).

  ## Across nodes

  The scope spans every connected node running it, so term subscribers anywhere get every
  broadcast. Fastlane frames cross a node boundary **once per broadcast per node**: a
  broadcast serves this node's fastlane subscribers itself, and sends the frame once to the
  relay (`Neptunus.PubSub.Relay`) of every other node that has fastlane subscribers of the
  topic, which serves its own (`deliver_local/3`). A node's relay is in the group
  `{:relay, topic}` while that node has fastlane subscribers of `topic`
  (`subscribe_fastlane/1` tells it). So a vehicle's node sends one message per watching
  node, whatever the number of browsers there, and encodes the frame once.

  ## When the scope restarts

  The subscriptions live in the scope process (`:pg` keeps them in its own table): when it
  dies they are gone, and the supervisor starts an empty scope. Until a subscriber joins
  again, broadcasts to it go nowhere, and nothing says so. So every long-lived subscriber
  watches the scope it subscribed with (`monitor/0`, taken **before** subscribing) and acts
  on the `:DOWN`: it subscribes again once the scope is back (`monitor/0` answers
  `{:error, :not_running}` until then), or, when what it missed cannot be made good, ends
  and lets its client start afresh.

  **The recipe for subscribing again** is `Neptunus.PubSub.Follow`: a process keeps a
  follow of its topics in its state, subscribes with `Follow.subscribe/1` and passes it
  every `:DOWN` and every `t:Neptunus.PubSub.Follow.retry/0` it receives (`Follow.handle/2`),
  which says `:lost`, `:waiting` (retrying every 20 ms while the scope is down) or
  `:subscribed`, and does the retrying; the process adds only what is its own. One attempt,
  for a process that waits by itself, is `follow/1`. The node's subscribers:

    * a WebSocket connection (`NeptunusWeb.Socket`) closes with 1012 "service restart": its
      browser may have missed a `stopped`, a `helm` or a presence diff, and only a rejoin
      gives it the whole state again (the phoenix client reconnects and rejoins by itself).
      It ends instead of following (`NeptunusWeb.Socket.Watch`);
    * the recorder (`Neptunus.Vehicle.Recorder`) says it is not recording, with the reason,
      subscribes again and says how long it was not; its video writer
      (`Neptunus.Vehicle.Recorder.Video`) subscribes again;
    * a ground station's vehicle (`Neptunus.GCS.Source`) subscribes again and reads the helm
      and the latest telemetry again; the MAVLink board subscribes again;
    * a camera viewer (`NeptunusWeb.CameraStream`, `NeptunusWeb.VideoSocket`) watches again
      (`follow/1` through `NeptunusWeb.CameraRelay.watch/1`; frames only replace each
      other), and a node's camera relay subscribes again;
    * the presence server (`NeptunusWeb.Presence`) subscribes again and joins its group
      again; this node's relay (`Neptunus.PubSub.Relay`) watches the new scope (a follow of
      no topic);
    * the simulated position devices (`Neptunus.Sim.UGPSServer`, `Neptunus.Sim.DVLServer`)
      and a rendering simulated camera (`Neptunus.Vehicle.Camera`) follow the simulator's
      pose again.

  Subscribing is idempotent (a process subscribed to a topic stays subscribed once), so a
  subscriber that raced a restart and joined the new scope before its `:DOWN` arrived can
  simply subscribe again.

  ## Paced broadcasts

  A broadcast to a thousand observers makes a thousand connection processes runnable at
  once, and each one's send costs the kernel more than the BEAM: a burst of ≈ 10 ms of CPU
  on a small vehicle computer, during which everything else on it (the serial port program,
  the kernel's tty work) waits for a core. `broadcast_paced/5` delivers the frame to the
  fastlane subscribers in slices instead: term subscribers and prioritized subscribers at
  once, then the others `slice` at a time, one slice every `gap_ms`, from the calling
  process' own timers (it passes each `t:slice_message/0` it receives to `deliver_slice/1`).

  Pacing is for a prioritized subscriber's sake (the pilot's commands travel through the
  same cores), and costs the others up to `spread_ms` of delay. So a topic without a
  prioritized subscriber, or with no more than `slice` others, is served at once, as by
  `broadcast/4`.
  """

  @scope __MODULE__
  @encoder_key {__MODULE__, :encoder}

  @type topic :: String.t()
  @type event :: String.t()

  @typedoc "A later slice of a paced broadcast, sent by the broadcaster to itself."
  @type slice_message :: {__MODULE__, :slice, topic(), event(), binary(), [pid()]}

  @typedoc """
  How a paced broadcast is spread: `slice` subscribers at a time, a slice every `gap_ms`,
  and the whole spread within `spread_ms` (slices grow when there are too many of them).
  """
  @type pace :: %{slice: pos_integer(), gap_ms: pos_integer(), spread_ms: non_neg_integer()}

  @doc """
  Child spec: the `:pg` scope. Start it before anything that subscribes.

  `encoder:` (required) is the module whose `encode_broadcast(topic, event, payload) ::
  binary` makes the fastlane subscribers' frames in `broadcast/3` and `broadcast_paced/4`:
  the fan-out does not know the wire format, whoever starts it (the application) says which.
  """
  @spec child_spec(encoder: module()) :: Supervisor.child_spec()
  def child_spec(opts) do
    encoder = Keyword.fetch!(opts, :encoder)
    %{id: __MODULE__, start: {__MODULE__, :start_link, [encoder]}, type: :worker}
  end

  @doc "Starts the scope with the default `encoder` (see `child_spec/1`)."
  @spec start_link(module()) :: {:ok, pid()} | {:error, term()}
  def start_link(encoder) when is_atom(encoder) do
    # unchanged on a restart of the scope: persistent_term only copies on a new value
    if :persistent_term.get(@encoder_key, nil) != encoder,
      do: :persistent_term.put(@encoder_key, encoder)

    :pg.start_link(@scope)
  end

  defp default_encoder, do: :persistent_term.get(@encoder_key)

  @doc """
  Monitors the scope process, for a subscriber to learn that its subscriptions are gone
  (see "When the scope restarts"): `{:ok, ref}`, then `{:DOWN, ref, :process, pid, reason}`
  when the scope stops; `{:error, :not_running}` while it is down or restarting.
  """
  @spec monitor() :: {:ok, reference()} | {:error, :not_running}
  def monitor do
    case Process.whereis(@scope) do
      nil -> {:error, :not_running}
      pid -> {:ok, Process.monitor(pid)}
    end
  end

  @doc """
  Watches the scope and subscribes the calling process to `topics` (term subscribers), in
  that order (see "When the scope restarts"): `{:ok, ref}`, the scope's monitor, whose
  `{:DOWN, ref, :process, pid, reason}` says the subscriptions are gone; or
  `{:error, :not_running}` while the scope is down or restarting, with no monitor left. One
  attempt: a long-lived process keeps a `Neptunus.PubSub.Follow`, which tries again.
  """
  @spec follow([topic()]) :: {:ok, reference()} | {:error, :not_running}
  def follow(topics) when is_list(topics) do
    with {:ok, ref} <- monitor() do
      case Enum.find(topics, &(subscribe(&1) != :ok)) do
        nil ->
          {:ok, ref}

        _topic ->
          Process.demonitor(ref, [:flush])
          {:error, :not_running}
      end
    end
  end

  @doc """
  Subscribes the calling process to `topic` as a term subscriber (once: subscribing again
  changes nothing). `{:error, :not_running}` while the scope is down or restarting.
  """
  @spec subscribe(topic()) :: :ok | {:error, :not_running}
  def subscribe(topic), do: join_once({:term, topic}, [{:term, topic}])

  @doc """
  Subscribes the calling process to pre-encoded frames of `topic` (once, like
  `subscribe/1`; a prioritized subscriber stays prioritized).
  """
  @spec subscribe_fastlane(topic()) :: :ok | {:error, :not_running}
  def subscribe_fastlane(topic) do
    with :ok <- join_once({:fastlane, topic}, [{:fastlane, topic}, {:fastlane_first, topic}]) do
      __MODULE__.Relay.watch(topic)
    end
  end

  defp join_once(group, groups) do
    cond do
      Process.whereis(@scope) == nil ->
        {:error, :not_running}

      Enum.any?(groups, &(self() in :pg.get_local_members(@scope, &1))) ->
        :ok

      true ->
        :pg.join(@scope, group, self())
    end
  catch
    # the scope stopped between the check and the join
    :exit, {_reason, {:gen_server, :call, _}} -> {:error, :not_running}
  end

  @doc """
  Serves the calling fastlane subscriber of `topic` first (`true`) or with the others
  (`false`) in paced broadcasts. No effect on a process that is not subscribed to `topic`.
  """
  @spec prioritize(topic(), boolean()) :: :ok
  def prioritize(topic, first?) when is_boolean(first?) do
    {from, to} =
      if first?,
        do: {{:fastlane, topic}, {:fastlane_first, topic}},
        else: {{:fastlane_first, topic}, {:fastlane, topic}}

    if self() in :pg.get_local_members(@scope, from) do
      :ok = :pg.join(@scope, to, self())
      :ok = :pg.leave(@scope, from, self())
    end

    :ok
  end

  @doc "Removes the calling process' subscriptions (all kinds) to `topic`."
  @spec unsubscribe(topic()) :: :ok
  def unsubscribe(topic) do
    for group <- groups(topic) do
      if self() in :pg.get_local_members(@scope, group), do: :pg.leave(@scope, group, self())
    end

    :ok
  end

  @doc """
  Broadcasts `event` with `payload` on `topic` to every subscriber on every node.

  `encoder` is a module with `encode_broadcast(topic, event, payload) :: binary` (by default
  the one the scope was started with, see `child_spec/1`); the frame is only encoded when
  there is at least one fastlane subscriber.
  """
  @spec broadcast(topic(), event(), map(), module()) :: :ok
  def broadcast(topic, event, payload, encoder \\ default_encoder()) do
    case send_terms_and_first(topic, event, payload, encoder) do
      nil -> :ok
      {frame, others, _first} -> deliver(topic, event, frame, others)
    end
  end

  @doc """
  Broadcasts like `broadcast/4`, but, while a fastlane subscriber is prioritized, serves the
  others in slices (see "Paced broadcasts" above): the first slice now, the others from
  timers of the calling process, which must pass each `t:slice_message/0` it receives to
  `deliver_slice/1`.
  """
  @spec broadcast_paced(topic(), event(), map(), pace(), module()) :: :ok
  def broadcast_paced(topic, event, payload, pace, encoder \\ default_encoder()) do
    case send_terms_and_first(topic, event, payload, encoder) do
      nil ->
        :ok

      {frame, others, []} ->
        deliver(topic, event, frame, others)

      {frame, others, _first} ->
        {slice, gap_ms} = plan(length(others), pace)

        others
        |> Enum.chunk_every(slice)
        |> Enum.with_index()
        |> Enum.each(fn
          {pids, 0} ->
            deliver(topic, event, frame, pids)

          {pids, k} ->
            Process.send_after(
              self(),
              {__MODULE__, :slice, topic, event, frame, pids},
              k * gap_ms
            )
        end)
    end
  end

  @doc "Delivers a later slice of a paced broadcast (see `broadcast_paced/5`)."
  @spec deliver_slice(slice_message()) :: :ok
  def deliver_slice({__MODULE__, :slice, topic, event, frame, pids}),
    do: deliver(topic, event, frame, pids)

  @doc """
  Broadcasts to this node's subscribers only (term and fastlane): for news about the
  cluster that only this node knows, e.g. that another node became unreachable.
  """
  @spec local_broadcast(topic(), event(), map(), module()) :: :ok
  def local_broadcast(topic, event, payload, encoder \\ default_encoder()) do
    for pid <- :pg.get_local_members(@scope, {:term, topic}) do
      send(pid, {:pubsub, topic, event, payload})
    end

    case local_fastlane(topic) do
      {[], []} ->
        :ok

      {first, others} ->
        frame = encoder.encode_broadcast(topic, event, payload)
        deliver(topic, event, frame, first)
        deliver(topic, event, frame, others)
    end
  end

  @doc """
  Serves an already encoded `frame` to this node's fastlane subscribers of `topic`
  (prioritized first): what a node's relay does with a frame from another node. Returns
  `:none` when the node has none (the relay then leaves the topic's relay group).
  """
  @spec deliver_local(topic(), event(), binary()) :: :ok | :none
  def deliver_local(topic, event, frame) when is_binary(frame) do
    case local_fastlane(topic) do
      {[], []} ->
        :none

      {first, others} ->
        deliver(topic, event, frame, first)
        deliver(topic, event, frame, others)
    end
  end

  defp local_fastlane(topic) do
    {:pg.get_local_members(@scope, {:fastlane_first, topic}),
     :pg.get_local_members(@scope, {:fastlane, topic})}
  end

  @doc false
  @spec scope() :: atom()
  def scope, do: @scope

  @doc """
  How `count` subscribers are sliced (pure): `{slice size, gap in ms}`. Slices are
  `pace.slice` long unless that would spread them beyond `pace.spread_ms`; then they grow
  so that the last one goes out by then.

      iex> Neptunus.PubSub.plan(1000, %{slice: 50, gap_ms: 2, spread_ms: 40})
      {50, 2}
      iex> Neptunus.PubSub.plan(1000, %{slice: 50, gap_ms: 2, spread_ms: 20})
      {91, 2}
      iex> Neptunus.PubSub.plan(10, %{slice: 50, gap_ms: 2, spread_ms: 0})
      {50, 2}
  """
  @spec plan(non_neg_integer(), pace()) :: {pos_integer(), pos_integer()}
  def plan(count, %{slice: slice, gap_ms: gap_ms, spread_ms: spread_ms})
      when is_integer(count) and count >= 0 and is_integer(slice) and slice > 0 and
             is_integer(gap_ms) and gap_ms > 0 and is_integer(spread_ms) and spread_ms >= 0 do
    slices = div(spread_ms, gap_ms) + 1
    {max(slice, ceil_div(count, slices)), gap_ms}
  end

  defp ceil_div(a, b), do: div(a + b - 1, b)

  # Term subscribers, prioritized fastlane subscribers and other nodes' relays get the
  # broadcast now; returns the frame, this node's other fastlane subscribers and its
  # prioritized ones (nil when no node has a fastlane subscriber).
  defp send_terms_and_first(topic, event, payload, encoder) do
    for pid <- :pg.get_members(@scope, {:term, topic}) do
      send(pid, {:pubsub, topic, event, payload})
    end

    relays = for pid <- :pg.get_members(@scope, {:relay, topic}), node(pid) != node(), do: pid

    case {local_fastlane(topic), relays} do
      {{[], []}, []} ->
        nil

      {{first, others}, relays} ->
        frame = encoder.encode_broadcast(topic, event, payload)
        deliver(topic, event, frame, first)
        # one message per other node with subscribers: its relay serves them
        Enum.each(relays, &send(&1, {__MODULE__.Relay, topic, event, frame}))
        {frame, others, first}
    end
  end

  defp deliver(topic, event, frame, pids),
    do: Enum.each(pids, &send(&1, {:pubsub_frame, topic, event, frame}))

  @doc "Number of subscribers (all kinds) of `topic` on all nodes."
  @spec subscriber_count(topic()) :: non_neg_integer()
  def subscriber_count(topic) do
    topic |> groups() |> Enum.map(&length(:pg.get_members(@scope, &1))) |> Enum.sum()
  end

  defp groups(topic), do: [{:term, topic}, {:fastlane_first, topic}, {:fastlane, topic}]
end
