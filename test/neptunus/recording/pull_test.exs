defmodule Neptunus.Recording.PullTest do
  # The fleet's recordings from one node: this node only, and this node standing in for a
  # remote one where the protocol is the same (pull/2, serve/2). Across two real nodes:
  # test/neptunus_web/fleet_cluster_test.exs; through the HTTP API:
  # test/neptunus_web/api/recordings_test.exs.
  use ExUnit.Case, async: true

  alias Neptunus.Recording
  alias Neptunus.Dive.Export
  alias Neptunus.Recording.Pull

  @moduletag :tmp_dir
  @moduletag :capture_log

  @name "20200101-000000Z-1.log"

  defp dir(path), do: {Function, :identity, [path]}

  defp write!(dir, vehicle, name, entries) do
    path = Recording.path(dir, vehicle, name)
    File.mkdir_p!(Path.dirname(path))
    {:ok, log} = :disk_log.open(name: {__MODULE__, make_ref()}, file: String.to_charlist(path))
    :ok = :disk_log.log_terms(log, entries)
    :ok = :disk_log.close(log)
    path
  end

  defp telemetry(n), do: for(i <- 1..n, do: {i, "telemetry", %{t: i / 20, depth: i / 100}})

  defp vehicle, do: "pull-#{System.unique_integer([:positive])}"

  test "list: this node's recordings with its name, all or one vehicle's", %{tmp_dir: tmp} do
    a = vehicle()
    write!(tmp, a, @name, telemetry(3))
    write!(tmp, vehicle(), @name, telemetry(3))
    here = Atom.to_string(node())

    assert {:ok, %{recording: true, recordings: all}} = Pull.list(nil, dir(tmp))
    assert length(all) == 2
    assert Enum.all?(all, &(&1.node == here))

    assert {:ok, %{recording: true, recordings: [%{vehicle: ^a, name: @name, node: ^here}]}} =
             Pull.list(a, dir(tmp))

    assert {:ok, %{recording: false, recordings: []}} = Pull.list(nil, dir(nil))
    assert {:error, :invalid, "vehicle must be a vehicle id"} = Pull.list("../etc", dir(tmp))
  end

  test "plan: the recording must exist before its options are looked at", %{tmp_dir: tmp} do
    v = vehicle()
    write!(tmp, v, @name, telemetry(30))

    assert {:error, :not_found, "recording is off on this server"} =
             Pull.plan(v, @name, %{"format" => "xml"}, dir(nil))

    assert {:error, :not_found, "no such recording"} =
             Pull.plan(v, "../../etc/passwd", %{"format" => "xml"}, dir(tmp))

    assert {:error, :not_found, "no such recording: " <> _} =
             Pull.plan(v, "20200101-000000Z-2.log", %{"every" => "0"}, dir(tmp))

    for {options, reason} <- [
          {%{"format" => "xml"}, ~s(format must be one of csv, jsonl, ass, mp4, mcap, got "xml")},
          {%{"every" => "0"}, ~s(every must be an integer in 1..1000000, got "0")},
          {%{"every" => "2x"}, ~s(every must be an integer in 1..1000000, got "2x")},
          {%{"max" => "1000001"}, ~s(max must be an integer in 1..1000000, got "1000001")}
        ] do
      assert Pull.plan(v, @name, options, dir(tmp)) == {:error, :invalid, reason}
    end
  end

  test "plan: counts and columns from a first pass; max raises every", %{tmp_dir: tmp} do
    v = vehicle()
    path = write!(tmp, v, @name, telemetry(30) ++ [{31, "stopped", %{reason: "deadman"}}])

    assert {:ok, plan} = Pull.plan(v, @name, %{}, dir(tmp))

    assert plan == %{
             path: path,
             format: "csv",
             every: 1,
             count: 31,
             columns: ["depth", "t"],
             file: "#{v}-20200101-000000Z-1.csv",
             mime: "text/csv; charset=utf-8"
           }

    assert {:ok, %{format: "jsonl", every: 5}} =
             Pull.plan(v, @name, %{"format" => "jsonl", "every" => "2", "max" => "7"}, dir(tmp))

    assert {:ok, %{every: 10}} = Pull.plan(v, @name, %{"every" => "10", "max" => "7"}, dir(tmp))
  end

  test "export here: the lines of the plan, read as they are enumerated", %{tmp_dir: tmp} do
    v = vehicle()
    path = write!(tmp, v, @name, telemetry(30))

    assert {:ok, %{format: "csv"}, lines} = Pull.export(v, @name, %{}, dir(tmp))
    expected = path |> Recording.entries() |> Recording.csv() |> IO.iodata_to_binary()
    assert lines |> Enum.to_list() |> IO.iodata_to_binary() == expected

    assert {:error, :invalid, _} = Pull.export(v, @name, %{"every" => "-1"}, dir(tmp))
    assert {:error, :not_found, _} = Pull.export(v, "20200101-000000Z-9.log", %{}, dir(tmp))
  end

  test "pull: the same lines, in batches from a process on the recording's node", %{
    tmp_dir: tmp
  } do
    v = vehicle()
    write!(tmp, v, @name, telemetry(1_000))
    {:ok, plan} = Pull.plan(v, @name, %{"format" => "jsonl"}, dir(tmp))

    pulled = Pull.pull(node(), {Export, :stream, [plan]}) |> Enum.to_list()
    assert pulled == plan |> Export.stream() |> Enum.to_list()
    assert length(pulled) == 1_000
  end

  test "pull: the serving process ends when the puller stops early or ends", %{tmp_dir: tmp} do
    v = vehicle()
    write!(tmp, v, @name, telemetry(1_000))
    {:ok, plan} = Pull.plan(v, @name, %{}, dir(tmp))
    before = Process.list()

    # one batch taken, then the enumeration stops: the server is killed
    assert [_header | _] = Pull.pull(node(), {Export, :stream, [plan]}) |> Enum.take(1)
    Enum.each(Process.list() -- before, &refute(serving?(&1)))

    # a puller that dies: the server sees it and ends
    puller = spawn(fn -> receive do: (:never -> :ok) end)
    server = Node.spawn(node(), Pull, :serve, [puller, {Export, :stream, [plan]}])
    ref = Process.monitor(server)
    Process.exit(puller, :kill)
    assert_receive {:DOWN, ^ref, :process, ^server, :normal}
  end

  test "pull: a server that fails ends the pull with the reason", %{tmp_dir: tmp} do
    # an export reads what is readable of a damaged dive; a file that cannot be read at all
    # makes the serving process fail
    missing = Path.join(tmp, "gone.csv")

    assert {:recording_node, {%File.Error{reason: :enoent}, _stack}} =
             catch_error(Pull.pull(node(), {File, :stream!, [missing]}) |> Enum.to_list())
  end

  test "delete: a finished recording, never one that is not there", %{tmp_dir: tmp} do
    v = vehicle()
    path = write!(tmp, v, @name, telemetry(3))

    assert Pull.delete(v, @name, dir(tmp)) == :ok
    refute File.exists?(path)
    assert {:error, :not_found, _} = Pull.delete(v, @name, dir(tmp))
    assert {:error, :not_found, _} = Pull.delete(v, "../../etc/passwd", dir(tmp))

    assert {:error, :not_found, "recording is off on this server"} =
             Pull.delete(v, @name, dir(nil))
  end

  test "delete: never the dive being recorded now", %{tmp_dir: tmp} do
    v = vehicle()
    start_supervised!({Neptunus.Vehicle.Recorder, id: v, recording: [dir: tmp]})
    Neptunus.PubSub.broadcast(Neptunus.Vehicle.Telemetry.topic(v), "stopped", %{reason: "x"})
    folder = Neptunus.Vehicle.Recorder.status(v).folder
    name = Path.basename(folder)

    assert {:error, :conflict, reason} = Pull.delete(v, name, dir(tmp))
    assert reason == "#{name} is being recorded now"
    assert File.dir?(folder)
  end

  defp serving?(pid) do
    match?({:current_function, {Pull, _, _}}, Process.info(pid, :current_function))
  end
end
