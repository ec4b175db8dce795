defmodule NeptunusWeb.CameraRelay do
  @moduledoc """
  One stream of a camera's frames per node: the camera of a vehicle on another node of the
  fleet reaches this node's viewers (`NeptunusWeb.VideoSocket`, `NeptunusWeb.CameraStream`)
  through one relay process here, the only subscriber of the camera's topic on this node.
  The camera's node sends each frame once to this node, whatever the number of viewers
  here; the relay hands it to each of them (a frame is a shared binary: a local send copies
  no pixels), with the camera's `stream` and `camera` messages in their order.

  Viewers call `watch/1`, which subscribes them to a camera here directly and to a camera
  elsewhere through this node's relay.

  A relay is started for the first viewer (under `Neptunus.Fleet`'s relays supervisor,
  named in its registry) and stops when the last one has gone. Viewers monitor it: if it
  dies they subscribe again (a new relay). When the PubSub scope restarts (its
  subscription gone) the relay subscribes again as soon as the scope is back.
  """
  use GenServer

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.PubSub.Follow
  alias Neptunus.Vehicle.Camera

  @supervisor Neptunus.Fleet.Relays

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            viewers: %{optional(pid()) => reference()},
            follow: Neptunus.PubSub.Follow.t()
          }
    @enforce_keys [:id, :follow]
    defstruct [:id, :follow, viewers: %{}]
  end

  @doc false
  @spec start_link(String.t()) :: GenServer.on_start()
  def start_link(id), do: GenServer.start_link(__MODULE__, id, name: Fleet.via(__MODULE__, id))

  @doc false
  @spec child_spec(String.t()) :: Supervisor.child_spec()
  def child_spec(id),
    do: %{id: {__MODULE__, id}, start: {__MODULE__, :start_link, [id]}, restart: :temporary}

  @doc """
  Subscribes the calling process to vehicle `id`'s camera (see `Neptunus.Vehicle.Camera`,
  the topic's messages): a vehicle on another node through this node's relay, a vehicle
  here directly. Returns a monitor of what serves the messages (the relay or the PubSub
  scope): on its `:DOWN`, watch again. While the PubSub scope restarts it waits.
  """
  @spec watch(String.t()) :: reference()
  def watch(id) do
    case Fleet.vehicle_node(id) do
      {:ok, node} when node != node() -> subscribe(id)
      _here_or_unreachable -> watch_here(id)
    end
  end

  # Subscribes to the camera's topic, watching the PubSub scope (waits while it restarts:
  # the caller is a viewer with nothing else to do, not a long-lived server's loop).
  defp watch_here(id) do
    case PubSub.follow([Camera.topic(id)]) do
      {:ok, ref} ->
        ref

      {:error, :not_running} ->
        Process.sleep(20)
        watch(id)
    end
  end

  @doc """
  Subscribes the calling process to vehicle `id`'s camera through this node's relay
  (term messages as from `Neptunus.PubSub`); returns a monitor of the relay: on its
  `:DOWN`, subscribe again.
  """
  @spec subscribe(String.t()) :: reference()
  def subscribe(id), do: subscribe(id, 5)

  defp subscribe(id, tries) do
    relay = relay!(id)
    ref = Process.monitor(relay)
    :ok = GenServer.call(relay, {:subscribe, self()})
    ref
  catch
    # the relay was stopping (its last viewer gone) or restarting: a new one
    :exit, _ when tries > 0 ->
      Process.sleep(10)
      subscribe(id, tries - 1)
  end

  @doc "This node's relay of vehicle `id`'s camera, or nil."
  @spec whereis(String.t()) :: pid() | nil
  def whereis(id), do: Fleet.whereis(__MODULE__, id)

  defp relay!(id) do
    case whereis(id) || DynamicSupervisor.start_child(@supervisor, {__MODULE__, id}) do
      pid when is_pid(pid) -> pid
      {:ok, pid} -> pid
      {:error, {:already_started, pid}} -> pid
    end
  end

  @impl true
  def init(id) do
    {_subscribed_or_waiting, follow} = Follow.subscribe(Follow.new([Camera.topic(id)]))
    {:ok, %State{id: id, follow: follow}}
  end

  @impl true
  def handle_call({:subscribe, viewer}, _from, state) do
    viewers = Map.put_new_lazy(state.viewers, viewer, fn -> Process.monitor(viewer) end)
    {:reply, :ok, %{state | viewers: viewers}}
  end

  @impl true
  def handle_info({:pubsub, _topic, _event, _payload} = message, state) do
    Enum.each(Map.keys(state.viewers), &send(&1, message))
    {:noreply, state}
  end

  # the PubSub scope's (Follow), or a viewer's: the last one gone, the relay stops
  def handle_info({:DOWN, _ref, :process, pid, _reason} = msg, state) do
    case Follow.handle(state.follow, msg) do
      {:other, _} -> viewer_gone(state, pid)
      {_lost, follow} -> {:noreply, %{state | follow: follow}}
    end
  end

  def handle_info({Follow, :retry, _} = msg, state) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  def handle_info(_msg, state), do: {:noreply, state}

  defp viewer_gone(state, pid) do
    viewers = Map.delete(state.viewers, pid)

    if viewers == %{},
      do: {:stop, :normal, %{state | viewers: viewers}},
      else: {:noreply, %{state | viewers: viewers}}
  end
end
