defmodule NeptunusWeb.CameraStream do
  @moduledoc """
  `GET /camera/<id>.mjpg` (a yaws appmod): the vehicle's camera as a
  `multipart/x-mixed-replace` Motion JPEG stream, which browsers show in an `<img>`. Who may
  watch the vehicle may watch its camera (`NeptunusWeb.API.Request.may_watch/1`: the token in
  `?token=` for an `<img>`).

  Only for an MJPEG camera (an H.264 camera is watched on the video WebSocket,
  `NeptunusWeb.VideoSocket`: `404` here). Each viewer is one streaming process: it sends
  the newest frame at once, then every new one. A viewer that cannot keep up gets the newest frame, not a queue: frames that arrived
  while it was writing are dropped for it alone. It ends when the client goes away. When the
  PubSub scope restarts (its subscription gone, see `Neptunus.PubSub`), it subscribes again
  as soon as the scope is back: the viewer misses a few frames, not the rest of the stream.

  A vehicle on another node of the fleet is watched the same way from any node: whether it
  has a camera and its newest frame are asked on its node (`Neptunus.Fleet.on_vehicle_node/5`);
  its frames come through this node's relay of that camera (`NeptunusWeb.CameraRelay`), so
  they cross between the nodes once per frame, not once per viewer.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Fleet
  alias Neptunus.Camera.{Frame, MJPEG}
  alias Neptunus.Vehicle.Camera
  alias NeptunusWeb.API.{Request, Response}
  alias NeptunusWeb.CameraRelay

  @doc false
  def out(arg) do
    path = arg(arg, :server_path) |> to_string()

    with {:ok, id} <- vehicle(path),
         :ok <- allowed(arg),
         :ok <- mjpeg(id) do
      socket = arg(arg, :clisock)
      pid = spawn(fn -> start(id, socket) end)
      {:streamcontent_from_pid, String.to_charlist(MJPEG.content_type()), pid}
    else
      {status, body} -> Response.respond({status, body})
    end
  end

  # the camera of a vehicle on another node of the fleet is asked there; its frames come as
  # broadcasts of its topic (term subscribers anywhere get them)
  defp mjpeg(id) do
    case Fleet.on_vehicle_node(id, Camera, :info, [id], nil) do
      %{codec: :mjpeg} ->
        :ok

      %{codec: codec, video: video} ->
        {404, %{error: "vehicle #{id}'s camera sends #{codec}: watch it at #{video}"}}

      nil ->
        {404, %{error: "vehicle #{id} has no camera"}}
    end
  end

  defp vehicle("/camera/" <> file) do
    case String.split(file, ".") do
      [id, "mjpg"] when id != "" -> {:ok, URI.decode(id)}
      _ -> {404, %{error: "no such camera: use /camera/<vehicle id>.mjpg"}}
    end
  end

  defp vehicle(_path), do: {404, %{error: "no such camera: use /camera/<vehicle id>.mjpg"}}

  defp allowed(arg) do
    case Request.may_watch(arg) do
      :ok -> :ok
      {:error, reason} -> {401, %{error: reason}}
    end
  end

  defp start(id, socket) do
    NeptunusWeb.Endpoint.Yaws.await_stream(
      socket,
      fn yaws ->
        pubsub = subscribe(id)
        ref = Process.monitor(yaws)
        watch = {id, ref, pubsub}
        # a simulated camera renders only while watched: this wakes it
        _ = Fleet.on_vehicle_node(id, Camera, :view, [id], nil)

        case Fleet.on_vehicle_node(id, Camera, :latest, [id], nil) do
          nil ->
            stream(socket, yaws, watch)

          %Frame{} = frame ->
            if send_frame(socket, Frame.payload(frame)) == :ok,
              do: stream(socket, yaws, watch),
              else: done(yaws)
        end
      end,
      10_000
    )
  end

  defp subscribe(id), do: CameraRelay.watch(id)

  defp stream(socket, yaws, {id, ref, pubsub} = watch) do
    receive do
      {:pubsub, _topic, "frame", %{frame: frame}} ->
        frame = newest(frame)

        case send_frame(socket, Frame.payload(frame)) do
          :ok -> stream(socket, yaws, watch)
          {:error, _} -> done(yaws)
        end

      {:pubsub, _topic, _stream_or_camera, _payload} ->
        stream(socket, yaws, watch)

      {:DOWN, ^pubsub, :process, _, _} ->
        stream(socket, yaws, {id, ref, subscribe(id)})

      {:DOWN, ^ref, :process, _, _} ->
        :ok
    end
  end

  # the newest of the frames waiting in the mailbox
  defp newest(frame) do
    receive do
      {:pubsub, _topic, "frame", %{frame: newer}} -> newest(newer)
    after
      0 -> frame
    end
  end

  # HTTP/1.1 without a length: yaws announced chunked transfer encoding, one chunk per frame
  defp send_frame(socket, frame) do
    case :yaws_api.stream_process_deliver_chunk(socket, MJPEG.part(frame)) do
      :ok -> :ok
      {:error, reason} -> {:error, reason}
    end
  end

  defp done(yaws), do: :yaws_api.stream_process_end(:closed, yaws)
end
