defmodule Neptunus.Dive.ExportTest do
  # A dive's exports checked by real peers, not our own readers: ffprobe and ffmpeg read the
  # MP4 (its video's duration and frames, its subtitle cues against the telemetry they
  # show), the `mcap` package (PyPI, the project's .venv) reads the MCAP (message counts and
  # log times against the recording, CRCs). Damaged dives (a truncated segment, a torn
  # index, a missing video, a corrupt entry) still list and export what is readable and say
  # what is not.
  use ExUnit.Case, async: true

  alias Neptunus.Dive
  alias Neptunus.Dive.{Export, Replay, Video}
  alias Neptunus.Test.Dives

  @moduletag :tmp_dir
  @moduletag timeout: 180_000

  @vehicle "rov-x"
  @fps 15
  @frame_us div(1_000_000, @fps)
  @start_ms 1_795_000_000_000

  setup_all do
    # 3 s of a 15 fps camera, a keyframe every second
    %{aus: Dives.h264(45, fps: @fps, gop: 15)}
  end

  # telemetry at 20 Hz from 0.2 s before the video to 0.3 s after it, a pilot, a stop, a
  # log entry, a snapshot; the video from @start_ms
  defp dive!(dir, aus, opts \\ []) do
    frames =
      aus
      |> Enum.with_index()
      |> Enum.map(fn {au, i} -> {@start_ms * 1000 + i * @frame_us, Dives.keyframe?(au), au} end)

    entries =
      (Dives.telemetry(@start_ms - 200, 70) ++
         [
           {@start_ms + 500, "helm",
            %{state: "piloted", pilot: %{name: "ada", id: "c1", role: "pilot"}}},
           {@start_ms + 1_500, "stopped", %{reason: "deadman"}},
           {@start_ms + 1_600, "log",
            %{category: "safety", level: "warning", message: "deadman", at: 0}},
           {@start_ms + 2_000, "snapshot", %{name: "x.jpg", depth: 0.2, heading: 0.1}}
         ])
      |> Enum.sort_by(&elem(&1, 0))

    name = Keyword.get(opts, :name, "20261118-110640Z-1")
    opts = Keyword.merge([started_at: @start_ms - 200], opts)
    path = Dives.write!(dir, @vehicle, name, entries, frames, opts)
    {path, entries, frames}
  end

  defp export!(path, format, dir, options \\ %{}) do
    {:ok, plan} = Export.plan(path, "label", Map.put(options, "format", format))
    out = Path.join(dir, "export.#{format}")
    File.write!(out, Enum.to_list(Export.stream(plan)))
    out
  end

  defp ffprobe!(args) do
    {out, 0} = System.cmd("ffprobe", ~w(-v error -of json) ++ args)
    :jiffy.decode(out, [:return_maps])
  end

  test "MP4: the video copied with its recorded times, the telemetry as subtitles within 50 ms",
       %{tmp_dir: dir, aus: aus} do
    {path, entries, frames} = dive!(dir, aus, segment_frames: 10)
    assert length(Video.numbers(Dive.video_folder(path))) == 3
    mp4 = export!(path, "mp4", dir)

    %{"streams" => streams, "format" => format} =
      ffprobe!(["-count_frames", "-show_streams", "-show_format", mp4])

    [video] = for s <- streams, s["codec_type"] == "video", do: s
    [subs] = for s <- streams, s["codec_type"] == "subtitle", do: s
    assert video["codec_name"] == "h264" and video["width"] == 160
    assert subs["codec_name"] == "mov_text"
    assert String.to_integer(video["nb_read_frames"]) == length(frames)
    assert format["format_name"] =~ "mp4"

    # the recorded video lasts from its first frame to one frame after its last
    {first, _, _} = hd(frames)
    {last, _, _} = List.last(frames)
    recorded_s = (last - first + @frame_us) / 1_000_000
    assert_in_delta String.to_float(video["duration"]), recorded_s, @frame_us / 1_000_000

    # every cue as ffmpeg reads it back (SRT) shows the telemetry of its own time, ±50 ms
    cues = srt_cues(mp4)
    assert length(cues) >= 10
    telemetry = for {at, "telemetry", p} <- entries, at >= div(first, 1000), do: {at, p}

    for {start_ms, text} <- cues do
      at = div(first, 1000) + start_ms
      {t_at, payload} = Enum.min_by(telemetry, fn {t, _} -> abs(t - at) end)
      assert abs(t_at - at) <= 50, "cue at #{start_ms} ms is #{t_at - at} ms off its telemetry"
      depth = :erlang.float_to_binary(payload.estimate.depth * 1.0, decimals: 2)
      assert text =~ "depth #{depth} m", "#{inspect(text)} does not show depth #{depth}"
    end

    # the pilot and the stops as they were at each cue
    assert Enum.any?(cues, fn {_, text} -> text =~ "pilot ada  stops 1" end)
    assert {_, first_text} = hd(cues)
    assert first_text =~ "pilot none  stops 0"
  end

  test "MP4 of an MJPEG camera, and its .ass beside", %{tmp_dir: dir} do
    jpegs = Dives.jpegs(10)

    frames =
      for {jpeg, i} <- Enum.with_index(jpegs), do: {@start_ms * 1000 + i * @frame_us, true, jpeg}

    path =
      Dives.write!(dir, @vehicle, "20261118-110640Z-2", Dives.telemetry(@start_ms, 20), frames,
        codec: "mjpeg"
      )

    mp4 = export!(path, "mp4", dir)
    %{"streams" => streams} = ffprobe!(["-count_frames", "-show_streams", mp4])
    [video] = for s <- streams, s["codec_type"] == "video", do: s
    assert video["codec_name"] == "mjpeg"
    assert String.to_integer(video["nb_read_frames"]) == 10

    ass = path |> export!("ass", dir) |> File.read!()
    assert ass =~ "[Script Info]"

    {out, 0} =
      System.cmd(
        "ffprobe",
        ~w(-v error -show_entries stream=codec_name -of csv=p=0) ++ [Path.join(dir, "export.ass")]
      )

    assert String.trim(out) == "ass"
    assert length(Regex.scan(~r/^Dialogue:/m, ass)) >= 4
  end

  test "MCAP: the mcap reader finds every entry and frame at its recorded time", %{
    tmp_dir: dir,
    aus: aus
  } do
    {path, entries, frames} = dive!(dir, aus, segment_frames: 10)
    schema = %{type: "object", title: "neptunus.Telemetry"}

    mcap =
      export!(path, "mcap", dir, %{"schemas" => %{"telemetry" => schema}, "chunk_bytes" => 4096})

    read = Dives.mcap_read!(mcap)

    ns = fn ms -> ms * 1_000_000 end
    telemetry = for {at, "telemetry", _} <- entries, do: ns.(at)
    events = for {at, e, _} <- entries, e not in ["telemetry", "log"], do: ns.(at)
    logs = for {at, "log", _} <- entries, do: ns.(at)
    video = for {at_us, _, _} <- frames, do: at_us * 1000

    topics = read["topics"]
    assert topics["/vehicle/telemetry"]["times"] == telemetry
    assert topics["/vehicle/events"]["times"] == events
    assert topics["/vehicle/log"]["times"] == logs
    assert topics["/camera"]["times"] == video
    assert topics["/camera"]["schema"] == "foxglove.CompressedVideo"
    assert topics["/vehicle/log"]["schema"] == "foxglove.Log"
    assert topics["/vehicle/telemetry"]["encoding"] == "jsonschema"

    total = length(entries) + length(frames)
    assert read["statistics"]["messages"] == total
    assert read["statistics"]["channels"]["/camera"] == length(frames)
    assert Enum.sum(Map.values(read["linear"])) == total

    keyframes = Enum.count(frames, fn {_, key, _} -> key end)

    assert %{"annexb" => true, "keyframes" => ^keyframes, "keyframes_with_sps" => ^keyframes} =
             read["video"]

    assert read["video"]["bytes"] == Enum.sum(Enum.map(frames, fn {_, _, p} -> byte_size(p) end))
    assert %{"neptunus.dive" => %{"pilots" => "ada", "stops" => "1"}} = read["metadata"]
  end

  test "MCAP, CSV and JSON lines of a dive without video", %{tmp_dir: dir} do
    entries =
      Dives.telemetry(@start_ms, 40) ++ [{@start_ms + 5_000, "stopped", %{reason: "pilot_stop"}}]

    path = Dives.write!(dir, @vehicle, "20261118-110640Z-3", entries, [])

    read = path |> export!("mcap", dir) |> Dives.mcap_read!()
    assert read["topics"]["/vehicle/telemetry"]["count"] == 40
    refute Map.has_key?(read["topics"], "/camera")

    csv = path |> export!("csv", dir) |> File.read!() |> String.split("\n", trim: true)
    assert length(csv) == 41
    assert hd(csv) =~ "time,"

    jsonl = path |> export!("jsonl", dir) |> File.read!() |> String.split("\n", trim: true)
    assert length(jsonl) == 41

    assert {:error, :conflict, "this dive has no video" <> _} =
             Export.plan(path, "x", %{"format" => "mp4"})

    assert {:error, :invalid, "format must be one of csv, jsonl, ass, mp4, mcap" <> _} =
             Export.plan(path, "x", %{"format" => "avi"})
  end

  test "a truncated segment and a torn index: listed with what is wrong, the rest exported", %{
    tmp_dir: dir,
    aus: aus
  } do
    {path, _entries, frames} = dive!(dir, aus, segment_frames: 10)
    folder = Dive.video_folder(path)
    [_, second, third] = Video.segments(folder)

    # the second segment's data cut inside its 5th frame, the third's index inside a record
    cut = Enum.at(second.frames, 4)
    {:ok, fd} = :file.open(second.data, [:read, :write, :raw])
    :ok = :file.position(fd, cut.offset + 3) |> elem(0)
    :ok = :file.truncate(fd)
    :file.close(fd)
    index_size = File.stat!(third.index).size
    {:ok, fd} = :file.open(third.index, [:read, :write, :raw])
    {:ok, _} = :file.position(fd, index_size - 7)
    :ok = :file.truncate(fd)
    :file.close(fd)

    video = Replay.video(path)
    lost = length(second.frames) - 4 + 1

    assert Enum.any?(
             video.problems,
             &(&1 =~ "segment 2: #{lost - 1} frames not (all) in 000002.h264")
           ) or
             Enum.any?(
               video.problems,
               &(&1 =~ "segment 2: #{lost} frames not (all) in 000002.h264")
             )

    assert Enum.any?(video.problems, &(&1 =~ "segment 3: a torn index record"))
    kept = Enum.sum(Enum.map(video.segments, & &1.frames))
    assert kept < length(frames) and kept >= length(frames) - lost - 1

    mp4 = export!(path, "mp4", dir)
    %{"streams" => streams} = ffprobe!(["-count_frames", "-show_streams", mp4])
    [v] = for s <- streams, s["codec_type"] == "video", do: s
    assert String.to_integer(v["nb_read_frames"]) == kept

    read = path |> export!("mcap", dir) |> Dives.mcap_read!()
    assert read["topics"]["/camera"]["count"] == kept
  end

  test "a missing video and a corrupt entry: the dive lists, says so, and exports the rest", %{
    tmp_dir: dir,
    aus: aus
  } do
    {path, entries, _frames} = dive!(dir, aus)
    File.rm_rf!(Dive.video_folder(path))

    # bytes of the entries' file overwritten in the middle
    part = Path.join(path, Dive.part_name(1))
    size = File.stat!(part).size
    {:ok, fd} = :file.open(part, [:read, :write, :raw, :binary])
    :ok = :file.pwrite(fd, div(size, 2), :binary.copy(<<0xAB>>, 200))
    :file.close(fd)

    info = Dive.info(dir, @vehicle, Path.basename(path))
    assert Enum.any?(info.problems, &(&1 =~ "the video is missing (45 frames were recorded)"))
    assert info.video == nil

    read = Enum.to_list(Dive.read(path))

    assert Enum.any?(
             read,
             &match?({:unreadable, ^part, bytes} when is_integer(bytes) and bytes > 0, &1)
           )

    kept = Enum.count(read, &(tuple_size(&1) == 3 and is_integer(elem(&1, 0))))
    assert kept > length(entries) / 2 and kept < length(entries)

    mcap = path |> export!("mcap", dir) |> Dives.mcap_read!()
    assert mcap["statistics"]["messages"] == kept

    assert :ok = Dive.repair(path)

    assert %{interrupted: true, problems: problems} =
             Dive.info(dir, @vehicle, Path.basename(path))

    assert Enum.any?(problems, &(&1 =~ "entries-0001.log: " and &1 =~ "bytes are not entries"))
  end

  test "a recording from before dives lists, reads and exports as a dive", %{tmp_dir: dir} do
    name = "20200101-000000Z-1.log"
    path = Path.join([dir, @vehicle, name])
    File.mkdir_p!(Path.dirname(path))
    {:ok, log} = :disk_log.open(name: {__MODULE__, make_ref()}, file: String.to_charlist(path))
    :ok = :disk_log.log_terms(log, Dives.telemetry(@start_ms, 10))
    :ok = :disk_log.close(log)

    assert [%{name: ^name, legacy: true, video: nil, started_at: 1_577_836_800_000}] =
             Dive.list(dir, @vehicle)

    assert path |> Dive.entries() |> Enum.count() == 10
    read = path |> export!("mcap", dir) |> Dives.mcap_read!()
    assert read["topics"]["/vehicle/telemetry"]["count"] == 10

    assert {:error, :conflict, _} = Dive.put_notes(path, %{"title" => "x"}, "ada", 0)
  end

  test "title and notes: saved beside the dive, checked, the recorded files untouched", %{
    tmp_dir: dir,
    aus: aus
  } do
    {path, _, _} = dive!(dir, Enum.take(aus, 15))

    before =
      for f <- Path.wildcard(Path.join(path, "**/*")), File.regular?(f), do: {f, File.read!(f)}

    assert {:ok, %{title: "Wreck survey", notes: "north side\nvisibility 3 m", edited_by: "ada"}} =
             Dive.put_notes(
               path,
               %{"title" => " Wreck survey ", "notes" => "north side\nvisibility 3 m"},
               "ada",
               1
             )

    assert {:ok, %{title: "Wreck survey", notes: nil}} =
             Dive.put_notes(path, %{"notes" => nil}, "bo", 2)

    assert {:error, :invalid, "title must not contain control characters" <> _} =
             Dive.put_notes(path, %{"title" => "a\nb"}, "ada", 3)

    assert {:error, :invalid, "title must be at most 200 characters"} =
             Dive.put_notes(path, %{"title" => String.duplicate("x", 201)}, "ada", 3)

    assert {:error, :invalid, "notes must be a string or null, got 5"} =
             Dive.put_notes(path, %{"notes" => 5}, "ada", 3)

    assert %{title: "Wreck survey", notes: nil} = Dive.info(dir, @vehicle, Path.basename(path))

    for {f, bytes} <- before, do: assert(File.read!(f) == bytes, "#{f} changed")
  end

  test "replay frames: from the keyframe before the window, in the video socket's format", %{
    tmp_dir: dir,
    aus: aus
  } do
    {path, _, frames} = dive!(dir, aus, segment_frames: 10)
    # a window inside the second second: frames from its keyframe (frame 15) on
    from_ms = @start_ms + 1_300
    to_ms = @start_ms + 1_700
    bytes = path |> Replay.frames(from_ms, to_ms) |> Enum.to_list() |> IO.iodata_to_binary()
    got = parse_frames(bytes)

    expected =
      frames
      |> Enum.with_index()
      |> Enum.filter(fn {{at, _, _}, i} -> i >= 15 and at <= to_ms * 1000 end)

    assert length(got) == length(expected)

    for {{header, {{at, key, payload}, _i}}} <- Enum.zip([Enum.zip(got, expected)]) do
      assert header.arrival_us == at and header.keyframe == key and header.payload == payload
    end

    assert hd(got).keyframe
    assert {:error, :invalid, "a window is at most 120 s"} = Replay.window("0", "200000")
    assert {:error, :invalid, "from must be a time" <> _} = Replay.window("x", "1")
  end

  defp parse_frames(<<>>), do: []

  defp parse_frames(<<len::32, frame::binary-size(len), rest::binary>>) do
    {:ok, header} = Neptunus.Camera.Frame.parse(frame)
    [header | parse_frames(rest)]
  end

  # the subtitles as ffmpeg decodes them: [{start_ms, text}]
  defp srt_cues(mp4) do
    {srt, 0} = System.cmd("ffmpeg", ~w(-v error -i) ++ [mp4] ++ ~w(-map 0:s -f srt -))

    srt
    |> String.split(~r/\r?\n\r?\n/, trim: true)
    |> Enum.map(fn block ->
      [_n, times | text] = String.split(block, ~r/\r?\n/)
      [[_, h, m, s, ms]] = Regex.scan(~r/^(\d+):(\d+):(\d+),(\d+)/, times)

      start =
        ((String.to_integer(h) * 60 + String.to_integer(m)) * 60 + String.to_integer(s)) * 1000 +
          String.to_integer(ms)

      {start, text |> Enum.join(" ") |> String.replace(~r/<[^>]*>/, "")}
    end)
  end
end
