defmodule Neptunus.Vehicle.RecorderKillTest do
  # A node that records is killed outright (SIGKILL to its OS process, as the kernel's OOM
  # killer or `kill -9` would): the recording on disk holds everything the vehicle broadcast
  # up to 0.25 s before the node's last broadcast, and reads back.
  use ExUnit.Case, async: true

  import Neptunus.Test.OSNode, only: [read_witness: 1]

  alias Neptunus.Test.OSNode

  alias Neptunus.Dive.Video
  alias Neptunus.Recording

  @moduletag :boot
  @moduletag :tmp_dir
  @moduletag timeout: 120_000
  @bound_ms 250

  # The node under test records its simulated vehicle. A witness process subscribed like the
  # recorder writes every broadcast it gets, with the wall clock, straight to a raw file (one
  # write(2) each, so the kernel has it when the node dies); a "mark" event goes out every
  # 700 ms, so telemetry mostly depends on the recorder's periodic sync.
  @script ~S"""
  topic = "vehicle:neptunus-1"

  spawn(fn ->
    {:ok, fd} = :file.open(System.fetch_env!("WITNESS"), [:raw, :write, :binary])
    :ok = Neptunus.PubSub.subscribe(topic)

    Stream.repeatedly(fn ->
      receive do
        {:pubsub, _, "telemetry", %{t: t}} ->
          :ok = :file.write(fd, "telemetry #{t} #{System.os_time(:millisecond)}\n")

        {:pubsub, _, "mark", %{n: n}} ->
          :ok = :file.write(fd, "mark #{n} #{System.os_time(:millisecond)}\n")

        _ ->
          :ok
      end
    end)
    |> Stream.run()
  end)

  spawn(fn ->
    Stream.iterate(1, &(&1 + 1))
    |> Enum.each(fn n ->
      Process.sleep(700)
      Neptunus.PubSub.broadcast(topic, "mark", %{n: n})
    end)
  end)

  IO.puts("PID #{System.pid()}")
  Process.sleep(:infinity)
  """

  test "kill -9 loses at most 0.25 s of telemetry and no event before that", %{tmp_dir: dir} do
    recordings = Path.join(dir, "recordings")
    witness = Path.join(dir, "witness")

    {port, _http} =
      OSNode.start(@script, [
        {~c"NEPTUNUS_RECORDINGS", String.to_charlist(recordings)},
        {~c"WITNESS", String.to_charlist(witness)}
      ])

    os_pid = OSNode.await_pid(port)
    # whatever happens to the test, the node goes
    on_exit(fn -> System.cmd("kill", ["-9", os_pid], stderr_to_stdout: true) end)

    # let it record a few seconds: at least 3 marks and 60 telemetry broadcasts witnessed
    OSNode.wait_for(
      fn ->
        lines = read_witness(witness)
        Enum.count(lines, &match?({"mark", _, _}, &1)) >= 3 and length(lines) >= 63
      end,
      "record"
    )

    {_, 0} = System.cmd("kill", ["-9", os_pid])
    assert_receive {^port, {:exit_status, status}}
    assert status != 0

    witnessed = read_witness(witness)
    [file] = Path.wildcard(Path.join([recordings, "neptunus-1", "*", "entries-*.log"]))
    # readable as it was left (repair on open), like Neptunus.Recording reads any recording
    recorded = file |> Recording.entries() |> Enum.to_list()

    newest = witnessed |> Enum.map(fn {_, _, at} -> at end) |> Enum.max()

    for kind <- ["telemetry", "mark"] do
      seen = for {^kind, value, at} <- witnessed, do: {value, at}
      on_disk = for {_, event, payload} <- recorded, event == kind, do: key(kind, payload)

      # what is on disk is what was broadcast, in order, with no hole ...
      seen_values = Enum.map(seen, &elem(&1, 0))
      from_first_seen = Enum.drop_while(on_disk, &(&1 != hd(seen_values)))
      assert from_first_seen == Enum.take(seen_values, length(from_first_seen))

      # ... up to at least 0.25 s before the node's last broadcast
      due = for {value, at} <- seen, at <= newest - @bound_ms, do: value

      missing = due -- from_first_seen

      assert missing == [],
             "#{kind} broadcast more than #{@bound_ms} ms before the kill is missing: " <>
               "#{inspect(missing)} (#{length(from_first_seen)} of #{length(seen)} on disk)"
    end
  end

  # The node under test records ffmpeg's test pattern as its camera (H.264, a keyframe a
  # second), its video writer cutting a segment at the first keyframe after 1 s. A witness
  # subscribed like the writer writes each frame's arrival time (the index's time) with the
  # wall clock when it got it.
  @video_script ~S"""
  id = "neptunus-1"
  recorder = GenServer.whereis(Neptunus.Fleet.via(Neptunus.Vehicle.Recorder, id))
  writer = :sys.get_state(recorder).video
  :sys.replace_state(writer, &%{&1 | segment_us: 1_000_000})

  spawn(fn ->
    {:ok, fd} = :file.open(System.fetch_env!("WITNESS"), [:raw, :write, :binary])
    :ok = Neptunus.PubSub.subscribe(Neptunus.Vehicle.Camera.record_topic(id))

    Stream.repeatedly(fn ->
      receive do
        {:pubsub, _, "frame", %{frame: frame}} ->
          {:ok, header} = Neptunus.Camera.Frame.parse(frame.data)
          line = "frame #{header.arrival_us} #{System.os_time(:millisecond)}\n"
          :ok = :file.write(fd, line)

        _ ->
          :ok
      end
    end)
    |> Stream.run()
  end)

  IO.puts("PID #{System.pid()}")
  Process.sleep(:infinity)
  """
  @video_bound_ms 1_000

  test "kill -9 loses at most 1 s of video; every segment before the cut plays, the dive lists and exports",
       %{tmp_dir: dir} do
    recordings = Path.join(dir, "recordings")
    witness = Path.join(dir, "witness")

    {port, _http} =
      OSNode.start(@video_script, [
        {~c"NEPTUNUS_RECORDINGS", String.to_charlist(recordings)},
        {~c"NEPTUNUS_CAMERAS", ~c"neptunus-1=testsrc@h264@160x120@15"},
        {~c"WITNESS", String.to_charlist(witness)}
      ])

    os_pid = OSNode.await_pid(port)
    on_exit(fn -> System.cmd("kill", ["-9", os_pid], stderr_to_stdout: true) end)

    # about 4 s of video witnessed (15 frames a second): three segments or more
    OSNode.wait_for(fn -> length(read_witness(witness)) >= 60 end, "record video")

    {_, 0} = System.cmd("kill", ["-9", os_pid])
    assert_receive {^port, {:exit_status, status}}, 10_000
    assert status != 0

    witnessed = read_witness(witness)
    newest = witnessed |> Enum.map(fn {_, _, at} -> at end) |> Enum.max()
    [folder] = Path.wildcard(Path.join([recordings, "neptunus-1", "*"]))
    segments = Video.segments(Neptunus.Dive.video_folder(folder))
    assert length(segments) >= 2, "expected the video cut into segments: #{inspect(segments)}"

    # what is on disk is what the camera sent, in order, from the first keyframe, no hole ...
    on_disk = for s <- segments, f <- s.frames, do: Integer.to_string(f.at_us)
    seen = for {"frame", arrival, at} <- witnessed, do: {arrival, at}
    seen_values = Enum.map(seen, &elem(&1, 0))

    # the witness subscribes once the node is up: the recorder may have written frames before
    # it, or the witness seen frames before the recorder's first keyframe; compared from the
    # first frame both have
    {on_disk_seen, from_first} =
      if hd(on_disk) in seen_values,
        do: {on_disk, Enum.drop_while(seen_values, &(&1 != hd(on_disk)))},
        else: {Enum.drop_while(on_disk, &(&1 != hd(seen_values))), seen_values}

    assert on_disk_seen != [], "no frame the witness saw is on disk"
    assert on_disk_seen == Enum.take(from_first, length(on_disk_seen))

    # ... up to at least 1 s before the node's last frame
    due =
      for {arrival, at} <- seen,
          at <= newest - @video_bound_ms,
          arrival in from_first,
          do: arrival

    missing = due -- on_disk

    assert missing == [],
           "video broadcast more than #{@video_bound_ms} ms before the kill is missing: " <>
             "#{length(missing)} frames (#{length(on_disk)} of #{length(seen)} on disk)"

    # every segment before the last is whole: ffmpeg decodes each of its frames; the last
    # decodes at least as far as its index goes
    {whole, [last]} = Enum.split(segments, -1)

    for s <- whole do
      assert s.problems == []
      assert decoded_frames(s.data) == length(s.frames), "segment #{s.n} does not play"
    end

    assert decoded_frames(last.data) >= length(last.frames)

    # the dive lists (its summary repaired at the next start, here by hand), and exports
    assert [%{video: %{codec: "h264"}} = listed] = Neptunus.Dive.list(recordings, "neptunus-1")
    assert listed.video.segments == length(segments)
    {:ok, plan} = Neptunus.Dive.Export.plan(folder, "killed", %{"format" => "mp4"})
    mp4 = Path.join(dir, "killed.mp4")
    File.write!(mp4, Enum.to_list(Neptunus.Dive.Export.stream(plan)))

    {out, 0} =
      System.cmd(
        "ffprobe",
        ~w(-v error -count_frames -select_streams v:0 -show_entries
                                stream=nb_read_frames -of csv=p=0) ++ [mp4]
      )

    assert String.to_integer(String.trim(out)) == length(on_disk)
  end

  defp decoded_frames(path) do
    {out, 0} =
      System.cmd(
        "ffprobe",
        ~w(-v error -f h264 -count_frames -select_streams v:0
                                -show_entries stream=nb_read_frames -of csv=p=0) ++ [path]
      )

    String.to_integer(String.trim(out))
  end

  # as the witness wrote them
  defp key("telemetry", %{t: t}), do: to_string(t)
  defp key("mark", %{n: n}), do: Integer.to_string(n)
end
