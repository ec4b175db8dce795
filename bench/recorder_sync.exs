# Recorder durability benchmark: what it costs to sync the recording to disk often enough that
# a killed node loses at most 0.25 s of telemetry (Neptunus.Vehicle.Recorder, "Durability").
#
#   bench/recorder_sync [SECONDS]      (default 60, or SYNC_SECONDS: the dive length per policy)
#
# disk_log keeps up to 64 KiB or 2 s of entries in memory; disk_log:sync/1 writes them and
# fsyncs the file. For each policy — disk_log alone, or a sync every 1 000, 250, 200, 100 or
# 50 ms of dive — it writes SECONDS of telemetry at 20 Hz (entries of a live vehicle's shape)
# as fast as it can, syncing as the policy says, and prints the time of one sync (median, 99th
# percentile, worst) and the CPU the VM spent per second of dive (user + system, from
# /proc/self/stat: the writes and fsyncs included). Then, in real time, a 100 Hz ticker at
# :high priority (the control path's place) measures how late it wakes while a process records
# at 20 Hz with disk_log alone and with the recorder's sync every 100 ms (SYNC_REAL_RUNS
# rounds, default 3, alternating, as the machine's load changes meanwhile). The directory is
# SYNC_DIR (default a temporary directory; point it at the vehicle's recording disk to
# measure that disk). Prints figures, never asserts.

Code.require_file("support/telemetry_sample.exs", __DIR__)

defmodule Bench.RecorderSync do
  @hz 20

  def main(args) do
    seconds =
      case args do
        [s] -> String.to_integer(s)
        [] -> String.to_integer(System.get_env("SYNC_SECONDS", "60"))
      end

    base = System.get_env("SYNC_DIR", System.tmp_dir!())
    dir = Path.join(base, "neptunus-sync-#{System.unique_integer([:positive])}")
    File.mkdir_p!(dir)

    try do
      entry_bytes = :erlang.external_size({1_795_000_000_000, "telemetry", payload(1)})

      IO.puts(
        "Neptunus recorder sync benchmark — #{seconds} s of dive per policy at #{@hz} Hz, " <>
          "entries of ≈ #{entry_bytes} bytes, in #{dir}\n"
      )

      IO.puts("Throughput (as fast as the disk allows):\n")

      IO.puts(
        pad("policy", 28) <>
          pad("syncs", 8) <>
          pad("sync median", 13) <>
          pad("sync p99", 11) <> pad("sync worst", 12) <> "VM CPU per s of dive"
      )

      for policy <- [nil, 1_000, 250, 200, 100, 50] do
        throughput(dir, policy, seconds)
      end

      {:ok, event} = one_event_sync(dir)
      IO.puts("\nOne event synced at once (open log, one entry, sync): median #{us(event)}\n")

      real = min(seconds, 10)

      IO.puts(
        "Real time (#{real} s per policy): a 100 Hz :high-priority ticker's lateness while " <>
          "the recorder records at #{@hz} Hz\n"
      )

      IO.puts(pad("policy", 28) <> pad("median", 10) <> pad("p99", 10) <> "worst")

      for policy <- List.duplicate([nil, 100], real_runs()) |> List.flatten() do
        real_time(dir, policy, real)
      end
    after
      File.rm_rf!(dir)
    end
  end

  defp real_runs, do: String.to_integer(System.get_env("SYNC_REAL_RUNS", "3"))

  defp name(nil), do: "disk_log alone (2 s cache)"
  defp name(ms), do: "sync every #{ms} ms"

  defp open(dir, tag) do
    path = Path.join(dir, "#{tag}-#{System.unique_integer([:positive])}.log")

    {:ok, log} =
      :disk_log.open(
        name: {:bench_sync, path},
        file: String.to_charlist(path),
        type: :halt,
        format: :internal,
        size: :infinity
      )

    log
  end

  defp throughput(dir, policy, seconds) do
    log = open(dir, "throughput")
    entries = seconds * @hz
    per_sync = if policy, do: max(div(policy * @hz, 1000), 1), else: nil
    cpu0 = cpu_ms()

    syncs =
      Enum.reduce(1..entries, [], fn i, syncs ->
        :ok = :disk_log.alog(log, {1_795_000_000_000 + i * 50, "telemetry", payload(i)})

        if per_sync && rem(i, per_sync) == 0 do
          {us, :ok} = :timer.tc(fn -> :disk_log.sync(log) end)
          [us | syncs]
        else
          syncs
        end
      end)

    :ok = :disk_log.close(log)
    cpu = cpu_ms() - cpu0
    sorted = Enum.sort(syncs)

    IO.puts(
      pad(name(policy), 28) <>
        pad("#{length(syncs)}", 8) <>
        pad(us(pct(sorted, 50)), 13) <>
        pad(us(pct(sorted, 99)), 11) <>
        pad(us(List.last(sorted)), 12) <>
        "#{Float.round(cpu / seconds, 2)} ms (#{Float.round(cpu / seconds / 10, 3)} % of a core)"
    )
  end

  defp one_event_sync(dir) do
    log = open(dir, "event")

    times =
      for i <- 1..50 do
        :ok = :disk_log.alog(log, {1_795_000_000_000 + i, "stopped", %{reason: "deadman"}})
        {us, :ok} = :timer.tc(fn -> :disk_log.sync(log) end)
        us
      end

    :ok = :disk_log.close(log)
    {:ok, pct(Enum.sort(times), 50)}
  end

  # The recorder's pattern in real time (a process writing at 20 Hz and syncing on its own
  # timer) next to a :high-priority ticker at 100 Hz on absolute deadlines.
  defp real_time(dir, policy, seconds) do
    log = open(dir, "real")
    parent = self()

    recorder =
      spawn_link(fn ->
        :timer.send_interval(div(1000, @hz), :entry)
        if policy, do: :timer.send_interval(policy, :sync)
        record(log, 0)
      end)

    ticker =
      spawn_link(fn ->
        Process.flag(:priority, :high)
        start = System.monotonic_time(:microsecond)
        tick(parent, start, 1, seconds * 100, [])
      end)

    lateness =
      receive do
        {:lateness, ^ticker, late} -> Enum.sort(late)
      end

    Process.unlink(recorder)
    Process.exit(recorder, :kill)
    :ok = :disk_log.close(log)

    IO.puts(
      pad(name(policy), 28) <>
        pad(us(pct(lateness, 50)), 10) <>
        pad(us(pct(lateness, 99)), 10) <> us(List.last(lateness))
    )
  end

  defp record(log, i) do
    receive do
      :entry ->
        :ok = :disk_log.alog(log, {1_795_000_000_000 + i * 50, "telemetry", payload(i)})
        record(log, i + 1)

      :sync ->
        :ok = :disk_log.sync(log)
        record(log, i)
    end
  end

  defp tick(parent, _start, n, total, late) when n > total,
    do: send(parent, {:lateness, self(), late})

  defp tick(parent, start, n, total, late) do
    deadline = start + n * 10_000
    wait = div(deadline - System.monotonic_time(:microsecond), 1000)
    if wait > 0, do: Process.sleep(wait)
    busy_until(deadline)
    tick(parent, start, n + 1, total, [System.monotonic_time(:microsecond) - deadline | late])
  end

  # Process.sleep has millisecond resolution: the last part of the wait in a yield loop
  defp busy_until(deadline) do
    if System.monotonic_time(:microsecond) < deadline do
      :erlang.yield()
      busy_until(deadline)
    end
  end

  # CPU time of the VM's OS process (user + system), ms
  defp cpu_ms do
    stat = File.read!("/proc/self/stat")
    [_, rest] = String.split(stat, ") ", parts: 2)
    fields = String.split(rest)
    # fields after the command: state is 3rd in the man page, utime 14th, stime 15th
    utime = String.to_integer(Enum.at(fields, 11))
    stime = String.to_integer(Enum.at(fields, 12))
    (utime + stime) * 1000 / ticks_per_second()
  end

  defp ticks_per_second do
    case System.cmd("getconf", ["CLK_TCK"]) do
      {out, 0} -> out |> String.trim() |> String.to_integer()
      _ -> 100
    end
  end

  defp pct([], _p), do: nil
  defp pct(sorted, p), do: Enum.at(sorted, min(div(length(sorted) * p, 100), length(sorted) - 1))

  defp us(nil), do: "-"
  defp us(us) when us >= 1000, do: "#{Float.round(us / 1000, 2)} ms"
  defp us(us), do: "#{us} µs"

  defp pad(text, n), do: String.pad_trailing(text, n)

  defp payload(i), do: Bench.TelemetrySample.payload(i)
end

Bench.RecorderSync.main(System.argv())
