# Simulator benchmark: headless speed of one vehicle, and 100 live simulated vehicles at 100 Hz.
#
#   bench/sim [VEHICLES] [SECONDS]          (defaults 100 and 10; or SIM_VEHICLES / SIM_SECONDS)
#
# Run through bench/sim (MIX_ENV=prod mix run --no-start bench/sim.exs). Prints figures, never
# asserts. Starts only what vehicles need (PubSub and the fleet), not the web endpoint.
# BENCH_SMOKE=1: a smoke run (bench/smoke): 1 000 headless steps once, a short warm-up.

Code.require_file("support/proc.exs", __DIR__)

defmodule Bench.Sim do
  alias Neptunus.{Scenario, Sim}
  alias Neptunus.Vehicle.Board

  def main(args) do
    Logger.configure(level: :warning)

    [vehicles, seconds] =
      case args do
        [v, s] -> [String.to_integer(v), String.to_integer(s)]
        [v] -> [String.to_integer(v), env_int("SIM_SECONDS", 10)]
        [] -> [env_int("SIM_VEHICLES", 100), env_int("SIM_SECONDS", 10)]
      end

    IO.puts(
      "Neptunus simulator benchmark — #{System.schedulers_online()} schedulers, " <>
        "OTP #{System.otp_release()}, #{:erlang.system_info(:emu_flavor)}\n"
    )

    headless(smoke?())
    live(vehicles, seconds, smoke?())
  end

  defp smoke?, do: System.get_env("BENCH_SMOKE") == "1"

  # --- headless ---

  defp headless(smoke?) do
    {n, runs} = if smoke?, do: {1_000, 1}, else: {100_000, 3}
    IO.puts("## Headless, one vehicle, dt = 0.01 s (best of #{runs} runs of #{n} steps)")
    IO.puts("   loop: elixir = Neptunus.Dynamics on the BEAM; C = Neptunus.Dynamics.Native")

    IO.puts(
      "   (bit-identical results). C library loaded: #{Neptunus.Dynamics.Native.available?()}"
    )

    cmd = %{port: 0.6, vertical: -0.3, starboard: 0.4}

    cases = [
      {"thesis-4dof, ideal sensors", [vehicle: "thesis-4dof"]},
      {"neptunus, ideal sensors", [vehicle: "neptunus"]},
      {"neptunus, noisy sensors (20 Hz)", [vehicle: "neptunus", noise: true]},
      {"neptunus, ideal sensors, varying current",
       [
         vehicle: "neptunus",
         current: {0.1, 0.0, 0.0},
         current_variation: [sigma: 0.02, time_constant: 30]
       ]},
      {"neptunus, noisy sensors, varying current",
       [
         vehicle: "neptunus",
         noise: true,
         current: {0.1, 0.0, 0.0},
         current_variation: [sigma: 0.02, time_constant: 30]
       ]}
    ]

    for {label, opts} <- cases, {loop, native} <- [{"elixir", false}, {"C", true}] do
      label = "#{label} [#{loop}]"
      sim = (opts ++ [native: native]) |> Sim.new() |> Sim.command(cmd) |> Sim.step(1_000)

      us =
        for _ <- 1..runs do
          {us, _} = :timer.tc(fn -> Sim.step(sim, n) end)
          us
        end
        |> Enum.min()

      rate = n / (us / 1.0e6)

      IO.puts(
        "  #{String.pad_trailing(label, 52)} #{fmt(rate, 0)} steps/s  = #{fmt(rate * 0.01, 0)}x real time  (#{fmt(us / n, 2)} µs/step)"
      )
    end

    path = Path.join(:code.priv_dir(:neptunus), "scenarios/dive-and-turn.json")
    {:ok, scenario} = path |> File.read!() |> Scenario.parse()

    {us, rows} =
      :timer.tc(fn ->
        scenario
        |> Scenario.Run.csv()
        |> Enum.reduce(0, fn line, n ->
          _ = IO.iodata_length(line)
          n + 1
        end)
      end)

    IO.puts(
      "  scenario dive-and-turn.json to CSV (#{rows - 1} rows)   #{fmt((rows - 1) / (us / 1.0e6), 0)} rows/s = #{fmt(scenario.duration / (us / 1.0e6), 0)}x real time"
    )

    IO.puts("")
  end

  # --- live ---

  defp live(vehicles, seconds, smoke?) do
    IO.puts(
      "## Live: #{vehicles} simulated vehicles (neptunus, noisy sensors) at 100 Hz, telemetry 20 Hz, #{seconds} s"
    )

    # PubSub as the application starts it (its broadcasts encoded for the wire)
    {:ok, _} =
      Supervisor.start_link(
        [{Neptunus.PubSub, encoder: NeptunusWeb.Channels.Wire}, {Neptunus.Fleet, []}],
        strategy: :one_for_one
      )

    ids = for i <- 1..vehicles, do: "bench-#{i}"

    {us, _} =
      :timer.tc(fn ->
        Enum.each(
          ids,
          &({:ok, _} = Neptunus.Fleet.start_vehicle(%{id: &1, board: :simulated, stats: true}))
        )
      end)

    warm_up_ms = if smoke?, do: 200, else: 2_000
    IO.puts("  started in #{fmt(us / 1000, 0)} ms; warming up #{warm_up_ms} ms")
    Process.sleep(warm_up_ms)
    Enum.each(ids, &Board.Simulated.stats(&1, reset: true))
    t0 = Enum.map(ids, &Sim.time(Board.Simulated.state(&1).sim))

    cpu0 = cpu_ticks()
    machine0 = machine_ticks()
    pressure0 = cpu_pressure()
    wall0 = System.monotonic_time(:microsecond)
    :erlang.statistics(:scheduler_wall_time_all)
    :erlang.system_flag(:scheduler_wall_time, true)
    sched0 = :erlang.statistics(:scheduler_wall_time_all)
    Process.sleep(seconds * 1_000)
    sched1 = :erlang.statistics(:scheduler_wall_time_all)
    wall = System.monotonic_time(:microsecond) - wall0
    cpu = cpu_ticks() - cpu0
    {busy1, total1} = machine_ticks()
    {busy0, total0} = machine0
    pressure = cpu_pressure() - pressure0

    states = Enum.map(ids, &Board.Simulated.state/1)
    stats = Enum.map(ids, &Board.Simulated.stats/1)
    lateness = stats |> Enum.flat_map(& &1.lateness) |> Enum.sort()
    work = stats |> Enum.flat_map(& &1.work) |> Enum.sort()
    abs_late = lateness |> Enum.map(&abs/1) |> Enum.sort()
    advanced = states |> Enum.zip(t0) |> Enum.map(fn {s, t} -> Sim.time(s.sim) - t end)
    skipped = states |> Enum.map(& &1.skipped_steps) |> Enum.sum()

    ticks = length(lateness)
    expected = vehicles * seconds * 100

    IO.puts(
      "  ticks handled: #{ticks} (#{fmt(ticks / (wall / 1.0e6) / vehicles, 1)} per vehicle per s; expected #{expected})"
    )

    IO.puts(
      "  simulated time advanced per vehicle: min #{fmt(Enum.min(advanced), 2)} s, max #{fmt(Enum.max(advanced), 2)} s over #{fmt(wall / 1.0e6, 2)} s wall; steps skipped after stalls: #{skipped}"
    )

    IO.puts(
      "  tick lateness vs its deadline (µs; negative = early, the timer has 1 ms resolution):"
    )

    IO.puts(
      "    p1 #{pct(lateness, 0.01)}  p50 #{pct(lateness, 0.5)}  p90 #{pct(lateness, 0.9)}  p99 #{pct(lateness, 0.99)}  p99.9 #{pct(lateness, 0.999)}  max #{List.last(lateness)}"
    )

    IO.puts(
      "    |lateness| (jitter) p50 #{pct(abs_late, 0.5)}  p99 #{pct(abs_late, 0.99)}  max #{List.last(abs_late)}"
    )

    IO.puts(
      "  tick work (step + sample + telemetry cast, µs): p50 #{pct(work, 0.5)}  p99 #{pct(work, 0.99)}  max #{List.last(work)}"
    )

    IO.puts(
      "  CPU of this BEAM: #{fmt(100 * cpu / (wall / 1.0e6) / clk_tck(), 1)} % of one core (/proc/self/stat utime+stime)"
    )

    IO.puts(
      "  scheduler utilisation: #{fmt(100 * utilisation(sched0, sched1), 1)} % (all #{System.schedulers_online()} schedulers)"
    )

    IO.puts(
      "  whole machine during the run: CPU busy #{fmt(100 * (busy1 - busy0) / max(total1 - total0, 1), 1)} % " <>
        "of #{System.schedulers_online()} cores (all processes, other people's too), " <>
        "CPU pressure (some) #{fmt(100 * pressure / wall, 1)} % of the time, " <>
        "load average #{File.read!("/proc/loadavg") |> String.split() |> Enum.take(3) |> Enum.join(" ")}"
    )
  end

  defp utilisation(s0, s1) do
    {active, total} =
      Enum.zip(Enum.sort(s0), Enum.sort(s1))
      |> Enum.filter(fn {{id, _, _}, _} -> id <= System.schedulers_online() end)
      |> Enum.reduce({0, 0}, fn {{_, a0, t0}, {_, a1, t1}}, {a, t} ->
        {a + a1 - a0, t + t1 - t0}
      end)

    if total == 0, do: 0.0, else: active / total
  end

  defp cpu_ticks, do: Bench.Proc.cpu_ticks()

  # {busy, total} jiffies of the whole machine (/proc/stat)
  defp machine_ticks, do: Bench.Proc.machine_ticks()

  # total µs some task waited for a CPU (/proc/pressure/cpu), 0 where unavailable
  defp cpu_pressure do
    with {:ok, text} <- File.read("/proc/pressure/cpu"),
         [_, total] <- Regex.run(~r/some .*total=(\d+)/, text) do
      String.to_integer(total)
    else
      _ -> 0
    end
  end

  defp clk_tck do
    case System.cmd("getconf", ["CLK_TCK"]) do
      {n, 0} -> n |> String.trim() |> String.to_integer()
      _ -> 100
    end
  end

  defp pct([], _), do: "-"
  defp pct(sorted, p), do: Enum.at(sorted, min(length(sorted) - 1, floor(p * length(sorted))))

  defp fmt(x, 0), do: x |> round() |> Integer.to_string()
  defp fmt(x, d), do: :erlang.float_to_binary(x * 1.0, decimals: d)

  defp env_int(name, default) do
    case System.get_env(name) do
      nil -> default
      value -> String.to_integer(value)
    end
  end
end

Bench.Sim.main(System.argv())
