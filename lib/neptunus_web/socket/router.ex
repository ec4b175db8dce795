defmodule NeptunusWeb.Socket.Router do
  @moduledoc """
  The server side of the Phoenix Channels v2 protocol for one connection (pure):
  `handle_message(router, message) -> {router, frames, effects}`. `NeptunusWeb.Socket` keeps
  one per WebSocket connection, sends the `frames` (encoded JSON text) to the client in
  order and carries out the `effects` in order; the router itself sends nothing, subscribes
  to nothing and reads no clock.

  The router holds the joined channels and calls their callbacks (`NeptunusWeb.Channel`):
  channels run inside the connection process, so a client's message is a function call
  away from the vehicle. An exception in a channel callback is caught here: the client
  gets `phx_error` for that topic and the other channels stay.

  ## Protocol (the client's view: `docs/API.md`)

    * frames are JSON `[join_ref, ref, topic, event, payload]` (`NeptunusWeb.Channels.Wire`);
    * `phoenix`/`heartbeat` is answered `ok`;
    * `phx_join` of a topic that `routes` match → `phx_reply` ok with the channel's join
      reply, or error with the channel's reason (`"join crashed"` if it raised); joining a
      joined topic again leaves the old channel first (its `join_ref` goes stale); a topic
      no route matches → error `unmatched topic`;
    * `phx_leave` → `phx_reply` ok, then `phx_close` with the join ref;
    * any other event on a joined topic → the channel's `handle_in/3` reply; on a topic that
      is not joined, or with a stale join ref → error `unmatched topic`;
    * a malformed frame → `phx_reply` error with a readable reason, addressed as well as the
      frame allows (topic `phoenix` when none); a binary frame → error; the connection stays;
    * a channel that raises → `[join_ref, join_ref, topic, "phx_error", {}]`; the channel is
      left (its `terminate/2` runs with `{:error, :crashed}`).

  ## Messages (`t:message/0`)

    * `{:text, data}`, `{:binary, data}` — a frame from the client;
    * `{:channel_info, topic, msg}` — a channel's own message (`NeptunusWeb.Channel.send_self/2`),
      for its `handle_info/2`; dropped when the topic is not joined;
    * `{:closed, reason}` — the connection is closing: every channel is left (its
      `terminate/2` gets `{:shutdown, reason}`);
    * `{:watched, msg, :ok | :restarting}`, `{:subscribed, msg, frame, :ok | :restarting}` —
      the answers to the requests below.

  ## Effects (`t:effect/0`), in the order they must be carried out

    * `{:watch, msg}` — a join needs the PubSub scope and the presence server (the channel
      may track a presence as it joins): watch both, then answer `{:watched, msg, result}`,
      `:restarting` while either is down (the join is refused with "server restarting: join
      again");
    * `{:subscribe, msg, frame}` — the channel has joined: subscribe the connection to
      `msg.topic`, then answer `{:subscribed, msg, frame, result}`; the join reply `frame`
      goes out on `:ok`; on `:restarting` the channel is left and the join refused. (The
      subscription comes after the channel's join, so the join's own pushes, such as the
      vehicle channel's `presence_state`, reach the client before any broadcast.)
    * `{:unsubscribe, topic}`, `{:terminate, module, reason, socket}` (call the channel's
      `terminate/2`; its result and any exception are ignored), `{:untrack, topic}` (the
      connection's presences on `topic`) — a channel is left, in this order, so a broadcast
      its `terminate/2` causes does not reach the client;
    * `:gc` — collect garbage once this message is done (a join builds large replies);
    * `{:log, :error, text}` — a channel raised.
  """

  alias NeptunusWeb.Channel
  alias NeptunusWeb.Channels.Wire
  alias NeptunusWeb.Channels.Wire.Message

  @type topic :: String.t()

  @typedoc """
  A topic pattern and its channel module: `"fleet"` matches that topic only, `"vehicle:*"`
  every topic that starts with `vehicle:`. The first matching route wins.
  """
  @type route :: {String.t(), module()}

  @type joined :: %{module: module(), socket: Channel.Socket.t()}

  @type t :: %__MODULE__{
          user: NeptunusWeb.Auth.user(),
          transport_pid: pid(),
          routes: [route()],
          channels: %{optional(topic()) => joined()}
        }
  @enforce_keys [:user, :transport_pid, :routes]
  defstruct [:user, :transport_pid, :routes, channels: %{}]

  @type result :: :ok | :restarting

  @type message ::
          {:text, binary()}
          | {:binary, binary()}
          | {:channel_info, topic(), term()}
          | {:closed, term()}
          | {:watched, Message.t(), result()}
          | {:subscribed, Message.t(), binary(), result()}

  @type effect ::
          {:watch, Message.t()}
          | {:subscribe, Message.t(), binary()}
          | {:unsubscribe, topic()}
          | {:terminate, module(), term(), Channel.Socket.t()}
          | {:untrack, topic()}
          | :gc
          | {:log, :error, String.t()}

  @doc """
  A router for the connection of `user` whose process is `transport_pid` (channels send
  themselves messages there), serving `routes`. Raises `ArgumentError` on a malformed route.
  """
  @spec new(NeptunusWeb.Auth.user(), pid(), [route()]) :: t()
  def new(user, transport_pid, routes) when is_pid(transport_pid) and is_list(routes) do
    for route <- routes do
      case route do
        {pattern, module} when is_binary(pattern) and pattern != "" and is_atom(module) ->
          :ok

        other ->
          raise ArgumentError, "a route is {pattern, channel module}, got #{inspect(other)}"
      end
    end

    %__MODULE__{user: user, transport_pid: transport_pid, routes: routes}
  end

  @doc "Whether `topic` is joined."
  @spec joined?(t(), topic()) :: boolean()
  def joined?(%__MODULE__{channels: channels}, topic), do: Map.has_key?(channels, topic)

  @doc "The joined topics."
  @spec topics(t()) :: [topic()]
  def topics(%__MODULE__{channels: channels}), do: Map.keys(channels)

  @doc "The channel module `routes` give `topic`, or nil."
  @spec route([route()], topic()) :: module() | nil
  def route(routes, topic) do
    Enum.find_value(routes, fn {pattern, module} -> if matches?(pattern, topic), do: module end)
  end

  defp matches?(pattern, topic) do
    case String.split_at(pattern, -1) do
      {prefix, "*"} -> String.starts_with?(topic, prefix)
      _ -> pattern == topic
    end
  end

  @doc "Handles one message (see the moduledoc): the frames to send and the effects to carry out."
  @spec handle_message(t(), message()) :: {t(), [binary()], [effect()]}
  def handle_message(%__MODULE__{} = router, {:text, data}) when is_binary(data) do
    case Wire.decode(data) do
      {:ok, msg} ->
        dispatch(router, msg)

      {:error, reason, partial} ->
        frame =
          Wire.encode_reply(partial.join_ref, partial.ref, partial.topic || "phoenix", :error, %{
            reason: reason
          })

        {router, [frame], []}
    end
  end

  def handle_message(%__MODULE__{} = router, {:binary, _data}) do
    frame =
      Wire.encode_reply(nil, nil, "phoenix", :error, %{
        reason: "binary frames are not supported: send JSON text"
      })

    {router, [frame], []}
  end

  def handle_message(%__MODULE__{} = router, {:channel_info, topic, msg}) do
    case Map.fetch(router.channels, topic) do
      {:ok, %{module: module, socket: socket} = joined} ->
        in_channel(router, topic, joined, fn ->
          case module.handle_info(msg, socket) do
            {:noreply, socket} ->
              {[], socket}

            {:push, event, payload, socket} ->
              {[Wire.encode(socket.join_ref, nil, topic, event, payload)], socket}
          end
        end)

      :error ->
        {router, [], []}
    end
  end

  def handle_message(%__MODULE__{} = router, {:closed, reason}) do
    effects =
      Enum.flat_map(router.channels, fn {topic, joined} ->
        leave(topic, joined, {:shutdown, reason})
      end)

    {%{router | channels: %{}}, [], effects}
  end

  def handle_message(%__MODULE__{} = router, {:watched, %Message{} = msg, :restarting}),
    do: {router, [error_reply(msg, "server restarting: join again")], []}

  def handle_message(%__MODULE__{} = router, {:watched, %Message{} = msg, :ok}),
    do: join(router, msg)

  def handle_message(%__MODULE__{} = router, {:subscribed, %Message{}, frame, :ok})
      when is_binary(frame),
      do: {router, [frame], [:gc]}

  def handle_message(
        %__MODULE__{} = router,
        {:subscribed, %Message{topic: topic} = msg, _, :restarting}
      ) do
    # the scope stopped during the join: its :DOWN closes the connection
    {joined, channels} = Map.pop(router.channels, topic)
    effects = if joined, do: leave(topic, joined, {:shutdown, :left}), else: []
    {%{router | channels: channels}, [error_reply(msg, "server restarting: join again")], effects}
  end

  # Frames from the client

  defp dispatch(router, %Message{topic: "phoenix", event: "heartbeat"} = msg),
    do: {router, [Wire.encode_reply(nil, msg.ref, "phoenix", :ok, %{})], []}

  defp dispatch(router, %Message{event: "phx_join", topic: topic} = msg) do
    {old, channels} = Map.pop(router.channels, topic)
    router = %{router | channels: channels}
    effects = if old, do: leave(topic, old, {:shutdown, :rejoin}), else: []

    case route(router.routes, topic) do
      nil -> {router, [error_reply(msg, "unmatched topic")], effects}
      _module -> {router, [], effects ++ [{:watch, msg}]}
    end
  end

  defp dispatch(router, %Message{event: "phx_leave", topic: topic} = msg) do
    case joined(router, msg) do
      {:ok, joined} ->
        frames = [
          Wire.encode_reply(msg.join_ref, msg.ref, topic, :ok, %{}),
          Wire.encode(msg.join_ref, msg.join_ref, topic, "phx_close", %{})
        ]

        {%{router | channels: Map.delete(router.channels, topic)}, frames,
         leave(topic, joined, {:shutdown, :left})}

      :error ->
        {router, [error_reply(msg, "unmatched topic")], []}
    end
  end

  defp dispatch(router, %Message{topic: topic} = msg) do
    case joined(router, msg) do
      {:ok, %{module: module, socket: socket} = joined} ->
        in_channel(router, topic, joined, fn ->
          {:reply, {status, response}, socket} = module.handle_in(msg.event, msg.payload, socket)
          {[Wire.encode_reply(msg.join_ref, msg.ref, topic, status, response)], socket}
        end)

      :error ->
        {router, [error_reply(msg, "unmatched topic")], []}
    end
  end

  # The services are watched: the channel joins, then the connection subscribes.
  defp join(router, %Message{topic: topic} = msg) do
    module = route(router.routes, topic)

    socket = %Channel.Socket{
      topic: topic,
      join_ref: msg.join_ref,
      user: router.user,
      transport_pid: router.transport_pid
    }

    joined =
      safe(fn ->
        case module.join(topic, msg.payload, socket) do
          {:ok, response, %Channel.Socket{} = socket} ->
            {:ok, %{module: module, socket: socket}, response}

          {:error, response} ->
            {:error, Wire.encode_reply(msg.join_ref, msg.ref, topic, :error, response)}
        end
      end)

    case joined do
      {:ok, {:ok, joined, response}} ->
        case safe(fn -> Wire.encode_reply(msg.join_ref, msg.ref, topic, :ok, response) end) do
          {:ok, frame} ->
            {put_in(router.channels[topic], joined), [], [{:subscribe, msg, frame}]}

          {:error, formatted} ->
            join_crashed(router, msg, formatted, leave(topic, joined, {:error, :crashed}))
        end

      {:ok, {:error, frame}} ->
        {router, [frame], []}

      {:error, formatted} ->
        join_crashed(router, msg, formatted, [])
    end
  end

  defp join_crashed(router, msg, formatted, effects) do
    log =
      {:log, :error,
       "join #{Neptunus.Log.safe(msg.topic)} failed: #{Neptunus.Log.safe(formatted)}"}

    {router, [error_reply(msg, "join crashed")], [log | effects]}
  end

  # The joined channel a push is for: same topic, and the join ref of its join (or none).
  defp joined(router, %Message{topic: topic, join_ref: join_ref}) do
    case Map.fetch(router.channels, topic) do
      {:ok, %{socket: %{join_ref: ^join_ref}} = joined} -> {:ok, joined}
      {:ok, joined} when join_ref == nil -> {:ok, joined}
      _ -> :error
    end
  end

  # Runs a channel callback returning {frames, socket}; on an exception the channel is left
  # with phx_error.
  defp in_channel(router, topic, joined, fun) do
    case safe(fun) do
      {:ok, {frames, socket}} ->
        {put_in(router.channels[topic], %{joined | socket: socket}), frames, []}

      {:error, formatted} ->
        log =
          {:log, :error,
           "channel #{Neptunus.Log.safe(topic)} crashed: #{Neptunus.Log.safe(formatted)}"}

        join_ref = joined.socket.join_ref

        {%{router | channels: Map.delete(router.channels, topic)},
         [Wire.encode(join_ref, join_ref, topic, "phx_error", %{})],
         [log | leave(topic, joined, {:error, :crashed})]}
    end
  end

  defp leave(topic, %{module: module, socket: socket}, reason),
    do: [{:unsubscribe, topic}, {:terminate, module, reason, socket}, {:untrack, topic}]

  defp error_reply(msg, reason),
    do: Wire.encode_reply(msg.join_ref, msg.ref, msg.topic, :error, %{reason: reason})

  defp safe(fun) do
    {:ok, fun.()}
  rescue
    exception -> {:error, Exception.format(:error, exception, __STACKTRACE__)}
  catch
    kind, value -> {:error, Exception.format(kind, value, __STACKTRACE__)}
  end
end
