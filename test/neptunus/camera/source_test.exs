defmodule Neptunus.Camera.SourceTest do
  use ExUnit.Case, async: true

  alias Neptunus.Camera.Source

  doctest Source

  @tools %{ffmpeg: "/usr/bin/ffmpeg", camera: "/priv/neptunus_camera"}

  test "parses every kind of source" do
    assert Source.parse("v4l2:/dev/video1@320x240") ==
             {:ok,
              %{
                kind: :v4l2,
                device: "/dev/video1",
                codec: :auto,
                width: 320,
                height: 240,
                fps: 15
              }}

    assert Source.parse("v4l2:/dev/video1@h264@5") ==
             {:ok,
              %{kind: :v4l2, device: "/dev/video1", codec: :h264, width: 640, height: 480, fps: 5}}

    assert {:ok, %{codec: :mjpeg, width: 1280}} = Source.parse("v4l2:/dev/video0@1280x720@mjpeg")

    assert Source.parse("testsrc@800x600@25") ==
             {:ok, %{kind: :testsrc, codec: :mjpeg, width: 800, height: 600, fps: 25}}

    assert {:ok, %{kind: :testsrc, codec: :h264}} = Source.parse("testsrc@h264")

    assert Source.parse("sim@mjpeg@1280x720@25@bottom=30") ==
             {:ok, %{kind: :sim, codec: :mjpeg, width: 1280, height: 720, fps: 25, bottom: 30.0}}

    assert Source.parse("rtsp://admin:pw@10.0.0.5:554/stream?x=1") ==
             {:ok, %{kind: :rtsp, url: "rtsp://admin:pw@10.0.0.5:554/stream?x=1"}}

    assert Source.parse("exec:/usr/bin/cam  --mjpeg -o -") ==
             {:ok,
              %{kind: :exec, codec: :mjpeg, program: "/usr/bin/cam", args: ["--mjpeg", "-o", "-"]}}

    assert Source.parse("exec@h264:/usr/bin/libcamera-vid -o -") ==
             {:ok,
              %{kind: :exec, codec: :h264, program: "/usr/bin/libcamera-vid", args: ["-o", "-"]}}
  end

  test "refuses what is not a source, saying what is" do
    for {text, message} <- [
          {"webcam", ~r/a camera source: v4l2:DEVICE/},
          {"v4l2:/dev/video0@0x480", ~r/WIDTHxHEIGHT, each 16..4096/},
          {"v4l2:/dev/video0@640x", ~r/WIDTHxHEIGHT/},
          {"v4l2:/dev/video0@120", ~r/frame rate is 1..60/},
          {"v4l2:/dev/video0@fast", ~r/unknown camera option "fast"/},
          {"v4l2:/dev/video0@bottom=3", ~r/unknown camera option/},
          {"testsrcx", ~r/testsrc@OPTION/},
          {"sim@320x240", ~r/at least 384 pixels wide/},
          {"sim@641x360", ~r/even/},
          {"sim@bottom=0.5", ~r/bottom is a depth in m, 1..1000/},
          {"sim@bottom=deep", ~r/bottom is a depth/},
          {"rtsp://", ~r/rtsp:\/\/192.168/},
          {"exec:", ~r/needs a program/},
          {"exec:cam -o -", ~r/absolute path/}
        ] do
      assert {:error, reason} = Source.parse(text)
      assert reason =~ message, "#{text}: #{reason}"
    end
  end

  defp command!(text) do
    {:ok, source} = Source.parse(text)
    {:ok, command} = Source.command(source, @tools)
    command
  end

  test "V4L2: the camera's own codec copied, never re-encoded; H.264 in FLV" do
    %{
      executable: "/priv/neptunus_camera",
      args: ["run", "--", "/usr/bin/ffmpeg" | args],
      format: :flv
    } = command!("v4l2:/dev/video0@h264@1280x720@30")

    line = Enum.join(args, " ")

    assert line =~
             "-f v4l2 -input_format h264 -framerate 30 -video_size 1280x720 -i /dev/video0 -c:v copy -f flv"

    refute line =~ "libx264"

    %{args: args, format: :mjpeg} = command!("v4l2:/dev/video0@mjpeg")

    assert Enum.join(args, " ") =~
             "-input_format mjpeg -framerate 15 -video_size 640x480 -i /dev/video0 -c:v copy -f mjpeg"

    # not probed yet: the probe first
    {:ok, auto} = Source.parse("v4l2:/dev/video2")
    assert {:error, "the camera's codec is not known yet" <> _} = Source.command(auto, @tools)
    {:ok, %{args: ["run", "--", "/usr/bin/ffmpeg" | args]}} = Source.probe_command(auto, @tools)
    assert Enum.join(args, " ") =~ "-f v4l2 -list_formats all -i /dev/video2"
  end

  test "RTSP: H.264 passed through over TCP, audio left out" do
    %{args: ["run", "--", "/usr/bin/ffmpeg" | args], format: :flv} =
      command!("rtsp://10.0.0.5/stream")

    line = Enum.join(args, " ")
    assert line =~ "-rtsp_transport tcp -timeout 5000000 -i rtsp://10.0.0.5/stream"
    assert line =~ "-map 0:v:0 -c:v copy -an -f flv"
  end

  test "sim: the renderer feeds ffmpeg raw pictures, x264 for a browser at the live edge" do
    %{args: args, format: :flv} = command!("sim@640x360@30@bottom=25")
    assert ["sim", "640", "360", "30", "25.00", "--", "/usr/bin/ffmpeg" | ffmpeg] = args
    line = Enum.join(ffmpeg, " ")
    assert line =~ "-f rawvideo -pix_fmt yuv420p -video_size 640x360 -framerate 30 -i pipe:0"

    assert line =~
             "-c:v libx264 -preset ultrafast -tune zerolatency -profile:v baseline -pix_fmt yuv420p -g 30 -keyint_min 30 -sc_threshold 0 -bf 0"

    assert List.last(ffmpeg) == "pipe:1"
    %{format: :mjpeg, args: args} = command!("sim@mjpeg")
    assert Enum.join(args, " ") =~ "-c:v mjpeg"
  end

  test "testsrc: MJPEG by default, H.264 when asked" do
    %{args: args, format: :mjpeg} = command!("testsrc")
    assert "testsrc=size=640x480:rate=15" in args
    %{args: args, format: :flv} = command!("testsrc@h264@320x240@10")
    assert "testsrc=size=320x240:rate=10" in args
    assert Enum.join(args, " ") =~ "libx264"
  end

  test "exec: the program itself through the port program; Annex B for H.264" do
    assert Source.command(%{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: ["x"]}, @tools) ==
             {:ok,
              %{
                executable: "/priv/neptunus_camera",
                args: ["run", "--", "/bin/sh", "x"],
                format: :mjpeg
              }}

    assert {:ok, %{format: :annexb}} =
             Source.command(%{kind: :exec, codec: :h264, program: "/bin/sh", args: []}, @tools)

    assert {:error, "camera program /nope/cam not found"} =
             Source.command(%{kind: :exec, codec: :mjpeg, program: "/nope/cam", args: []}, @tools)
  end

  test "without ffmpeg: a reason, for every source that needs it" do
    for text <- ["testsrc", "sim", "rtsp://x/y", "v4l2:/dev/video0@h264"] do
      {:ok, source} = Source.parse(text)

      assert {:error, "ffmpeg is not installed" <> _} =
               Source.command(source, %{@tools | ffmpeg: nil})
    end

    {:ok, auto} = Source.parse("v4l2:/dev/video0")

    assert {:error, "ffmpeg is not installed" <> _} =
             Source.probe_command(auto, %{@tools | ffmpeg: nil})
  end

  test "described without secrets" do
    {:ok, rtsp} = Source.parse("rtsp://admin:secret@cam.local/live")
    refute Source.describe(rtsp) =~ "secret"
    {:ok, v4l2} = Source.parse("v4l2:/dev/video0@h264")
    assert Source.describe(v4l2) == "v4l2:/dev/video0@h264@640x480@15"
    assert Source.fps(rtsp) == nil and Source.codec(rtsp) == :h264
  end
end
