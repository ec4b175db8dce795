defmodule NeptunusWeb.Socket do
  @moduledoc """
  A Phoenix Channels v2 WebSocket connection, served by yaws (`/socket/websocket`): one
  process per connection holding its joined channels (see `NeptunusWeb.Channel`).

  Protocol (what the official `phoenix` JS client expects; details in `docs/API.md`):

    * frames are JSON `[join_ref, ref, topic, event, payload]`;
    * `phoenix`/`heartbeat` is answered `ok`; a connection silent for 60 s (config
      `:socket_idle_timeout_ms`) is closed with 1000 "heartbeat timeout" (the client
      heartbeats every 30 s);
    * `phx_join` → `phx_reply` ok with the channel's join reply, or error with a reason;
      joining a joined topic again replaces the old channel;
    * `phx_leave` → `phx_reply` ok, then `phx_close` with the join ref;
    * a push to a topic that is not joined (or with a stale join ref) → error
      `unmatched topic`;
    * a malformed frame → `phx_reply` error with a readable reason, addressed as well as
      the frame allows; the connection stays up;
    * a channel that raises → `phx_error` for its topic; the other channels stay.

  Connection parameters (query string): `vsn` must be `2.x`; `token` is the login token
  (`POST /api/login`; required in secure mode unless anonymous observers are allowed);
  `name` is the display name in local mode (trimmed to 40 characters; default
  `guest-XXXX`). The upgrade is refused with HTTP 403 `{"error": reason}` for an `Origin`
  (or, in local mode, a `Host`) that is not allowed and with 401 for a missing, invalid or
  expired token (see `NeptunusWeb.Auth`). A refused upgrade is the only refusal that closes
  anything: who may *command* is decided per command by the vehicle's helm.

  Priority: a connection process runs at process priority `:low`, and at `:high` while it
  pilots a vehicle (between the helm's `control_granted` and `control_lost` for that topic),
  like the vehicle's control path it commands (see `Neptunus.Vehicle.Helm`). `:normal` would
  not do: the BEAM runs `:normal` and `:low` processes from one queue, interleaved, so a
  pilot at `:normal` waits behind the observers' connections that a telemetry broadcast has
  made runnable (measured: 5 ms at the 99th percentile with 1 000 observers). `:high` runs
  before both. The pilot keeps it only within a frame budget (`NeptunusWeb.PilotBudget`,
  `:pilot_frames_per_s`, default 200): a client that sends more runs at `:normal` for the
  rest of that second, so it cannot starve everything else. While piloting, the connection
  also gets its telemetry first (`Neptunus.PubSub.prioritize/2`). Frames of a topic the
  connection has left (still in flight, or from a paced broadcast's later slice) are
  dropped.

  Slow clients: a connection whose client reads slower than its telemetry arrives (a weak
  link, a busy tablet) would queue frames without bound, in the kernel's send buffer (which
  Linux grows to megabytes) and then in its mailbox, and show the pilot or observer ever
  older data. So the kernel may hold only `:socket_unsent_bytes` (default 4 096) of a
  connection's frames unsent (Linux's `TCP_NOTSENT_LOWAT`), and when `:socket_backlog`
  (default 8) or more messages wait for the connection, it drops `telemetry` frames (the
  newest ones, at the back of the queue, still go out) and logs it at most once a minute
  with the count; every other event (`helm`, `presence_diff`, `stopped`, replies, …) is
  always sent. Measured on a 120 kbit/s link (`bench/slow_link`): the telemetry such a
  client sees is ≈ 1.3 s old and stays so, where it was 20 s old after a minute, and
  growing, before. A client that stops reading altogether has its socket closed by the
  endpoint's send timeout (`NeptunusWeb.Endpoint`, `:send_timeout_ms`); yaws is not told,
  so the connection checks its socket when it finds itself behind and at every idle check,
  and ends when the socket is gone: its channels are left as for any other closed
  connection (a pilot's helm is freed and the vehicle stops).

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
  """
  require Logger

  import NeptunusWeb.Yaws

  alias Neptunus.PubSub
  alias NeptunusWeb.{Auth, Channel, PilotBudget, Presence}
  alias NeptunusWeb.Channels.{FleetChannel, LogChannel, VehicleChannel, Wire}

  @default_idle_timeout_ms 60_000
  @default_pilot_frames_per_s 200
  @default_backlog 8
  @default_unsent 4_096
  @ipproto_tcp 6
  @tcp_notsent_lowat 25
  @shed_report_ms 60_000
  @max_message_bytes 65_536
  # how often to look for the presence server while it restarts
  @presence_retry_ms 20

  defmodule State do
    @moduledoc false
    @type joined :: %{module: module(), socket: NeptunusWeb.Channel.Socket.t()}
    @type t :: %__MODULE__{
            user: NeptunusWeb.Auth.user(),
            channels: %{optional(String.t()) => joined()},
            last_seen: integer(),
            idle_timeout: pos_integer(),
            piloting: MapSet.t(String.t()),
            budget: NeptunusWeb.PilotBudget.t(),
            over_budget: boolean(),
            backlog: pos_integer(),
            shed: non_neg_integer(),
            shed_reported_at: integer() | nil,
            sock: port() | {:ssl, :ssl.sslsocket()} | nil,
            pubsub: reference() | nil,
            presence: reference() | nil
          }
    @enforce_keys [:user, :last_seen, :idle_timeout, :budget, :backlog]
    defstruct [
      :user,
      :last_seen,
      :idle_timeout,
      :budget,
      :backlog,
      :shed_reported_at,
      :sock,
      :pubsub,
      :presence,
      channels: %{},
      piloting: MapSet.new(),
      over_budget: false,
      shed: 0
    ]
  end

  # yaws appmod: upgrade /socket/websocket

  @doc false
  def out(arg) do
    path = arg(arg, :server_path) |> to_string()
    params = query_params(arg(arg, :querydata))

    cond do
      path != "/socket/websocket" ->
        http_error(404, "no such socket endpoint: #{path}")

      not String.starts_with?(Map.get(params, "vsn", ""), "2.") ->
        http_error(400, "unsupported protocol version: use vsn=2.0.0")

      true ->
        upgrade(arg, params)
    end
  end

  defp upgrade(arg, params) do
    headers = arg(arg, :headers)

    request = %{
      origin: header(headers, "origin"),
      host: charlist_or_nil(headers(headers, :host)),
      token: params["token"],
      name: params["name"]
    }

    case Auth.connect(request) do
      {:ok, user} ->
        opts = [
          {:callback, {:basic, %{user: user}}},
          {:max_frame_size, @max_message_bytes},
          {:max_message_size, @max_message_bytes}
        ]

        {:websocket, __MODULE__, opts}

      {:error, status, reason} ->
        http_error(status, reason)
    end
  end

  @doc false
  # A header yaws does not parse into a field of its #headers{} record, or nil.
  def header(headers, name) do
    Enum.find_value(headers(headers, :other), fn
      {:http_header, _, key, _, value} ->
        if String.downcase(to_string(key)) == name, do: to_string(value)

      _ ->
        nil
    end)
  end

  defp charlist_or_nil(:undefined), do: nil
  defp charlist_or_nil(value) when is_list(value), do: to_string(value)
  defp charlist_or_nil(_), do: nil

  defp query_params(:undefined), do: %{}

  defp query_params(query) do
    URI.decode_query(to_string(query))
  rescue
    _ -> %{}
  end

  defp http_error(status, reason) do
    [{:status, status}, {:content, ~c"application/json", Wire.encode_json(%{error: reason})}]
  end

  # yaws WebSocket callbacks (basic mode). yaws does not catch exceptions from handle_info
  # and closes with 1011 without a log on exceptions from handle_message: every body is
  # guarded.

  @doc false
  def init([_arg, %{user: user}]) do
    idle_timeout =
      Application.get_env(:neptunus, :socket_idle_timeout_ms, @default_idle_timeout_ms)

    # an observer until the helm grants this connection control (see the moduledoc)
    Process.flag(:priority, :low)
    :timer.send_interval(max(div(idle_timeout, 4), 10), :check_idle)

    budget =
      PilotBudget.new(
        Application.get_env(:neptunus, :pilot_frames_per_s, @default_pilot_frames_per_s)
      )

    {:ok,
     %State{
       user: user,
       last_seen: now_ms(),
       idle_timeout: idle_timeout,
       budget: budget,
       backlog: Application.get_env(:neptunus, :socket_backlog, @default_backlog)
     }}
  end

  @doc false
  def handle_open(ws_state, state) do
    # The upgrade leaves garbage behind; collecting it now keeps an idle connection small.
    send(self(), :gc)
    sock = ws_state(ws_state, :sock)
    limit_unsent(sock)
    {:ok, %{state | sock: sock}}
  end

  @doc false
  def handle_message({:text, data}, state) do
    now = now_ms()
    state = %{state | last_seen: now} |> count_frame(now)
    guarded(state, fn -> handle_text(data, state) end)
  end

  def handle_message({:binary, _data}, state) do
    frame =
      Wire.encode_reply(nil, nil, "phoenix", :error, %{
        reason: "binary frames are not supported: send JSON text"
      })

    {:reply, {:text, frame}, state}
  end

  # Echo the client's close (RFC 6455 §5.5.1); yaws then ends the connection.
  def handle_message({:close, code, _reason}, state) when code in [1005, 1006],
    do: {:close, 1000, state}

  def handle_message({:close, code, _reason}, state), do: {:close, code, state}

  @doc false
  def handle_info({:pubsub_frame, topic, event, frame}, state) do
    cond do
      not Map.has_key?(state.channels, topic) -> {:noreply, state}
      event == "telemetry" and backlogged?(state) -> shed(state)
      true -> {:reply, {:text, frame}, state}
    end
  end

  def handle_info(msg, state), do: guarded(state, fn -> handle_other(msg, state) end)

  @doc false
  def terminate(reason, state) do
    for {topic, joined} <- state.channels, do: leave_channel(topic, joined, {:shutdown, reason})
    :ok
  end

  # Frames from the client

  defp handle_text(data, state) do
    case Wire.decode(data) do
      {:ok, msg} ->
        dispatch(msg, state)

      {:error, reason, partial} ->
        topic = partial.topic || "phoenix"

        reply(state, [
          Wire.encode_reply(partial.join_ref, partial.ref, topic, :error, %{reason: reason})
        ])
    end
  end

  defp dispatch(%Wire.Message{topic: "phoenix", event: "heartbeat"} = msg, state) do
    reply(state, [Wire.encode_reply(nil, msg.ref, "phoenix", :ok, %{})])
  end

  defp dispatch(%Wire.Message{event: "phx_join"} = msg, state), do: join(msg, state)

  defp dispatch(%Wire.Message{event: "phx_leave", topic: topic} = msg, state) do
    case joined(state, msg) do
      {:ok, joined} ->
        leave_channel(topic, joined, {:shutdown, :left})
        state = %{state | channels: Map.delete(state.channels, topic)}

        reply(state, [
          Wire.encode_reply(msg.join_ref, msg.ref, topic, :ok, %{}),
          Wire.encode(msg.join_ref, msg.join_ref, topic, "phx_close", %{})
        ])

      :error ->
        unmatched(msg, state)
    end
  end

  defp dispatch(%Wire.Message{topic: topic} = msg, state) do
    case joined(state, msg) do
      {:ok, %{module: module, socket: socket} = joined} ->
        in_channel(state, topic, joined, fn ->
          {:reply, {status, response}, socket} = module.handle_in(msg.event, msg.payload, socket)
          {[Wire.encode_reply(msg.join_ref, msg.ref, topic, status, response)], socket}
        end)

      :error ->
        unmatched(msg, state)
    end
  end

  defp join(%Wire.Message{topic: topic} = msg, state) do
    state =
      case Map.pop(state.channels, topic) do
        {nil, _} ->
          state

        {old, channels} ->
          leave_channel(topic, old, {:shutdown, :rejoin})
          %{state | channels: channels}
      end

    case {channel_module(topic), watch(state)} do
      {nil, _} ->
        reply(state, [error_reply(msg, "unmatched topic")])

      {_module, :restarting} ->
        reply(state, [error_reply(msg, "server restarting: join again")])

      {module, {:ok, state}} ->
        socket = %Channel.Socket{
          topic: topic,
          join_ref: msg.join_ref,
          user: state.user,
          transport_pid: self()
        }

        case safe(fn -> module.join(topic, msg.payload, socket) end) do
          {:ok, {:ok, response, socket}} ->
            joined = %{module: module, socket: socket}
            subscribed(state, msg, joined, response)

          {:ok, {:error, response}} ->
            reply(state, [Wire.encode_reply(msg.join_ref, msg.ref, topic, :error, response)])

          {:error, exception} ->
            Logger.error(
              "join #{Neptunus.Log.safe(topic)} failed: #{Neptunus.Log.safe(exception)}"
            )

            reply(state, [error_reply(msg, "join crashed")])
        end
    end
  end

  defp subscribed(state, %Wire.Message{topic: topic} = msg, joined, response) do
    case PubSub.subscribe_fastlane(topic) do
      :ok ->
        # a join builds large replies (snapshot, presence_state): collect afterwards
        send(self(), :gc)
        state = %{state | channels: Map.put(state.channels, topic, joined)}
        reply(state, [Wire.encode_reply(msg.join_ref, msg.ref, topic, :ok, response)])

      {:error, :not_running} ->
        # the scope stopped during the join: its :DOWN closes the connection
        leave_channel(topic, joined, {:shutdown, :left})
        reply(state, [error_reply(msg, "server restarting: join again")])
    end
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

  defp channel_module("fleet"), do: FleetChannel
  defp channel_module("vehicle:" <> _id), do: VehicleChannel
  defp channel_module("log:" <> _id), do: LogChannel
  defp channel_module(_topic), do: nil

  # Messages to the connection process

  # The helm's grant and loss of control, on their way to the vehicle channel: a connection
  # that pilots a vehicle runs at :high within its frame budget and gets telemetry first,
  # any other runs at :low (see the moduledoc).
  defp handle_other({:channel_info, topic, {:helm, event, _} = msg}, state)
       when event in ["control_granted", "control_lost"] do
    granted? = event == "control_granted"
    PubSub.prioritize(topic, granted?)

    piloting =
      if granted?,
        do: MapSet.put(state.piloting, topic),
        else: MapSet.delete(state.piloting, topic)

    over? = state.over_budget and MapSet.size(piloting) > 0
    state = set_priority(%{state | piloting: piloting, over_budget: over?})
    channel_info(topic, msg, state)
  end

  defp handle_other({:channel_info, topic, msg}, state), do: channel_info(topic, msg, state)

  defp handle_other(:check_idle, state) do
    cond do
      not connected?(state) ->
        gone(state)

      now_ms() - state.last_seen > state.idle_timeout ->
        {:close, {1000, "heartbeat timeout"}, state}

      true ->
        {:noreply, state}
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
    for topic <- Map.keys(state.channels),
        do: send(self(), {:channel_info, topic, :presence_restarted})

    %{state | presence: ref}
  end

  defp channel_info(topic, msg, state) do
    case Map.fetch(state.channels, topic) do
      {:ok, %{module: module, socket: socket} = joined} ->
        in_channel(state, topic, joined, fn ->
          case module.handle_info(msg, socket) do
            {:noreply, socket} ->
              {[], socket}

            {:push, event, payload, socket} ->
              {[Wire.encode(socket.join_ref, nil, topic, event, payload)], socket}
          end
        end)

      :error ->
        {:noreply, state}
    end
  end

  # Channel plumbing

  defp joined(state, %Wire.Message{topic: topic, join_ref: join_ref}) do
    case Map.fetch(state.channels, topic) do
      {:ok, %{socket: %{join_ref: ^join_ref}} = joined} -> {:ok, joined}
      {:ok, joined} when join_ref == nil -> {:ok, joined}
      _ -> :error
    end
  end

  # Runs a channel callback; on an exception the channel is dropped with phx_error.
  defp in_channel(state, topic, joined, fun) do
    case safe(fun) do
      {:ok, {frames, socket}} ->
        state = put_in(state.channels[topic], %{joined | socket: socket})
        reply(state, frames)

      {:error, exception} ->
        Logger.error(
          "channel #{Neptunus.Log.safe(topic)} crashed: #{Neptunus.Log.safe(exception)}"
        )

        # the channel is gone: let it clean up (a pilot's channel gives the helm up)
        leave_channel(topic, joined, {:error, :crashed})
        state = %{state | channels: Map.delete(state.channels, topic)}
        join_ref = joined.socket.join_ref
        reply(state, [Wire.encode(join_ref, join_ref, topic, "phx_error", %{})])
    end
  end

  defp leave_channel(topic, %{module: module, socket: socket}, reason) do
    PubSub.unsubscribe(topic)
    safe(fn -> module.terminate(reason, socket) end)
    Presence.untrack(self(), topic)
  end

  defp unmatched(msg, state), do: reply(state, [error_reply(msg, "unmatched topic")])

  defp error_reply(msg, reason),
    do: Wire.encode_reply(msg.join_ref, msg.ref, msg.topic, :error, %{reason: reason})

  defp reply(state, []), do: {:noreply, state}
  defp reply(state, frames), do: {:reply, Enum.map(frames, &{:text, &1}), state}

  defp safe(fun) do
    {:ok, fun.()}
  rescue
    exception -> {:error, Exception.format(:error, exception, __STACKTRACE__)}
  catch
    kind, value -> {:error, Exception.format(kind, value, __STACKTRACE__)}
  end

  defp guarded(state, fun) do
    case safe(fun) do
      {:ok, result} ->
        result

      {:error, formatted} ->
        Logger.error("socket callback failed: #{Neptunus.Log.safe(formatted)}")
        {:noreply, state}
    end
  end

  # Slow clients (see the moduledoc)

  defp backlogged?(state) do
    {:message_queue_len, waiting} = Process.info(self(), :message_queue_len)
    waiting >= state.backlog
  end

  # Behind: a send may have waited for the client until the send timeout closed the socket.
  defp shed(%State{shed: shed, shed_reported_at: reported} = state) do
    now = now_ms()

    cond do
      not connected?(state) ->
        gone(state)

      reported == nil or now - reported >= @shed_report_ms ->
        Logger.info(
          "#{inspect(state.user.name)} reads slower than its telemetry arrives: " <>
            "dropped #{shed + 1} stale telemetry frame(s)" <>
            if(reported == nil, do: "", else: " in the last #{div(now - reported, 1000)} s")
        )

        {:noreply, %{state | shed: 0, shed_reported_at: now}}

      true ->
        {:noreply, %{state | shed: shed + 1}}
    end
  end

  # Linux: the kernel takes a frame only while less than :socket_unsent_bytes of this
  # connection's earlier frames wait there unsent (TCP_NOTSENT_LOWAT). On a slow link the
  # backlog then forms in the mailbox, where stale telemetry is dropped, instead of in a
  # send buffer that the kernel grows to megabytes: seconds of old data for the client.
  defp limit_unsent(sock) do
    case {:os.type(), Application.get_env(:neptunus, :socket_unsent_bytes, @default_unsent)} do
      {{:unix, :linux}, bytes} when is_integer(bytes) and bytes > 0 and sock != nil ->
        # best effort: a kernel without the option only keeps the larger buffer
        _ = setopts(sock, [{:raw, @ipproto_tcp, @tcp_notsent_lowat, <<bytes::native-32>>}])
        :ok

      _ ->
        :ok
    end
  end

  defp setopts({:ssl, sock}, opts), do: :ssl.setopts(sock, opts)
  defp setopts(sock, opts), do: :inet.setopts(sock, opts)

  defp connected?(%State{sock: nil}), do: true
  defp connected?(%State{sock: {:ssl, sock}}), do: match?({:ok, _}, :ssl.peername(sock))
  defp connected?(%State{sock: sock}), do: match?({:ok, _}, :inet.peername(sock))

  # The socket is closed under yaws (the send timeout): end the connection now.
  defp gone(state) do
    Logger.info(
      "#{inspect(state.user.name)}'s client read nothing for " <>
        "#{NeptunusWeb.Endpoint.send_timeout_ms()} ms: connection closed"
    )

    {:close, {1000, "send timeout"}, state}
  end

  # Priority

  defp count_frame(%State{piloting: piloting} = state, now) do
    if MapSet.size(piloting) == 0 do
      state
    else
      {verdict, budget} = PilotBudget.frame(state.budget, now)
      over? = verdict == :over

      if over? and not state.over_budget,
        do:
          Logger.warning(
            "pilot #{inspect(state.user.name)} sends more than #{budget.limit} frames/s: " <>
              "its connection runs at :normal for the rest of this second"
          ),
        else: :ok

      set_priority(%{state | budget: budget, over_budget: over?})
    end
  end

  defp set_priority(%State{} = state) do
    priority =
      cond do
        MapSet.size(state.piloting) == 0 -> :low
        state.over_budget -> :normal
        true -> :high
      end

    Process.flag(:priority, priority)
    state
  end

  defp now_ms, do: System.monotonic_time(:millisecond)
end
