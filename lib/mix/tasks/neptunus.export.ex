defmodule Mix.Tasks.Neptunus.Export do
  @shortdoc "Exports a recorded dive (MP4, MCAP, CSV, JSON lines, ASS)"
  @moduledoc """
  Exports a dive from the recordings folder, for scripts:

      mix neptunus.export VEHICLE/DIVE --format mp4|mcap|csv|jsonl|ass --out FILE [--dir DIR]

  `DIVE` is the dive's name in the recordings folder (`NEPTUNUS_RECORDINGS/VEHICLE/DIVE`, as
  `GET /api/recordings` lists it; a recording from before dives by its file name,
  `….log`). `--dir` is the recordings folder (default: `NEPTUNUS_RECORDINGS`, as the server
  reads it). The formats are those of `GET /api/recordings/VEHICLE/DIVE?format=…`
  (`Neptunus.Dive.Export`): MP4 (the video copied by ffmpeg, the telemetry subtitles as a
  track), MCAP (Foxglove: telemetry, events, log, video), CSV (the telemetry), JSON lines
  (every entry), ASS (the telemetry subtitles). The export is written to a temporary file
  next to FILE and renamed when complete, so FILE is never left half-written.

  It reads the files only: no server, no vehicle. A dive being recorded exports as far as it
  is on disk. A bad request stops the task with a message and a non-zero exit status.
  """
  use Mix.Task

  alias Neptunus.Dive
  alias Neptunus.Dive.Export

  @switches [format: :string, out: :string, dir: :string]

  @impl Mix.Task
  def run(args) do
    {opts, positional, invalid} = OptionParser.parse(args, strict: @switches)

    {vehicle, name} =
      case {positional, invalid} do
        {[dive], []} ->
          case String.split(dive, "/") do
            [vehicle, name] -> {vehicle, name}
            _ -> Mix.raise("DIVE must be VEHICLE/DIVE, got #{inspect(dive)}\n\n#{usage()}")
          end

        {_, [{option, _} | _]} ->
          Mix.raise("unknown or invalid option #{option}\n\n#{usage()}")

        _ ->
          Mix.raise(usage())
      end

    out = Keyword.get(opts, :out) || Mix.raise("--out FILE is required\n\n#{usage()}")
    format = Keyword.get(opts, :format) || Mix.raise("--format is required\n\n#{usage()}")

    # code and config only: the application (endpoint, vehicles) is not started
    Mix.Task.run("app.config")
    {:ok, _} = Application.ensure_all_started(:jiffy)

    dir =
      Keyword.get(opts, :dir) || get_in(Application.get_env(:neptunus, :recording, []), [:dir]) ||
        Mix.raise("recording is off (NEPTUNUS_RECORDINGS=off): give the folder with --dir")

    path = dive!(dir, vehicle, name)
    unless format in Export.formats(), do: Mix.raise(bad_format(format))
    out_dir = Path.dirname(Path.expand(out))

    cond do
      File.dir?(out) -> Mix.raise("--out #{out} is a folder: give a file name")
      not File.dir?(out_dir) -> Mix.raise("--out #{out}: the folder #{out_dir} does not exist")
      true -> :ok
    end

    options = %{
      "format" => format,
      "schemas" => %{"telemetry" => NeptunusWeb.API.Recordings.telemetry_schema()}
    }

    plan =
      case Export.plan(path, "#{vehicle}-#{Path.rootname(name)}", options) do
        {:ok, plan} -> plan
        {:error, _kind, reason} -> Mix.raise(reason)
      end

    write_file(plan, out)
  end

  # The dive's path, or a message that says what is there instead.
  defp dive!(dir, vehicle, name) do
    path = Dive.path(dir, vehicle, name)

    cond do
      not File.dir?(dir) ->
        Mix.raise("the recordings folder #{dir} does not exist")

      not Dive.valid_vehicle?(vehicle) ->
        Mix.raise(
          "VEHICLE must be a vehicle id (letters, digits, - and _), got #{inspect(vehicle)}"
        )

      not File.dir?(Path.join(dir, vehicle)) ->
        Mix.raise(
          "no recordings of vehicle #{vehicle} in #{dir}#{known(Dive.vehicles(dir), "vehicles")}"
        )

      not Dive.valid?(vehicle, name) or not File.exists?(path) ->
        names = dir |> Dive.list(vehicle) |> Enum.map(& &1.name)
        Mix.raise("no such dive: #{vehicle}/#{name} in #{dir}#{known(names, "dives")}")

      true ->
        path
    end
  end

  defp known([], what), do: " (no #{what} there)"
  defp known(names, what), do: " (#{what} there: #{Enum.join(Enum.take(names, 10), ", ")})"

  defp bad_format(format),
    do: "--format must be one of #{Enum.join(Export.formats(), ", ")}, got #{inspect(format)}"

  defp usage,
    do:
      "usage: mix neptunus.export VEHICLE/DIVE --format mp4|mcap|csv|jsonl|ass --out FILE [--dir DIR]"

  defp write_file(plan, out) do
    tmp =
      Path.join(
        Path.dirname(out),
        ".#{Path.basename(out)}.#{System.unique_integer([:positive])}.tmp"
      )

    started = Neptunus.Clock.monotonic_ms()

    try do
      bytes =
        File.open!(tmp, [:write, :raw, :binary, :delayed_write], fn device ->
          plan
          |> Export.stream()
          |> Enum.reduce(0, fn piece, bytes ->
            :ok = :file.write(device, piece)
            bytes + IO.iodata_length(piece)
          end)
        end)

      File.rename!(tmp, out)
      ms = Neptunus.Clock.monotonic_ms() - started
      Mix.shell().info("#{out}: #{bytes} bytes (#{plan.format}) in #{ms} ms")
    rescue
      error ->
        File.rm(tmp)
        Mix.raise("export failed: #{Exception.message(error)}")
    end
  end
end
