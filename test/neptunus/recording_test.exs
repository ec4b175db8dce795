defmodule Neptunus.RecordingTest do
  use ExUnit.Case, async: true

  alias Neptunus.Recording

  import Neptunus.Test.Properties, only: [check: 3, bind: 2]

  doctest Neptunus.Recording

  @moduletag :tmp_dir

  defp telemetry(t, extra \\ %{}) do
    Map.merge(
      %{t: t, measurement: %{depth: t / 10, heading: 1.0}, link: %{up: true, reason: "open"}},
      extra
    )
  end

  defp write!(path, entries) do
    File.mkdir_p!(Path.dirname(path))
    name = {__MODULE__, make_ref()}
    {:ok, log} = :disk_log.open(name: name, file: String.to_charlist(path), type: :halt)
    :ok = :disk_log.log_terms(log, entries)
    :ok = :disk_log.close(log)
    path
  end

  test "file names: valid only as the recorder writes them, never a path" do
    assert Recording.valid?("rov", Recording.file_name(~U[2026-01-02 03:04:05Z], 12))

    for {v, n} <- [
          {"rov", "x.log"},
          {"rov", "20261122-130509Z-1.log/../x"},
          {"../rov", "20261122-130509Z-1.log"},
          {"rov/x", "20261122-130509Z-1.log"},
          {"rov", "20261122-130509Z-1.csv"},
          {"", "20261122-130509Z-1.log"},
          {nil, "20261122-130509Z-1.log"},
          {"rov", "20261122-130509-1.log"},
          # a trailing newline (which `$` would let through, into paths and logs)
          {"rov\n", "20261122-130509Z-1.log"},
          {"rov", "20261122-130509Z-1.log\n"},
          {"\nrov", "20261122-130509Z-1.log"}
        ] do
      refute Recording.valid?(v, n), "#{inspect({v, n})} accepted"
    end

    assert Recording.started_at("20261399-130509Z-1.log") == nil
  end

  test "lists recordings of every vehicle, newest first, ignoring other files", %{tmp_dir: dir} do
    write!(Path.join([dir, "a", "20261122-100000Z-1.log"]), [{1, "telemetry", telemetry(0.0)}])
    write!(Path.join([dir, "a", "20261122-110000Z-1.log"]), [{1, "telemetry", telemetry(0.0)}])
    write!(Path.join([dir, "b", "20261122-105000Z-1.log"]), [{1, "telemetry", telemetry(0.0)}])
    File.write!(Path.join([dir, "a", "notes.txt"]), "x")
    File.mkdir_p!(Path.join(dir, "not a vehicle"))

    assert [
             %{vehicle: "a", name: "20261122-110000Z-1.log"},
             %{vehicle: "b", name: "20261122-105000Z-1.log"},
             %{vehicle: "a", name: "20261122-100000Z-1.log", bytes: bytes, started_at: at}
           ] = Recording.list(dir)

    assert bytes > 0
    assert at == DateTime.to_unix(~U[2026-11-22 10:00:00Z], :millisecond)
    assert [%{vehicle: "b"}] = Recording.list(dir, "b")
    assert Recording.list(dir, "c") == []
    assert Recording.list(Path.join(dir, "missing")) == []
  end

  test "reads entries back in order; a torn tail is skipped, not fatal", %{tmp_dir: dir} do
    entries = for i <- 1..500, do: {1_000 + i, "telemetry", telemetry(i * 0.05)}
    path = write!(Path.join([dir, "a", "20261122-100000Z-1.log"]), entries)
    assert Enum.to_list(Recording.entries(path)) == entries

    # a crash mid-write leaves half an entry at the end
    File.write!(path, :binary.copy(<<1, 2, 3>>, 7), [:append])
    assert path |> Recording.entries() |> Enum.to_list() |> length() == 500

    assert_raise File.Error, fn ->
      Recording.entries(Path.join(dir, "nope.log")) |> Enum.to_list()
    end
  end

  test "CSV: one column per numeric series in order of first appearance, telemetry rows only" do
    entries = [
      {100, "telemetry", telemetry(0.0)},
      {150, "stopped", %{reason: "deadman"}},
      {200, "telemetry", telemetry(0.05, %{estimate: %{depth: 0.01}})},
      {250, "telemetry", %{t: 0.1, "odd,key": 2}}
    ]

    csv = entries |> Recording.csv() |> IO.iodata_to_binary()

    assert csv ==
             """
             time,link.up,measurement.depth,measurement.heading,t,estimate.depth,"odd,key"
             100,1,0.0,1.0,0.0,,
             200,1,0.005,1.0,0.05,0.01,
             250,,,,0.1,,2
             """
  end

  # The first flatten (sorting every level by the keys' text, appending nested lists): the
  # faster one must give the same series in the same order.
  defp reference_flatten(payload), do: payload |> reference_flatten("") |> Enum.reverse()

  defp reference_flatten(map, prefix) do
    map
    |> Enum.sort_by(fn {k, _} -> to_string(k) end)
    |> Enum.reduce([], fn {key, value}, acc ->
      path = if prefix == "", do: to_string(key), else: prefix <> "." <> to_string(key)

      case value do
        v when is_number(v) -> [{path, v} | acc]
        true -> [{path, 1} | acc]
        false -> [{path, 0} | acc]
        %{} = nested -> reference_flatten(nested, path) ++ acc
        _ -> acc
      end
    end)
  end

  defp payload_gen do
    key =
      :proper_types.oneof([
        :proper_types.elements([:t, :depth, :a, :ab, :"a.b", :"a-b", :Z, :é, nil, true, false]),
        :proper_types.elements(["a", "b", "a-b", "Z", "é", ""]),
        :proper_unicode.utf8(3)
      ])

    leaf =
      :proper_types.oneof([
        :proper_types.integer(),
        :proper_types.float(),
        :proper_types.boolean(),
        :proper_types.exactly(nil),
        :proper_types.exactly("text")
      ])

    # keys of one map with the same text (`nil` and "", :a and "a") would name one series twice:
    # payloads never have them, and their order is the map's, not the text's
    level = fn inner ->
      bind(
        :proper_types.list({key, :proper_types.oneof([leaf, inner])}),
        &(&1 |> Enum.uniq_by(fn {k, _} -> to_string(k) end) |> Map.new())
      )
    end

    level.(level.(level.(leaf)))
  end

  test "flatten gives the series of the first implementation, in its order (property)" do
    check(
      payload_gen(),
      fn payload -> Recording.flatten(payload) == reference_flatten(payload) end,
      1_000
    )
  end

  test "CSV stream: every N-th telemetry row, lazily" do
    entries = for i <- 0..9, do: {i, "telemetry", %{t: i}}
    stream = Recording.csv_stream(entries, ["t"], 4)
    assert Enum.map(stream, &IO.iodata_to_binary/1) == ["time,t\n", "0,0\n", "4,4\n", "8,8\n"]

    # nothing is read beyond what is taken
    endless = Stream.map(Stream.iterate(0, &(&1 + 1)), &{&1, "telemetry", %{t: &1}})
    assert endless |> Recording.csv_stream(["t"]) |> Enum.take(3) |> length() == 3
    assert endless |> Recording.json_lines_stream(2) |> Enum.take(2) |> length() == 2
  end

  test "JSON lines keep every event and every N-th telemetry entry" do
    entries =
      for i <- 0..9 do
        if i == 4, do: {i, "stopped", %{reason: "deadman"}}, else: {i, "telemetry", %{t: i}}
      end

    lines =
      entries
      |> Recording.json_lines_stream(3)
      |> Enum.to_list()
      |> IO.iodata_to_binary()
      |> String.split("\n", trim: true)
      |> Enum.map(&:jiffy.decode(&1, [:return_maps]))

    assert Enum.map(lines, &{&1["at"], &1["event"]}) == [
             {0, "telemetry"},
             {3, "telemetry"},
             {4, "stopped"},
             {7, "telemetry"}
           ]

    assert hd(lines)["payload"] == %{"t" => 0}
    assert %{telemetry: 9, entries: 10, columns: ["t"]} = Recording.scan(entries)
  end
end
