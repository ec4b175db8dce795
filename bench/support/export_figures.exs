# Shared by the export benchmarks (dive_export, recording_export): one export's size, time,
# throughput and the VM's peak memory while it runs, printed as a row.
defmodule Bench.ExportFigures do
  @moduledoc false

  @doc """
  Runs `fun` (it returns how many bytes it exported) in a task and prints a row: `label`
  padded to `width`, the bytes, the time, MB/s and how far the VM's total memory rose above
  `baseline` at its peak (sampled every 5 ms by another process).
  """
  def row(label, width, baseline, fun) do
    :erlang.garbage_collect()
    sampler = spawn_link(fn -> sample(baseline) end)
    {us, bytes} = :timer.tc(fn -> Task.async(fun) |> Task.await(:infinity) end)
    send(sampler, {:report, self()})

    peak =
      receive do
        {:peak, peak} -> peak
      end

    IO.puts(
      "#{String.pad_trailing(label <> ":", width)} #{mb(bytes)} in #{s(us)} " <>
        "(#{Float.round(bytes / 1_048_576 / (us / 1_000_000), 1)} MB/s), peak VM memory +#{mb(peak - baseline)}"
    )
  end

  defp sample(peak) do
    receive do
      {:report, to} -> send(to, {:peak, max(peak, :erlang.memory(:total))})
    after
      5 -> sample(max(peak, :erlang.memory(:total)))
    end
  end

  @doc "Bytes as MB (MiB, one decimal)."
  def mb(bytes), do: "#{Float.round(bytes / 1_048_576, 1)} MB"

  @doc "Microseconds as seconds (two decimals)."
  def s(us), do: "#{Float.round(us / 1_000_000, 2)} s"
end
