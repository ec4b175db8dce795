defmodule Neptunus.Recording do
  @moduledoc """
  Recordings of a vehicle: everything published on its `"vehicle:<id>"` topic — telemetry at
  its full rate, stops, helm and control events — written by `Neptunus.Vehicle.Recorder` to
  `disk_log` files, one per recorder run:

      <dir>/<vehicle id>/<YYYYMMDD-HHMMSS>Z-<n>.log

  Each entry is `{at, event, payload}`: `at` the wall clock (ms since the Unix epoch),
  `event` the topic's event name, `payload` the map as broadcast. This module is the pure
  part and the file reading: names, listing, reading entries back, and the exports — CSV of
  the telemetry (one column per numeric series, as the developer page plots them) and JSON
  lines of every entry (what the developer page replays).
  """

  alias Neptunus.JSON

  @typedoc "A recorded entry: wall clock (ms), event, payload."
  @type entry :: {integer(), String.t(), map()}

  @typedoc "A recording file, as listed."
  @type info :: %{
          vehicle: String.t(),
          name: String.t(),
          bytes: non_neg_integer(),
          started_at: integer() | nil,
          modified_at: integer()
        }

  # \A and \z: `^` and `$` would also match before a trailing newline ("alpha\n")
  @name_re ~r/\A\d{8}-\d{6}Z-\d+\.log\z/
  @id_re ~r/\A[A-Za-z0-9_-]{1,32}\z/

  @doc """
  The file name of a recording started at `datetime` (UTC), `n`-th of that second.

      iex> Neptunus.Recording.file_name(~U[2026-11-22 13:05:09Z], 1)
      "20261122-130509Z-1.log"
  """
  @spec file_name(DateTime.t(), pos_integer()) :: String.t()
  def file_name(%DateTime{} = datetime, n) when is_integer(n) and n >= 1 do
    Calendar.strftime(datetime, "%Y%m%d-%H%M%SZ") <> "-#{n}.log"
  end

  @doc """
  Whether `vehicle` and `name` name a recording (and nothing else: no paths, no `..`).

      iex> Neptunus.Recording.valid?("rov-1", "20261122-130509Z-1.log")
      true
      iex> Neptunus.Recording.valid?("rov-1", "../../etc/passwd")
      false
  """
  @spec valid?(term(), term()) :: boolean()
  def valid?(vehicle, name) when is_binary(vehicle) and is_binary(name),
    do: Regex.match?(@id_re, vehicle) and Regex.match?(@name_re, name)

  def valid?(_vehicle, _name), do: false

  @doc "The path of a recording in `dir`."
  @spec path(Path.t(), String.t(), String.t()) :: Path.t()
  def path(dir, vehicle, name), do: Path.join([dir, vehicle, name])

  @doc "The recordings in `dir`, newest first (optionally of one vehicle)."
  @spec list(Path.t(), String.t() | nil) :: [info()]
  def list(dir, vehicle \\ nil) do
    vehicles =
      if vehicle, do: [vehicle], else: dir |> ls() |> Enum.filter(&Regex.match?(@id_re, &1))

    for v <- vehicles,
        name <- ls(Path.join(dir, v)),
        valid?(v, name),
        {:ok, %File.Stat{type: :regular} = stat} <- [File.stat(path(dir, v, name), time: :posix)] do
      %{
        vehicle: v,
        name: name,
        bytes: stat.size,
        started_at: started_at(name),
        modified_at: stat.mtime * 1000
      }
    end
    |> Enum.sort_by(&{&1.started_at || 0, &1.vehicle, &1.name}, :desc)
  end

  defp ls(dir) do
    case File.ls(dir) do
      {:ok, names} -> names
      {:error, _} -> []
    end
  end

  @doc """
  When a recording started (ms since the epoch), from its name.

      iex> Neptunus.Recording.started_at("20261122-130509Z-1.log")
      1795352709000
  """
  @spec started_at(String.t()) :: integer() | nil
  def started_at(
        <<y::binary-4, mo::binary-2, d::binary-2, "-", h::binary-2, mi::binary-2, s::binary-2,
          "Z-", _::binary>>
      ) do
    with {:ok, date} <- Date.from_iso8601("#{y}-#{mo}-#{d}"),
         {:ok, time} <- Time.from_iso8601("#{h}:#{mi}:#{s}"),
         {:ok, datetime} <- DateTime.new(date, time) do
      DateTime.to_unix(datetime, :millisecond)
    else
      _ -> nil
    end
  end

  def started_at(_name), do: nil

  @doc """
  The entries of the recording file at `path`, lazily, in order. A file that is still being
  written is read as far as it is on disk; a torn last entry (a crash mid-write) is skipped.
  Raises `File.Error` when the file cannot be opened.
  """
  @spec entries(Path.t()) :: Enumerable.t()
  def entries(path) do
    path
    |> stream(true)
    |> Stream.filter(&match?({at, event, %{}} when is_integer(at) and is_binary(event), &1))
  end

  @doc """
  The file's entries as `entries/1` gives them (and any other term in it), with
  `{:unreadable, path, bytes}` where bytes could not be read as entries (a torn end, a
  damaged block: reading goes on after them), `{:unreadable, path, :rest}` when the rest of
  the file cannot be read, and `{:unreadable, path, :file}` when the file cannot be opened.
  Never raises.
  """
  @spec read(Path.t()) :: Enumerable.t()
  def read(path), do: stream(path, false)

  defp stream(path, raise?) do
    Stream.resource(
      fn -> open(path, raise?) end,
      fn
        :unopened ->
          {[{:unreadable, path, :file}], :done}

        :done ->
          {:halt, :done}

        {log, :eof} ->
          {:halt, {log, :eof}}

        {log, cont} ->
          case :disk_log.chunk(log, cont) do
            :eof ->
              {:halt, {log, :eof}}

            {:error, _reason} ->
              {if(raise?, do: [], else: [{:unreadable, path, :rest}]), {log, :eof}}

            {cont, terms} ->
              {terms, {log, cont}}

            {cont, terms, 0} ->
              {terms, {log, cont}}

            {cont, terms, bad} ->
              {terms ++ [{:unreadable, path, bad}], {log, cont}}
          end
      end,
      fn
        {log, _} -> :disk_log.close(log)
        _ -> :ok
      end
    )
  end

  defp open(path, raise?) do
    name = {__MODULE__, :reader, make_ref()}

    case :disk_log.open(name: name, file: String.to_charlist(path), mode: :read_only) do
      {:ok, log} ->
        {log, :start}

      {:repaired, log, _recovered, _bad} ->
        {log, :start}

      {:error, reason} when not raise? ->
        _ = reason
        :unopened

      {:error, {:file_error, _file, posix}} ->
        raise File.Error, reason: posix, action: "read recording", path: path

      {:error, reason} ->
        raise File.Error, reason: reason, action: "read recording", path: path
    end
  end

  @doc """
  Whether the recorder writes an entry of `event` to disk at once (every event but
  `telemetry`: rare, and each one may be what a dive is remembered by) or with its next
  periodic sync (`telemetry`, 20 times a second).

      iex> Neptunus.Recording.sync_at_once?("stopped")
      true
      iex> Neptunus.Recording.sync_at_once?("telemetry")
      false
  """
  @spec sync_at_once?(String.t()) :: boolean()
  def sync_at_once?("telemetry"), do: false
  def sync_at_once?(event) when is_binary(event), do: true

  @doc """
  The numeric series of a payload as `{path, value}`, paths dotted (`"measurement.depth"`),
  in payload order; booleans as 0/1, everything else left out. The same series as the
  developer page's plots.

      iex> Neptunus.Recording.flatten(%{t: 1.5, link: %{up: true, reason: "open"}, thrusters: %{port: 0.25}})
      [{"link.up", 1}, {"t", 1.5}, {"thrusters.port", 0.25}]
  """
  @spec flatten(map()) :: [{String.t(), number()}]
  def flatten(payload) when is_map(payload),
    do: payload |> flatten_into("", []) |> Enum.reverse()

  # pushes the series of `map` onto `acc` (reversed), keys in order at each level
  defp flatten_into(map, prefix, acc) do
    map
    |> sorted_pairs()
    |> Enum.reduce(acc, fn {key, value}, acc ->
      case value do
        v when is_number(v) -> [{path(prefix, key), v} | acc]
        true -> [{path(prefix, key), 1} | acc]
        false -> [{path(prefix, key), 0} | acc]
        %{} = nested -> flatten_into(nested, path(prefix, key), acc)
        _ -> acc
      end
    end)
  end

  defp path("", key), do: to_string(key)
  defp path(prefix, key), do: prefix <> "." <> to_string(key)

  # ordered by the keys' text; atoms (what recorded payloads have) compare by their text
  # already, except nil, true and false, whose text `to_string/1` gives differently
  defp sorted_pairs(map) do
    pairs = :maps.to_list(map)

    if Enum.all?(pairs, fn {k, _} -> is_atom(k) and k not in [nil, true, false] end),
      do: List.keysort(pairs, 0),
      else: Enum.sort_by(pairs, fn {k, _} -> to_string(k) end)
  end

  @typedoc """
  What one pass over a recording's entries found (`scan/1`): the CSV columns (every numeric
  series of its telemetry, in order of first appearance), how many telemetry entries and how
  many entries in all.
  """
  @type summary :: %{
          columns: [String.t()],
          telemetry: non_neg_integer(),
          entries: non_neg_integer()
        }

  @doc """
  Reads `entries` once and keeps only what a streamed export needs to know first (its memory
  is the column names, whatever the length of the recording).

      iex> Neptunus.Recording.scan([{1, "telemetry", %{t: 0.0}}, {2, "stopped", %{}},
      ...>   {3, "telemetry", %{t: 0.1, depth: 1.0}}])
      %{columns: ["t", "depth"], telemetry: 2, entries: 3}
  """
  @spec scan(Enumerable.t()) :: summary()
  def scan(entries) do
    {_seen, columns, telemetry, count} =
      Enum.reduce(entries, {MapSet.new(), [], 0, 0}, fn
        {_at, "telemetry", payload}, {seen, columns, telemetry, count} ->
          {seen, columns} =
            payload
            |> flatten()
            |> Enum.reduce({seen, columns}, fn {path, _}, {seen, columns} ->
              if MapSet.member?(seen, path),
                do: {seen, columns},
                else: {MapSet.put(seen, path), [path | columns]}
            end)

          {seen, columns, telemetry + 1, count + 1}

        _entry, {seen, columns, telemetry, count} ->
          {seen, columns, telemetry, count + 1}
      end)

    %{columns: Enum.reverse(columns), telemetry: telemetry, entries: count}
  end

  @doc """
  The telemetry of `entries` as CSV, lazily, one iodata element per line: a header
  `time,<columns…>` — `time` the wall clock in ms, then `columns` (from `scan/1`) — and one
  row per `every`-th telemetry entry (empty where a series has no value).
  """
  @spec csv_stream(Enumerable.t(), [String.t()], pos_integer()) :: Enumerable.t()
  def csv_stream(entries, columns, every \\ 1) when is_integer(every) and every >= 1 do
    header = [Enum.map_intersperse(["time" | columns], ",", &csv_field/1), "\n"]

    rows =
      entries
      |> decimate(every)
      |> Stream.filter(&telemetry?/1)
      |> Stream.map(fn {at, _event, payload} ->
        values = payload |> flatten() |> Map.new()
        [Integer.to_string(at), Enum.map(columns, &["," | number(Map.get(values, &1))]), "\n"]
      end)

    Stream.concat([header], rows)
  end

  @doc """
  The telemetry of `entries` as CSV (iodata, `csv_stream/3` of every entry with the columns
  of `scan/1`). For entries in memory; a file is exported with the two passes.
  """
  @spec csv(Enumerable.t()) :: iodata()
  def csv(entries) do
    entries = Enum.to_list(entries)
    entries |> csv_stream(scan(entries).columns) |> Enum.to_list()
  end

  @doc """
  Every `every`-th telemetry entry and every other entry, as JSON lines
  `{"at": ms, "event": e, "payload": {…}}`, lazily, one iodata element per line.
  """
  @spec json_lines_stream(Enumerable.t(), pos_integer()) :: Enumerable.t()
  def json_lines_stream(entries, every \\ 1) when is_integer(every) and every >= 1 do
    entries
    |> decimate(every)
    |> Stream.map(fn {at, event, payload} ->
      [JSON.encode!(%{at: at, event: event, payload: payload}), "\n"]
    end)
  end

  # every entry that is not telemetry, and every `every`-th telemetry entry
  defp decimate(entries, 1), do: entries

  defp decimate(entries, every) do
    Stream.transform(entries, 0, fn entry, n ->
      cond do
        not telemetry?(entry) -> {[entry], n}
        rem(n, every) == 0 -> {[entry], n + 1}
        true -> {[], n + 1}
      end
    end)
  end

  @doc """
  Free bytes on the file system holding `dir` (by `df -Pk`, which every Debian has); nil when
  it cannot be told.
  """
  @spec free_bytes(Path.t()) :: non_neg_integer() | nil
  def free_bytes(dir) do
    case System.cmd("df", ["-Pk", dir], stderr_to_stdout: true) do
      {output, 0} -> parse_df(output)
      _ -> nil
    end
  rescue
    _ -> nil
  end

  @doc """
  The available bytes from `df -Pk` output (POSIX format: 1024-byte blocks).

      iex> Neptunus.Recording.parse_df("Filesystem 1024-blocks Used Available Capacity Mounted on\\n/dev/vda 264212084 13382120 82119144 15% /\\n")
      84090003456
      iex> Neptunus.Recording.parse_df("df: nope")
      nil
  """
  @spec parse_df(String.t()) :: non_neg_integer() | nil
  def parse_df(output) do
    with [_header, line | _] <- String.split(output, "\n", trim: true),
         [_fs, _blocks, _used, available | _] <- String.split(line),
         {kib, ""} <- Integer.parse(available) do
      kib * 1024
    else
      _ -> nil
    end
  end

  defp telemetry?({_, "telemetry", _}), do: true
  defp telemetry?(_entry), do: false

  defp number(nil), do: []
  defp number(v) when is_integer(v), do: Integer.to_string(v)
  defp number(v) when is_float(v), do: :erlang.float_to_binary(v, [:short])

  defp csv_field(text) do
    if String.contains?(text, [",", "\"", "\n"]),
      do: ["\"", String.replace(text, "\"", "\"\""), "\""],
      else: text
  end
end
