defmodule Neptunus.GCS.Link do
  @moduledoc """
  One ground station session (a process): it decodes what the ground station sends, admits
  it (`Neptunus.GCS.Admission`: signing, replays), runs the session's core
  (`Neptunus.GCS.Session`) and carries out its actions — sends replies and the vehicles'
  shared frames, asks the helm and control through `Neptunus.GCS.Intents`.

  It is the ground station's party on every helm it deals with: the helm monitors this
  process, so a session that ends — silence (`timeout_ms`), a closed connection, its
  endpoint gone, a crash — leaves every helm it held (`pilot_disconnected`; the vehicle
  stops, as when a pilot's browser goes away).

  ## Transports

  A `udpin` or `udpout` session gets its datagrams from its endpoint's process
  (`{:datagram, data}`) and sends with the endpoint's socket; a `tcpin` session owns its
  connection.

  ## A flooding ground station

  Whatever it sends costs its own session and nobody else's: at most
  #{300} messages a second are handled (the rest dropped and counted, `:flood`); a datagram
  over #{2048} bytes is dropped whole (`:oversized`); malformed bytes are the decoder's
  (`garbage_bytes`, `bad_checksum`) and never raise. Intents that may take long (a mode
  change waiting for an ArduSub, a tuning written to disk) run in tasks, at most 8 at a
  time per session. The session runs at process priority `:high` while it pilots — as the
  pilot's browser connection does, so its stick is not queued behind observers — and only
  within its budget; otherwise at `:low`.
  """
  use GenServer

  require Logger

  alias Neptunus.GCS.{Admission, Intents, Session, Source}
  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Signing

  @messages_per_s 300
  @max_datagram 2048
  @check_ms 1_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            transport: {:udp, port(), :inet.ip_address(), :inet.port_number()} | {:tcp, port()},
            endpoint: pid() | nil,
            link_id: byte(),
            admission: Neptunus.GCS.Admission.config(),
            vehicles: %{(1..255) => map()},
            by_id: %{String.t() => 1..255},
            decoder: Neptunus.Protocol.MAVLink.Decoder.t(),
            session: Neptunus.GCS.Session.t() | nil,
            bound: String.t() | nil,
            out_key: binary() | nil,
            out_timestamp: non_neg_integer(),
            seq: %{(1..255) => byte()},
            frames: %{(1..255) => map()},
            tasks: %{reference() => {pos_integer(), 1..255}},
            budget: {integer(), non_neg_integer()},
            priority: :low | :high | :normal,
            counters: %{atom() => non_neg_integer()},
            timeout_ms: pos_integer(),
            last_data_ms: integer(),
            text_id: pos_integer()
          }
    @enforce_keys [:id, :transport, :link_id, :admission, :vehicles, :by_id]
    defstruct @enforce_keys ++
                [
                  endpoint: nil,
                  decoder: %Neptunus.Protocol.MAVLink.Decoder{},
                  session: nil,
                  bound: nil,
                  out_key: nil,
                  out_timestamp: 0,
                  seq: %{},
                  frames: %{},
                  tasks: %{},
                  budget: {0, 0},
                  priority: :low,
                  counters: %{},
                  timeout_ms: 5_000,
                  last_data_ms: 0,
                  text_id: 1
                ]
  end

  @doc """
  Starts a session. Options: `:id` (endpoint and peer), `:transport`, `:endpoint` (its
  endpoint's pid, monitored), `:link_id` (the signing link id), `:admission`
  (`t:Neptunus.GCS.Admission.config/0`), `:vehicles` (`%{sysid => %{id, board, wiring}}`),
  `:gcs` (a udpout's ground station: the key that signs what it pushes), `:timeout_ms`.
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: GenServer.start_link(__MODULE__, opts)

  @spec child_spec(keyword()) :: Supervisor.child_spec()
  def child_spec(opts),
    do: %{id: __MODULE__, start: {__MODULE__, :start_link, [opts]}, restart: :temporary}

  @doc "The session's counters (received, dropped by reason, …): for tests and diagnostics."
  @spec stats(pid()) :: map()
  def stats(pid), do: GenServer.call(pid, :stats)

  # Callbacks

  @impl true
  def init(opts) do
    Process.flag(:priority, :low)
    vehicles = Keyword.fetch!(opts, :vehicles)

    state = %State{
      id: Keyword.fetch!(opts, :id),
      transport: Keyword.fetch!(opts, :transport),
      endpoint: Keyword.get(opts, :endpoint),
      link_id: Keyword.get(opts, :link_id, 0),
      admission: Keyword.fetch!(opts, :admission),
      vehicles: vehicles,
      by_id: Map.new(vehicles, fn {sysid, v} -> {v.id, sysid} end),
      timeout_ms: Keyword.get(opts, :timeout_ms, 5_000),
      last_data_ms: Neptunus.Clock.monotonic_ms()
    }

    if state.endpoint, do: Process.monitor(state.endpoint)
    Process.send_after(self(), :check, @check_ms)

    # a udpout pushes to its ground station from the start (signed with its key, if named)
    state =
      case Keyword.get(opts, :gcs) do
        :push -> start_session(state, Admission.unsigned_identity(state.admission, 0), nil)
        nil -> state
        name -> start_session(state, Admission.signed_identity(state.admission, name, 0), name)
      end

    {:ok, state}
  end

  @impl true
  def handle_call(:stats, _from, state) do
    stats =
      state.counters
      |> Map.merge((state.session && state.session.counters) || %{})
      |> Map.merge(MAVLink.stats(state.decoder))
      |> Map.merge(%{
        identity: state.session && state.session.identity,
        piloting: (state.session && Session.piloting(state.session)) || [],
        priority: state.priority
      })

    {:reply, stats, state}
  end

  @impl true
  def handle_info({:datagram, data}, state) when byte_size(data) > @max_datagram,
    do: {:noreply, count(state, :oversized)}

  def handle_info({:datagram, data}, state), do: {:noreply, received(state, data)}

  def handle_info({:tcp, socket, data}, %State{transport: {:tcp, socket}} = state) do
    :inet.setopts(socket, active: :once)
    {:noreply, received(state, data)}
  end

  def handle_info({:tcp_closed, socket}, %State{transport: {:tcp, socket}} = state),
    do: {:stop, :normal, state}

  def handle_info({:tcp_error, socket, _why}, %State{transport: {:tcp, socket}} = state),
    do: {:stop, :normal, state}

  def handle_info({:gcs_tick, sysid, now, view, frames}, %State{session: session} = state)
      when session != nil do
    state = %{state | frames: Map.put(state.frames, sysid, frames)}
    {session, []} = Session.handle(session, {:vehicle, sysid, view})
    available = frames |> Map.keys() |> List.delete(:autopilot_version)
    {session, due} = Session.due(session, sysid, available, now)
    state = %{state | session: session} |> adjust_priority()
    {:noreply, send_frames(state, sysid, Enum.flat_map(due, &List.wrap(frames[&1])))}
  end

  def handle_info({:gcs_event, sysid, frames}, %State{session: session} = state)
      when session != nil,
      do: {:noreply, send_frames(state, sysid, frames)}

  def handle_info({:helm_notify, vehicle_id, event, payload}, state) do
    case {state.session, state.by_id} do
      {%Session{}, %{^vehicle_id => sysid}} ->
        {:noreply, run_core(state, {:helm, sysid, event, payload})}

      _ ->
        {:noreply, state}
    end
  end

  def handle_info({ref, result}, state) when is_map_key(state.tasks, ref) do
    Process.demonitor(ref, [:flush])
    {{session_ref, _sysid}, tasks} = Map.pop(state.tasks, ref)
    {:noreply, run_core(%{state | tasks: tasks}, {:result, session_ref, result})}
  end

  def handle_info({:DOWN, ref, :process, _pid, reason}, state)
      when is_map_key(state.tasks, ref) do
    {{session_ref, _sysid}, tasks} = Map.pop(state.tasks, ref)
    Logger.warning("gcs session #{state.id}: an intent failed: #{inspect(reason, limit: 10)}")

    {:noreply,
     run_core(%{state | tasks: tasks}, {:result, session_ref, {:error, "internal error"}})}
  end

  # its endpoint is gone (its socket with it)
  def handle_info({:DOWN, _ref, :process, pid, _reason}, %State{endpoint: pid} = state),
    do: {:stop, :normal, state}

  def handle_info(:check, state) do
    Process.send_after(self(), :check, @check_ms)
    now = Neptunus.Clock.monotonic_ms()

    case state.session do
      # nothing admitted yet: it ends after the same silence as a session
      nil when now - state.last_data_ms > state.timeout_ms -> {:stop, :normal, state}
      nil -> {:noreply, state}
      _session -> {:noreply, run_core(state, {:check, now})}
    end
  end

  def handle_info(:close, state), do: {:stop, :normal, state}

  def handle_info(_msg, state), do: {:noreply, state}

  # --- input ----------------------------------------------------------------------------------

  defp received(state, data) do
    {decoder, messages, events} = MAVLink.decode(state.decoder, data)

    # a datagram holds whole frames: what is left of one is cut, not the start of the next
    {decoder, state} =
      case {state.transport, decoder.buffer} do
        {{:udp, _, _, _}, rest} when rest != <<>> ->
          {%{decoder | buffer: <<>>}, count(state, :truncated)}

        _ ->
          {decoder, state}
      end

    state = %{state | decoder: decoder, last_data_ms: Neptunus.Clock.monotonic_ms()}
    state = if events == [], do: state, else: count(state, :malformed_events, length(events))
    Enum.reduce(messages, state, &message/2)
  end

  defp message(message, state) do
    case spend(state) do
      {:ok, state} -> admit(state, message)
      {:flood, state} -> count(state, :flood)
    end
  end

  # at most @messages_per_s a second
  defp spend(%State{budget: {second, spent}} = state) do
    now_s = div(Neptunus.Clock.monotonic_ms(), 1000)
    spent = if second == now_s, do: spent, else: 0

    if spent >= @messages_per_s,
      do: {:flood, %{state | budget: {now_s, spent}}},
      else: {:ok, %{state | budget: {now_s, spent + 1}}}
  end

  defp admit(state, message) do
    now = Neptunus.Clock.monotonic_ms()

    case Admission.check(state.admission, state.bound, message) do
      {:drop, reason} ->
        count(state, reason)

      {:watch, identity} ->
        state = if state.session, do: state, else: start_session(state, identity, nil)
        count(state, :unsigned)

      {:unsigned, identity} ->
        state |> ensure_session(identity, nil, message) |> run_core({:message, message, now})

      {:signed, name, stream, timestamp} ->
        case Neptunus.GCS.Replay.advance(stream, timestamp, signing_now()) do
          :ok ->
            identity = Admission.signed_identity(state.admission, name, message.system)

            state
            |> ensure_session(identity, name, message)
            |> run_core({:message, message, now})

          {:error, reason} ->
            count(state, reason)
        end
    end
  end

  defp ensure_session(%State{session: nil} = state, identity, key, _message),
    do: start_session(state, identity, key)

  # a udpout's session started before its ground station spoke: now it knows who it is
  defp ensure_session(%State{session: %Session{gcs: nil} = session} = state, identity, key, _msg) do
    %{state | session: %{session | identity: identity}, bound: key || state.bound}
  end

  defp ensure_session(state, _identity, _key, _message), do: state

  defp start_session(state, identity, key) do
    vehicles = Map.new(state.vehicles, fn {sysid, v} -> {sysid, Map.take(v, [:id, :board])} end)

    session =
      Session.new(state.id, identity, vehicles, Neptunus.Clock.monotonic_ms(),
        timeout_ms: state.timeout_ms
      )

    for sysid <- Map.keys(state.vehicles),
        do: {:ok, _} = Registry.register(Neptunus.GCS.Registry, Source.key(sysid), nil)

    out_key = key && state.admission.keys[key].key
    %{state | session: session, bound: key, out_key: out_key}
  end

  # --- the core and its actions ---------------------------------------------------------------

  defp run_core(state, event) do
    {session, actions} = Session.handle(state.session, event)
    Enum.reduce(actions, %{state | session: session}, &act/2)
  end

  defp act({:send, sysid, name, fields}, state) do
    header = %{system: sysid, component: Neptunus.GCS.Vehicle.component(), seq: 0}

    case MAVLink.encode(name, fields, header) do
      {:ok, frame} ->
        send_frames(state, sysid, [frame])

      {:error, reason} ->
        Logger.warning("gcs session #{state.id}: #{name} not encoded: #{inspect(reason)}")
        state
    end
  end

  defp act({:text, sysid, severity, text}, state) do
    id = state.text_id
    header = %{system: sysid, component: Neptunus.GCS.Vehicle.component(), seq: 0}

    frames =
      for fields <- Neptunus.GCS.Vehicle.statustext(severity, text, id) do
        {:ok, frame} = MAVLink.encode(:statustext, fields, header)
        frame
      end

    send_frames(%{state | text_id: rem(id, 0xFFFF) + 1}, sysid, frames)
  end

  defp act({:frames, sysid, names}, state) do
    frames = Map.get(state.frames, sysid, %{})
    send_frames(state, sysid, Enum.flat_map(names, &List.wrap(frames[&1])))
  end

  defp act({:intent, ref, sysid, intent}, state) do
    vehicle = Map.fetch!(state.vehicles, sysid)
    party = party(state, vehicle.id)

    if Session.slow?(intent) do
      task =
        Task.Supervisor.async_nolink(Neptunus.GCS.Tasks, fn ->
          Intents.run(intent, vehicle, party)
        end)

      %{state | tasks: Map.put(state.tasks, task.ref, {ref, sysid})}
    else
      result = Intents.run(intent, vehicle, party)
      if ref == 0, do: state, else: run_core(state, {:result, ref, result})
    end
  end

  defp act(:close, state) do
    # ends the process after this message; the helms see it go
    send(self(), :close)
    state
  end

  # this session as vehicle `vehicle_id`'s helm sees it; the helm's targeted events come back
  # as {:helm_notify, vehicle_id, event, payload}
  defp party(state, vehicle_id) do
    me = self()

    %{
      id: Session.party_id(state.session),
      name: Session.party_name(state.session),
      role: state.session.identity.role,
      pid: me,
      notify: fn event, payload -> send(me, {:helm_notify, vehicle_id, event, payload}) end
    }
  end

  # --- output ---------------------------------------------------------------------------------

  defp send_frames(state, _sysid, []), do: state

  defp send_frames(state, sysid, frames) do
    {state, stamped} =
      Enum.map_reduce(frames, state, fn frame, state ->
        seq = Map.get(state.seq, sysid, 0)
        state = %{state | seq: Map.put(state.seq, sysid, rem(seq + 1, 256))}

        case state.out_key do
          nil ->
            {MAVLink.restamp(frame, seq), state}

          key ->
            ts = Signing.next_timestamp(signing_now(), state.out_timestamp)
            {Signing.sign(frame, seq, key, state.link_id, ts), %{state | out_timestamp: ts}}
        end
      end)
      |> then(fn {stamped, state} -> {state, stamped} end)

    transmit(state, stamped)
  end

  defp transmit(%State{transport: {:udp, socket, ip, port}} = state, frames) do
    Enum.reduce(frames, state, fn frame, state ->
      case :gen_udp.send(socket, ip, port, frame) do
        :ok -> state
        {:error, _} -> count(state, :send_errors)
      end
    end)
  end

  defp transmit(%State{transport: {:tcp, socket}} = state, frames) do
    case :gen_tcp.send(socket, frames) do
      :ok -> state
      {:error, _} -> count(state, :send_errors)
    end
  end

  # --- priority -------------------------------------------------------------------------------

  # :high while piloting within the budget (the pilot's stick first), :low otherwise
  defp adjust_priority(state) do
    {_second, spent} = state.budget

    wanted =
      cond do
        Session.piloting(state.session) == [] -> :low
        spent >= div(@messages_per_s, 2) -> :normal
        true -> :high
      end

    if wanted != state.priority, do: Process.flag(:priority, wanted)
    %{state | priority: wanted}
  end

  defp count(state, kind, n \\ 1),
    do: %{state | counters: Map.update(state.counters, kind, n, &(&1 + n))}

  defp signing_now, do: Signing.timestamp(Neptunus.Clock.wall_us())
end
