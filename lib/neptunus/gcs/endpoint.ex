defmodule Neptunus.GCS.Endpoint do
  @moduledoc """
  One configured ground station endpoint (`NEPTUNUS_MAVLINK_SERVE`), the process that owns
  its socket:

    * `udpin:ADDRESS:PORT` — binds the address; every source address that sends an
      admissible message is a session (`Neptunus.GCS.Link`), and its later datagrams go to it;
    * `udpout:HOST:PORT` — sends from an ephemeral port to one ground station, whose session
      starts at once and pushes telemetry (as a vehicle does to port 14550); what comes back
      from that address goes to it, anything from elsewhere is dropped;
    * `tcpin:ADDRESS:PORT` — listens; every connection is a session owning its socket.

  A datagram from an address without a session is looked at before a session is made for it:
  it must hold a message the endpoint would admit (signed with a configured key beyond
  loopback; `Neptunus.GCS.Admission`). At most #{32} sessions per endpoint, and at most
  #{200} datagrams a second from unknown addresses are looked at: the rest are dropped and
  counted, so spoofed sources cannot make the node spawn processes or hash without end.

  The endpoint only sorts datagrams to their sessions (a map lookup and a message each); it
  runs at process priority `:high`, so a pilot's datagram is not queued behind other work,
  while it sorts at most #{2000} datagrams a second (beyond, `:normal` for the rest of
  that second).
  """
  use GenServer

  require Logger

  alias Neptunus.GCS.{Admission, Link}
  alias Neptunus.Protocol.MAVLink

  @max_sessions 32
  @unknown_per_s 200
  @high_per_s 2_000
  @active 100

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            endpoint: Neptunus.Config.GCS.endpoint(),
            admission: Neptunus.GCS.Admission.config(),
            vehicles: %{(1..255) => map()},
            socket: port() | nil,
            peers: %{{:inet.ip_address(), :inet.port_number()} => pid()},
            monitors: %{reference() => term()},
            unknown: {integer(), non_neg_integer()},
            load: {integer(), non_neg_integer()},
            counters: %{atom() => non_neg_integer()},
            timeout_ms: pos_integer()
          }
    @enforce_keys [:endpoint, :admission, :vehicles]
    defstruct @enforce_keys ++
                [
                  socket: nil,
                  peers: %{},
                  monitors: %{},
                  unknown: {0, 0},
                  load: {0, 0},
                  counters: %{},
                  timeout_ms: 5_000
                ]
  end

  @doc """
  Options: `:endpoint` (`t:Neptunus.Config.GCS.endpoint/0`), `:admission`
  (`t:Neptunus.GCS.Admission.config/0` without `loopback`, which is the endpoint's),
  `:vehicles` (`%{sysid => %{id, board, wiring}}`), `:timeout_ms` (a session's silence).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    endpoint = Keyword.fetch!(opts, :endpoint)
    GenServer.start_link(__MODULE__, opts, name: name(endpoint.link_id))
  end

  @spec child_spec(keyword()) :: Supervisor.child_spec()
  def child_spec(opts),
    do: %{
      id: {__MODULE__, Keyword.fetch!(opts, :endpoint).link_id},
      start: {__MODULE__, :start_link, [opts]}
    }

  @doc "The process of the endpoint with link id `link_id` (its place in NEPTUNUS_MAVLINK_SERVE)."
  @spec name(byte()) :: GenServer.name()
  def name(link_id), do: {:via, Registry, {Neptunus.GCS.Names, {__MODULE__, link_id}}}

  @doc "The endpoint's counters, its sessions' pids and the local port it uses."
  @spec stats(GenServer.server()) :: map()
  def stats(server), do: GenServer.call(server, :stats)

  # Callbacks

  @impl true
  def init(opts) do
    endpoint = Keyword.fetch!(opts, :endpoint)

    state = %State{
      endpoint: endpoint,
      admission: Map.put(Keyword.fetch!(opts, :admission), :loopback, endpoint.loopback),
      vehicles: Keyword.fetch!(opts, :vehicles),
      timeout_ms: Keyword.get(opts, :timeout_ms, 5_000)
    }

    {:ok, state, {:continue, :open}}
  end

  @impl true
  def handle_continue(:open, %State{endpoint: endpoint} = state) do
    Process.flag(:priority, :high)

    case open(endpoint) do
      {:ok, socket} ->
        state = %{state | socket: socket}
        Logger.info("MAVLink endpoint #{endpoint.spec} serving ground stations")
        {:noreply, start(state)}

      {:error, reason} ->
        # the node cannot serve what it was configured to: say so and stop (the supervisor
        # retries; a port in use stays an error)
        {:stop, {:shutdown, "MAVLink endpoint #{endpoint.spec}: #{:inet.format_error(reason)}"},
         state}
    end
  end

  @impl true
  def handle_call(:stats, _from, state) do
    {:ok, port} = :inet.port(state.socket)

    {:reply,
     %{
       counters: state.counters,
       sessions: Map.values(state.peers) ++ tcp_sessions(state),
       port: port
     }, state}
  end

  def handle_call(:may_accept?, _from, state),
    do: {:reply, map_size(state.monitors) < @max_sessions, state}

  def handle_call({:accepted, pid}, _from, state) do
    ref = Process.monitor(pid)
    {:reply, :ok, %{state | monitors: Map.put(state.monitors, ref, {:tcp, pid})}}
  end

  @impl true
  def handle_info({:udp, socket, ip, port, data}, %State{socket: socket} = state) do
    state = load(state)

    case state.peers do
      %{{^ip, ^port} => pid} ->
        send(pid, {:datagram, data})
        {:noreply, state}

      _ when state.endpoint.kind == :udpin ->
        {:noreply, unknown(state, ip, port, data)}

      _ ->
        {:noreply, count(state, :foreign_peer)}
    end
  end

  def handle_info({:udp_passive, socket}, %State{socket: socket} = state) do
    :ok = :inet.setopts(socket, active: @active)
    {:noreply, state}
  end

  def handle_info({:DOWN, ref, :process, _pid, _reason}, state) do
    case Map.pop(state.monitors, ref) do
      {{:udp, peer}, monitors} ->
        {:noreply, %{state | monitors: monitors, peers: Map.delete(state.peers, peer)}}

      {{:tcp, _pid}, monitors} ->
        {:noreply, %{state | monitors: monitors}}

      {nil, _} ->
        {:noreply, state}
    end
  end

  def handle_info(msg, state) do
    Logger.debug("MAVLink endpoint #{state.endpoint.spec} ignored #{inspect(msg, limit: 5)}")
    {:noreply, state}
  end

  # --- sockets --------------------------------------------------------------------------------

  defp open(%{kind: :udpin, address: address, port: port}),
    do:
      :gen_udp.open(port, [
        :binary,
        family(address),
        ip: address,
        active: @active,
        reuseaddr: true
      ])

  defp open(%{kind: :udpout, address: address}),
    do: :gen_udp.open(0, [:binary, family(address), active: @active])

  defp open(%{kind: :tcpin, address: address, port: port}) do
    :gen_tcp.listen(port, [
      :binary,
      family(address),
      ip: address,
      active: false,
      reuseaddr: true,
      nodelay: true,
      backlog: 16,
      send_timeout: 2_000,
      send_timeout_close: true
    ])
  end

  defp family(address) when tuple_size(address) == 8, do: :inet6
  defp family(_address), do: :inet

  # a udpout's session starts now; a tcpin's acceptor starts accepting
  defp start(%State{endpoint: %{kind: :udpout} = endpoint} = state) do
    peer = {endpoint.address, endpoint.port}

    {:ok, pid} =
      start_link_session(
        state,
        {:udp, state.socket, endpoint.address, endpoint.port},
        peer,
        endpoint.gcs || :push
      )

    ref = Process.monitor(pid)

    %{
      state
      | peers: Map.put(state.peers, peer, pid),
        monitors: Map.put(state.monitors, ref, {:udp, peer})
    }
  end

  defp start(%State{endpoint: %{kind: :tcpin}} = state) do
    me = self()
    listen = state.socket
    spawn_link(fn -> accept_loop(me, listen, state) end)
    state
  end

  defp start(state), do: state

  defp accept_loop(endpoint, listen, state) do
    case :gen_tcp.accept(listen) do
      {:ok, socket} ->
        if GenServer.call(endpoint, :may_accept?) do
          {:ok, {ip, port}} = :inet.peername(socket)

          case start_link_session(state, {:tcp, socket}, {ip, port}, nil, endpoint) do
            {:ok, pid} ->
              :ok = GenServer.call(endpoint, {:accepted, pid})
              :ok = :gen_tcp.controlling_process(socket, pid)
              :ok = :inet.setopts(socket, active: :once)

            _ ->
              :gen_tcp.close(socket)
          end
        else
          :gen_tcp.close(socket)
        end

        accept_loop(endpoint, listen, state)

      {:error, :closed} ->
        :ok

      {:error, _reason} ->
        Process.sleep(100)
        accept_loop(endpoint, listen, state)
    end
  end

  # a session watches its endpoint (`owner`: the acceptor starts tcpin's for it)
  defp start_link_session(state, transport, {ip, port}, gcs, owner \\ self()) do
    endpoint = state.endpoint

    DynamicSupervisor.start_child(
      Neptunus.GCS.Links,
      {Link,
       id: "#{endpoint.kind}#{endpoint.link_id}/#{:inet.ntoa(ip)}:#{port}",
       transport: transport,
       endpoint: owner,
       link_id: endpoint.link_id,
       admission: state.admission,
       vehicles: state.vehicles,
       gcs: gcs,
       timeout_ms: state.timeout_ms}
    )
  end

  defp tcp_sessions(state), do: for({_ref, {:tcp, pid}} <- state.monitors, do: pid)

  # --- unknown peers --------------------------------------------------------------------------

  defp unknown(state, ip, port, data) do
    now_s = div(Neptunus.Clock.monotonic_ms(), 1000)
    {second, seen} = state.unknown
    seen = if second == now_s, do: seen, else: 0

    cond do
      seen >= @unknown_per_s ->
        count(%{state | unknown: {now_s, seen}}, :unknown_flood)

      map_size(state.peers) >= @max_sessions ->
        count(%{state | unknown: {now_s, seen + 1}}, :no_room)

      byte_size(data) > 2048 or not admissible?(state, data) ->
        count(%{state | unknown: {now_s, seen + 1}}, :not_admitted)

      true ->
        state = %{state | unknown: {now_s, seen + 1}}

        case start_link_session(state, {:udp, state.socket, ip, port}, {ip, port}, nil) do
          {:ok, pid} ->
            send(pid, {:datagram, data})
            ref = Process.monitor(pid)
            peer = {ip, port}

            %{
              state
              | peers: Map.put(state.peers, peer, pid),
                monitors: Map.put(state.monitors, ref, {:udp, peer})
            }

          _ ->
            count(state, :no_room)
        end
    end
  end

  # whether a first datagram holds a message this endpoint would admit (its replay is
  # checked by the session)
  defp admissible?(state, data) do
    {_decoder, messages, _events} = MAVLink.decode(MAVLink.new(), data)

    Enum.any?(messages, fn message ->
      not match?({:drop, _}, Admission.check(state.admission, nil, message))
    end)
  end

  # the datagrams sorted this second: :high within the budget, :normal beyond
  defp load(state) do
    now_s = div(Neptunus.Clock.monotonic_ms(), 1000)

    case state.load do
      {^now_s, n} when n + 1 == @high_per_s ->
        Process.flag(:priority, :normal)
        %{state | load: {now_s, n + 1}}

      {^now_s, n} ->
        %{state | load: {now_s, n + 1}}

      {_, n} ->
        if n >= @high_per_s, do: Process.flag(:priority, :high)
        %{state | load: {now_s, 1}}
    end
  end

  defp count(state, kind), do: %{state | counters: Map.update(state.counters, kind, 1, &(&1 + 1))}
end
