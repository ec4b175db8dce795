defmodule Neptunus.Fleet.Directory do
  @moduledoc """
  This node's view of the fleet's directory: a `Neptunus.Fleet.Book` kept from the `:pg`
  events of the fleet's scope (`:pg.monitor_scope/1`) and the node monitor
  (`:net_kernel.monitor_nodes/1`), published in a protected ETS table for lookups without a
  call (every command of a browser on this node to a vehicle on another looks its helm up).

  When a vehicle becomes unreachable (its node cut off) or reachable again, it says so to
  this node's subscribers of the vehicle's topic (`Neptunus.PubSub.local_broadcast/4`):
  events `unreachable` `%{id, node, reason: "node_unreachable"}` and `reachable`
  `%{id, node}`, followed by the helm's state as it is now (`helm`: what the helm broadcast
  while the nodes were apart never arrived here); the vehicle's own node cannot tell them,
  and a page must not show frozen telemetry as live. The same two events go to this node's
  subscribers of `"fleet"` (the fleet channel's clients, and the presence server, which
  tells a pilot of this node that it lost control).
  """
  use GenServer

  require Logger

  alias Neptunus.Fleet.Book
  alias Neptunus.PubSub

  @table __MODULE__
  @fleet_topic "fleet"

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            book: Neptunus.Fleet.Book.t(),
            ref: reference(),
            scope: atom(),
            node: node()
          }
    @enforce_keys [:book, :ref, :scope, :node]
    defstruct [:book, :ref, :scope, :node]
  end

  @spec start_link(atom()) :: GenServer.on_start()
  def start_link(scope), do: GenServer.start_link(__MODULE__, scope, name: __MODULE__)

  @spec child_spec(atom()) :: Supervisor.child_spec()
  def child_spec(scope), do: %{id: __MODULE__, start: {__MODULE__, :start_link, [scope]}}

  @doc "Vehicle `id`'s entry (`t:Neptunus.Fleet.Book.entry/0`), or nil."
  @spec lookup(String.t()) :: Book.entry() | nil
  def lookup(id) do
    case :ets.lookup(@table, id) do
      [{^id, entry}] -> current_node(entry)
      [] -> nil
    end
  rescue
    # the directory is restarting
    ArgumentError -> nil
  end

  @doc "Every entry, sorted by id."
  @spec entries() :: [Book.entry()]
  def entries do
    @table |> :ets.tab2list() |> Enum.map(&current_node(elem(&1, 1))) |> Enum.sort_by(& &1.id)
  rescue
    ArgumentError -> []
  end

  # A vehicle that is up is on its helm's node as it is named now: this node's own vehicles
  # joined before distribution may have started (then as nonode@nohost), and a pid's node
  # follows the node's name.
  defp current_node(%{pid: pid} = entry) when is_pid(pid), do: %{entry | node: node(pid)}
  defp current_node(entry), do: entry

  @doc """
  Forgets the vehicles remembered as unreachable on `node` (a node taken out of the fleet
  for good): they are no longer listed. A vehicle of it that comes back is listed again.
  """
  @spec forget(node()) :: :ok
  def forget(node) when is_atom(node), do: GenServer.call(__MODULE__, {:forget, node})

  @doc "Waits until the directory has handled every event sent to it so far (tests)."
  @spec sync() :: :ok
  def sync, do: GenServer.call(__MODULE__, :sync)

  @impl true
  def init(scope) do
    :ets.new(@table, [:named_table, :set, :protected, read_concurrency: true])
    :ok = :net_kernel.monitor_nodes(true)
    {ref, groups} = :pg.monitor_scope(scope)

    book =
      Enum.reduce(groups, Book.new(), fn
        {{:vehicle, id, board}, pids}, book -> book |> join(id, board, pids) |> elem(0)
        _, book -> book
      end)

    {:ok, publish(%State{book: book, ref: ref, scope: scope, node: node()})}
  end

  @impl true
  def handle_call(:sync, _from, state), do: {:reply, :ok, renamed(state)}

  def handle_call({:forget, node}, _from, state) do
    state = renamed(state)
    {:reply, :ok, publish(%{state | book: Book.forget(state.book, node)})}
  end

  @impl true
  def handle_info(msg, %State{node: named} = state) when named != node() do
    handle_info(msg, renamed(state))
  end

  def handle_info({ref, :join, {:vehicle, id, board}, pids}, %State{ref: ref} = state) do
    {book, announced} = join(state.book, id, board, pids)
    {:noreply, publish_then_announce(state, book, announced)}
  end

  def handle_info({ref, :leave, {:vehicle, id, _board}, pids}, %State{ref: ref} = state) do
    connected = [node() | Node.list()]

    {book, announced} =
      Enum.reduce(pids, {state.book, []}, fn pid, {book, announced} ->
        {book, more} = Book.leave(book, id, pid, node(pid) in connected)
        {book, announced ++ more}
      end)

    {:noreply, publish_then_announce(state, book, announced)}
  end

  def handle_info({:nodedown, node}, state) do
    {book, announced} = Book.nodedown(state.book, node)
    {:noreply, publish_then_announce(state, book, announced)}
  end

  def handle_info(_msg, state), do: {:noreply, state}

  # This node became distributed (or was renamed) since the last event: its vehicles joined
  # under its former name.
  defp renamed(%State{node: named} = state) do
    case node() do
      ^named -> state
      now -> publish(%{state | book: Book.rename(state.book, named, now), node: now})
    end
  end

  defp join(book, id, board, pids) do
    Enum.reduce(pids, {book, []}, fn pid, {book, announced} ->
      {book, more} = Book.join(book, id, board, pid, node(pid), node())
      {book, announced ++ more}
    end)
  end

  # whoever hears an announcement and reads the directory sees what was announced
  defp publish_then_announce(state, book, announced) do
    state = publish(%{state | book: book})
    Enum.each(announced, &announce/1)
    state
  end

  defp publish(state) do
    entries = Book.entries(state.book)
    ids = MapSet.new(entries, & &1.id)

    for {id, _} <- :ets.tab2list(@table), not MapSet.member?(ids, id), do: :ets.delete(@table, id)

    :ets.insert(@table, Enum.map(entries, &{&1.id, &1}))
    state
  end

  defp announce({:unreachable, id, node}) do
    Logger.warning("vehicle #{id} unreachable: node #{node} is not connected")
    payload = %{id: id, node: Atom.to_string(node), reason: "node_unreachable"}
    PubSub.local_broadcast(Neptunus.Vehicle.Telemetry.topic(id), "unreachable", payload)
    PubSub.local_broadcast(@fleet_topic, "unreachable", payload)
  end

  defp announce({:reachable, id, node}) do
    Logger.info("vehicle #{id} reachable again on node #{node}")
    topic = Neptunus.Vehicle.Telemetry.topic(id)
    payload = %{id: id, node: Atom.to_string(node)}
    PubSub.local_broadcast(topic, "reachable", payload)
    PubSub.local_broadcast(@fleet_topic, "reachable", payload)

    # The helm's broadcasts while the nodes were apart never came here (it freed a pilot of
    # this node, for one): this node's subscribers get its state now, asked off this process.
    spawn(fn -> refresh_helm(id, topic) end)
  end

  defp refresh_helm(id, topic) do
    PubSub.local_broadcast(topic, "helm", Neptunus.Vehicle.Helm.status(id))
  catch
    # cut off again, or stopped: the next announcement says so
    :exit, _ -> :ok
  end
end
