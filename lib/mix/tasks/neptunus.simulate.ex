defmodule Mix.Tasks.Neptunus.Simulate do
  @shortdoc "Runs a headless simulation scenario and writes CSV"
  @moduledoc """
  Runs a scenario (JSON, see `Neptunus.Scenario` and the README) on the simulator headless
  and writes one CSV row per integration step.

      mix neptunus.simulate SCENARIO.json [--out run.csv] [--every N]

    * `--out FILE` — write the CSV to FILE (written to a temporary file next to it and
      renamed when complete, so FILE is never left half-written); without it, CSV goes to
      stdout.
    * `--every N` — keep only every N-th row (the simulation still steps at `dt`).

  A bad scenario (unknown or missing field, wrong type, value out of range, unknown
  vehicle) stops the task with a message naming the field and a non-zero exit status;
  no output file is created.

  The task loads the project's code and configuration only: no web endpoint, no vehicles.
  """
  use Mix.Task

  alias Neptunus.Scenario

  @switches [out: :string, every: :integer]

  @impl Mix.Task
  def run(args) do
    {opts, files, invalid} = OptionParser.parse(args, strict: @switches)

    file =
      case {files, invalid} do
        {[file], []} ->
          file

        {_, [{option, _} | _]} ->
          Mix.raise("unknown or invalid option #{option}\n\n#{usage()}")

        _ ->
          Mix.raise(usage())
      end

    every = Keyword.get(opts, :every, 1)
    if every < 1, do: Mix.raise("--every must be a positive integer, got #{every}")

    # code and config only: the application (endpoint, vehicles) is not started
    Mix.Task.run("app.config")

    scenario =
      with {:ok, json} <- Neptunus.Validate.read_file(file),
           {:ok, scenario} <- Scenario.parse(json) do
        scenario
      else
        {:error, reason} -> Mix.raise("#{file}: #{reason}")
      end

    case Keyword.fetch(opts, :out) do
      {:ok, out} -> write_file(scenario, every, out)
      :error -> scenario |> Scenario.Run.csv(every) |> Enum.each(&IO.binwrite/1)
    end
  end

  defp usage, do: "usage: mix neptunus.simulate SCENARIO.json [--out run.csv] [--every N]"

  defp write_file(scenario, every, out) do
    tmp =
      Path.join(
        Path.dirname(out),
        ".#{Path.basename(out)}.#{System.unique_integer([:positive])}.tmp"
      )

    started = Neptunus.Clock.monotonic_ms()

    try do
      rows =
        File.open!(tmp, [:write, :raw, :delayed_write], fn device ->
          scenario
          |> Scenario.Run.csv(every)
          |> Stream.chunk_every(256)
          |> Enum.reduce(-1, fn chunk, rows ->
            :ok = IO.binwrite(device, chunk)
            rows + length(chunk)
          end)
        end)

      File.rename!(tmp, out)
      ms = Neptunus.Clock.monotonic_ms() - started

      Mix.shell().info(
        "#{out}: #{rows} rows, #{scenario.vehicle}, #{scenario.duration} s at dt #{scenario.dt} s " <>
          "(#{ms} ms, #{realtime(scenario.duration, ms)}x real time)"
      )
    rescue
      error ->
        File.rm(tmp)
        Mix.raise("#{out}: #{Exception.message(error)}")
    end
  end

  defp realtime(_duration, 0), do: "> 1000"
  defp realtime(duration, ms), do: round(duration * 1000 / ms)
end
