defmodule Neptunus.Camera.SourceTest do
  use ExUnit.Case, async: true

  alias Neptunus.Camera.Source

  doctest Source

  test "parses every kind of source" do
    assert Source.parse("v4l2:/dev/video1@320x240") ==
             {:ok, %{kind: :v4l2, device: "/dev/video1", width: 320, height: 240, fps: 15}}

    assert Source.parse("v4l2:/dev/video1@5") ==
             {:ok, %{kind: :v4l2, device: "/dev/video1", width: 640, height: 480, fps: 5}}

    assert Source.parse("testsrc@800x600@25") ==
             {:ok, %{kind: :testsrc, width: 800, height: 600, fps: 25}}

    assert Source.parse("exec:/usr/bin/cam  --mjpeg -o -") ==
             {:ok, %{kind: :exec, program: "/usr/bin/cam", args: ["--mjpeg", "-o", "-"]}}
  end

  test "refuses what is not a source, saying what is" do
    for {text, message} <- [
          {"webcam", ~r/a camera source: v4l2:DEVICE/},
          {"v4l2:/dev/video0@0x480", ~r/WIDTHxHEIGHT, each 16..4096/},
          {"v4l2:/dev/video0@640x", ~r/WIDTHxHEIGHT/},
          {"v4l2:/dev/video0@120", ~r/frame rate is 1..60/},
          {"v4l2:/dev/video0@fast", ~r/frame rate is 1..60/},
          {"testsrcx", ~r/testsrc@WIDTHxHEIGHT@FPS/},
          {"exec:", ~r/needs a program/},
          {"exec:cam -o -", ~r/absolute path/}
        ] do
      assert {:error, reason} = Source.parse(text)
      assert reason =~ message, "#{text}: #{reason}"
    end
  end

  test "commands: ffmpeg for v4l2 (copying the camera's MJPEG) and testsrc, the program for exec" do
    {:ok, v4l2} = Source.parse("v4l2:/dev/video0@1280x720@30")
    {:ok, ffmpeg, args} = Source.command(v4l2, fn "ffmpeg" -> "/usr/bin/ffmpeg" end)
    assert ffmpeg == "/usr/bin/ffmpeg"

    assert Enum.join(args, " ") =~
             "-f v4l2 -input_format mjpeg -framerate 30 -video_size 1280x720 -i /dev/video0 -c:v copy -f mjpeg -"

    {:ok, test} = Source.parse("testsrc")
    {:ok, _, args} = Source.command(test, fn _ -> "/usr/bin/ffmpeg" end)
    assert "testsrc=size=640x480:rate=15" in args

    assert Source.command(test, fn _ -> nil end) ==
             {:error, "ffmpeg is not installed (apt install ffmpeg)"}

    assert Source.command(%{kind: :exec, program: "/bin/sh", args: ["x"]}) ==
             {:ok, "/bin/sh", ["x"]}

    assert {:error, "camera program /nope/cam not found"} =
             Source.command(%{kind: :exec, program: "/nope/cam", args: []})
  end
end
