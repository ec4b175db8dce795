defmodule NeptunusWeb.CameraStreamTest do
  # /camera/<id>.mjpg against the running endpoint, for a vehicle whose camera is the fake
  # camera program (test/fixtures/camera/fake_camera.sh).
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias NeptunusWeb.Auth.Token

  @moduletag :capture_log
  @script Path.expand("../fixtures/camera/fake_camera.sh", __DIR__)
  @frames [
    File.read!("test/fixtures/camera/frame1.jpg"),
    File.read!("test/fixtures/camera/frame2.jpg")
  ]
  @secret "camera-test-secret-" <> String.duplicate("z", 20)

  setup do
    id = "camv-#{System.unique_integer([:positive])}"
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [@script, "0"]}
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: camera})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, id: id}
  end

  defp open(path), do: NeptunusWeb.Test.Wire.raw_get(path)

  # The body, de-chunked (Transfer-Encoding: chunked): {data, undecoded rest}
  defp dechunk(raw, acc \\ <<>>) do
    case :binary.split(raw, "\r\n") do
      [size_line, rest] ->
        {size, ""} = Integer.parse(size_line, 16)

        if byte_size(rest) >= size + 2 do
          <<chunk::binary-size(size), "\r\n", more::binary>> = rest
          dechunk(more, acc <> chunk)
        else
          {acc, raw}
        end

      [_] ->
        {acc, raw}
    end
  end

  # the next multipart part's JPEG from the de-chunked body: {frame, {data, raw}}
  defp next_part(socket, {data, raw}) do
    case Regex.run(
           ~r/\A--neptunusframe\r\nContent-Type: image\/jpeg\r\nContent-Length: (\d+)\r\n\r\n/,
           data,
           return: :index
         ) do
      [{0, len}, {ls, ll}] ->
        size = data |> binary_part(ls, ll) |> String.to_integer()

        if byte_size(data) >= len + size + 2 do
          <<_::binary-size(len), frame::binary-size(size), "\r\n", rest::binary>> = data
          {frame, {rest, raw}}
        else
          more(socket, {data, raw})
        end

      nil ->
        assert byte_size(data) < 80,
               "not a part: #{inspect(binary_part(data, 0, min(80, byte_size(data))))}"

        more(socket, {data, raw})
    end
  end

  defp more(socket, {data, raw}) do
    {:ok, bytes} = :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms())
    {new, raw} = dechunk(raw <> bytes)
    next_part(socket, {data <> new, raw})
  end

  defp stream_start(headers, body) do
    assert headers["transfer-encoding"] == "chunked"
    dechunk(body)
  end

  test "streams the camera's frames as multipart JPEG, several viewers at once", %{id: id} do
    {200, headers, body, socket} = open("/camera/#{id}.mjpg")
    assert headers["content-type"] == "multipart/x-mixed-replace; boundary=neptunusframe"
    {200, headers2, body2, socket2} = open("/camera/#{id}.mjpg")

    {frames, _} =
      Enum.map_reduce(1..6, stream_start(headers, body), fn _, buffer ->
        next_part(socket, buffer)
      end)

    assert Enum.all?(frames, &(&1 in @frames))
    assert Enum.uniq(frames) |> length() == 2
    {frame, _} = next_part(socket2, stream_start(headers2, body2))
    assert frame in @frames

    :gen_tcp.close(socket)
    :gen_tcp.close(socket2)
  end

  test "a viewer that stops reading is dropped after the send timeout", %{id: id} do
    topic = Neptunus.Vehicle.Camera.topic(id)
    before = :pg.get_members(Neptunus.PubSub, {:term, topic})
    {200, _headers, _body, socket} = open("/camera/#{id}.mjpg")

    viewers = fn -> :pg.get_members(Neptunus.PubSub, {:term, topic}) -- before end
    Neptunus.Test.Pty.wait_until(fn -> viewers.() != [] end, "the viewer's stream process")
    [viewer] = viewers.()
    ref = Process.monitor(viewer)

    # the client reads nothing more while big frames keep coming: the buffers fill, the
    # viewer's send waits, and the send timeout ends it (instead of a process that waits
    # forever holding frames)
    big = String.duplicate("j", 512 * 1024)
    started = System.monotonic_time(:millisecond)

    for seq <- 1..60 do
      frame =
        Neptunus.Camera.Frame.new(:jpeg, big,
          keyframe: true,
          generation: 1,
          seq: seq,
          arrival_us: 1
        )

      Neptunus.PubSub.broadcast(topic, "frame", %{frame: frame})
      Process.sleep(10)
    end

    timeout = NeptunusWeb.Endpoint.send_timeout_ms()
    assert_receive {:DOWN, ^ref, :process, ^viewer, _}, timeout + Neptunus.Test.Patience.ms()
    assert System.monotonic_time(:millisecond) - started >= timeout
    :gen_tcp.close(socket)
  end

  test "the snapshot gives the camera's address; a vehicle without camera has none", %{id: id} do
    %{snapshot: snapshot} = client!("vehicle:" <> id, %{"name" => "cam-viewer"})

    assert snapshot["camera"] == %{
             "codec" => "mjpeg",
             "url" => "/camera/#{id}.mjpg",
             "video" => "/video/#{id}/websocket"
           }

    other = start_vehicle!("nocam")
    %{snapshot: snapshot} = client!(other.topic, %{"name" => "cam-viewer"})
    assert snapshot["camera"] == nil
    {404, _, body, _} = open("/camera/#{other.id}.mjpg")
    assert body =~ "has no camera"
  end

  test "telemetry carries the camera's state", %{id: id} do
    Neptunus.PubSub.subscribe("vehicle:" <> id)

    assert_receive {:pubsub, _, "telemetry", %{camera: %{running: true, fps: fps, error: nil}}}
                   when fps > 0
  end

  test "wrong addresses are 404 with a reason" do
    for path <- ["/camera/", "/camera/x", "/camera/x.jpg", "/camera/nope.mjpg"] do
      {404, _, body, socket} = open(path)
      :gen_tcp.close(socket)
      assert body =~ "camera", "#{path}: #{body}"
    end
  end

  test "secure mode: the token in the query opens the stream", %{id: id} do
    secure!(@secret, %{"olga" => %{name: "olga", role: :observer, hash: "unused"}})

    {401, _, body, _} = open("/camera/#{id}.mjpg")
    assert body =~ "log in"
    token = Token.sign("olga", @secret, System.os_time(:second), 600)
    {200, headers, body, socket} = open("/camera/#{id}.mjpg?token=#{URI.encode_www_form(token)}")
    {frame, _} = next_part(socket, stream_start(headers, body))
    assert frame in @frames
    :gen_tcp.close(socket)
  end
end
