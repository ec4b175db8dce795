defmodule NeptunusWeb.Socket do
  @moduledoc """
  A Phoenix Channels v2 WebSocket connection, served by yaws (`/socket/websocket`): one
  process per connection. This module is the process shell; the decisions are pure:

    * `NeptunusWeb.Socket.Router` — the Channels protocol and the joined channels: what to
      answer to each frame and which effects (subscribe, leave, log) to carry out;
    * `NeptunusWeb.Socket.FlowControl` — the process priority (the pilot's `:high` within
      its frame budget) and which telemetry frames to drop for a slow client.

  The shell upgrades the HTTP request, runs yaws' WebSocket callbacks, feeds the router and
  the flow control, and carries out their answers: it sends the frames, subscribes and
  unsubscribes, sets the process priority, sets the socket's options, checks that the
  client is alive, and watches the PubSub scope and the presence server.

  Connection parameters (query string): `vsn` must be `2.x`; `token` is the login token
  (`POST /api/login`; required in secure mode unless anonymous observers are allowed);
  `name` is the display name in local mode (trimmed to 40 characters; default
  `guest-XXXX`). The upgrade is refused with HTTP 403 `{"error": reason}` for an `Origin`
  (or, in local mode, a `Host`) that is not allowed and with 401 for a missing, invalid or
  expired token (see `NeptunusWeb.Auth`). A refused upgrade is the only refusal that closes
  anything: who may *command* is decided per command by the vehicle's helm.

  The settings below are `NeptunusWeb.Settings`, read when the connection starts.

  Liveness: a connection silent for 60 s (`idle_timeout_ms`; the phoenix
  client heartbeats every 30 s) is closed with 1000 "heartbeat timeout". A client that
  stops reading altogether has its socket closed by the endpoint's send timeout
  (`NeptunusWeb.Endpoint`, `send_timeout_ms`); yaws is not told, so the connection checks
  its socket when it finds itself behind and at every idle check, and ends when the socket
  is gone: its channels are left as for any other closed connection (a pilot's helm is
  freed and the vehicle stops).

  Slow clients: on Linux the kernel may hold only `unsent_bytes` (default 4 096) of
  a connection's frames unsent (`NeptunusWeb.Socket.Transport.limit_unsent/1`), so a slow
  client's backlog forms in the mailbox, where `FlowControl` drops it (`backlog`, default 8
  waiting messages). While piloting,
  the connection also gets its telemetry first (`Neptunus.PubSub.prioritize/2`). Frames of
  a topic the connection has left (still in flight, or from a paced broadcast's later
  slice) are dropped.

  Restarts of the PubSub scope and of the presence server (see `Neptunus.PubSub`, "When the
  scope restarts"): the connection watches both from its first join. When the scope stops,
  the connection's subscriptions are gone and its client may have missed any broadcast (a
  `stopped`, a `helm`, a presence diff); only a rejoin gives a client the whole state again,
  so the connection closes with 1012 "service restart", and the phoenix client reconnects
  and rejoins (a pilot's channel is left like on any close: the helm is freed and the vehicle
  stops, `pilot_disconnected`). When the presence server stops, the connection waits for the
  new one and sends each joined channel `:presence_restarted` (see `NeptunusWeb.Channel`):
  the vehicle channel tracks again and pushes a fresh `presence_state`. A join while either
  is restarting is refused with "server restarting: join again" (the client retries).

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

  import NeptunusWeb.Yaws

  alias Neptunus.PubSub
  alias NeptunusWeb.Presence
  alias NeptunusWeb.Channels.{FleetChannel, LogChannel, VehicleChannel}
  alias NeptunusWeb.Socket.{FlowControl, Router, Transport, WsFrame}

  @routes [{"fleet", FleetChannel}, {"vehicle:*", VehicleChannel}, {"log:*", LogChannel}]

  # see "Memory"
  @fullsweep_after 0
  @max_message_bytes 65_536
  # how often to look for the presence server while it restarts
  @presence_retry_ms 20
  # an idle connection (nothing received for this long) hibernates (see "Memory")
  @hibernate_after_ms 1_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            router: NeptunusWeb.Socket.Router.t(),
            flow: NeptunusWeb.Socket.FlowControl.t(),
            last_seen_ms: integer(),
            idle_timeout_ms: pos_integer(),
            sock: port() | {:ssl, :ssl.sslsocket()} | nil,
            pubsub: reference() | nil,
            presence: reference() | nil
          }
    @enforce_keys [:router, :flow, :last_seen_ms, :idle_timeout_ms]
    defstruct [:router, :flow, :last_seen_ms, :idle_timeout_ms, :sock, :pubsub, :presence]
  end

  # yaws appmod: upgrade /socket/websocket

  @doc false
  def out(arg) do
    path = arg(arg, :server_path) |> to_string()
    params = query(arg)

    cond do
      path != "/socket/websocket" ->
        Transport.http_error(404, "no such socket endpoint: #{path}")

      not String.starts_with?(Map.get(params, "vsn", ""), "2.") ->
        Transport.http_error(400, "unsupported protocol version: use vsn=2.0.0")

      true ->
        upgrade(arg)
    end
  end

  defp upgrade(arg) do
    case Transport.authorize(arg) do
      {:ok, user} ->
        opts = [
          {:callback, {:basic, %{user: user}}},
          {:hibernate_after, @hibernate_after_ms},
          {:max_frame_size, @max_message_bytes},
          {:max_message_size, @max_message_bytes}
        ]

        {:websocket, __MODULE__, opts}

      {:error, status, reason} ->
        Transport.http_error(status, reason)
    end
  end

  # yaws WebSocket callbacks (basic mode). yaws does not catch exceptions from handle_info
  # and closes with 1011 without a log on exceptions from handle_message: every body is
  # guarded.

  @doc false
  def init([_arg, %{user: user}]) do
    settings = NeptunusWeb.Settings.get()
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
    sock = ws_state(ws_state, :sock)
    Transport.limit_unsent(sock)
    {:ok, %{state | sock: sock}}
  end

  @doc false
  def handle_message({:text, data}, state) do
    now = now_ms()
    state = %{state | last_seen_ms: now} |> count_frame(now)
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
      not Router.joined?(state.router, topic) -> {:noreply, state}
      FlowControl.deliver?(state.flow, event, waiting()) -> push(state, frame)
      true -> shed(state)
    end
  end

  def handle_info(msg, state), do: guarded(state, fn -> handle_other(msg, state) end)

  @doc false
  def terminate(reason, state) do
    {router, _frames, effects} = Router.handle_message(state.router, {:closed, reason})
    Enum.reduce(effects, %{state | router: router}, &carry_out_effect/2)
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
    case watch(state) do
      {:ok, state} -> {:answer, {:watched, msg, :ok}, state}
      :restarting -> {:answer, {:watched, msg, :restarting}, state}
    end
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

  # Watches the PubSub scope and the presence server from the first join on (see the
  # moduledoc): :restarting while either is down.
  defp watch(%State{pubsub: nil} = state) do
    case PubSub.monitor() do
      {:ok, ref} -> watch(%{state | pubsub: ref})
      {:error, :not_running} -> :restarting
    end
  end

  defp watch(%State{presence: nil} = state) do
    case Presence.monitor() do
      {:ok, ref} -> {:ok, presence_back(state, ref)}
      {:error, :not_running} -> :restarting
    end
  end

  defp watch(state), do: {:ok, state}

  # Messages to the connection process

  # The helm's grant and loss of control, on their way to the vehicle channel: a connection
  # that pilots a vehicle runs at :high within its frame budget and gets telemetry first,
  # any other runs at :low (FlowControl).
  defp handle_other({:channel_info, topic, {:helm, event, _}} = msg, state)
       when event in ["control_granted", "control_lost"] do
    granted? = event == "control_granted"
    PubSub.prioritize(topic, granted?)
    state = set_priority(state, FlowControl.piloting(state.flow, topic, granted?))
    route(state, msg)
  end

  defp handle_other({:channel_info, _topic, _msg} = msg, state), do: route(state, msg)

  defp handle_other(:check_idle, state) do
    cond do
      not connected?(state) ->
        gone(state)

      now_ms() - state.last_seen_ms > state.idle_timeout_ms ->
        {:close, {1000, "heartbeat timeout"}, state}

      true ->
        # compact the heap a burst left large (see "Memory")
        {:noreply, state, :hibernate}
    end
  end

  # The PubSub scope stopped: every subscription of this connection is gone.
  defp handle_other({:DOWN, ref, :process, _pid, _reason}, %State{pubsub: ref} = state),
    do: {:close, {1012, "service restart"}, %{state | pubsub: nil}}

  # The presence server stopped: its presences are gone; track again once it is back.
  defp handle_other({:DOWN, ref, :process, _pid, _reason}, %State{presence: ref} = state),
    do: handle_other(:presence_back?, %{state | presence: nil})

  defp handle_other(:presence_back?, %State{presence: nil} = state) do
    case Presence.monitor() do
      {:ok, ref} ->
        {:noreply, presence_back(state, ref)}

      {:error, :not_running} ->
        Process.send_after(self(), :presence_back?, @presence_retry_ms)
        {:noreply, state}
    end
  end

  defp handle_other(:presence_back?, state), do: {:noreply, state}

  defp handle_other(:gc, state) do
    :erlang.garbage_collect()
    {:noreply, state}
  end

  defp handle_other(msg, state) do
    Logger.debug("socket ignored message #{inspect(msg)}")
    {:noreply, state}
  end

  # A presence server is watched again: the joined channels track again (none on the first
  # join; after a restart, whichever of a join and the retry finds the new server first).
  defp presence_back(state, ref) do
    for topic <- Router.topics(state.router),
        do: send(self(), {:channel_info, topic, :presence_restarted})

    %{state | presence: ref}
  end

  # A broadcast frame, shared with every other connection that receives it: sent as the
  # header and that binary, not through yaws, which would copy it (see "Memory"). The result
  # is ignored as yaws ignores it: a socket closed by the send timeout is found by
  # `connected?/1`, one the client closed by yaws.
  defp push(%State{sock: nil} = state, frame), do: {:reply, {:text, frame}, state}

  defp push(%State{sock: sock} = state, frame) do
    _ = Transport.send_data(sock, WsFrame.text(frame))
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

  # Behind: a send may have waited for the client until the send timeout closed the socket.
  defp shed(state) do
    if connected?(state) do
      {flow, report} = FlowControl.dropped(state.flow, now_ms())

      case report do
        {:report, count, since_ms} ->
          Logger.info(
            "#{inspect(state.router.user.name)} reads slower than its telemetry arrives: " <>
              "dropped #{count} stale telemetry frame(s)" <>
              if(since_ms == nil, do: "", else: " in the last #{div(since_ms, 1000)} s")
          )

        nil ->
          :ok
      end

      {:noreply, %{state | flow: flow}}
    else
      gone(state)
    end
  end

  defp connected?(state), do: Transport.connected?(state.sock)

  # The socket is closed under yaws (the send timeout): end the connection now.
  defp gone(state) do
    Logger.info(
      "#{inspect(state.router.user.name)}'s client read nothing for " <>
        "#{NeptunusWeb.Endpoint.send_timeout_ms()} ms: connection closed"
    )

    {:close, {1000, "send timeout"}, state}
  end

  # Priority (see FlowControl)

  defp count_frame(state, now) do
    {flow, verdict} = FlowControl.frame(state.flow, now)

    if verdict == :over_budget,
      do:
        Logger.warning(
          "pilot #{inspect(state.router.user.name)} sends more than #{flow.frame_limit} " <>
            "frames/s: its connection runs at :normal for the rest of this second"
        )

    set_priority(state, flow)
  end

  defp set_priority(state, flow) do
    priority = FlowControl.priority(flow)
    if priority != FlowControl.priority(state.flow), do: Process.flag(:priority, priority)
    %{state | flow: flow}
  end

  defp now_ms, do: Neptunus.Clock.monotonic_ms()
end
