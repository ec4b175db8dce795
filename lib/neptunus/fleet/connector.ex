defmodule Neptunus.Fleet.Connector do
  @moduledoc """
  Keeps this node connected to the fleet's other nodes (`NEPTUNUS_CLUSTER`): connects to
  each at start, and again after it goes down, with a backoff per node
  (`Neptunus.Vehicle.Board.Backoff`, 100 ms doubling to 5 s, back to 100 ms once a
  connection held for 5 s), learning of ups and downs from `:net_kernel.monitor_nodes/1`.
  Connecting is the only thing it does: what the connection carries (the directory, the
  relays) follows from `:pg` and the monitors.
  """
  use GenServer

  require Logger

  alias Neptunus.Vehicle.Board.Backoff

  @min_ms 100
  @max_ms 5_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            nodes: [node()],
            backoff: %{optional(node()) => Neptunus.Vehicle.Board.Backoff.t()},
            up_since: %{optional(node()) => integer()},
            timers: %{optional(node()) => reference()}
          }
    defstruct nodes: [], backoff: %{}, up_since: %{}, timers: %{}
  end

  @spec start_link([node()]) :: GenServer.on_start()
  def start_link(nodes) when is_list(nodes),
    do: GenServer.start_link(__MODULE__, nodes, name: __MODULE__)

  @spec child_spec([node()]) :: Supervisor.child_spec()
  def child_spec(nodes), do: %{id: __MODULE__, start: {__MODULE__, :start_link, [nodes]}}

  @impl true
  def init(nodes) do
    :ok = :net_kernel.monitor_nodes(true)
    state = %State{nodes: nodes, backoff: Map.new(nodes, &{&1, Backoff.new(@min_ms, @max_ms)})}
    Enum.each(nodes, &send(self(), {:connect, &1}))
    {:ok, state}
  end

  @impl true
  def handle_info({:connect, node}, state) do
    state = %{state | timers: Map.delete(state.timers, node)}

    cond do
      node in Node.list() -> {:noreply, state}
      Node.connect(node) == true -> {:noreply, state}
      true -> {:noreply, retry(state, node)}
    end
  end

  def handle_info({:nodeup, node}, state) do
    if node in state.nodes, do: Logger.info("fleet: connected to #{node}")
    {:noreply, put_in(state.up_since[node], now())}
  end

  def handle_info({:nodedown, node}, state) do
    if node in state.nodes do
      Logger.warning("fleet: lost #{node}, reconnecting")
      {since, up_since} = Map.pop(state.up_since, node)
      backoff = Backoff.up_for(state.backoff[node], if(since, do: now() - since, else: 0))
      state = %{state | up_since: up_since, backoff: Map.put(state.backoff, node, backoff)}
      {:noreply, retry(state, node)}
    else
      {:noreply, state}
    end
  end

  def handle_info(_msg, state), do: {:noreply, state}

  defp retry(state, node) do
    if Map.has_key?(state.timers, node) do
      state
    else
      {delay, backoff} = Backoff.next(state.backoff[node])
      timer = Process.send_after(self(), {:connect, node}, delay)

      %{
        state
        | backoff: Map.put(state.backoff, node, backoff),
          timers: Map.put(state.timers, node, timer)
      }
    end
  end

  defp now, do: Neptunus.Clock.monotonic_ms()
end
