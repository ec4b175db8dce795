defmodule Neptunus.Vehicle.CameraTest do
  use ExUnit.Case, async: true

  alias Neptunus.Camera.{Frame, H264, Pose, Source}
  alias Neptunus.PubSub
  alias Neptunus.Test.Patience
  alias Neptunus.Vehicle.{Camera, Telemetry}

  @moduletag :capture_log

  @fixtures Path.expand("../../fixtures/camera", __DIR__)
  @script Path.join(@fixtures, "fake_camera.sh")
  @fake_ffmpeg Path.join(@fixtures, "fake_ffmpeg.sh")
  @frame1 File.read!("test/fixtures/camera/frame1.jpg")
  @frame2 File.read!("test/fixtures/camera/frame2.jpg")

  defp start!(source, opts \\ []) do
    id = "cam-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Camera.topic(id))
    PubSub.subscribe(Telemetry.log_topic(id))
    start_supervised!(Supervisor.child_spec({Camera, [id: id, camera: source] ++ opts}, id: id))
    id
  end

  defp fake(count),
    do: %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [@script, "#{count}"]}

  defp sh(script, codec \\ :mjpeg),
    do: %{kind: :exec, codec: codec, program: "/bin/sh", args: ["-c", script]}

  defp next_frame(timeout \\ Patience.ms()) do
    assert_receive {:pubsub, _, "frame", %{frame: %Frame{} = frame}}, timeout
    frame
  end

  defp camera_event(state, timeout \\ Patience.ms()) do
    assert_receive {:pubsub, _, "camera", %{state: ^state} = event}, timeout
    event
  end

  test "JPEG images from the camera program reach subscribers whole, in order, as frames" do
    id = start!(fake(0))

    assert_receive {:pubsub, _, "stream", %{codec: "mjpeg", avc: nil, generation: g} = info}

    assert {info.width, info.height} == Neptunus.Camera.MJPEG.size(@frame1)
    first = next_frame()
    second = next_frame()

    assert Enum.sort([Frame.payload(first), Frame.payload(second)]) ==
             Enum.sort([@frame1, @frame2])

    assert first.keyframe and first.generation == g and second.seq == first.seq + 1
    assert {:ok, %{kind: :jpeg}} = Frame.parse(first.data)

    assert Frame.payload(Camera.latest(id)) in [@frame1, @frame2]

    assert %{configured: true, running: true, state: "running", error: nil, skipped: 0} =
             Camera.status(id)

    assert Camera.url(id) == "/camera/#{id}.mjpg"
    assert %{codec: :mjpeg, video: "/video/" <> _} = Camera.info(id)
  end

  test "stopping the camera stops its program, even one that neither reads nor writes" do
    # a program that would outlive a closed port: it never writes (no SIGPIPE) nor reads stdin
    marker = "#{System.unique_integer([:positive])}"
    on_exit(fn -> System.cmd("pkill", ["-f", "^sleep 3#{marker}$"]) end)
    id = start!(sh("exec sleep 3#{marker}"))
    assert wait_until(fn -> os_pids("sleep 3#{marker}") != [] end)
    assert %{running: true, state: "starting"} = Camera.status(id)

    :ok = stop_supervised(id)

    assert wait_until(fn -> os_pids("sleep 3#{marker}") == [] end),
           "the camera program outlived the camera"
  end

  defp os_pids(pattern) do
    case System.cmd("pgrep", ["-f", "^#{pattern}$"]) do
      {out, 0} -> String.split(out)
      {_, _} -> []
    end
  end

  defp wait_until(fun, tries \\ div(Patience.ms(), 50)) do
    cond do
      fun.() -> true
      tries == 0 -> false
      true -> Process.sleep(50) && wait_until(fun, tries - 1)
    end
  end

  test "when the program exits the camera says why (its last words) and starts it again" do
    # (no stall check to race the exit on a saturated machine)
    id =
      start!(sh("cat #{@fixtures}/frame1.jpg; echo 'the lens cap is on' >&2; exit 3"),
        stall_ms: 600_000
      )

    assert_receive {:pubsub, _, "stream", %{generation: g}}
    assert %Frame{generation: ^g} = next_frame()

    assert_receive {:pubsub, _, "log", %{category: "errors", message: message}}
    assert message == "camera: the camera program exited (status 3): the lens cap is on"
    event = camera_event("restarting")
    assert event.reason =~ "lens cap"
    # until it starts again (after 1 s: perhaps already, on a busy machine) its status says why
    case Camera.status(id) do
      %{restarts: 0} = status ->
        assert %{running: false, state: "restarting", error: "the camera program exited" <> _} =
                 status

      status ->
        assert status.restarts == 1
    end

    # restarted after 1 s: a new stream (generation), a frame again
    assert_receive {:pubsub, _, "stream", %{generation: g2}}
    assert g2 > g
    assert %Frame{generation: ^g2, seq: 0} = next_frame()
    # counted once (the new program exits too, and is started again 2 s later: perhaps
    # already, so the count is read from what the camera said when it started again)
    assert_receive {:pubsub, _, "camera", %{state: "starting", restarts: 1}}
  end

  test "a port that ends with only its exit signal (a write that found the program gone) is an exit too" do
    # what the VM gets when an acknowledgement written as the program ends fails (epipe): the
    # port program's 'x' with the code, then the port's exit signal, no exit status
    marker = "#{System.unique_integer([:positive])}"
    on_exit(fn -> System.cmd("pkill", ["-f", "^sleep 4#{marker}$"]) end)
    id = start!(sh("echo 'no signal' >&2; exec sleep 4#{marker}"), stall_ms: 600_000)
    camera = GenServer.whereis(Neptunus.Fleet.via(Camera, id))
    assert wait_until(fn -> :sys.get_state(camera).errors == ["no signal"] end)
    port = :sys.get_state(camera).port

    send(camera, {port, {:data, <<?x, 7>>}})
    send(camera, {:EXIT, port, :epipe})

    assert camera_event("restarting").reason == "the camera program exited (status 7): no signal"
  end

  test "a missing program: failed, said so, never a crash" do
    id = start!(%{kind: :exec, codec: :mjpeg, program: "/nonexistent/camera", args: []})

    assert_receive {:pubsub, _, "log",
                    %{message: "camera: camera program /nonexistent/camera not found"}}

    assert %{running: false, configured: true, state: "failed"} = Camera.status(id)
    assert Camera.view(id).camera.state == "failed"
  end

  test "no camera configured: idle, no url" do
    id = start!(nil)
    assert %{configured: false, running: false} = Camera.status(id)
    assert Camera.url(id) == nil and Camera.info(id) == nil
    assert Camera.latest(id) == nil
    assert Camera.url("no-such-vehicle") == nil
    assert {:error, _} = Camera.pictures(id)
  end

  test "a camera that stalls is started again, saying so" do
    _id = start!(sh("cat #{@fixtures}/frame1.jpg; exec sleep 30"), stall_ms: 300)
    _ = next_frame()
    assert camera_event("restarting").reason == "no picture for 0.3 s"
    assert_receive {:pubsub, _, "log", %{message: "camera: no picture for 0.3 s"}}
  end

  test "a camera that never sends a picture is started again" do
    _id = start!(sh("exec sleep 30"), start_ms: 300)
    assert camera_event("restarting").reason == "no picture within 0.3 s of starting"
  end

  test "a camera that sends garbage is started again" do
    _id = start!(sh("exec cat /dev/urandom", :h264), start_ms: 500)
    assert camera_event("restarting").reason == "no picture within 0.5 s of starting"
  end

  test "an ffmpeg stream that is not FLV: the camera says so and starts again" do
    id =
      start!(
        %{kind: :v4l2, device: "/dev/garbage", codec: :h264, width: 320, height: 240, fps: 15},
        ffmpeg: @fake_ffmpeg
      )

    assert camera_event("restarting").reason =~ "the camera program's output is not FLV"
    assert %{state: "restarting"} = Camera.status(id)
  end

  describe "V4L2" do
    defp v4l2(name, codec \\ :auto),
      do: %{kind: :v4l2, device: "/dev/#{name}", codec: codec, width: 320, height: 240, fps: 15}

    test "a camera that offers H.264 is probed and its H.264 passed on" do
      id = start!(v4l2("c920"), ffmpeg: @fake_ffmpeg)
      assert_receive {:pubsub, _, "stream", %{codec: "h264", width: 320, source: "v4l2"}}
      frame = next_frame()
      assert frame.keyframe and String.starts_with?(Frame.payload(frame), <<0, 0, 0, 1, 0x67>>)
      # probed: the pages are told the codec it sends
      assert %{codec: :h264, url: nil} = Camera.info(id)
    end

    test "an MJPEG webcam's MJPEG; forced H.264 it lacks is refused with what it offers" do
      _id = start!(v4l2("webcam"), ffmpeg: @fake_ffmpeg)
      assert_receive {:pubsub, _, "stream", %{codec: "mjpeg", source: "v4l2"}}

      _id = start!(v4l2("webcam", :h264), ffmpeg: @fake_ffmpeg)
      # forced: no probe; the fake device then sends H.264 all the same
      assert_receive {:pubsub, _, "stream", %{codec: "h264"}}
    end

    test "a raw-only camera, a missing device: failed, saying why" do
      _id = start!(v4l2("raw"), ffmpeg: @fake_ffmpeg)
      event = camera_event("failed")
      assert event.reason =~ "offers neither H.264 nor MJPEG (only yuyv422, nv12)"

      _id = start!(v4l2("missing"), ffmpeg: @fake_ffmpeg)
      assert camera_event("failed").reason =~ "No such file or directory"
    end
  end

  describe "H.264 from an exec program (Annex B)" do
    setup do
      dir = Path.join(System.tmp_dir!(), "camtest-#{System.unique_integer([:positive])}")
      File.mkdir_p!(dir)
      on_exit(fn -> File.rm_rf!(dir) end)

      for {name, size} <- [{"small", "320x240"}, {"big", "640x480"}] do
        {_, 0} =
          System.cmd(
            "ffmpeg",
            ~w(-nostdin -loglevel error -f lavfi -i testsrc=size=#{size}:rate=15
            -frames:v 20 -c:v libx264 -preset ultrafast -tune zerolatency -pix_fmt yuv420p -g 15
            -bf 0 -f h264) ++ [Path.join(dir, "#{name}.h264")]
          )
      end

      {:ok, dir: dir}
    end

    test "a picture that changes size is a new generation, without a restart", %{dir: dir} do
      _id = start!(sh("cat #{dir}/small.h264 #{dir}/big.h264; exec sleep 30", :h264))
      assert_receive {:pubsub, _, "stream", %{width: 320, height: 240, generation: g}}
      assert_receive {:pubsub, _, "stream", %{width: 640, height: 480, generation: g2}}
      assert g2 == g + 1
      event = camera_event("running")
      event = if event.reason, do: event, else: camera_event("running")
      assert event.reason == "the picture changed from 320x240 to 640x480"
      assert event.restarts == 0
    end
  end

  describe "RTSP (a local RTSP server, ffmpeg its client as with an IP camera)" do
    setup do
      file = Path.join(System.tmp_dir!(), "rtsp-#{System.unique_integer([:positive])}.h264")

      {_, 0} =
        System.cmd(
          "ffmpeg",
          ~w(-nostdin -loglevel error -f lavfi -i testsrc=size=320x240:rate=15 -frames:v 30
             -c:v libx264 -preset ultrafast -tune zerolatency -pix_fmt yuv420p -g 15 -bf 0
             -f h264) ++ [file]
        )

      {nals, rest, 0} = H264.split(File.read!(file))
      File.rm!(file)

      {acc, aus} =
        Enum.reduce(nals ++ [H264.flush(rest)], {H264.AccessUnits.new(), []}, fn nal,
                                                                                 {acc, aus} ->
          case H264.AccessUnits.push(acc, nal) do
            {acc, nil} -> {acc, aus}
            {acc, au} -> {acc, [au | aus]}
          end
        end)

      {_, last} = H264.AccessUnits.flush(acc)

      aus =
        Enum.reverse([last | aus])
        |> Enum.map(fn au -> Enum.reject(au, &(H264.type(&1) == 9)) end)

      {:ok, server, port} = Neptunus.Test.RTSPServer.start(aus, 15)
      on_exit(fn -> if Process.alive?(server), do: Neptunus.Test.RTSPServer.stop(server) end)
      {:ok, server: server, url: "rtsp://user:secret@127.0.0.1:#{port}/stream"}
    end

    test "the camera's H.264 passed through; when the camera goes away, said and started again",
         %{server: server, url: url} do
      {:ok, source} = Source.parse(url)
      id = start!(source)

      assert_receive {:pubsub, _, "stream",
                      %{codec: "h264", width: 320, height: 240, source: "rtsp", avc: "avc1." <> _}}

      frames = for _ <- 1..20, do: next_frame()
      assert hd(frames).keyframe
      assert Enum.map(frames, & &1.seq) == Enum.to_list(hd(frames).seq..(hd(frames).seq + 19))
      assert Enum.count(frames, & &1.keyframe) >= 1

      Neptunus.Test.RTSPServer.stop(server)
      event = camera_event("restarting", 5_000 + Patience.ms())
      assert event.reason =~ "exited" or event.reason =~ "no picture"
      # the password never shows (ffmpeg names the URL in its errors)
      refute event.reason =~ "secret"
      assert Source.redact("#{url}: refused", source) =~ "user:***@"
      assert %{state: "restarting"} = Camera.status(id)
    end
  end

  describe "the simulated camera" do
    defp sim!(opts \\ []) do
      {:ok, source} = Source.parse("sim@384x216@10")
      start!(source, opts)
    end

    defp pose(changes) do
      Map.merge(
        Pose.new(
          %{x: 0, y: 0, z: 6, phi: 0, theta: -0.4, psi: 0, u: 0, v: 0, w: 0, p: 0, q: 0, r: 0},
          %{lights: 0, laser: 0, tilt: 0}
        ),
        Map.new(changes)
      )
    end

    # a keyframe after `pose` was published, decoded to grey levels (one byte per pixel)
    defp picture_at(id, pose) do
      PubSub.broadcast(Pose.topic(id), "pose", pose)
      # frames rendered before the pose arrived may still come: wait for the next keyframe
      # after a later one
      flush_frames()
      _ = next_frame()
      keyframe = wait_keyframe()
      {keyframe, decode(Frame.payload(keyframe))}
    end

    defp wait_keyframe do
      frame = next_frame()
      if frame.keyframe, do: frame, else: wait_keyframe()
    end

    defp flush_frames do
      receive do
        {:pubsub, _, "frame", _} -> flush_frames()
      after
        0 -> :ok
      end
    end

    # the first picture of `annexb`, decoded to raw pixels of `pix_fmt` (gray, rgb24)
    defp decode(annexb, pix_fmt \\ "gray") do
      file = Path.join(System.tmp_dir!(), "sim-#{System.unique_integer([:positive])}.h264")
      File.write!(file, annexb)

      {pixels, 0} =
        System.cmd(
          "ffmpeg",
          ~w(-nostdin -loglevel error -f h264 -i) ++
            [file] ++ ~w(-frames:v 1 -f rawvideo -pix_fmt #{pix_fmt} -)
        )

      File.rm(file)
      pixels
    end

    # the render time the picture shows in its corner (ms since the epoch, mod 2^48)
    defp time_code(grey, width) do
      import Bitwise

      Enum.reduce(0..47, 0, fn k, acc ->
        code = :binary.at(grey, 4 * width + 8 * k + 4)
        inverted = :binary.at(grey, 12 * width + 8 * k + 4)
        assert code > 128 != inverted > 128, "block #{k}: #{code} / #{inverted}"
        acc <<< 1 ||| if(code > 128, do: 1, else: 0)
      end)
    end

    defp mean(grey, from) do
      part = binary_part(grey, from, byte_size(grey) - from)
      Enum.sum(:binary.bin_to_list(part)) / byte_size(part)
    end

    test "idle until watched; renders H.264 with its render time in the corner and the header" do
      id = sim!()
      assert %{state: "idle", running: false} = Camera.status(id)
      assert %{camera: %{state: state}} = Camera.view(id)
      assert state in ["starting", "running"]

      assert_receive {:pubsub, _, "stream",
                      %{
                        codec: "h264",
                        width: 384,
                        height: 216,
                        fps: 10,
                        source: "sim",
                        avc: "avc1.42C0" <> _
                      }}

      {keyframe, grey} = picture_at(id, pose([]))
      assert byte_size(grey) == 384 * 216
      assert keyframe.data |> Frame.parse() |> elem(1) |> Map.fetch!(:capture_us) > 0
      {:ok, %{capture_us: capture_us, arrival_us: arrival_us}} = Frame.parse(keyframe.data)
      assert time_code(grey, 384) == rem(div(capture_us, 1000), Bitwise.bsl(1, 48))
      assert arrival_us >= capture_us
      assert H264.keyframe?(elem(H264.split(Frame.payload(keyframe) <> <<0, 0, 1>>), 0))
    end

    test "the picture follows the pose: a yaw changes it, the lights brighten it" do
      id = sim!()
      _ = Camera.view(id)
      # below the time code
      from = 384 * 20
      {_, a} = picture_at(id, pose(psi: 0.0))
      {_, b} = picture_at(id, pose(psi: 1.5))

      diff =
        Enum.zip(
          :binary.bin_to_list(binary_part(a, from, 384 * 150)),
          :binary.bin_to_list(binary_part(b, from, 384 * 150))
        )
        |> Enum.count(fn {x, y} -> abs(x - y) > 6 end)

      assert diff > 384 * 150 / 10, "a quarter turn changed only #{diff} pixels"

      {_, dark} = picture_at(id, pose(psi: 1.5, z: 9.0, lights: 0.0))
      {_, lit} = picture_at(id, pose(psi: 1.5, z: 9.0, lights: 1.0))
      assert mean(lit, from) > mean(dark, from) + 5
    end

    test "the laser shows as red dots on the seabed only while it is on" do
      id = sim!()
      _ = Camera.view(id)
      on = pose(z: 8.0, theta: -0.6, laser: 1.0)
      {keyframe, _} = picture_at(id, on)
      {keyframe_off, _} = picture_at(id, %{on | laser: 0.0})
      assert red_pixels(Frame.payload(keyframe)) > 4
      assert red_pixels(Frame.payload(keyframe_off)) == 0
    end

    defp red_pixels(annexb) do
      for <<r, g, b <- decode(annexb, "rgb24")>>, r > g + 50 and r > b + 50, reduce: 0 do
        n -> n + 1
      end
    end

    test "stops rendering when nobody watches any more" do
      id = sim!(linger_ms: 200)
      _ = Camera.view(id)
      _ = next_frame()
      PubSub.unsubscribe(Camera.topic(id))
      assert wait_until(fn -> Camera.status(id).state == "idle" end)
    end
  end
end
