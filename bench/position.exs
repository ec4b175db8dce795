# Position hold and missions, headless, over many seeds: how close each vehicle holds a point
# in a 0.1 m/s current with a DVL, with a USBL only, and with both, and how closely it follows a
# four-waypoint mission — on the simulated DVL and USBL (noise, dropouts, delay, outliers), the
# live navigation filter and the live control (`Neptunus.Scenario.Run`).
#
#   bench/position [SEEDS]          (default 8, or POSITION_SEEDS)
#
# Run through bench/position (MIX_ENV=prod mix run --no-start bench/position.exs). Prints
# figures, never asserts. The errors are the truth's: the simulator's true position against
# the target (so a drifting estimate counts), and against the mission's legs; beside them the
# estimate's RMS against the true position while valid (`Neptunus.Scenario.MonteCarlo`'s
# statistics, as `mix neptunus.simulate --runs` prints them).
# BENCH_SMOKE=1 (bench/smoke, which make test runs): one seed, holds of 60 s judged from 20 s,
# the missions whole — seconds, to show the bench still starts and prints; its figures mean
# little then.

defmodule Bench.Position do
  alias Neptunus.Scenario
  alias Neptunus.Scenario.{MonteCarlo, Run}

  @current [0.0, 0.1, 0.0]
  @mission_speed 0.3

  def main(args) do
    Logger.configure(level: :warning)

    smoke? = System.get_env("BENCH_SMOKE") == "1"

    seeds =
      case args do
        [n] -> String.to_integer(n)
        [] -> String.to_integer(System.get_env("POSITION_SEEDS", if(smoke?, do: "1", else: "8")))
      end

    # a hold's length and when its radius starts counting, s
    {hold_s, settle_s} = if smoke?, do: {60, 20}, else: {150, 40}

    IO.puts(
      "Neptunus position bench — #{System.schedulers_online()} schedulers, " <>
        "#{seeds} seeds per row, current #{inspect(@current)} m/s (NED), " <>
        "load #{load()}\n"
    )

    IO.puts(
      "## Position hold (DP), #{hold_s} s, radius from #{settle_s} s on (m, true position to target)"
    )

    IO.puts("| vehicle | sources | p50 | p95 | max | valid % | estimate RMS (m) |")
    IO.puts("|---|---|---|---|---|---|---|")

    for vehicle <- ["neptunus-sway", "neptunus"],
        {label, position} <- [
          {"DVL", %{"dvl" => true}},
          {"USBL only", %{"usbl" => true}},
          {"DVL + USBL", %{"dvl" => true, "usbl" => true}}
        ] do
      results = for seed <- 1..seeds, do: hold(vehicle, position, seed, hold_s, settle_s)
      radii = Enum.flat_map(results, & &1.radii)

      valid =
        Enum.sum(Enum.map(results, & &1.valid)) / max(Enum.sum(Enum.map(results, & &1.rows)), 1)

      rms = results |> Enum.flat_map(& &1.errors) |> MonteCarlo.rms()

      IO.puts(
        "| #{vehicle} | #{label} | #{f(pct(radii, 50))} | #{f(pct(radii, 95))} | " <>
          "#{f(Enum.max(radii, fn -> nil end))} | #{f(100 * valid, 1)} | #{f(rms)} |"
      )
    end

    IO.puts("\n## Mission: a 10 m square at #{@mission_speed} m/s, depth 3 m, DVL + USBL")
    IO.puts("(cross-track: the true position's distance from the leg's line, legs 2–4)")

    IO.puts(
      "| vehicle | cross-track p50 | p95 | max | done in (s, median) | runs done | estimate RMS (m) |"
    )

    IO.puts("|---|---|---|---|---|---|---|")

    for vehicle <- ["neptunus-sway", "neptunus"] do
      results = for seed <- 1..seeds, do: mission(vehicle, seed)
      xt = Enum.flat_map(results, & &1.cross_track)
      done = results |> Enum.map(& &1.done_at) |> Enum.reject(&is_nil/1)

      IO.puts(
        "| #{vehicle} | #{f(pct(xt, 50))} | #{f(pct(xt, 95))} | #{f(Enum.max(xt, fn -> nil end))} | " <>
          "#{f(pct(done, 50), 0)} | #{length(done)}/#{seeds} | " <>
          "#{f(results |> Enum.flat_map(& &1.errors) |> MonteCarlo.rms())} |"
      )
    end
  end

  defp scenario(vehicle, position, seed, duration, events) do
    {:ok, s} =
      Scenario.validate(%{
        "vehicle" => vehicle,
        "duration" => duration,
        "seed" => seed,
        "noise" => true,
        "current" => @current,
        "initial" => %{"z" => 2.0},
        "position" => position,
        "events" => events
      })

    s
  end

  defp hold(vehicle, position, seed, hold_s, settle_s) do
    events = [
      %{"t" => 0, "autopilot" => %{"depth" => "hold", "heading" => "hold"}},
      %{"t" => 5, "control_mode" => "dp"}
    ]

    s = scenario(vehicle, position, seed, hold_s, events)
    cols = index()

    rows =
      s
      |> Run.rows(10)
      |> Enum.filter(fn row -> at(row, cols, "t") >= settle_s end)

    radii =
      for row <- rows,
          tn = at(row, cols, "target_north"),
          te = at(row, cols, "target_east"),
          is_number(tn) and is_number(te) do
        :math.sqrt(sq(at(row, cols, "x") - tn) + sq(at(row, cols, "y") - te))
      end

    %{
      radii: radii,
      rows: length(rows),
      valid: Enum.count(rows, &(at(&1, cols, "position_valid") == 1.0)),
      errors: estimate_errors(rows, cols)
    }
  end

  # the estimate's distance from the truth, while valid
  defp estimate_errors(rows, cols) do
    for row <- rows, at(row, cols, "position_valid") == 1.0 do
      :math.sqrt(
        sq(at(row, cols, "north_est") - at(row, cols, "x")) +
          sq(at(row, cols, "east_est") - at(row, cols, "y"))
      )
    end
  end

  defp mission(vehicle, seed) do
    # from where it holds at (0, 0): a 10 m square, each corner reached within 0.5 m
    square = [{10.0, 0.0}, {10.0, 10.0}, {0.0, 10.0}, {0.0, 0.0}]

    waypoints =
      for {n, e} <- square,
          do: %{"north" => n, "east" => e, "depth" => 3.0, "speed" => @mission_speed}

    events = [
      %{"t" => 0, "autopilot" => %{"depth" => "hold", "heading" => "hold"}},
      %{"t" => 5, "control_mode" => "dp"},
      %{"t" => 30, "mission" => %{"waypoints" => waypoints}}
    ]

    s = scenario(vehicle, %{"dvl" => true, "usbl" => true}, seed, 260, events)
    cols = index()
    rows = Run.rows(s, 10) |> Enum.to_list()
    legs = Enum.zip([{0.0, 0.0} | square], square)

    cross_track =
      for row <- rows,
          leg = at(row, cols, "leg"),
          is_number(leg) and leg >= 2 and leg <= 4 do
        {a, b} = Enum.at(legs, trunc(leg) - 1)
        line_distance({at(row, cols, "x"), at(row, cols, "y")}, a, b)
      end

    # done: the last waypoint reached (the leg counter stops moving and the target is set on it)
    done_at =
      Enum.find_value(rows, fn row ->
        t = at(row, cols, "t")
        tn = at(row, cols, "target_north")
        te = at(row, cols, "target_east")

        if t > 35 and is_number(tn) and is_number(te) and at(row, cols, "leg") == 4.0 and
             abs(tn) < 1.0e-6 and abs(te) < 1.0e-6,
           do: t - 30
      end)

    %{cross_track: cross_track, done_at: done_at, errors: estimate_errors(rows, cols)}
  end

  defp line_distance({x, y}, {an, ae}, {bn, be}) do
    {dn, de} = {bn - an, be - ae}
    len = :math.sqrt(dn * dn + de * de)
    abs((x - an) * de - (y - ae) * dn) / len
  end

  defp index, do: Run.columns() |> Enum.with_index() |> Map.new()
  defp at(row, cols, name), do: Enum.at(row, Map.fetch!(cols, name))
  defp sq(x), do: x * x

  defp pct(values, p), do: MonteCarlo.percentile(values, p)

  defp f(x, decimals \\ 2)
  defp f(nil, _decimals), do: "—"
  defp f(x, decimals), do: :erlang.float_to_binary(x * 1.0, decimals: decimals)

  defp load do
    case File.read("/proc/loadavg") do
      {:ok, text} -> text |> String.split() |> Enum.take(3) |> Enum.join(" ")
      _ -> "?"
    end
  end
end

Bench.Position.main(System.argv())
