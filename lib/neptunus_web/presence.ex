defmodule NeptunusWeb.Presence do
  @moduledoc """
  Who is watching which topic, in the Phoenix Presence wire format.

  One server per node keeps the presences of its own connections (ETS, monitored: a
  connection that dies leaves). `track/4` and `untrack/2` broadcast `presence_diff`
  `%{joins: %{key => %{metas: [meta]}}, leaves: %{...}}` on the topic to every node;
  `list/1` merges the presences of every node's server (found through the PubSub `:pg`
  scope) into `%{key => %{metas: [meta, ...]}}`, the `presence_state` payload.

  Every meta carries a unique `phx_ref`, which the JS client uses to tell metas apart.
  """
  use GenServer

  alias Neptunus.PubSub

  @table __MODULE__
  @group {__MODULE__, :servers}

  @type key :: String.t()
  @type meta :: map()
  @type presences :: %{optional(key()) => %{metas: [meta()]}}

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(_opts \\ []), do: GenServer.start_link(__MODULE__, nil, name: __MODULE__)

  @doc "Tracks `pid` on `topic` under `key` with `meta`; returns the meta with its phx_ref."
  @spec track(pid(), String.t(), key(), meta()) :: {:ok, meta()}
  def track(pid, topic, key, meta),
    do: GenServer.call(__MODULE__, {:track, pid, topic, key, meta})

  @doc "Untracks `pid` from `topic` (no-op if it is not tracked there)."
  @spec untrack(pid(), String.t()) :: :ok
  def untrack(pid, topic), do: GenServer.call(__MODULE__, {:untrack, pid, topic})

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
    :pg.join(Neptunus.PubSub, @group, self())
    {:ok, %{monitors: %{}}}
  end

  @impl true
  def handle_call({:track, pid, topic, key, meta}, _from, state) do
    state = untrack_entry(state, pid, topic)

    meta =
      Map.put(meta, :phx_ref, Base.url_encode64(:crypto.strong_rand_bytes(8), padding: false))

    :ets.insert(@table, {{topic, pid}, key, meta})
    diff(topic, %{key => %{metas: [meta]}}, %{})
    {:reply, {:ok, meta}, monitor(state, pid)}
  end

  def handle_call({:untrack, pid, topic}, _from, state) do
    {:reply, :ok, untrack_entry(state, pid, topic)}
  end

  @impl true
  def handle_info({:DOWN, _ref, :process, pid, _reason}, state) do
    for [topic] <- :ets.match(@table, {{:"$1", pid}, :_, :_}), do: leave(topic, pid)
    {:noreply, %{state | monitors: Map.delete(state.monitors, pid)}}
  end

  defp untrack_entry(state, pid, topic) do
    leave(topic, pid)

    if :ets.match(@table, {{:_, pid}, :_, :_}) == [] do
      case Map.pop(state.monitors, pid) do
        {nil, _} -> state
        {ref, monitors} -> Process.demonitor(ref, [:flush]) && %{state | monitors: monitors}
      end
    else
      state
    end
  end

  defp leave(topic, pid) do
    case :ets.take(@table, {topic, pid}) do
      [{_, key, meta}] -> diff(topic, %{}, %{key => %{metas: [meta]}})
      [] -> :ok
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
