defmodule NeptunusWeb.Presence do
  @moduledoc """
  Who is watching which topic, in the Phoenix Presence wire format.

  One server per node keeps the presences of its own connections (ETS, monitored: a
  connection that dies leaves). Joins and leaves are broadcast as `presence_diff`
  `%{joins: %{key => %{metas: [meta]}}, leaves: %{...}}` on the topic to every node,
  **batched**: one diff per topic per `@batch_ms` ms at most, with a meta that joined and left
  within the same batch dropped from both. Without batching, N observers joining cost N²
  frames (every join to everyone) and the join storm of a crowd starved the server;
  `list/1` merges the presences of every node's server (found through the PubSub `:pg`
  scope) into `%{key => %{metas: [meta, ...]}}`, the `presence_state` payload.

  Every meta carries a unique `phx_ref`, which the JS client uses to tell metas apart.

  Restarts: the presences are in this server's table, so when it dies they are gone, and its
  pending diffs with them. Each connection watches it (`monitor/0`, see
  `NeptunusWeb.Socket`) and, once a new server runs, its channels track again and push a
  fresh `presence_state` to their client, which replaces the client's whole state (metas of
  the dead server and of connections that went meanwhile disappear); the others' tracks
  reach it as diffs. The server itself watches the PubSub scope and joins its group again
  when the scope restarts, so the other nodes find it.

  A fleet: when a vehicle of another node is cut off from this one (`unreachable` on topic
  `"fleet"`, from `Neptunus.Fleet.Directory`), its helm frees a pilot connected here but
  cannot tell it: the server tells that connection's channel `control_lost`
  (`pilot_unreachable`), as the helm would have.
  """
  use GenServer

  alias Neptunus.PubSub
  alias Neptunus.PubSub.Follow

  @table __MODULE__
  @group {__MODULE__, :servers}
  @batch_ms 100
  @fleet_topic "fleet"

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            monitors: %{optional(pid()) => reference()},
            pending: %{optional(String.t()) => [{:join | :leave, String.t(), map()}]},
            flush: reference() | nil,
            follow: Neptunus.PubSub.Follow.t()
          }
    @enforce_keys [:follow]
    defstruct [:follow, monitors: %{}, pending: %{}, flush: nil]
  end

  @type key :: String.t()
  @type meta :: map()
  @type presences :: %{optional(key()) => %{metas: [meta()]}}

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(_opts \\ []), do: GenServer.start_link(__MODULE__, nil, name: __MODULE__)

  @doc """
  Monitors the presence server, for a tracked process to learn that its presences are gone
  (see "Restarts"): `{:ok, ref}`, or `{:error, :not_running}` while it is down or restarting.
  """
  @spec monitor() :: {:ok, reference()} | {:error, :not_running}
  def monitor do
    case Process.whereis(__MODULE__) do
      nil -> {:error, :not_running}
      pid -> {:ok, Process.monitor(pid)}
    end
  end

  @doc "Tracks `pid` on `topic` under `key` with `meta`; returns the meta with its phx_ref."
  @spec track(pid(), String.t(), key(), meta()) :: {:ok, meta()}
  def track(pid, topic, key, meta),
    do: GenServer.call(__MODULE__, {:track, pid, topic, key, meta})

  @doc """
  Untracks `pid` from `topic` (no-op if it is not tracked there, and while the server is
  down: its presences went with it).
  """
  @spec untrack(pid(), String.t()) :: :ok
  def untrack(pid, topic) do
    GenServer.call(__MODULE__, {:untrack, pid, topic})
  catch
    :exit, {:noproc, _} -> :ok
  end

  @doc "Presences on `topic` across all nodes."
  @spec list(String.t()) :: presences()
  def list(topic) do
    nodes =
      for pid <- :pg.get_members(Neptunus.PubSub, @group), node(pid) != node(), do: node(pid)

    remote =
      nodes
      |> :erpc.multicall(__MODULE__, :local_entries, [topic], 5_000)
      |> Enum.flat_map(fn
        {:ok, entries} -> entries
        _ -> []
      end)

    group(local_entries(topic) ++ remote)
  end

  @doc false
  @spec local_entries(String.t()) :: [{key(), meta()}]
  def local_entries(topic) do
    :ets.match(@table, {{topic, :_}, :"$1", :"$2"}) |> Enum.map(fn [k, m] -> {k, m} end)
  rescue
    # the server is restarting: its presences went with it (see "Restarts")
    ArgumentError -> []
  end

  defp group(entries) do
    Enum.reduce(entries, %{}, fn {key, meta}, acc ->
      Map.update(acc, key, %{metas: [meta]}, fn %{metas: metas} -> %{metas: metas ++ [meta]} end)
    end)
  end

  # Callbacks

  @impl true
  def init(nil) do
    :ets.new(@table, [:named_table, :set, :protected, read_concurrency: true])
    # pending: topic => [{:join | :leave, key, meta}], newest first, flushed every @batch_ms
    state = %State{follow: Follow.new([@fleet_topic])}
    {:ok, follow(state, Follow.subscribe(state.follow))}
  end

  # Subscribed to "fleet" (again, see "Restarts"): joins the group the other nodes find this
  # server by. A scope that stops meanwhile takes the join with it, and the follow's :DOWN
  # brings both again.
  defp follow(state, {:subscribed, follow}) do
    :pg.join(PubSub.scope(), @group, self())
    %{state | follow: follow}
  catch
    :exit, _ -> %{state | follow: follow}
  end

  defp follow(state, {_waiting_or_lost, follow}), do: %{state | follow: follow}

  @impl true
  def handle_call({:track, pid, topic, key, meta}, _from, state) do
    state = untrack_entry(state, pid, topic)

    meta =
      Map.put(meta, :phx_ref, Base.url_encode64(:crypto.strong_rand_bytes(8), padding: false))

    :ets.insert(@table, {{topic, pid}, key, meta})
    state = state |> pend(topic, {:join, key, meta}) |> monitor(pid)
    {:reply, {:ok, meta}, state}
  end

  def handle_call({:untrack, pid, topic}, _from, state) do
    {:reply, :ok, untrack_entry(state, pid, topic)}
  end

  @impl true
  # the PubSub scope's (Follow), or a tracked process'
  def handle_info({:DOWN, _ref, :process, pid, _reason} = msg, state) do
    case Follow.handle(state.follow, msg) do
      {:other, _} -> {:noreply, gone(state, pid)}
      event -> {:noreply, follow(state, event)}
    end
  end

  def handle_info({Follow, :retry, _} = msg, state),
    do: {:noreply, follow(state, Follow.handle(state.follow, msg))}

  # A vehicle of another node is cut off from this one (Neptunus.Fleet.Directory): its helm
  # has freed a pilot connected here (`pilot_unreachable`) but cannot tell it; this node can.
  def handle_info({:pubsub, @fleet_topic, "unreachable", %{id: id}}, state) do
    topic = Neptunus.Vehicle.Telemetry.topic(id)

    for [pid] <- :ets.match(@table, {{topic, :"$1"}, :_, %{pilot: true}}) do
      # as the helm's own targeted events arrive (NeptunusWeb.Channel.send_self/2)
      send(pid, {:channel_info, topic, {:helm, "control_lost", %{reason: "pilot_unreachable"}}})
    end

    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  def handle_info(:flush, state) do
    for {topic, events} <- state.pending do
      {joins, leaves} = fold_events(Enum.reverse(events))
      if joins != %{} or leaves != %{}, do: diff(topic, joins, leaves)
    end

    {:noreply, %{state | pending: %{}, flush: nil}}
  end

  @doc false
  # Folds a batch of events (oldest first) into a diff, dropping metas that joined and left
  # within the batch.
  @spec fold_events([{:join | :leave, key(), meta()}]) :: {presences(), presences()}
  def fold_events(events) do
    refs = fn kind -> for {^kind, _, %{phx_ref: ref}} <- events, into: MapSet.new(), do: ref end
    transient = MapSet.intersection(refs.(:join), refs.(:leave))

    events
    |> Enum.reject(fn {_, _, %{phx_ref: ref}} -> MapSet.member?(transient, ref) end)
    |> Enum.reduce({%{}, %{}}, fn
      {:join, key, meta}, {joins, leaves} -> {add_meta(joins, key, meta), leaves}
      {:leave, key, meta}, {joins, leaves} -> {joins, add_meta(leaves, key, meta)}
    end)
  end

  defp add_meta(presences, key, meta) do
    Map.update(presences, key, %{metas: [meta]}, fn %{metas: metas} ->
      %{metas: metas ++ [meta]}
    end)
  end

  defp pend(state, topic, event) do
    state =
      update_in(state.pending, &Map.update(&1, topic, [event], fn list -> [event | list] end))

    case state.flush do
      nil -> %{state | flush: Process.send_after(self(), :flush, @batch_ms)}
      _ -> state
    end
  end

  defp untrack_entry(state, pid, topic) do
    state = leave(state, topic, pid)

    if :ets.match(@table, {{:_, pid}, :_, :_}) == [] do
      case Map.pop(state.monitors, pid) do
        {nil, _} -> state
        {ref, monitors} -> Process.demonitor(ref, [:flush]) && %{state | monitors: monitors}
      end
    else
      state
    end
  end

  # a tracked process is gone: it leaves every topic
  defp gone(state, pid) do
    state =
      Enum.reduce(:ets.match(@table, {{:"$1", pid}, :_, :_}), state, fn [topic], state ->
        leave(state, topic, pid)
      end)

    %{state | monitors: Map.delete(state.monitors, pid)}
  end

  defp leave(state, topic, pid) do
    case :ets.take(@table, {topic, pid}) do
      [{_, key, meta}] -> pend(state, topic, {:leave, key, meta})
      [] -> state
    end
  end

  defp monitor(state, pid) do
    if Map.has_key?(state.monitors, pid),
      do: state,
      else: put_in(state.monitors[pid], Process.monitor(pid))
  end

  defp diff(topic, joins, leaves),
    do: PubSub.broadcast(topic, "presence_diff", %{joins: joins, leaves: leaves})
end
