defmodule Neptunus.Dive do
  @moduledoc """
  Dives: what a vehicle's recorder (`Neptunus.Vehicle.Recorder`) writes, one folder per dive
  in the recordings directory (`NEPTUNUS_RECORDINGS`):

      <dir>/<vehicle>/<YYYYMMDD-HHMMSS>Z-<n>/     the dive, named after its start (UTC)
        entries-0001.log    every entry the vehicle published — telemetry at its full rate,
        entries-0002.log    stops, helm and control events, the developer log, snapshots
                            taken — a `disk_log` of `{at, event, payload}` terms
                            (`Neptunus.Recording`); the next part when one reaches the size
                            limit (`NEPTUNUS_RECORDING_MAX_MB`)
        video/000001.h264   the camera's frames as received, in segments, each with its
        video/000001.idx    index of frame times (`Neptunus.Dive.Video`)
        snapshots/*.jpg     the snapshots taken during the dive (`Neptunus.Camera.Snapshot`)
        summary.json        the recorder's summary (`Neptunus.Dive.Summary`)
        notes.json          the title and notes people gave it (`put_notes/4`)

  One time base: every entry's `at` and every frame's arrival are the vehicle node's wall
  clock (ms and µs since the epoch).

  Recordings made before dives — one `disk_log` file per recorder run,
  `<dir>/<vehicle>/<YYYYMMDD-HHMMSS>Z-<n>.log` — are listed, replayed and exported as dives
  too (`legacy: true`, named by their file name, without video or summary); they are
  never moved or changed.

  This module is the layout and its reading: names, the listing with each dive's summary,
  the entries, the summary's repair after a killed node, the notes, deleting. Bad input is
  refused with a reason (`{:error, kind, reason}`) and changes nothing; a dive whose files
  are damaged still lists and reads as far as it can, and says what it could not
  (`problems`).
  """

  alias Neptunus.{JSON, Recording}
  alias Neptunus.Dive.{Summary, Video}

  @name_re ~r/\A\d{8}-\d{6}Z-\d+\z/
  @legacy_re ~r/\A\d{8}-\d{6}Z-\d+\.log\z/
  @id_re ~r/\A[A-Za-z0-9_-]{1,32}\z/
  @part_re ~r/\Aentries-(\d{4,})\.log\z/

  @max_title 200
  @max_notes 10_000

  @typedoc "Why a request is refused (as `Neptunus.Recording.Pull`'s)."
  @type error :: {:error, :invalid | :not_found | :conflict | :failed, String.t()}

  @doc """
  The name of a dive started at `datetime` (UTC), the `n`-th of that second.

      iex> Neptunus.Dive.name(~U[2026-11-22 13:05:09Z], 1)
      "20261122-130509Z-1"
  """
  @spec name(DateTime.t(), pos_integer()) :: String.t()
  def name(%DateTime{} = datetime, n) when is_integer(n) and n >= 1,
    do: Calendar.strftime(datetime, "%Y%m%d-%H%M%SZ") <> "-#{n}"

  @doc """
  Whether `vehicle` and `name` name a dive (a dive folder's name, or a recording file's from
  before dives), and nothing else: no paths, no `..`.

      iex> Neptunus.Dive.valid?("rov-1", "20261122-130509Z-1")
      true
      iex> Neptunus.Dive.valid?("rov-1", "20261122-130509Z-1.log")
      true
      iex> Neptunus.Dive.valid?("rov-1", "../20261122-130509Z-1")
      false
  """
  @spec valid?(term(), term()) :: boolean()
  def valid?(vehicle, name) when is_binary(vehicle) and is_binary(name),
    do: valid_vehicle?(vehicle) and (Regex.match?(@name_re, name) or legacy?(name))

  def valid?(_vehicle, _name), do: false

  @doc "Whether `vehicle` is a vehicle id (as dives are kept under)."
  @spec valid_vehicle?(term()) :: boolean()
  def valid_vehicle?(vehicle) when is_binary(vehicle), do: Regex.match?(@id_re, vehicle)
  def valid_vehicle?(_), do: false

  @doc "Whether `name` is a recording file's from before dives."
  @spec legacy?(String.t()) :: boolean()
  def legacy?(name), do: Regex.match?(@legacy_re, name)

  @doc "The path of dive `name` of `vehicle` in `dir` (its folder, or a legacy file)."
  @spec path(Path.t(), String.t(), String.t()) :: Path.t()
  def path(dir, vehicle, name), do: Path.join([dir, vehicle, name])

  @doc "The video folder of a dive folder."
  @spec video_folder(Path.t()) :: Path.t()
  def video_folder(folder), do: Path.join(folder, "video")

  @doc "The snapshots folder of a dive folder."
  @spec snapshots_folder(Path.t()) :: Path.t()
  def snapshots_folder(folder), do: Path.join(folder, "snapshots")

  @doc """
  The name of entries part `n` of a dive.

      iex> Neptunus.Dive.part_name(2)
      "entries-0002.log"
  """
  @spec part_name(pos_integer()) :: String.t()
  def part_name(n), do: "entries-" <> String.pad_leading(Integer.to_string(n), 4, "0") <> ".log"

  @doc "The entries parts of a dive (its folder, or a legacy file), in order."
  @spec parts(Path.t()) :: [Path.t()]
  def parts(path) do
    if legacy?(Path.basename(path)) do
      if File.regular?(path), do: [path], else: []
    else
      path
      |> ls()
      |> Enum.flat_map(fn name ->
        case Regex.run(@part_re, name) do
          [_, n] -> [{String.to_integer(n), Path.join(path, name)}]
          nil -> []
        end
      end)
      |> Enum.sort()
      |> Enum.map(&elem(&1, 1))
    end
  end

  @doc """
  The entries of a dive, lazily and in order (every part's, `Neptunus.Recording.entries/1`):
  what is whole of each; unreadable bytes are skipped (`read/1` says how many).
  """
  @spec entries(Path.t()) :: Enumerable.t()
  def entries(path), do: path |> read() |> Stream.filter(&is_tuple/1) |> Stream.filter(&entry?/1)

  @doc """
  The dive's entries as `entries/1`, with `{:unreadable, part, bytes}` where a part has bytes
  that are not entries (a torn end, a damaged block) and `{:unreadable, part, :file}` for a
  part that cannot be opened.
  """
  @spec read(Path.t()) :: Enumerable.t()
  def read(path), do: path |> parts() |> Stream.flat_map(&Recording.read/1)

  defp entry?({at, event, %{}}) when is_integer(at) and is_binary(event), do: true
  defp entry?(_), do: false

  @doc "Vehicle ids with dives (or recordings) in `dir`."
  @spec vehicles(Path.t()) :: [String.t()]
  def vehicles(dir), do: dir |> ls() |> Enum.filter(&valid_vehicle?/1) |> Enum.sort()

  @doc """
  The dives in `dir`, newest first (optionally of one vehicle), each as listed
  (`info/3`).
  """
  @spec list(Path.t(), String.t() | nil) :: [map()]
  def list(dir, vehicle \\ nil) do
    vehicles = if vehicle, do: [vehicle], else: vehicles(dir)

    for v <- vehicles,
        name <- ls(Path.join(dir, v)),
        valid?(v, name),
        info = info(dir, v, name),
        info != nil do
      info
    end
    |> Enum.sort_by(&{&1.started_at || 0, &1.vehicle, &1.name}, :desc)
  end

  @doc """
  One dive as listed, nil when there is none: `vehicle`, `name`, `legacy`, `bytes` (all its
  files), `modified_at` (its newest file, ms), the summary's fields (`Summary.to_map/2`:
  `started_at`, `ended_at`, `duration_ms`, `max_depth`, `pilots`, `stops`, `snapshots`,
  `entries`, `telemetry`, `closed`, and `interrupted` for a summary repaired after a killed
  node), `video` (`%{codec, segments, bytes}` or nil), `title` and `notes` (nil until
  someone gives them) and `problems` (what the listing found missing or damaged).
  """
  @spec info(Path.t(), String.t(), String.t()) :: map() | nil
  def info(dir, vehicle, name) do
    path = path(dir, vehicle, name)

    cond do
      legacy?(name) -> legacy_info(path, vehicle, name)
      File.dir?(path) -> folder_info(path, vehicle, name)
      true -> nil
    end
  end

  defp legacy_info(path, vehicle, name) do
    case File.stat(path, time: :posix) do
      {:ok, %File.Stat{type: :regular} = stat} ->
        started = Recording.started_at(name)
        modified = stat.mtime * 1000

        %{
          vehicle: vehicle,
          name: name,
          legacy: true,
          bytes: stat.size,
          modified_at: modified,
          started_at: started,
          ended_at: modified,
          duration_ms: if(started, do: max(modified - started, 0), else: nil),
          max_depth: nil,
          pilots: [],
          stops: nil,
          snapshots: 0,
          entries: nil,
          telemetry: nil,
          closed: true,
          interrupted: false,
          video: nil,
          title: nil,
          notes: nil,
          problems: []
        }

      _ ->
        nil
    end
  end

  defp folder_info(path, vehicle, name) do
    {bytes, modified} = du(path)
    started = Recording.started_at(name <> ".log")

    {summary, problems} =
      case read_json(Path.join(path, "summary.json")) do
        {:ok, %{} = summary} -> {summary, []}
        {:error, :enoent} -> {%{}, ["no summary (summary.json is missing)"]}
        {:error, reason} -> {%{}, ["summary.json unreadable: #{reason}"]}
      end

    notes =
      case read_json(Path.join(path, "notes.json")) do
        {:ok, %{} = notes} -> notes
        _ -> %{}
      end

    video = video_listing(video_folder(path))
    parts = parts(path)

    problems =
      problems ++
        if(parts == [], do: ["no entries (no entries-*.log file)"], else: []) ++
        video_problems(summary, video) ++ List.wrap(summary["problems"])

    %{
      vehicle: vehicle,
      name: name,
      legacy: false,
      bytes: bytes,
      modified_at: modified,
      started_at: summary["started_at"] || started,
      ended_at: summary["ended_at"],
      duration_ms: summary["duration_ms"],
      max_depth: summary["max_depth"],
      pilots: summary["pilots"] || [],
      stops: summary["stops"],
      snapshots: summary["snapshots"] || count_snapshots(path),
      entries: summary["entries"],
      telemetry: summary["telemetry"],
      closed: summary["closed"] == true,
      interrupted: summary["interrupted"] == true,
      video: video,
      title: string_or_nil(notes["title"]),
      notes: string_or_nil(notes["notes"]),
      problems: Enum.filter(problems, &is_binary/1)
    }
  end

  defp string_or_nil(s) when is_binary(s), do: s
  defp string_or_nil(_), do: nil

  defp video_problems(%{"video" => %{"frames" => frames}}, nil)
       when is_integer(frames) and frames > 0,
       do: ["the video is missing (#{frames} frames were recorded)"]

  defp video_problems(_summary, _video), do: []

  # the video folder's segments, without reading their indexes
  defp video_listing(folder) do
    files = ls(folder)
    data = Enum.filter(files, &Regex.match?(~r/\A\d{6}\.(h264|mjpeg)\z/, &1))

    if data == [] do
      nil
    else
      codec = if Enum.any?(data, &String.ends_with?(&1, ".h264")), do: "h264", else: "mjpeg"

      bytes =
        Enum.reduce(data, 0, fn name, acc ->
          case File.stat(Path.join(folder, name)) do
            {:ok, %{size: size}} -> acc + size
            _ -> acc
          end
        end)

      %{codec: codec, segments: length(data), bytes: bytes}
    end
  end

  defp count_snapshots(path),
    do: path |> snapshots_folder() |> ls() |> Enum.count(&String.ends_with?(&1, ".jpg"))

  # bytes and the newest modification (ms) of every file under `path`
  defp du(path) do
    path
    |> ls()
    |> Enum.reduce({0, 0}, fn name, {bytes, newest} ->
      child = Path.join(path, name)

      case File.lstat(child, time: :posix) do
        {:ok, %File.Stat{type: :directory}} ->
          {b, n} = du(child)
          {bytes + b, max(newest, n)}

        {:ok, %File.Stat{type: :regular, size: size, mtime: mtime}} ->
          {bytes + size, max(newest, mtime * 1000)}

        _ ->
          {bytes, newest}
      end
    end)
  end

  defp ls(dir) do
    case File.ls(dir) do
      {:ok, names} -> names
      {:error, _} -> []
    end
  end

  defp read_json(path) do
    with {:ok, text} <- File.read(path) do
      case JSON.decode(text) do
        {:ok, value} -> {:ok, value}
        {:error, reason} -> {:error, reason}
      end
    end
  end

  @doc """
  Writes `summary.json` of the dive folder `folder` (through a new file and a rename: a
  reader never sees half of it). `extra` adds fields (`video`, `interrupted`, `problems`).
  """
  @spec write_summary(Path.t(), Summary.t(), boolean(), map()) :: :ok | {:error, term()}
  def write_summary(folder, %Summary{} = summary, closed, extra \\ %{}) do
    write_json(
      Path.join(folder, "summary.json"),
      Map.merge(Summary.to_map(summary, closed), extra)
    )
  end

  defp write_json(path, value) do
    tmp = path <> ".tmp"

    with :ok <- File.write(tmp, JSON.encode!(value)) do
      File.rename(tmp, path)
    end
  end

  @doc """
  Makes the summary of a dive its node was killed in (`closed` false, not being written):
  folds its entries into a summary again (`Neptunus.Dive.Summary`), counts its video from
  the segments' indexes, and saves it closed, `interrupted`, with the problems found. The
  entries and video are only read.
  """
  @spec repair(Path.t()) :: :ok | {:error, term()}
  def repair(folder) do
    started = Recording.started_at(Path.basename(folder) <> ".log") || 0

    {summary, unreadable} =
      folder
      |> read()
      |> Enum.reduce({Summary.new(started), []}, fn
        {:unreadable, part, what}, {s, bad} -> {s, [{Path.basename(part), what} | bad]}
        entry, {s, bad} -> {Summary.add(s, entry), bad}
      end)

    segments = Video.segments(video_folder(folder))

    problems =
      Enum.map(Enum.reverse(unreadable), fn
        {part, :file} -> "#{part} cannot be read"
        {part, :rest} -> "#{part}: the end cannot be read (skipped)"
        {part, bytes} -> "#{part}: #{bytes} bytes are not entries (skipped)"
      end) ++ Enum.flat_map(segments, & &1.problems)

    write_summary(folder, summary, true, %{
      interrupted: true,
      video: video_summary(segments),
      problems: problems
    })
  end

  @doc "What the summary says of a dive's video, from its segments (nil without video)."
  @spec video_summary([Video.segment()]) :: map() | nil
  def video_summary([]), do: nil

  def video_summary(segments) do
    %{
      codec: segments |> Enum.find_value(& &1.codec),
      segments: length(segments),
      frames: Enum.reduce(segments, 0, &(length(&1.frames) + &2)),
      bytes: Enum.reduce(segments, 0, &(&1.bytes + &2))
    }
  end

  @doc "The dive folders of `vehicle` in `dir` whose summary is not closed."
  @spec unclosed(Path.t(), String.t()) :: [Path.t()]
  def unclosed(dir, vehicle) do
    for name <- ls(Path.join(dir, vehicle)),
        Regex.match?(@name_re, name),
        folder = path(dir, vehicle, name),
        File.dir?(folder),
        not closed?(folder),
        do: folder
  end

  defp closed?(folder) do
    case read_json(Path.join(folder, "summary.json")) do
      {:ok, %{"closed" => true}} -> true
      _ -> false
    end
  end

  @doc """
  Gives dive `folder` a title and notes (`%{"title" => ..., "notes" => ...}`, either may be
  left out to keep it; `by` is who, for the record): a title of at most #{@max_title}
  characters on one line, notes of at most #{@max_notes}. Saved in `notes.json`; the
  recorded files are not touched. A legacy recording cannot have notes (it is one file).
  """
  @spec put_notes(Path.t(), map(), String.t() | nil, integer()) :: {:ok, map()} | error()
  def put_notes(folder, changes, by, now_ms) when is_map(changes) do
    with :ok <- folder_dive(folder),
         {:ok, title} <- text(changes, "title", @max_title, false),
         {:ok, notes} <- text(changes, "notes", @max_notes, true) do
      old =
        case read_json(Path.join(folder, "notes.json")) do
          {:ok, %{} = old} -> old
          _ -> %{}
        end

      new = %{
        title: if(title == :keep, do: string_or_nil(old["title"]), else: title),
        notes: if(notes == :keep, do: string_or_nil(old["notes"]), else: notes),
        edited_at: now_ms,
        edited_by: by
      }

      case write_json(Path.join(folder, "notes.json"), new) do
        :ok ->
          {:ok, new}

        {:error, reason} ->
          {:error, :failed, "cannot save the notes: #{:file.format_error(reason)}"}
      end
    end
  end

  def put_notes(_folder, _changes, _by, _now_ms),
    do: {:error, :invalid, "send an object with title and/or notes"}

  defp folder_dive(folder) do
    cond do
      legacy?(Path.basename(folder)) ->
        {:error, :conflict, "a recording from before dives cannot have a title or notes"}

      File.dir?(folder) ->
        :ok

      true ->
        {:error, :not_found, "no such dive"}
    end
  end

  defp text(changes, key, max, multiline?) do
    case Map.fetch(changes, key) do
      :error ->
        {:ok, :keep}

      {:ok, nil} ->
        {:ok, nil}

      {:ok, value} when is_binary(value) ->
        value = String.trim(value)

        cond do
          not String.valid?(value) ->
            {:error, :invalid, "#{key} must be UTF-8 text"}

          String.length(value) > max ->
            {:error, :invalid, "#{key} must be at most #{max} characters"}

          Regex.match?(
            if(multiline?, do: ~r/[\x00-\x08\x0B-\x1F\x7F]/, else: ~r/[\x00-\x1F\x7F]/),
            value
          ) ->
            {:error, :invalid,
             "#{key} must not contain control characters#{if multiline?, do: " (but new lines and tabs)", else: " or new lines"}"}

          value == "" ->
            {:ok, nil}

          true ->
            {:ok, value}
        end

      {:ok, other} ->
        {:error, :invalid, "#{key} must be a string or null, got #{inspect(other)}"}
    end
  end

  @doc """
  Dives of `list` (from `list/2`) to delete under a retention of `keep_ms`: those last
  written more than `keep_ms` before `now_wall_ms`, never `current` (the dive being written,
  its path). Oldest first.

      iex> list = [%{vehicle: "rov", name: "b", modified_at: 9_000},
      ...>         %{vehicle: "rov", name: "a", modified_at: 1_000}]
      iex> Neptunus.Dive.expired(list, "recs", 10_000, 5_000, nil) |> Enum.map(& &1.name)
      ["a"]
      iex> Neptunus.Dive.expired(list, "recs", 10_000, 5_000, "recs/rov/a")
      []
  """
  @spec expired([map()], Path.t(), integer(), pos_integer(), Path.t() | nil) :: [map()]
  def expired(list, dir, now_wall_ms, keep_ms, current)
      when is_integer(keep_ms) and keep_ms > 0 do
    list
    |> Enum.filter(
      &(&1.modified_at < now_wall_ms - keep_ms and path(dir, &1.vehicle, &1.name) != current)
    )
    |> Enum.sort_by(& &1.modified_at)
  end

  @doc "Deletes a dive (its folder and everything in it, or a legacy file)."
  @spec delete(Path.t()) :: :ok | {:error, File.posix()}
  def delete(path) do
    if legacy?(Path.basename(path)) do
      File.rm(path)
    else
      case File.rm_rf(path) do
        {:ok, _} -> :ok
        {:error, reason, _file} -> {:error, reason}
      end
    end
  end
end
