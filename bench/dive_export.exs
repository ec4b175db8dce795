# Dive export benchmark: time and peak memory of exporting a long dive with video, as
# GET /api/recordings/… and mix neptunus.export stream it (Neptunus.Dive.Export).
#
#   bench/dive_export [MINUTES]      (default 60: one hour)
#
# Writes a dive folder like the recorder's (test/support/dives.ex): telemetry at 20 Hz of a
# live vehicle's shape, and H.264 video at 15 fps, 320x240 (ffmpeg's test pattern, 10 s of
# access units repeated with the dive's times; a keyframe a second), then exports it to CSV,
# JSON lines, MCAP and MP4 into /dev/null-like sinks. Peak memory is the VM's total, sampled
# every 5 ms by another process (ffmpeg's own memory, for the MP4, is not in it). Prints
# figures, never asserts.

Code.require_file("support/telemetry_sample.exs", __DIR__)
Code.require_file("support/export_figures.exs", __DIR__)
Code.require_file("../test/support/dives.ex", __DIR__)

defmodule Bench.DiveExport do
  alias Neptunus.Dive.Export
  alias Neptunus.Test.Dives
  import Bench.ExportFigures

  @fps 15
  @start_ms 1_795_000_000_000

  def main(args) do
    minutes =
      case args do
        [m] -> String.to_integer(m)
        [] -> String.to_integer(System.get_env("EXPORT_MINUTES", "60"))
      end

    {:ok, _} = Application.ensure_all_started(:jiffy)

    dir =
      Path.join(System.tmp_dir!(), "neptunus-dive-export-#{System.unique_integer([:positive])}")

    File.mkdir_p!(dir)

    try do
      seconds = minutes * 60
      aus = Dives.h264(10 * @fps, fps: @fps, gop: @fps, size: "320x240")
      keys = Enum.map(aus, &Dives.keyframe?/1)
      n_frames = seconds * @fps
      frame_us = div(1_000_000, @fps)

      frames =
        Stream.zip(Stream.cycle(aus), Stream.cycle(keys))
        |> Stream.take(n_frames)
        |> Stream.with_index()
        |> Stream.map(fn {{au, key}, i} -> {@start_ms * 1000 + i * frame_us, key, au} end)

      n_entries = seconds * 20

      entries =
        Stream.map(1..n_entries, fn i ->
          {@start_ms + i * 50, "telemetry", Bench.TelemetrySample.payload(i)}
        end)

      {write_us, folder} =
        :timer.tc(fn ->
          Dives.write!(dir, "rov", "20261122-120000Z-1", entries, frames,
            started_at: @start_ms,
            segment_frames: 60 * @fps,
            info: %{codec: "h264", generation: 1, width: 320, height: 240, fps: @fps}
          )
        end)

      IO.puts(
        "Neptunus dive export benchmark — #{minutes} min: #{n_entries} telemetry entries at " <>
          "20 Hz, #{n_frames} H.264 frames at #{@fps} fps (320x240), #{mb(du(folder))} on disk " <>
          "(written in #{s(write_us)})\n"
      )

      :erlang.garbage_collect()
      baseline = :erlang.memory(:total)
      IO.puts("VM memory before each run: #{mb(baseline)}\n")
      schemas = %{"telemetry" => NeptunusWeb.API.Recordings.telemetry_schema()}

      for format <- ~w(csv jsonl mcap mp4) do
        row(format, 8, baseline, fn ->
          {:ok, plan} = Export.plan(folder, "bench", %{"format" => format, "schemas" => schemas})
          plan |> Export.stream() |> Enum.reduce(0, &(&2 + IO.iodata_length(&1)))
        end)
      end
    after
      File.rm_rf!(dir)
    end
  end

  defp du(folder) do
    Path.join(folder, "**")
    |> Path.wildcard()
    |> Enum.filter(&File.regular?/1)
    |> Enum.map(&File.stat!(&1).size)
    |> Enum.sum()
  end
end

Bench.DiveExport.main(System.argv())
