defmodule Neptunus.Vehicle.RecorderTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Dive, PubSub, Recording}
  alias Neptunus.Vehicle.{Recorder, Telemetry}

  @moduletag :tmp_dir
  @moduletag :capture_log

  defp start!(dir, opts \\ []) do
    id = "rec-#{System.unique_integer([:positive])}"
    recording = Keyword.merge([dir: dir], opts)
    start_supervised!({Recorder, id: id, recording: recording})
    # handle_continue has run (subscribed, file open) once a call is answered
    _ = Recorder.status(id)
    id
  end

  defp publish(id, event, payload), do: PubSub.broadcast(Telemetry.topic(id), event, payload)

  defp entries(id) do
    Recorder.sync(id)
    Recorder.status(id).files |> Enum.flat_map(&Enum.to_list(Recording.entries(&1)))
  end

  test "records every event on the vehicle's topic, in order, with its wall clock", %{
    tmp_dir: dir
  } do
    id = start!(dir)
    before = System.os_time(:millisecond)

    for i <- 1..50, do: publish(id, "telemetry", %{t: i * 0.05, measurement: %{depth: i / 100}})
    publish(id, "stopped", %{reason: "deadman"})

    recorded = entries(id)
    assert length(recorded) == 51
    assert {at, "telemetry", %{t: 0.05, measurement: %{depth: 0.01}}} = hd(recorded)
    assert at >= before and at <= System.os_time(:millisecond)
    assert {_, "stopped", %{reason: "deadman"}} = List.last(recorded)
    assert Enum.map(recorded, &elem(&1, 0)) == Enum.sort(Enum.map(recorded, &elem(&1, 0)))

    assert %{recording: true, entries: 51, error: nil, file: file, dive: dive} =
             Recorder.status(id)

    assert [%{vehicle: ^id, name: ^dive, entries: 51, telemetry: 50, stops: 1, closed: false}] =
             Dive.list(dir, id)

    assert file == Path.join([dir, id, dive, "entries-0001.log"])
  end

  test "records the vehicle's log entries too (safety, link, errors), on disk at once", %{
    tmp_dir: dir
  } do
    id = start!(dir, sync_ms: 3_600_000)
    publish(id, "telemetry", %{t: 0.05})

    PubSub.broadcast(Telemetry.log_topic(id), "log", %{
      category: "link",
      level: "warning",
      message: "board link down: hangup",
      at: 1
    })

    publish(id, "stopped", %{reason: "deadman"})

    assert [
             {_, "telemetry", %{t: 0.05}},
             {_, "log", %{category: "link", message: "board link down: hangup"}},
             {_, "stopped", %{reason: "deadman"}}
           ] = on_disk(id)
  end

  # What another reader finds in the file being written, without asking the recorder to sync.
  defp on_disk(id) do
    %{file: file} = Recorder.status(id)
    file |> Recording.entries() |> Enum.to_list()
  end

  test "an event that is not telemetry is on disk as soon as the recorder has handled it", %{
    tmp_dir: dir
  } do
    # no periodic sync during the test
    id = start!(dir, sync_ms: 3_600_000)
    for i <- 1..3, do: publish(id, "telemetry", %{t: i * 0.05})
    publish(id, "stopped", %{reason: "deadman"})

    assert [
             {_, "telemetry", %{t: 0.05}},
             {_, "telemetry", %{t: 0.1}},
             {_, "telemetry", _},
             {_, "stopped", %{reason: "deadman"}}
           ] = on_disk(id)
  end

  test "telemetry is on disk at the recorder's next periodic sync", %{tmp_dir: dir} do
    id = start!(dir, sync_ms: 3_600_000)
    for i <- 1..3, do: publish(id, "telemetry", %{t: i * 0.05})

    # the recorder's own timer, sent now
    send(GenServer.whereis(Neptunus.Fleet.via(Recorder, id)), :sync_tick)
    assert [{_, "telemetry", %{t: 0.05}}, _, {_, "telemetry", %{t: t}}] = on_disk(id)
    assert_in_delta t, 0.15, 1.0e-9
  end

  test "on a disk slower than the events, syncs are batched: the recorder keeps up", %{
    tmp_dir: dir
  } do
    test = self()

    slow_sync = fn log ->
      Process.sleep(30)
      send(test, :synced)
      :disk_log.sync(log)
    end

    id = start!(dir, sync_ms: 50, sync: slow_sync)
    for i <- 1..100, do: publish(id, "helm", %{n: i})

    # one sync per event would take 3 s and keep the recorder ever further behind
    assert Enum.map(on_disk(id), fn {_, "helm", %{n: n}} -> n end) == Enum.to_list(1..100)
    syncs = count_synced(0)
    assert syncs in 1..49, "#{syncs} syncs for 100 events"
  end

  defp count_synced(n) do
    receive do
      :synced -> count_synced(n + 1)
    after
      0 -> n
    end
  end

  test "a full part is closed and the dive goes on in the next: nothing is refused", %{
    tmp_dir: dir
  } do
    id = start!(dir, max_bytes: 4_000)
    payload = %{t: 0.0, blob: String.duplicate("x", 300)}

    for i <- 1..40, do: publish(id, "telemetry", %{payload | t: i * 1.0})

    %{files: files} = Recorder.status(id)
    assert length(files) >= 3
    recorded = entries(id)
    assert Enum.map(recorded, fn {_, _, p} -> p.t end) == Enum.map(1..40, &(&1 * 1.0))
    assert [%{name: dive}] = Dive.list(dir, id)
    assert Dive.parts(Dive.path(dir, id, dive)) == files
    assert length(Enum.to_list(Dive.entries(Dive.path(dir, id, dive)))) == 40
  end

  test "a restart begins a new dive and closes the old one", %{tmp_dir: dir} do
    id = start!(dir)
    publish(id, "telemetry", %{t: 1.0})
    Recorder.sync(id)
    [first] = Recorder.status(id).files
    stop_supervised!(Recorder)

    start_supervised!({Recorder, id: id, recording: [dir: dir]})
    publish(id, "telemetry", %{t: 2.0})
    [second] = Recorder.status(id).files
    assert Path.dirname(first) != Path.dirname(second)
    assert [{_, "telemetry", %{t: 1.0}}] = Enum.to_list(Recording.entries(first))
    assert [%{closed: false}, %{closed: true, entries: 1}] = Dive.list(dir, id)
  end

  test "when the directory cannot be used, recording stops and says so", %{tmp_dir: dir} do
    blocker = Path.join(dir, "a-file")
    File.write!(blocker, "not a directory")
    id = "rec-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.log_topic(id))
    PubSub.subscribe(Telemetry.topic(id))

    start_supervised!({Recorder, id: id, recording: [dir: blocker]})

    assert_receive {:pubsub, _, "log",
                    %{category: "errors", message: "recording stopped: " <> why}},
                   5_000

    assert why =~ "cannot record to"
    assert_receive {:pubsub, _, "recording", %{recording: false, error: ^why}}, 5_000
    assert %{recording: false, error: ^why} = Recorder.status(id)
    # still alive and harmless
    publish(id, "telemetry", %{t: 1.0})
    assert %{entries: 0} = Recorder.status(id)
  end

  test "recording off: no directory, no files, no subscription", %{tmp_dir: dir} do
    id = "rec-#{System.unique_integer([:positive])}"
    start_supervised!({Recorder, id: id, recording: [dir: nil]})
    publish(id, "telemetry", %{t: 1.0})
    assert %{recording: false, entries: 0, error: nil} = Recorder.status(id)
    assert File.ls!(dir) == []
  end

  test "a vehicle started with recording on records its telemetry", %{tmp_dir: dir} do
    id = "rec-#{System.unique_integer([:positive])}"

    start_supervised!(
      {Neptunus.Vehicle.Supervisor,
       %{id: id, board: :simulated, recording: [dir: dir], helm: [tick_ms: 3_600_000]}}
    )

    PubSub.subscribe(Telemetry.topic(id))
    assert_receive {:pubsub, _, "telemetry", _}
    # and says so in its telemetry (a tick may come between its subscription and its report)
    assert_receive {:pubsub, _, "telemetry", %{recording: %{on: true, error: nil}}}
    recorded = entries(id)
    assert Enum.count(recorded, &match?({_, "telemetry", %{t: _}}, &1)) >= 2

    assert Enum.any?(
             recorded,
             &match?({_, "telemetry", %{recording: %{on: true, error: nil}}}, &1)
           )
  end

  test "telemetry says when a vehicle does not record, and why", %{tmp_dir: dir} do
    off = "rec-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(off))

    start_supervised!(
      {Neptunus.Vehicle.Supervisor, %{id: off, board: :simulated, recording: [dir: nil]}},
      id: :off
    )

    assert_receive {:pubsub, _, "telemetry", %{recording: %{on: false, error: nil}}}

    blocked = "rec-#{System.unique_integer([:positive])}"
    file = Path.join(dir, "not-a-dir")
    File.write!(file, "")
    PubSub.subscribe(Telemetry.topic(blocked))

    start_supervised!(
      {Neptunus.Vehicle.Supervisor, %{id: blocked, board: :simulated, recording: [dir: file]}},
      id: :blocked
    )

    assert_receive {:pubsub, "vehicle:" <> ^blocked, "telemetry",
                    %{recording: %{on: false, error: "cannot record to" <> _}}}
  end

  test "retention: deletes the vehicle's dives older than keep_ms, each one said", %{
    tmp_dir: dir
  } do
    id = "rec-#{System.unique_integer([:positive])}"
    now = System.os_time(:second)
    day = 86_400

    # a dive folder (its files as old as it is) or a recording file from before dives
    old = fn vehicle, name, age_s ->
      path = Path.join([dir, vehicle, name])

      if String.ends_with?(name, ".log") do
        File.mkdir_p!(Path.dirname(path))
        File.write!(path, "x")
        File.touch!(path, now - age_s)
      else
        File.mkdir_p!(Path.join(path, "video"))
        File.write!(Path.join(path, "entries-0001.log"), "x")
        File.write!(Path.join(path, "video/000001.h264"), "x")

        for f <- ["entries-0001.log", "video/000001.h264"],
            do: File.touch!(Path.join(path, f), now - age_s)
      end

      path
    end

    expired = old.(id, "20260101-000000Z-1", 20 * day)
    also_expired = old.(id, "20260102-000000Z-1.log", 11 * day)
    recent = old.(id, "20261120-000000Z-1", 1 * day)
    other_vehicle = old.("other-#{id}", "20260101-000000Z-1", 20 * day)
    # one the file system refuses to delete: said, not hidden
    stuck = old.(id, "20260103-000000Z-1", 30 * day)
    rm = fn path -> if path == stuck, do: {:error, :eacces}, else: Dive.delete(path) end
    # a directory is not a recording from before dives, whatever its name
    not_a_file = Path.join([dir, id, "20260104-000000Z-1.log"])
    File.mkdir_p!(not_a_file)
    File.touch!(not_a_file, now - 30 * day)

    PubSub.subscribe(Telemetry.log_topic(id))
    start_supervised!({Recorder, id: id, recording: [dir: dir, keep_ms: 10 * day * 1000, rm: rm]})
    %{file: current, folder: folder, recording: true} = Recorder.status(id)

    for name <- ["20260101-000000Z-1", "20260102-000000Z-1.log"] do
      assert_receive {:pubsub, _, "log",
                      %{category: "recording", level: "info", name: ^name, message: message}},
                     5_000

      assert message == "recording #{name} deleted: older than 10 days (retention)"
    end

    assert_receive {:pubsub, _, "log",
                    %{category: "errors", name: "20260103-000000Z-1", message: message}},
                   5_000

    assert message =~ "cannot be deleted: eacces"
    refute_received {:pubsub, _, "log", %{name: "20260104-000000Z-1.log"}}
    refute File.exists?(expired) or File.exists?(also_expired)
    assert File.exists?(recent) and File.exists?(other_vehicle) and File.exists?(current)
    assert File.exists?(stuck) and File.dir?(not_a_file)

    # the dive being written is never deleted, however old it looks
    for name <- File.ls!(folder), do: File.touch!(Path.join(folder, name), now - 100 * day)
    send(GenServer.whereis(Neptunus.Fleet.via(Recorder, id)), :expire)
    assert %{recording: true, file: ^current} = Recorder.status(id)
    assert File.exists?(current)
  end

  test "no retention by default: nothing is deleted", %{tmp_dir: dir} do
    id = "rec-#{System.unique_integer([:positive])}"
    path = Path.join([dir, id, "20200101-000000Z-1.log"])
    File.mkdir_p!(Path.dirname(path))
    File.write!(path, "x")
    File.touch!(path, System.os_time(:second) - 3650 * 86_400)
    start_supervised!({Recorder, id: id, recording: [dir: dir]})
    _ = Recorder.status(id)
    assert File.exists?(path)
  end

  test "stops before the disk fills and resumes in a new dive when there is room", %{
    tmp_dir: dir
  } do
    free = start_supervised!({Agent, fn -> 10 * 1_048_576 end}, id: :free)
    id = "rec-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.log_topic(id))
    PubSub.subscribe(Telemetry.topic(id))

    recording = [
      dir: dir,
      min_free_bytes: 100 * 1_048_576,
      free_bytes: fn _dir -> Agent.get(free, & &1) end
    ]

    start_supervised!({Recorder, id: id, recording: recording})

    # 10 MB free, 100 MB needed: no file at all, and it says why
    assert_receive {:pubsub, _, "log",
                    %{category: "errors", message: "recording stopped: " <> why}},
                   5_000

    assert why ==
             "disk nearly full: 10 MB free (below the 100 MB kept free, " <>
               "NEPTUNUS_RECORDING_MIN_FREE_MB): recording stopped; what was recorded is kept"

    assert %{recording: false, error: ^why, files: []} = Recorder.status(id)
    publish(id, "telemetry", %{t: 1.0})
    assert %{entries: 0} = Recorder.status(id)

    # room again: the next check opens a file and recording goes on
    Agent.update(free, fn _ -> 1_000 * 1_048_576 end)
    send(GenServer.whereis(Neptunus.Fleet.via(Recorder, id)), :check_disk)
    assert %{recording: true, error: nil, files: [file]} = Recorder.status(id)
    publish(id, "telemetry", %{t: 2.0})

    # nearly full again: the dive is closed with what it holds
    Agent.update(free, fn _ -> 1_048_576 end)
    send(GenServer.whereis(Neptunus.Fleet.via(Recorder, id)), :check_disk)
    assert %{recording: false, error: "disk nearly full: 1 MB free" <> _} = Recorder.status(id)
    assert [{_, "telemetry", %{t: 2.0}}] = Enum.to_list(Recording.entries(file))
    assert [%{closed: true, telemetry: 1}] = Dive.list(dir, id)
  end
end
