defmodule Neptunus.PubSub.Relay do
  @moduledoc """
  A node's relay of fastlane frames from the other nodes (see `Neptunus.PubSub`, "Across
  nodes"): while this node has fastlane subscribers of a topic, the relay is in the scope's
  group `{:relay, topic}`, so a broadcast on another node sends it the encoded frame once,
  and it serves this node's subscribers (`Neptunus.PubSub.deliver_local/3`). A frame that
  finds no subscriber here any more makes it leave the group (subscribing tells it again:
  `watch/1`).

  The relay watches the scope like every subscriber: when the scope restarts its
  memberships are gone, and the subscribers that subscribe again tell it again.
  """
  use GenServer

  alias Neptunus.PubSub
  alias Neptunus.PubSub.Follow

  defmodule State do
    @moduledoc false
    # the scope watched (a follow of no topic: the relay's groups are joined on demand)
    @type t :: %__MODULE__{follow: Neptunus.PubSub.Follow.t()}
    @enforce_keys [:follow]
    defstruct [:follow]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(_opts \\ []), do: GenServer.start_link(__MODULE__, nil, name: __MODULE__)

  @spec child_spec(keyword()) :: Supervisor.child_spec()
  def child_spec(opts), do: %{id: __MODULE__, start: {__MODULE__, :start_link, [opts]}}

  @doc "This node has (or just got) a fastlane subscriber of `topic`: relay it. Asynchronous."
  @spec watch(PubSub.topic()) :: :ok
  def watch(topic) do
    case Process.whereis(__MODULE__) do
      nil -> :ok
      pid -> GenServer.cast(pid, {:watch, topic})
    end
  end

  @impl true
  def init(nil) do
    {_watched_or_waiting, follow} = Follow.subscribe(Follow.new([]))
    {:ok, %State{follow: follow}}
  end

  @impl true
  def handle_cast({:watch, topic}, state) do
    group = {:relay, topic}

    if Follow.subscribed?(state.follow) and
         self() not in :pg.get_local_members(PubSub.scope(), group) do
      join(group)
    end

    {:noreply, state}
  end

  @impl true
  def handle_info({__MODULE__, topic, event, frame}, state) do
    if PubSub.deliver_local(topic, event, frame) == :none do
      leave({:relay, topic})
    end

    {:noreply, state}
  end

  # the scope restarted: its memberships are gone; watch the new one
  def handle_info({:DOWN, _, :process, _, _} = msg, state), do: follow(state, msg)
  def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)

  def handle_info(_msg, state), do: {:noreply, state}

  defp follow(state, msg) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  # the scope may stop between the check and the call: its memberships went with it
  defp join(group) do
    :pg.join(PubSub.scope(), group, self())
  catch
    :exit, _ -> :ok
  end

  defp leave(group) do
    if self() in :pg.get_local_members(PubSub.scope(), group),
      do: :pg.leave(PubSub.scope(), group, self())
  catch
    :exit, _ -> :ok
  end
end
