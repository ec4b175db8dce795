defmodule Neptunus.Vehicle.CameraTest do
  use ExUnit.Case, async: true

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.{Camera, Telemetry}

  @moduletag :capture_log

  @script Path.expand("../../fixtures/camera/fake_camera.sh", __DIR__)
  @frame1 File.read!("test/fixtures/camera/frame1.jpg")
  @frame2 File.read!("test/fixtures/camera/frame2.jpg")

  defp start!(source) do
    id = "cam-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Camera.topic(id))
    PubSub.subscribe(Telemetry.log_topic(id))
    start_supervised!({Camera, id: id, camera: source})
    id
  end

  defp fake(count), do: %{kind: :exec, program: "/bin/sh", args: [@script, "#{count}"]}

  test "frames from the camera program reach subscribers whole, in order" do
    id = start!(fake(0))
    assert_receive {:pubsub, _, "frame", %{jpeg: first}}
    assert first in [@frame1, @frame2]
    assert_receive {:pubsub, _, "frame", %{jpeg: second}}
    assert Enum.sort([first, second]) == Enum.sort([@frame1, @frame2])

    assert Camera.latest(id) in [@frame1, @frame2]

    assert %{configured: true, running: true, error: nil, skipped: 0, frames: n} =
             Camera.status(id)

    assert n >= 2
    assert Camera.url(id) == "/camera/#{id}.mjpg"
  end

  test "stopping the camera stops its program, even one that neither reads nor writes" do
    # a program that would outlive a closed port: it never writes (no SIGPIPE) nor reads stdin
    marker = "#{System.unique_integer([:positive])}"
    on_exit(fn -> System.cmd("pkill", ["-f", "^sleep 3#{marker}$"]) end)
    id = start!(%{kind: :exec, program: "/bin/sh", args: ["-c", "exec sleep 3#{marker}"]})
    assert wait_until(fn -> os_pids("sleep 3#{marker}") != [] end)
    assert %{running: true} = Camera.status(id)

    :ok = stop_supervised(Camera)

    assert wait_until(fn -> os_pids("sleep 3#{marker}") == [] end),
           "the camera program outlived the camera"
  end

  defp os_pids(pattern) do
    case System.cmd("pgrep", ["-f", "^#{pattern}$"]) do
      {out, 0} -> String.split(out)
      {_, _} -> []
    end
  end

  defp wait_until(fun, tries \\ div(Neptunus.Test.Patience.ms(), 50)) do
    cond do
      fun.() -> true
      tries == 0 -> false
      true -> Process.sleep(50) && wait_until(fun, tries - 1)
    end
  end

  test "when the program exits the camera says why and starts it again" do
    id = start!(fake(1))
    assert_receive {:pubsub, _, "frame", _}

    assert_receive {:pubsub, _, "log",
                    %{category: "errors", message: "camera: the camera program exited (status 0)"}}

    assert %{running: false, error: "the camera program exited (status 0)"} = Camera.status(id)
    # restarted after 1 s: frames again
    flush_frames()
    assert_receive {:pubsub, _, "frame", _}
    assert %{running: true, restarts: 1} = Camera.status(id)
  end

  test "a missing program is reported, never a crash" do
    id = start!(%{kind: :exec, program: "/nonexistent/camera", args: []})

    assert_receive {:pubsub, _, "log",
                    %{message: "camera: camera program /nonexistent/camera not found"}}

    assert %{running: false, configured: true} = Camera.status(id)
  end

  test "no camera configured: idle, no url" do
    id = start!(nil)
    assert %{configured: false, running: false} = Camera.status(id)
    assert Camera.url(id) == nil
    assert Camera.latest(id) == nil
    assert Camera.url("no-such-vehicle") == nil
  end

  test "stopping the camera stops its program" do
    id = start!(fake(0))
    assert_receive {:pubsub, _, "frame", _}
    {:os_pid, os_pid} = Port.info(:sys.get_state(Neptunus.Fleet.via(Camera, id)).port, :os_pid)
    stop_supervised!(Camera)
    # the shell gets EOF/SIGPIPE on its next write and exits
    assert Enum.any?(1..50, fn _ ->
             Process.sleep(20)
             not File.exists?("/proc/#{os_pid}")
           end)
  end

  defp flush_frames do
    receive do
      {:pubsub, _, "frame", _} -> flush_frames()
    after
      0 -> :ok
    end
  end
end
