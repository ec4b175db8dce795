defmodule Neptunus.Camera.V4L2Test do
  use ExUnit.Case, async: true

  alias Neptunus.Camera.V4L2

  doctest V4L2

  defp lines(name),
    do: "test/fixtures/camera/v4l2_#{name}.txt" |> File.read!() |> String.split("\n", trim: true)

  defp source(codec, w \\ 640, h \\ 480),
    do: %{kind: :v4l2, device: "/dev/video0", codec: codec, width: w, height: h, fps: 15}

  test "an H.264 UVC camera (captured ffmpeg output): its H.264, unless MJPEG is forced" do
    assert V4L2.decide(lines("c920"), source(:auto)) == {:ok, :h264}
    assert V4L2.decide(lines("c920"), source(:mjpeg)) == {:ok, :mjpeg}

    assert [%{codec: "yuyv422", compressed: false}, %{codec: "h264"}, %{codec: "mjpeg"}] =
             V4L2.formats(lines("c920"))
  end

  test "an MJPEG webcam: its MJPEG; H.264 forced is refused, saying what it offers" do
    assert V4L2.decide(lines("webcam"), source(:auto)) == {:ok, :mjpeg}

    assert V4L2.decide(lines("webcam"), source(:h264)) ==
             {:error, "/dev/video0 does not offer H.264 (it offers mjpeg, yuyv422)"}
  end

  test "a size the camera does not list is refused with the sizes it does" do
    assert {:error, reason} = V4L2.decide(lines("webcam"), source(:auto, 1024, 768))
    assert reason =~ "does not send MJPEG at 1024x768 (it does at 1920x1080 1280x720"
  end

  test "raw only (a range of sizes), a device that cannot be opened" do
    assert [%{codec: "yuyv422", sizes: :range}, %{codec: "nv12", sizes: :range}] =
             V4L2.formats(lines("raw"))

    assert {:error, "/dev/video0 offers neither H.264 nor MJPEG (only yuyv422, nv12)" <> _} =
             V4L2.decide(lines("raw"), source(:auto))

    assert V4L2.decide(lines("missing"), source(:auto)) ==
             {:error,
              "/dev/video0: no formats listed (ffmpeg: /dev/video9: No such file or directory)"}
  end
end
