defmodule NeptunusWeb.VideoSocketTest do
  # /video/<id>/websocket against the running endpoint, for vehicles whose camera is ffmpeg's
  # test pattern encoded to H.264 (as the sim camera and V4L2 H.264 cameras come: FLV).
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire, only: [port: 0, secure!: 2, start_vehicle!: 1]

  alias Neptunus.Camera.H264
  alias Neptunus.Vehicle.Camera
  alias NeptunusWeb.Auth.Token
  alias NeptunusWeb.Test.{Video, WSClient}

  @moduletag :capture_log
  @secret "video-test-secret-" <> String.duplicate("v", 20)

  setup do
    id = "vid-#{System.unique_integer([:positive])}"
    {:ok, camera} = Neptunus.Camera.Source.parse("testsrc@h264@320x240@15")
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: camera})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, id: id}
  end

  defp connect!(id, opts \\ []) do
    {:ok, ws} = Video.connect(id, opts)
    ws
  end

  defp keyframe_with_parameter_sets?(frame) do
    {nals, rest, 0} = H264.split(frame.payload)
    nals = nals ++ List.wrap(H264.flush(rest))
    Enum.map(nals, &H264.type/1) |> Enum.take(2) == [7, 8] and H264.keyframe?(nals)
  end

  test "a viewer gets the camera's state, the stream, then frames from a keyframe with SPS and PPS",
       %{id: id} do
    ws = connect!(id)
    {{:text, stream}, before} = Video.until(ws, &match?({:text, %{"event" => "stream"}}, &1))

    assert %{
             "codec" => "h264",
             "width" => 320,
             "height" => 240,
             "fps" => 15,
             "source" => "testsrc",
             "avc" => "avc1.42C0" <> _,
             "generation" => generation
           } = stream

    assert Enum.any?(before, &match?({:text, %{"event" => "camera"}}, &1))
    {[first | rest], _texts} = Video.frames(ws, 20)
    assert first.kind == :h264 and first.keyframe and first.generation == generation
    assert keyframe_with_parameter_sets?(first)
    assert first.arrival_us > 0
    # numbered without gaps for a viewer that keeps up
    seqs = Enum.map([first | rest], & &1.seq)
    assert seqs == Enum.to_list(first.seq..(first.seq + 19))
    WSClient.close(ws)
  end

  test "a late joiner starts at the next keyframe, with the parameter sets in front", %{id: id} do
    ws = connect!(id)
    # well into the stream: past its first keyframe
    {_, _} = Video.frames(ws, 20)
    late = connect!(id)
    {[first | _], texts} = Video.frames(late, 3)
    assert Enum.any?(texts, &(&1["event"] == "stream"))
    assert first.keyframe and first.seq > 0
    assert keyframe_with_parameter_sets?(first)
    refute first.first
  end

  test "what the server sends is H.264 that ffprobe reads whole", %{id: id} do
    ws = connect!(id)
    # three groups of pictures (a keyframe every second at 15 fps)
    {frames, _} = Video.frames(ws, 45)
    file = Path.join(System.tmp_dir!(), "video-#{id}.h264")
    File.write!(file, Enum.map(frames, & &1.payload))
    on_exit(fn -> File.rm(file) end)

    {out, 0} = System.cmd("ffprobe", ~w(-v error -show_streams -count_frames -of json) ++ [file])

    {:ok, %{"streams" => [stream]}} = Neptunus.JSON.decode(out)
    assert %{"codec_name" => "h264", "width" => 320, "height" => 240} = stream
    assert stream["nb_read_frames"] == "45"
    assert Enum.count(frames, & &1.keyframe) >= 2
  end

  test "a viewer that stops reading drops whole groups of pictures; another stays live",
       %{id: id} do
    topic = Camera.topic(id)
    live = connect!(id)
    {_, _} = Video.frames(live, 2)
    before = :pg.get_members(Neptunus.PubSub, {:term, topic})
    slow = connect!(id, paused: true, recbuf: 2048)

    Neptunus.Test.Pty.wait_until(
      fn -> :pg.get_members(Neptunus.PubSub, {:term, topic}) -- before != [] end,
      "the slow viewer's process"
    )

    [viewer] = :pg.get_members(Neptunus.PubSub, {:term, topic}) -- before

    # its client reads nothing: the buffers fill, its sends wait, frames queue for it
    Neptunus.Test.Pty.wait_until(
      fn ->
        match?({:message_queue_len, n} when n >= 12, Process.info(viewer, :message_queue_len))
      end,
      "frames queued for the slow viewer",
      15_000 + Neptunus.Test.Patience.ms()
    )

    WSClient.resume(slow)

    {{:text, skipped}, seen} = Video.until(slow, &match?({:text, %{"event" => "skipped"}}, &1))

    assert %{"frames" => n, "reason" => "slow_viewer"} = skipped
    assert n > 0
    last_before = seen |> Enum.filter(&match?({:frame, _}, &1)) |> List.last()
    {[resumed], _} = Video.frames(slow, 1)
    # it skipped to a keyframe, and the gap is exactly what it was told
    assert resumed.keyframe
    {:frame, before_gap} = last_before
    assert resumed.seq - before_gap.seq - 1 == n

    # meanwhile the other viewer got every frame, up to past that keyframe
    {frames, texts} = collect_through(live, resumed.seq)
    refute Enum.any?(texts, &(&1["event"] == "skipped"))
    seqs = Enum.map(frames, & &1.seq)
    assert seqs == Enum.to_list(hd(seqs)..List.last(seqs))
  end

  defp collect_through(ws, seq, acc \\ {[], []}) do
    {[frame], texts} = Video.frames(ws, 1)
    {frames, all_texts} = acc
    acc = {frames ++ [frame], all_texts ++ texts}
    if frame.seq >= seq, do: acc, else: collect_through(ws, seq, acc)
  end

  test "a camera restart is a new generation, told before its first frame", %{id: id} do
    ws = connect!(id)

    {{:text, %{"generation" => g}}, _} =
      Video.until(ws, &match?({:text, %{"event" => "stream"}}, &1))

    {_, _} = Video.frames(ws, 2)

    # the camera's program dies
    %{port: port} = :sys.get_state(Neptunus.Fleet.via(Camera, id))
    {:os_pid, os_pid} = Port.info(port, :os_pid)
    System.cmd("kill", ["-KILL", "#{os_pid}"])

    {{:text, restarting}, _} =
      Video.until(ws, &match?({:text, %{"event" => "camera", "state" => "restarting"}}, &1))

    assert restarting["reason"] =~ "exited"
    {{:text, stream}, _} = Video.until(ws, &match?({:text, %{"event" => "stream"}}, &1))
    assert stream["generation"] > g
    {[first | _], _} = Video.frames(ws, 1)
    assert first.generation == stream["generation"] and first.keyframe and first.first
    assert first.seq == 0
  end

  test "the keyframe request: frames until the next keyframe are dropped", %{id: id} do
    ws = connect!(id)
    {_, _} = Video.frames(ws, 3)
    WSClient.send_json(ws, %{event: "keyframe"})
    # frames already on their way may come; then a keyframe, and nothing before it after
    {frames, _} = Video.frames(ws, 25)
    assert Enum.any?(frames, & &1.keyframe)
  end

  test "the vehicle's join reply says how to watch an H.264 camera", %{id: id} do
    %{snapshot: snapshot, ws: ws} =
      NeptunusWeb.Test.Wire.client!("vehicle:" <> id, %{"name" => "v"})

    assert snapshot["camera"] == %{
             "codec" => "h264",
             "video" => "/video/#{id}/websocket",
             "url" => nil
           }

    WSClient.close(ws)
    {:ok, 404, body} = mjpeg_status(id)
    assert body =~ "sends h264: watch it at /video/#{id}/websocket"
  end

  defp mjpeg_status(id) do
    {status, _headers, body, socket} = NeptunusWeb.Test.Wire.raw_get("/camera/#{id}.mjpg")
    :gen_tcp.close(socket)
    {:ok, status, body}
  end

  test "unknown vehicle, no camera, wrong path: 404 with a reason" do
    other = start_vehicle!("nocam")

    for {path, reason} <- [
          {"/video/nope/websocket", "unknown vehicle"},
          {"/video/#{other.id}/websocket", "has no camera"},
          {"/video/x", "no such video endpoint"}
        ] do
      assert {:error, {:http_status, 404, %{body: body}}} = WSClient.connect(port(), path)

      assert body =~ reason
    end
  end

  test "authorised like the Channels socket: origin, token, observers", %{id: id} do
    {:error, {:http_status, 403, %{body: body}}} =
      Video.connect(id, headers: [{"Origin", "http://evil.example"}])

    assert body =~ "origin"

    secure!(@secret, %{"olga" => %{name: "olga", role: :observer, hash: "unused"}})
    {:error, {:http_status, 401, %{body: body}}} = Video.connect(id)
    assert body =~ "login required"

    token = Token.sign("olga", @secret, System.os_time(:second), 600)
    {:ok, ws} = Video.connect(id, query: %{"token" => token})
    {[frame], _} = Video.frames(ws, 1)
    assert frame.keyframe
  end
end
