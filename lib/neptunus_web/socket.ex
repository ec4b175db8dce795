defmodule NeptunusWeb.Socket do
  @moduledoc """
  A Phoenix Channels v2 WebSocket connection, served by yaws (`/socket/websocket`): one
  process per connection. This module is the process shell: yaws' WebSocket callbacks, and
  carrying out what these decide:

    * `NeptunusWeb.WebSocket.Upgrade` — who may open the connection (as for every WebSocket
      endpoint of the node);
    * `NeptunusWeb.Socket.Router` (pure) — the Channels protocol and the joined channels:
      what to answer to each frame and which effects (watch, subscribe, leave, log) to carry
      out;
    * `NeptunusWeb.Socket.FlowControl` (pure) — the process priority (the pilot's `:high`
      within its frame budget), which telemetry frames to drop for a slow client, and the
      effects of both (priority, the pilot's telemetry first, log lines);
    * `NeptunusWeb.Socket.Watch` — the monitors of the PubSub scope and the presence server,
      and what their restarts mean;
    * `NeptunusWeb.WebSocket.Transport` — the socket itself: frames written without a copy,
      `TCP_NOTSENT_LOWAT`, whether the client is still there.

  The shell feeds the router and the flow control the client's frames, the channels'
  messages and the clock, sends the frames they answer and carries out their effects in
  order (`Router`'s requests for a watch or a subscription are answered with a message to
  the router), checks the client's liveness, and keeps its own memory small.

  Connection parameters (query string): `vsn` must be `2.x`; `token` is the login token
  (`POST /api/login`; required in secure mode unless anonymous observers are allowed);
  `name` is the display name in local mode (trimmed to 40 characters; default
  `guest-XXXX`). Who may connect is decided as for every WebSocket endpoint
  (`NeptunusWeb.WebSocket.Upgrade`): the upgrade is refused with HTTP 403 `{"error": reason}`
  for an `Origin` (or, in local mode, a `Host`) that is not allowed and with 401 for a
  missing, invalid or expired token (see `NeptunusWeb.Auth`). A refused upgrade is the only
  refusal that closes anything: who may *command* is decided per command by the vehicle's
  helm.

  The settings below are `NeptunusWeb.Endpoint.Settings`, read when the connection starts.

  Liveness: a connection silent for 60 s (`idle_timeout_ms`; the phoenix
  client heartbeats every 30 s) is closed with 1000 "heartbeat timeout". A client that
  stops reading altogether has its socket closed by the endpoint's send timeout
  (`NeptunusWeb.Endpoint`, `send_timeout_ms`); yaws is not told, so the connection checks
  its socket when it finds itself behind and at every idle check, and ends when the socket
  is gone: its channels are left as for any other closed connection (a pilot's helm is
  freed and the vehicle stops).

  Slow clients: on Linux the kernel may hold only `unsent_bytes` (default 4 096) of
  a connection's frames unsent (`TCP_NOTSENT_LOWAT`, plain and TLS sockets alike). Without
  it the kernel grows the send buffer to megabytes and a slow client's backlog forms there,
  where nothing can drop stale telemetry; with it the backlog forms in the mailbox, where
  `FlowControl` drops it (`backlog`, default 8 waiting messages). While piloting,
  the connection also gets its telemetry first (`Neptunus.PubSub.prioritize/2`). Frames of
  a topic the connection has left (still in flight, or from a paced broadcast's later
  slice) are dropped.

  Restarts of the PubSub scope and of the presence server: the connection watches both from
  its first join (`NeptunusWeb.Socket.Watch`). When the scope stops, the connection closes
  with 1012 "service restart" and the phoenix client reconnects and rejoins; when the
  presence server stops, the connection waits for the new one and its channels track again.
  A join while either is restarting is refused with "server restarting: join again".

  ## Memory

  A board serves many observers, so a connection is kept small (`bench/observer_memory`):

    * broadcast frames go out as the shared binary `Neptunus.PubSub` encoded once, behind a
      WebSocket header written here (`NeptunusWeb.Socket.WsFrame`), never through yaws' send,
      which copies header and payload into one new binary per connection and so would give
      each connection a private copy of every recent frame until its next collection;
    * every garbage collection of the connection process is a full one (`fullsweep_after`
      0): the connection's live data is small and lasts (yaws' request record, the router),
      while each frame leaves only short-lived garbage, so a generational old heap would only
      fill up with dead states between its rare full sweeps and keep the heap large;
    * a connection that receives nothing for a second (an observer of a vehicle that does
      not stream, a page left open on the fleet) hibernates: its heap is shrunk to its live
      data until the next message;
    * a streaming connection is never idle that long, so it also hibernates at each idle
      check (every quarter of `idle_timeout_ms`): a burst (the presence diffs of many joins,
      a backlog of frames) grows the heap, and a full sweep shrinks a heap only when little
      of it is in use; hibernation shrinks it to the live data, and the heap grows back only
      as far as the frames need.
  """
  require Logger

  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.PubSub
  alias NeptunusWeb.Channels.{FleetChannel, LogChannel, VehicleChannel}
  alias NeptunusWeb.Presence
  alias NeptunusWeb.Socket.{FlowControl, Router, Watch, WsFrame}
  alias NeptunusWeb.WebSocket.{Transport, Upgrade}

  @routes [{"fleet", FleetChannel}, {"vehicle:*", VehicleChannel}, {"log:*", LogChannel}]

  # see "Memory"
  @fullsweep_after 0
  @max_message_bytes 65_536
  # an idle connection (nothing received for this long) hibernates (see "Memory")
  @hibernate_after_ms 1_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            router: NeptunusWeb.Socket.Router.t(),
            flow: NeptunusWeb.Socket.FlowControl.t(),
            last_seen_ms: integer(),
            idle_timeout_ms: pos_integer(),
            sock: NeptunusWeb.WebSocket.Transport.socket() | nil,
            watch: NeptunusWeb.Socket.Watch.t()
          }
    @enforce_keys [:router, :flow, :last_seen_ms, :idle_timeout_ms]
    defstruct [:router, :flow, :last_seen_ms, :idle_timeout_ms, :sock, watch: %Watch{}]
  end

  # yaws appmod: upgrade /socket/websocket

  @doc false
  def out(arg) do
    path = arg(arg, :server_path) |> to_string()

    cond do
      path != "/socket/websocket" ->
        Upgrade.refuse(404, "no such socket endpoint: #{path}")

      not String.starts_with?(Map.get(query(arg), "vsn", ""), "2.") ->
        Upgrade.refuse(400, "unsupported protocol version: use vsn=2.0.0")

      true ->
        Upgrade.upgrade(arg, __MODULE__, %{},
          hibernate_after: @hibernate_after_ms,
          max_frame_size: @max_message_bytes,
          max_message_size: @max_message_bytes
        )
    end
  end

  # yaws WebSocket callbacks (basic mode). yaws does not catch exceptions from handle_info
  # and closes with 1011 without a log on exceptions from handle_message: every body is
  # guarded.

  @doc false
  def init([_arg, %{user: user}]) do
    settings = NeptunusWeb.Endpoint.Settings.get()
    idle_timeout_ms = settings.idle_timeout_ms

    flow =
      FlowControl.new(
        pilot_frames_per_s: settings.pilot_frames_per_s,
        backlog: settings.backlog
      )

    # an observer until the helm grants this connection control (FlowControl)
    Process.flag(:priority, FlowControl.priority(flow))
    # every collection a full one: no old heap of dead frames and states (see "Memory")
    :erlang.process_flag(:fullsweep_after, @fullsweep_after)
    :timer.send_interval(max(div(idle_timeout_ms, 4), 10), :check_idle)

    {:ok,
     %State{
       router: Router.new(user, self(), @routes),
       flow: flow,
       last_seen_ms: now_ms(),
       idle_timeout_ms: idle_timeout_ms
     }}
  end

  @doc false
  def handle_open(ws_state, state) do
    # The upgrade leaves garbage behind; collecting it now keeps an idle connection small.
    send(self(), :gc)
    sock = Transport.socket(ws_state)
    # the backlog of a slow client forms in the mailbox, where FlowControl drops it
    Transport.limit_unsent(sock, NeptunusWeb.Endpoint.Settings.get().unsent_bytes)
    {:ok, %{state | sock: sock}}
  end

  @doc false
  def handle_message({:text, data}, state) do
    now = now_ms()
    {flow, effects} = FlowControl.frame_received(state.flow, now, name(state))
    state = carry_out_all(effects, %{state | last_seen_ms: now, flow: flow})
    guarded(state, fn -> route(state, {:text, data}) end)
  end

  def handle_message({:binary, data}, state),
    do: guarded(state, fn -> route(state, {:binary, data}) end)

  # Echo the client's close (RFC 6455 §5.5.1); yaws then ends the connection.
  def handle_message({:close, code, _reason}, state) when code in [1005, 1006],
    do: {:close, 1000, state}

  def handle_message({:close, code, _reason}, state), do: {:close, code, state}

  @doc false
  def handle_info({:pubsub_frame, topic, event, frame}, state) do
    cond do
      not Router.joined?(state.router, topic) ->
        {:noreply, state}

      FlowControl.deliver?(state.flow, event, waiting()) ->
        push(state, frame)

      # behind: a send may have waited for the client until the send timeout closed the socket
      not Transport.connected?(state.sock) ->
        gone(state)

      true ->
        {flow, effects} = FlowControl.telemetry_dropped(state.flow, now_ms(), name(state))
        {:noreply, carry_out_all(effects, %{state | flow: flow})}
    end
  end

  def handle_info(msg, state), do: guarded(state, fn -> handle_other(msg, state) end)

  @doc false
  def terminate(reason, state) do
    {router, _frames, effects} = Router.handle_message(state.router, {:closed, reason})
    carry_out_all(effects, %{state | router: router})
    :ok
  end

  # Runs the router on `message` and carries out its effects: the frames to send.
  defp route(state, message) do
    {state, frames} = run(state, message)
    reply(state, frames)
  end

  defp run(state, message) do
    {router, frames, effects} = Router.handle_message(state.router, message)

    Enum.reduce(effects, {%{state | router: router}, frames}, fn effect, {state, frames} ->
      case carry_out(effect, state) do
        {:answer, answer, state} ->
          {state, more} = run(state, answer)
          {state, frames ++ more}

        state ->
          {state, frames}
      end
    end)
  end

  defp carry_out({:watch, msg}, state) do
    {result, watch} = Watch.watch(state.watch, Router.topics(state.router))
    {:answer, {:watched, msg, result}, %{state | watch: watch}}
  end

  defp carry_out({:subscribe, msg, frame}, state) do
    case PubSub.subscribe_fastlane(msg.topic) do
      :ok -> {:answer, {:subscribed, msg, frame, :ok}, state}
      {:error, :not_running} -> {:answer, {:subscribed, msg, frame, :restarting}, state}
    end
  end

  defp carry_out(effect, state), do: carry_out_effect(effect, state)

  defp carry_out_effect({:unsubscribe, topic}, state) do
    PubSub.unsubscribe(topic)
    state
  end

  defp carry_out_effect({:terminate, module, reason, socket}, state) do
    try do
      module.terminate(reason, socket)
    rescue
      _ -> :ok
    catch
      _, _ -> :ok
    end

    state
  end

  defp carry_out_effect({:untrack, topic}, state) do
    Presence.untrack(self(), topic)
    state
  end

  defp carry_out_effect(:gc, state) do
    send(self(), :gc)
    state
  end

  defp carry_out_effect({:log, level, text}, state) do
    Logger.log(level, text)
    state
  end

  defp carry_out_effect({:priority, priority}, state) do
    Process.flag(:priority, priority)
    state
  end

  defp carry_out_effect({:prioritize, topic, first?}, state) do
    PubSub.prioritize(topic, first?)
    state
  end

  defp carry_out_all(effects, state), do: Enum.reduce(effects, state, &carry_out_effect/2)

  # Messages to the connection process

  # The helm's grant and loss of control, on their way to the vehicle channel: a connection
  # that pilots a vehicle runs at :high within its frame budget and gets telemetry first,
  # any other runs at :low (FlowControl).
  defp handle_other({:channel_info, topic, {:helm, event, _}} = msg, state)
       when event in ["control_granted", "control_lost"] do
    {flow, effects} = FlowControl.control_changed(state.flow, topic, event == "control_granted")
    route(carry_out_all(effects, %{state | flow: flow}), msg)
  end

  defp handle_other({:channel_info, _topic, _msg} = msg, state), do: route(state, msg)

  defp handle_other(:check_idle, state) do
    cond do
      not Transport.connected?(state.sock) ->
        gone(state)

      now_ms() - state.last_seen_ms > state.idle_timeout_ms ->
        {:close, {1000, "heartbeat timeout"}, state}

      true ->
        # compact the heap a burst left large (see "Memory")
        {:noreply, state, :hibernate}
    end
  end

  # The PubSub scope or the presence server stopped (Watch).
  defp handle_other({:DOWN, ref, :process, _pid, _reason} = msg, state) do
    case Watch.down(state.watch, ref) do
      # every subscription of this connection is gone
      {:scope_stopped, watch} ->
        {:close, {1012, "service restart"}, %{state | watch: watch}}

      # its presences are gone: track again once it is back
      {:presence_stopped, watch} ->
        handle_other(:presence_back?, %{state | watch: watch})

      :other ->
        ignored(msg, state)
    end
  end

  defp handle_other(:presence_back?, state),
    do:
      {:noreply, %{state | watch: Watch.presence_back(state.watch, Router.topics(state.router))}}

  defp handle_other(:gc, state) do
    :erlang.garbage_collect()
    {:noreply, state}
  end

  defp handle_other(msg, state), do: ignored(msg, state)

  defp ignored(msg, state) do
    Logger.debug("socket ignored message #{inspect(msg)}")
    {:noreply, state}
  end

  # A broadcast frame, shared with every other connection that receives it: sent as the
  # header and that binary, not through yaws, which would copy it (see "Memory"). The result
  # is ignored as yaws ignores it: a socket closed by the send timeout is found by
  # `Transport.connected?/1`, one the client closed by yaws.
  defp push(%State{sock: nil} = state, frame), do: {:reply, {:text, frame}, state}

  defp push(%State{sock: sock} = state, frame) do
    _ = Transport.write(sock, WsFrame.text(frame))
    {:noreply, state}
  end

  defp reply(state, []), do: {:noreply, state}
  defp reply(state, frames), do: {:reply, Enum.map(frames, &{:text, &1}), state}

  defp guarded(state, fun) do
    fun.()
  rescue
    exception ->
      log_failure(Exception.format(:error, exception, __STACKTRACE__))
      {:noreply, state}
  catch
    kind, value ->
      log_failure(Exception.format(kind, value, __STACKTRACE__))
      {:noreply, state}
  end

  defp log_failure(formatted),
    do: Logger.error("socket callback failed: #{Neptunus.Log.safe(formatted)}")

  # Slow clients (see the moduledoc and FlowControl)

  defp waiting do
    {:message_queue_len, waiting} = Process.info(self(), :message_queue_len)
    waiting
  end

  # The socket is closed under yaws (the send timeout): end the connection now.
  defp gone(state) do
    Logger.info(
      "#{inspect(name(state))}'s client read nothing for " <>
        "#{NeptunusWeb.Endpoint.send_timeout_ms()} ms: connection closed"
    )

    {:close, {1000, "send timeout"}, state}
  end

  defp name(state), do: state.router.user.name

  defp now_ms, do: Neptunus.Clock.monotonic_ms()
end
