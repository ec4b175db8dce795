defmodule Neptunus.Vehicle.RecorderDiskTest do
  # A node records video onto a small disk of its own (a 6 MiB tmpfs, mounted in a mount
  # namespace of the node's: `unshare`, no root needed where user namespaces are allowed)
  # with 3 MiB kept free: recording stops with a message before the disk is full, the vehicle
  # and the server go on, and the dive recorded so far stays whole and exports.
  use ExUnit.Case, async: true

  import Neptunus.Test.OSNode, only: [read_witness: 1]

  alias Neptunus.Dive
  alias Neptunus.Dive.Video
  alias Neptunus.Test.OSNode

  @moduletag :boot
  @moduletag :tmp_dir
  @moduletag timeout: 120_000

  # the witness: the vehicle's log entries, and its telemetry's recording state
  @script ~S"""
  id = "neptunus-1"

  spawn(fn ->
    {:ok, fd} = :file.open(System.fetch_env!("WITNESS"), [:raw, :write, :binary])
    :ok = Neptunus.PubSub.subscribe(Neptunus.Vehicle.Telemetry.log_topic(id))
    :ok = Neptunus.PubSub.subscribe(Neptunus.Vehicle.Telemetry.topic(id))

    Stream.repeatedly(fn ->
      receive do
        {:pubsub, _, "log", %{category: "errors", message: message}} ->
          :ok = :file.write(fd, "log #{message} #{System.os_time(:millisecond)}\n")

        {:pubsub, _, "telemetry", %{recording: %{on: on, error: error}}} ->
          :ok = :file.write(fd, "recording #{on}:#{error} #{System.os_time(:millisecond)}\n")

        _ ->
          :ok
      end
    end)
    |> Stream.run()
  end)

  IO.puts("PID #{System.pid()}")
  Process.sleep(:infinity)
  """

  setup do
    case System.cmd("unshare", ~w(--user --map-root-user --mount true), stderr_to_stdout: true) do
      {_, 0} -> :ok
      {out, _} -> flunk("this test needs user and mount namespaces (unshare): #{out}")
    end
  end

  test "a nearly full disk stops recording with a message; nothing else breaks, nothing recorded is touched",
       %{tmp_dir: dir} do
    recordings = Path.join(dir, "recordings")
    File.mkdir_p!(recordings)
    witness = Path.join(dir, "witness")
    mount = ~s(mount -t tmpfs -o size=6m tmpfs "$NEPTUNUS_RECORDINGS" && exec "$0" "$@")

    {port, http} =
      OSNode.start(
        @script,
        [
          {~c"NEPTUNUS_RECORDINGS", String.to_charlist(recordings)},
          {~c"NEPTUNUS_RECORDING_MIN_FREE_MB", ~c"3"},
          {~c"NEPTUNUS_CAMERAS", ~c"neptunus-1=testsrc@mjpeg@640x480@15"},
          {~c"WITNESS", String.to_charlist(witness)}
        ],
        {System.find_executable("unshare"), ~w(--user --map-root-user --mount sh -c) ++ [mount]}
      )

    os_pid = OSNode.await_pid(port)
    on_exit(fn -> System.cmd("kill", ["-9", os_pid], stderr_to_stdout: true) end)
    # the node's own view of its recordings (its tmpfs), from outside its mount namespace
    seen = "/proc/#{os_pid}/root" <> recordings

    OSNode.wait_for(
      fn ->
        Enum.any?(read_witness(witness), &match?({"log", "recording stopped" <> _, _}, &1))
      end,
      "stop recording"
    )

    lines = read_witness(witness)

    {"log", message, stopped_at} =
      Enum.find(lines, &match?({"log", "recording stopped" <> _, _}, &1))

    assert message =~ "disk nearly full"
    assert message =~ "NEPTUNUS_RECORDING_MIN_FREE_MB"

    # the disk was never full: what the reserve promised is still free
    free = Neptunus.Recording.free_bytes(seen)
    assert free != nil and free > 0

    # the vehicle goes on: its telemetry says it does not record, and why (the pages show it)
    OSNode.wait_for(
      fn ->
        Enum.any?(read_witness(witness), fn {kind, value, at} ->
          kind == "recording" and at > stopped_at and value =~ ~r/^false:.*disk nearly full/
        end)
      end,
      "say it does not record"
    )

    # the server goes on
    {:ok, {{_, 200, _}, _, _}} = :httpc.request(~c"http://127.0.0.1:#{http}/api/health")

    # the dive recorded so far is closed, whole, and exports
    assert [%{closed: true, video: %{codec: "mjpeg"}} = dive] = Dive.list(seen, "neptunus-1")
    assert dive.problems == []
    folder = Dive.path(seen, "neptunus-1", dive.name)
    segments = Video.segments(Dive.video_folder(folder))
    assert segments != [] and Enum.all?(segments, &(&1.problems == []))
    frames = segments |> Enum.map(&length(&1.frames)) |> Enum.sum()
    assert frames > 0

    {:ok, plan} = Dive.Export.plan(folder, "full", %{"format" => "mp4"})
    mp4 = Path.join(dir, "full.mp4")
    File.write!(mp4, Enum.to_list(Dive.Export.stream(plan)))

    {out, 0} =
      System.cmd(
        "ffprobe",
        ~w(-v error -count_frames -select_streams v:0 -show_entries
                                stream=nb_read_frames -of csv=p=0) ++ [mp4]
      )

    assert String.to_integer(String.trim(out)) == frames

    {_, 0} = System.cmd("kill", ["-9", os_pid])
    assert_receive {^port, {:exit_status, _}}, 10_000
  end
end
