defmodule Neptunus.Vehicle.RecorderDiveTest do
  # The recorder's dives: the camera's frames written beside the entries, segments cut at
  # keyframes, a new dive after the helm was free long enough, snapshots recorded, a killed
  # dive's summary repaired, a video write that fails stopping the recording with a reason.
  use ExUnit.Case, async: true

  alias Neptunus.Camera.Frame
  alias Neptunus.{Dive, PubSub}
  alias Neptunus.Dive.Video
  alias Neptunus.Vehicle.{Camera, Recorder, Telemetry}

  @moduletag :tmp_dir
  @moduletag :capture_log

  defp start!(dir, opts \\ []) do
    id = "dive-#{System.unique_integer([:positive])}"
    recording = Keyword.merge([dir: dir], opts)
    start_supervised!({Recorder, id: id, recording: recording})
    _ = Recorder.status(id)
    id
  end

  defp frame(id, generation, seq, key, payload) do
    frame =
      Frame.new(:h264, payload,
        keyframe: key,
        generation: generation,
        seq: seq,
        arrival_us: Neptunus.Clock.wall_us(),
        capture_us: 7
      )

    PubSub.broadcast(Camera.record_topic(id), "frame", %{frame: frame})
    frame
  end

  # the recorder and its writer have handled everything sent before
  defp settle(id) do
    Recorder.sync(id)
    _ = Recorder.status(id)
  end

  test "the camera's frames go into the dive as received, from the first keyframe", %{
    tmp_dir: dir
  } do
    id = start!(dir)

    PubSub.broadcast(Camera.record_topic(id), "stream", %{
      codec: "h264",
      width: 640,
      height: 360,
      fps: 30,
      generation: 4,
      source: "sim",
      avc: "avc1.42c01e"
    })

    frame(id, 4, 0, false, "before any keyframe")

    sent =
      for {key, i} <- Enum.with_index([true, false, false, true, false]),
          do: frame(id, 4, i + 1, key, "picture #{i}")

    settle(id)

    %{folder: folder, video: %{frames: 5, segments: 1, codec: "h264"}} = Recorder.status(id)
    [segment] = Video.segments(Dive.video_folder(folder))
    assert segment.info["width"] == 640 and segment.info["generation"] == 4
    assert segment.info["first_seq"] == 1
    assert File.read!(segment.data) == Enum.map_join(sent, &Frame.payload/1)

    for {recorded, sent} <- Enum.zip(segment.frames, sent) do
      {:ok, header} = Frame.parse(sent.data)
      assert recorded.at_us == header.arrival_us and recorded.keyframe == sent.keyframe
      assert recorded.capture_us == 7
    end

    # a new stream (the camera restarted): a new segment from its first keyframe
    frame(id, 5, 0, false, "no keyframe yet")
    frame(id, 5, 1, true, "new stream")
    settle(id)

    assert [_, %{n: 2, frames: [%{keyframe: true}]} = second] =
             Video.segments(Dive.video_folder(folder))

    assert File.read!(second.data) == "new stream"

    # the dive's summary says it when it closes
    stop_supervised!(Recorder)
    assert [%{closed: true, video: %{codec: "h264", segments: 2}}] = Dive.list(dir, id)
    summary = read_json(Path.join(folder, "summary.json"))
    assert summary["video"]["frames"] == 6
  end

  defp read_json(path), do: path |> File.read!() |> Neptunus.JSON.decode() |> elem(1)

  test "a segment is cut at the first keyframe once it is long enough", %{tmp_dir: dir} do
    id = start!(dir, video: [segment_bytes: 10])
    frame(id, 1, 0, true, "0123456789abc")
    frame(id, 1, 1, false, "d")
    frame(id, 1, 2, true, "e")
    frame(id, 1, 3, false, "f")
    settle(id)
    %{folder: folder} = Recorder.status(id)

    assert [%{frames: [_, _]}, %{frames: [_, _]}] = Video.segments(Dive.video_folder(folder))
  end

  test "a pilot after the helm was free for the gap begins a new dive", %{tmp_dir: dir} do
    id = start!(dir, gap_ms: 1)
    topic = Telemetry.topic(id)
    piloted = %{state: "piloted", pilot: %{name: "ada"}}

    PubSub.broadcast(topic, "helm", piloted)
    PubSub.broadcast(topic, "telemetry", %{t: 1.0})
    PubSub.broadcast(topic, "helm", %{state: "free", pilot: nil})
    settle(id)
    %{dive: first} = Recorder.status(id)

    # the wall clock has moved past the gap (1 ms)
    now = System.os_time(:millisecond)
    wait_until(fn -> System.os_time(:millisecond) > now + 1 end)
    PubSub.broadcast(topic, "helm", %{piloted | pilot: %{name: "bo"}})
    PubSub.broadcast(topic, "telemetry", %{t: 2.0})
    settle(id)

    %{dive: second, dives: dives} = Recorder.status(id)
    assert second != first and dives == [first, second]

    [new, old] = Dive.list(dir, id)
    assert %{name: ^second, pilots: ["bo"], closed: false, telemetry: 1} = new
    assert %{name: ^first, pilots: ["ada"], closed: true, telemetry: 1} = old
  end

  test "a snapshot goes into the dive's folder and is recorded at its time", %{tmp_dir: dir} do
    id = start!(dir)
    folder = Recorder.dive_folder(id)
    assert folder == Recorder.status(id).folder

    :ok = Recorder.note(id, "snapshot", %{name: "x.jpg", depth: 1.5})
    settle(id)

    assert [{_, "snapshot", %{name: "x.jpg"}}] = folder |> Dive.entries() |> Enum.to_list()
    assert [%{snapshots: 1}] = Dive.list(dir, id)
  end

  test "a dive left unclosed by a killed node gets its summary again at the next start", %{
    tmp_dir: dir
  } do
    id = "dive-#{System.unique_integer([:positive])}"

    entries = [
      {1_000, "telemetry", %{estimate: %{depth: 4.0}}},
      {2_000, "stopped", %{reason: "x"}}
    ]

    killed =
      Neptunus.Test.Dives.write!(dir, id, "20260101-000000Z-1", entries, [],
        closed: false,
        summary: false
      )

    assert [%{closed: false, problems: ["no summary" <> _]}] = Dive.list(dir, id)

    start_supervised!({Recorder, id: id, recording: [dir: dir]})
    _ = Recorder.status(id)

    wait_until(fn ->
      Enum.any?(Dive.list(dir, id), &(&1.name == Path.basename(killed) and &1.closed))
    end)

    old = Enum.find(Dive.list(dir, id), &(&1.name == Path.basename(killed)))
    assert %{interrupted: true, max_depth: 4.0, stops: 1, entries: 2, problems: []} = old
  end

  test "a video write that fails stops recording and says why; what was written stays", %{
    tmp_dir: dir
  } do
    id = start!(dir)
    PubSub.subscribe(Telemetry.log_topic(id))
    frame(id, 1, 0, true, "kept")
    settle(id)
    %{folder: folder} = Recorder.status(id)
    video = Dive.video_folder(folder)

    # the segment file gone from under the writer (a disk pulled out): the next write fails
    [data] = Path.wildcard(Path.join(video, "*.h264"))
    %{video: %{frames: 1}} = Recorder.status(id)
    writer = :sys.get_state(GenServer.whereis(Neptunus.Fleet.via(Recorder, id))).video
    :sys.replace_state(writer, fn s -> %{s | segment: %{s.segment | data: :closed_fd}} end)
    frame(id, 1, 1, false, "lost")

    assert_receive {:pubsub, _, "log",
                    %{category: "errors", message: "recording stopped: writing video failed" <> _}},
                   5_000

    assert %{recording: false, error: "writing video failed" <> _} = Recorder.status(id)
    assert File.read!(data) == "kept"
    assert [%{closed: true}] = Dive.list(dir, id)
  end

  defp wait_until(fun, tries \\ 500) do
    cond do
      fun.() -> :ok
      tries == 0 -> flunk("condition not met")
      true -> Process.sleep(10) && wait_until(fun, tries - 1)
    end
  end
end
