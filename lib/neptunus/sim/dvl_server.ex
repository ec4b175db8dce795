defmodule Neptunus.Sim.DVLServer do
  @moduledoc """
  The simulated DVL as a device on the network: a TCP server on loopback speaking the Water
  Linked DVL JSON protocol (`Neptunus.Protocol.WaterLinkedDVL`), so the real driver
  (`Neptunus.Position.DVL`) is what reads a simulated vehicle's DVL.

  It follows the vehicle's simulator through its pose (`Neptunus.Camera.Pose`, published at
  every simulation step), steps a `Neptunus.Sim.DVL` with it on the node's monotonic clock,
  and writes each report as a line to every connected client; the clients' commands go to the
  simulated DVL and its responses come back the same way. While the simulator is paused or
  stopped no pose comes, and no report either — as a DVL whose power is off.

  Options: `:id` (the vehicle), `:name` (the source's name, for the registry), `:port`
  (default 0: any free port; `port/2` tells which), `:dvl` (`Neptunus.Sim.DVL` settings),
  `:seed`.
  """
  use GenServer

  require Logger

  alias Neptunus.Camera.Pose
  alias Neptunus.PubSub.Follow
  alias Neptunus.Protocol.{Lines, WaterLinkedDVL}
  alias Neptunus.Sim.DVL

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{}
    defstruct [:id, :listen, :port, :dvl, :follow, clients: %{}]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts,
      name: via(Keyword.fetch!(opts, :id), Keyword.get(opts, :name, :dvl))
    )
  end

  @doc "The TCP port the simulated DVL of vehicle `id` (source `name`) listens on."
  @spec port(String.t(), atom()) :: :inet.port_number()
  def port(id, name), do: GenServer.call(via(id, name), :port)

  defp via(id, name), do: Neptunus.Fleet.via({__MODULE__, name}, id)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    opts_listen = [:binary, active: false, reuseaddr: true, ip: {127, 0, 0, 1}, packet: :raw]
    {:ok, listen} = :gen_tcp.listen(Keyword.get(opts, :port, 0), opts_listen)
    {:ok, port} = :inet.port(listen)
    server = self()
    spawn_link(fn -> accept(listen, server) end)

    # the DVL's clock: Unix microseconds, as the real one stamps its reports
    epoch_us = Neptunus.Clock.wall_ms() * 1000 - Neptunus.Clock.monotonic_ms() * 1000
    seed = Keyword.get(opts, :seed, :erlang.unique_integer([:positive]))
    dvl = DVL.new(Keyword.merge(Keyword.get(opts, :dvl, []), epoch_us: epoch_us), seed)

    {:ok, %State{id: id, listen: listen, port: port, dvl: dvl}, {:continue, :subscribe}}
  end

  @impl true
  def handle_continue(:subscribe, state) do
    {_subscribed_or_waiting, follow} = Follow.subscribe(Follow.new([Pose.topic(state.id)]))
    {:noreply, %{state | follow: follow}}
  end

  @impl true
  def handle_call(:port, _from, state), do: {:reply, state.port, state}

  @impl true
  def handle_info({:client, socket}, state) do
    :ok = :inet.setopts(socket, active: :once)
    {:noreply, %{state | clients: Map.put(state.clients, socket, Lines.new(1024))}}
  end

  def handle_info({:pubsub, _topic, "pose", pose}, state) do
    {reports, dvl} = DVL.step(state.dvl, now(), pose)
    lines = Enum.map(reports, &encode/1)
    if lines != [], do: for(socket <- Map.keys(state.clients), do: :gen_tcp.send(socket, lines))
    {:noreply, %{state | dvl: dvl}}
  end

  def handle_info({:tcp, socket, data}, state) do
    :ok = :inet.setopts(socket, active: :once)
    {lines, framer} = Lines.feed(Map.fetch!(state.clients, socket), data)

    dvl =
      Enum.reduce(lines, state.dvl, fn line, dvl ->
        case WaterLinkedDVL.decode_command(line) do
          {:ok, command} -> DVL.command(dvl, now(), command)
          {:error, _reason} -> dvl
        end
      end)

    {:noreply, %{state | dvl: dvl, clients: Map.put(state.clients, socket, framer)}}
  end

  def handle_info({:tcp_closed, socket}, state),
    do: {:noreply, %{state | clients: Map.delete(state.clients, socket)}}

  def handle_info({:tcp_error, socket, _reason}, state) do
    :gen_tcp.close(socket)
    {:noreply, %{state | clients: Map.delete(state.clients, socket)}}
  end

  # PubSub restarted: subscribe to the simulator's pose again
  def handle_info({:DOWN, _, :process, _, _} = msg, state), do: follow(state, msg)
  def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)
  def handle_info(_other, state), do: {:noreply, state}

  defp follow(state, msg) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  defp encode({:velocity, v}), do: WaterLinkedDVL.encode_velocity(v)
  defp encode({:position_local, p}), do: WaterLinkedDVL.encode_position_local(p)

  defp encode({:response, r}),
    do: WaterLinkedDVL.encode_response(r.to, r.success, r.error_message, r.result)

  defp accept(listen, server) do
    case :gen_tcp.accept(listen) do
      {:ok, socket} ->
        :ok = :gen_tcp.controlling_process(socket, server)
        send(server, {:client, socket})
        accept(listen, server)

      {:error, :closed} ->
        :ok
    end
  end

  defp now, do: Neptunus.Clock.monotonic_ms() / 1000
end
