defmodule NeptunusWeb.VideoSocket do
  @moduledoc """
  The video WebSocket, `/video/<vehicle id>/websocket` (a yaws appmod): a vehicle's camera
  for a browser's decoder (WebCodecs or Media Source Extensions). The wire is docs/API.md,
  "Video": text messages `camera`, `stream` and `skipped` (JSON), and one binary message
  per frame — the camera's shared binary (`Neptunus.Camera.Frame`) behind a WebSocket
  header, never copied per viewer.

  Upgrades are authorised exactly as the Channels socket's
  (`NeptunusWeb.WebSocket.Upgrade.authorize/1`: `Origin`, `Host`, `token`): refused with 403
  or 401 and a reason; a vehicle without camera (or unknown) with 404.

  One process per viewer, at `:low` priority (the control path and the Channels sockets
  first). It watches the camera (`NeptunusWeb.CameraRelay.watch/1`: directly, or through
  this node's relay for a vehicle on another node), sends the camera's state and stream
  first, then the frames from the next keyframe on. Which frames go out is
  `NeptunusWeb.VideoSocket.Flow`'s decision: a viewer that falls behind (its client reads
  slower than the camera sends; the kernel holds little unsent,
  `NeptunusWeb.WebSocket.Transport.limit_unsent/2`, so the backlog forms in this process'
  mailbox) drops whole groups of pictures, and is told (`skipped`); the camera and other
  viewers never wait for it. A client that reads nothing at all is closed by the endpoint's
  send timeout; the viewer finds its socket gone at its next check.

  The client may send `{"event": "keyframe"}` (after a decoder error): the frames until the
  next keyframe are dropped for it. Anything else it sends is ignored.
  """
  require Logger

  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Fleet
  alias Neptunus.Camera.Frame
  alias Neptunus.Vehicle.Camera
  alias NeptunusWeb.CameraRelay
  alias NeptunusWeb.Endpoint.Settings
  alias NeptunusWeb.Socket.WsFrame
  alias NeptunusWeb.WebSocket.{Transport, Upgrade}
  alias NeptunusWeb.VideoSocket.Flow

  # frames waiting for a viewer from which on it is behind (a third of a second at 30 fps)
  @backlog 10
  @check_ms 2_000
  @max_message_bytes 4_096

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            user: NeptunusWeb.Auth.user(),
            flow: NeptunusWeb.VideoSocket.Flow.t(),
            sock: NeptunusWeb.WebSocket.Transport.socket() | nil,
            watch: reference() | nil,
            generation: non_neg_integer() | nil,
            camera: map() | nil
          }
    @enforce_keys [:id, :user, :flow]
    defstruct [:id, :user, :flow, :sock, :watch, :generation, :camera]
  end

  @doc false
  def out(arg) do
    path = arg(arg, :server_path) |> to_string()

    with {:ok, id} <- vehicle(path),
         {:ok, user} <- Upgrade.authorize(arg),
         :ok <- camera(id) do
      {:websocket, __MODULE__,
       [
         {:callback, {:basic, %{user: user, id: id}}},
         {:max_frame_size, @max_message_bytes},
         {:max_message_size, @max_message_bytes}
       ]}
    else
      {:error, status, reason} -> Upgrade.refuse(status, reason)
    end
  end

  defp vehicle("/video/" <> rest) do
    case String.split(rest, "/") do
      [id, "websocket"] when id != "" -> {:ok, URI.decode(id)}
      _ -> {:error, 404, "no such video endpoint: use /video/<vehicle id>/websocket"}
    end
  end

  defp vehicle(_path),
    do: {:error, 404, "no such video endpoint: use /video/<vehicle id>/websocket"}

  defp camera(id) do
    cond do
      not Fleet.exists?(id) ->
        {:error, 404, "unknown vehicle: #{id}"}

      Fleet.on_vehicle_node(id, Camera, :info, [id], nil) == nil ->
        {:error, 404, "vehicle #{id} has no camera"}

      true ->
        :ok
    end
  end

  # yaws WebSocket callbacks (basic mode); every body is guarded (see NeptunusWeb.Socket)

  @doc false
  def init([_arg, %{user: user, id: id}]) do
    Process.flag(:priority, :low)
    :timer.send_interval(@check_ms, :check)
    {:ok, %State{id: id, user: user, flow: Flow.new(backlog: @backlog)}}
  end

  @doc false
  def handle_open(ws_state, state) do
    sock = Transport.socket(ws_state)
    Transport.limit_unsent(sock, Settings.get().unsent_bytes)
    send(self(), :watch)
    {:ok, %{state | sock: sock}}
  end

  @doc false
  def handle_message({:text, data}, state) do
    guarded(state, fn ->
      case Neptunus.JSON.decode(data) do
        {:ok, %{"event" => "keyframe"}} ->
          {:noreply, %{state | flow: Flow.await_keyframe(state.flow)}}

        _ ->
          {:noreply, state}
      end
    end)
  end

  def handle_message({:close, code, _reason}, state) when code in [1005, 1006],
    do: {:close, 1000, state}

  def handle_message({:close, code, _reason}, state), do: {:close, code, state}
  def handle_message(_other, state), do: {:noreply, state}

  @doc false
  def handle_info({:pubsub, _topic, "frame", %{frame: %Frame{} = frame}}, state) do
    if frame.generation == state.generation, do: frame(state, frame), else: {:noreply, state}
  end

  def handle_info(msg, state), do: guarded(state, fn -> handle_other(msg, state) end)

  @doc false
  def terminate(_reason, _state), do: :ok

  defp frame(state, frame) do
    {:message_queue_len, waiting} = Process.info(self(), :message_queue_len)
    {flow, verdict} = Flow.frame(state.flow, frame.keyframe, waiting)
    state = %{state | flow: flow}

    case verdict do
      :send ->
        send_frame(state, frame)

      :drop ->
        {:noreply, state}

      {:skipped, n} ->
        text(state, %{event: "skipped", frames: n, reason: "slow_viewer"})
        send_frame(state, frame)
    end
  end

  defp send_frame(state, frame) do
    _ = Transport.write(state.sock, WsFrame.binary(frame.data))
    {:noreply, state}
  end

  defp handle_other(:watch, state) do
    ref = CameraRelay.watch(state.id)
    view = Fleet.on_vehicle_node(state.id, Camera, :view, [state.id], nil)
    state = %{state | watch: ref}

    case view do
      %{camera: camera, stream: stream} ->
        state = camera_message(state, camera)
        {:noreply, if(stream, do: stream_message(state, stream), else: state)}

      nil ->
        {:noreply, camera_message(state, %{state: "none", reason: nil, restarts: 0})}
    end
  end

  defp handle_other({:pubsub, _topic, "stream", info}, state),
    do: {:noreply, stream_message(state, info)}

  defp handle_other({:pubsub, _topic, "camera", camera}, state),
    do: {:noreply, camera_message(state, camera)}

  defp handle_other({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  # what served the camera's messages (the relay, the PubSub scope) went away: watch again
  defp handle_other({:DOWN, ref, :process, _pid, _reason}, %State{watch: ref} = state),
    do: handle_other(:watch, %{state | watch: nil})

  defp handle_other(:check, state) do
    if Transport.connected?(state.sock) do
      {:noreply, state}
    else
      Logger.info(
        "#{inspect(state.user.name)}'s video client read nothing for " <>
          "#{Settings.get().send_timeout_ms} ms: connection closed"
      )

      {:close, {1000, "send timeout"}, state}
    end
  end

  defp handle_other(_msg, state), do: {:noreply, state}

  # A stream (generation) the client has not been told of: tell it, wait for a keyframe.
  defp stream_message(%State{generation: g} = state, %{generation: g}), do: state

  defp stream_message(state, info) do
    text(state, Map.put(info, :event, "stream"))
    %{state | generation: info.generation, flow: Flow.await_keyframe(state.flow)}
  end

  defp camera_message(%State{camera: camera} = state, camera), do: state

  defp camera_message(state, camera) do
    text(state, Map.put(camera, :event, "camera"))
    %{state | camera: camera}
  end

  defp text(state, message) do
    _ = Transport.write(state.sock, WsFrame.text(Neptunus.JSON.encode!(message)))
    :ok
  end

  defp guarded(state, fun) do
    fun.()
  rescue
    exception ->
      Logger.error(
        "video socket callback failed: " <>
          Neptunus.Log.safe(Exception.format(:error, exception, __STACKTRACE__))
      )

      {:noreply, state}
  end
end
