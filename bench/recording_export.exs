# Recording export benchmark: time and peak memory of exporting a long recording, streamed (as
# GET /api/recordings/… does) against reading it whole into memory (as it did before).
#
#   bench/recording_export [MINUTES]      (default 60: a recording of one hour at 20 Hz)
#
# Writes a disk_log file like the recorder's (telemetry payloads of a live vehicle's shape) to a
# temporary directory, then exports it. Peak memory is the VM's total, sampled every 5 ms by
# another process. Prints figures, never asserts.

Code.require_file("support/telemetry_sample.exs", __DIR__)
Code.require_file("support/export_figures.exs", __DIR__)

defmodule Bench.RecordingExport do
  alias Neptunus.Recording
  import Bench.ExportFigures

  def main(args) do
    minutes =
      case args do
        [m] -> String.to_integer(m)
        [] -> String.to_integer(System.get_env("EXPORT_MINUTES", "60"))
      end

    dir = Path.join(System.tmp_dir!(), "neptunus-export-#{System.unique_integer([:positive])}")
    File.mkdir_p!(dir)

    try do
      path = Path.join(dir, "20261122-120000Z-1.log")
      entries = minutes * 60 * 20
      {write_us, _} = :timer.tc(fn -> write(path, entries) end)

      IO.puts(
        "Neptunus recording export benchmark — #{minutes} min at 20 Hz: #{entries} telemetry " <>
          "entries, #{mb(File.stat!(path).size)} on disk (written in #{s(write_us)})\n"
      )

      :erlang.garbage_collect()
      baseline = :erlang.memory(:total)
      IO.puts("VM memory before each run: #{mb(baseline)}\n")

      row("streamed CSV (two passes, 64 KiB chunks)", 46, baseline, fn -> streamed_csv(path) end)
      row("streamed JSON lines", 46, baseline, fn -> streamed_jsonl(path) end)
      row("CSV of the whole file in memory (before)", 46, baseline, fn -> eager_csv(path) end)
    after
      File.rm_rf!(dir)
    end
  end

  defp write(path, count) do
    {:ok, log} =
      :disk_log.open(
        name: :bench_export,
        file: String.to_charlist(path),
        type: :halt,
        format: :internal,
        size: :infinity
      )

    Enum.each(1..count, fn i ->
      :ok = :disk_log.log(log, {1_795_000_000_000 + i * 50, "telemetry", payload(i)})
    end)

    :ok = :disk_log.close(log)
  end

  defp payload(i), do: Bench.TelemetrySample.payload(i)

  defp streamed_csv(path) do
    summary = path |> Recording.entries() |> Recording.scan()

    path
    |> Recording.entries()
    |> Stream.take(summary.entries)
    |> Recording.csv_stream(summary.columns)
    |> sink()
  end

  defp streamed_jsonl(path),
    do: path |> Recording.entries() |> Recording.json_lines_stream() |> sink()

  defp eager_csv(path) do
    path |> Recording.entries() |> Enum.to_list() |> Recording.csv() |> IO.iodata_length()
  end

  # what the HTTP side does with a stream: 64 KiB chunks, each sent and dropped
  defp sink(lines) do
    lines
    |> Stream.chunk_every(500)
    |> Enum.reduce(0, fn chunk, bytes -> bytes + IO.iodata_length(chunk) end)
  end
end

Bench.RecordingExport.main(System.argv())
