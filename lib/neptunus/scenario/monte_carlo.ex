defmodule Neptunus.Scenario.MonteCarlo do
  @moduledoc """
  A Monte Carlo over a scenario (`mix neptunus.simulate SCENARIO.json --runs N`), pure: the
  options checked, each run's draw of the current and the position sources' noise from its
  own seed, the scenario that draw makes, the figures of one run from its rows
  (`Neptunus.Scenario.Run`), and the statistics over the runs. Running is the caller's.

  ## Draws

  Run `k` (1-based) of a Monte Carlo from seed `S` has the seed `S + k − 1`. Everything
  random about it comes from that seed alone: the draw (a `:rand` stream seeded with it, the
  same order of draws whatever the ranges) and the simulation (the scenario's `seed`
  becomes it). So `--runs 1 --seed S+k−1` with the same ranges runs run `k` again, exactly.

  Each draw is uniform within its range (a range `lo..hi`; `lo = hi` fixes it):

    * `current_speed` (m/s) and `current_direction` (rad, the direction the current flows
      towards, from north, clockwise): the scenario's initial current becomes
      `speed · (cos χ, sin χ)` horizontally, its vertical part kept; `current` events later in
      the scenario still change it;
    * `dvl_noise`, `usbl_noise`: scales of the simulated DVL's and USBL's noise (`noise` and
      `noise_per_m` of `Neptunus.Sim.DVL`, `Neptunus.Sim.USBL`, the scenario's settings or
      their defaults; 0: none). Outliers and dropouts are not scaled. A scenario without
      simulated sources (the truth as its position) has no noise to scale.

  ## Figures of a run (`figures/3`)

  From the rows the run produced (every step, or every n-th), all against the simulator's
  truth:

    * `estimate_rms` — the RMS of the horizontal distance from navigation's position estimate
      to the true position, over the rows where the estimate is valid (nil: never valid);
      `valid` the fraction of rows where it is;
    * `hold_p95` — the 95th percentile of the true position's distance to DP's target while
      DP holds a position (not during a mission; after `settle` s of scenario time);
    * `cross_track_p95` — during a mission, the 95th percentile of the true position's
      distance from the line of the leg flown, from the second leg on (the first starts
      wherever the vehicle was), in the simulator's frame;
    * `mission` — nil without a mission, `{:done, s}` (the last waypoint reached, s after
      the mission started) or `:not_done`;
    * `error` — nil, or why the run stopped (`failed/1`: an event the control refused).
  """

  alias Neptunus.Scenario

  @ranges [:current_speed, :current_direction, :dvl_noise, :usbl_noise]
  @defaults %{
    runs: 10,
    seed: 1,
    current_speed: {0.0, 0.2},
    current_direction: {0.0, 360.0},
    dvl_noise: {0.5, 2.0},
    usbl_noise: {0.5, 2.0},
    settle: 0.0,
    every: 10
  }
  @max_runs 10_000
  @max_speed 2.0
  @max_scale 100.0

  @typedoc "A closed range `{lo, hi}`, `lo ≤ hi`."
  @type range :: {float(), float()}

  @typedoc "The options of a Monte Carlo (`config/1`); `current_direction` in degrees."
  @type config :: %{
          runs: pos_integer(),
          seed: integer(),
          current_speed: range(),
          current_direction: range(),
          dvl_noise: range(),
          usbl_noise: range(),
          settle: float(),
          every: pos_integer()
        }

  @typedoc "One run's draw (`current_direction` in rad)."
  @type draw :: %{
          seed: integer(),
          current_speed: float(),
          current_direction: float(),
          dvl_noise: float(),
          usbl_noise: float()
        }

  @type figures :: %{
          estimate_rms: float() | nil,
          valid: float() | nil,
          hold_p95: float() | nil,
          cross_track_p95: float() | nil,
          mission: nil | {:done, float()} | :not_done,
          error: String.t() | nil
        }

  @typedoc "Statistics of one figure over the runs that have it."
  @type stats :: %{n: non_neg_integer(), mean: float(), p50: float(), p95: float(), max: float()}

  @doc "The defaults of `config/1`'s options (`current_direction` in degrees)."
  @spec defaults() :: config()
  def defaults, do: @defaults

  @doc """
  Checks the options of a Monte Carlo, as `OptionParser` gives them: `runs`, `seed`,
  `every` (integers), `settle` (s, a number), and the ranges as text, `"LO:HI"` or one number
  (`current_speed` m/s in [0, #{@max_speed}], `current_direction` degrees in [-360, 360],
  `dvl_noise` and `usbl_noise` scales in [0, #{@max_scale}]). Absent options take
  `defaults/0`; anything else in `opts` is ignored (the caller's).

      iex> {:ok, c} = Neptunus.Scenario.MonteCarlo.config(runs: 3, current_speed: "0.1")
      iex> {c.runs, c.current_speed}
      {3, {0.1, 0.1}}

      iex> Neptunus.Scenario.MonteCarlo.config(runs: 3, dvl_noise: "2:1")
      {:error, "--dvl-noise must be LO:HI with LO ≤ HI, got \\"2:1\\""}
  """
  @spec config(keyword()) :: {:ok, config()} | {:error, String.t()}
  def config(opts) do
    with {:ok, runs} <- integer(opts, :runs, 1, @max_runs),
         {:ok, seed} <- integer(opts, :seed, nil, nil),
         {:ok, every} <- integer(opts, :every, 1, nil),
         {:ok, settle} <- settle(opts),
         {:ok, speed} <- range(opts, :current_speed, 0.0, @max_speed),
         {:ok, direction} <- range(opts, :current_direction, -360.0, 360.0),
         {:ok, dvl} <- range(opts, :dvl_noise, 0.0, @max_scale),
         {:ok, usbl} <- range(opts, :usbl_noise, 0.0, @max_scale) do
      {:ok,
       %{
         runs: runs,
         seed: seed,
         every: every,
         settle: settle,
         current_speed: speed,
         current_direction: direction,
         dvl_noise: dvl,
         usbl_noise: usbl
       }}
    end
  end

  defp integer(opts, key, min, max) do
    case Keyword.fetch(opts, key) do
      :error ->
        {:ok, Map.fetch!(@defaults, key)}

      {:ok, n} when is_integer(n) and (min == nil or n >= min) and (max == nil or n <= max) ->
        {:ok, n}

      {:ok, n} ->
        {:error, "#{flag(key)} must be #{integer_kind(min, max)}, got #{inspect(n)}"}
    end
  end

  defp integer_kind(nil, nil), do: "an integer"
  defp integer_kind(1, nil), do: "a positive integer"
  defp integer_kind(1, max), do: "an integer in 1..#{max}"

  defp settle(opts) do
    case Keyword.fetch(opts, :settle) do
      :error ->
        {:ok, @defaults.settle}

      {:ok, text} ->
        case number(text) do
          {:ok, s} when s >= 0 -> {:ok, s}
          _ -> {:error, "--settle must be a number of seconds ≥ 0, got #{inspect(text)}"}
        end
    end
  end

  defp range(opts, key, min, max) do
    case Keyword.fetch(opts, key) do
      :error ->
        {:ok, Map.fetch!(@defaults, key)}

      {:ok, text} ->
        parse_range(text, key, min, max)
    end
  end

  defp parse_range(text, key, min, max) do
    parsed =
      case String.split(text, ":") do
        [one] -> with {:ok, x} <- number(one), do: {:ok, {x, x}}
        [lo, hi] -> with {:ok, a} <- number(lo), {:ok, b} <- number(hi), do: {:ok, {a, b}}
        _ -> :error
      end

    case parsed do
      {:ok, {lo, hi}} when lo > hi ->
        {:error, "#{flag(key)} must be LO:HI with LO ≤ HI, got #{inspect(text)}"}

      {:ok, {lo, hi}} when lo < min or hi > max ->
        {:error,
         "#{flag(key)} must be within #{show(min)}:#{show(max)}#{unit(key)}, got #{inspect(text)}"}

      {:ok, range} ->
        {:ok, range}

      _ ->
        {:error, "#{flag(key)} must be a number or LO:HI#{unit(key)}, got #{inspect(text)}"}
    end
  end

  defp number(text) do
    case Float.parse(String.trim(text)) do
      {x, ""} -> {:ok, x}
      _ -> :error
    end
  end

  defp unit(:current_speed), do: " (m/s)"
  defp unit(:current_direction), do: " (degrees)"
  defp unit(_scale), do: " (a scale of the noise)"

  @doc "The option's flag: `:dvl_noise` → `--dvl-noise`."
  @spec flag(atom()) :: String.t()
  def flag(key), do: "--" <> String.replace(Atom.to_string(key), "_", "-")

  @doc "The seeds of the runs: `seed, seed + 1, …`, one per run."
  @spec seeds(config()) :: [integer()]
  def seeds(%{runs: runs, seed: seed}), do: Enum.to_list(seed..(seed + runs - 1))

  @doc """
  The draw of the run with seed `seed`: each parameter uniform in its range, from a `:rand`
  stream seeded with `seed` alone (in the order current speed, direction, DVL noise, USBL
  noise, always all four, so one range does not change another's draw).
  """
  @spec draw(config(), integer()) :: draw()
  def draw(config, seed) do
    rand = :rand.seed_s(:exsss, seed)

    {values, _rand} =
      Enum.map_reduce(@ranges, rand, fn key, rand ->
        {u, rand} = :rand.uniform_s(rand)
        {lo, hi} = Map.fetch!(config, key)
        # uniform_s is in (0, 1]: 1 − u is in [0, 1)
        x = lo + (hi - lo) * (1.0 - u)
        {{key, if(key == :current_direction, do: x * :math.pi() / 180, else: x)}, rand}
      end)

    Map.new([{:seed, seed} | values])
  end

  @doc "The scenario a draw makes of `scenario` (see the moduledoc)."
  @spec apply_draw(Scenario.t(), draw()) :: Scenario.t()
  def apply_draw(%Scenario{} = scenario, draw) do
    {_, _, down} = scenario.current
    speed = draw.current_speed
    chi = draw.current_direction
    current = {speed * :math.cos(chi), speed * :math.sin(chi), down}

    position =
      case scenario.position do
        :truth ->
          :truth

        %{dvl: dvl, usbl: usbl} ->
          %{
            dvl: scale(dvl, Neptunus.Sim.DVL, draw.dvl_noise),
            usbl: scale(usbl, Neptunus.Sim.USBL, draw.usbl_noise)
          }
      end

    %{scenario | seed: draw.seed, current: current, position: position}
  end

  defp scale(nil, _module, _scale), do: nil

  defp scale(settings, module, scale) do
    defaults = module.defaults()

    Enum.reduce([:noise, :noise_per_m], settings, fn key, acc ->
      Map.put(acc, key, scale * Map.get(settings, key, Map.fetch!(defaults, key)))
    end)
  end

  @doc """
  The figures of one run (see the moduledoc) from its rows (lists in the order of
  `columns`, `Neptunus.Scenario.Run.columns/0`) of `scenario` (whose mission events give
  the legs); hold radii from `settle` s on.
  """
  @spec figures(Enumerable.t(), [String.t()], Scenario.t(), float()) :: figures()
  def figures(rows, columns, %Scenario{} = scenario, settle \\ 0.0) do
    index = columns |> Enum.with_index() |> Map.new()
    at = fn row, name -> Enum.at(row, Map.fetch!(index, name)) end
    missions = for %{mission: wps, t: t} when is_list(wps) <- scenario.events, do: {t, wps}

    acc =
      Enum.reduce(
        rows,
        %{rows: 0, valid: 0, errors: [], radii: [], cross: [], done_at: nil},
        fn row, acc -> figure_row(acc, row, at, missions, settle) end
      )

    mission =
      cond do
        missions == [] -> nil
        acc.done_at -> {:done, acc.done_at}
        true -> :not_done
      end

    %{
      estimate_rms: rms(acc.errors),
      valid: if(acc.rows > 0, do: acc.valid / acc.rows),
      hold_p95: percentile(acc.radii, 95),
      cross_track_p95: percentile(acc.cross, 95),
      mission: mission,
      error: nil
    }
  end

  @doc """
  The figures of a run that could not be flown to its end (a scenario event the control
  refused, e.g. a mission without a valid position): no figures, the reason.
  """
  @spec failed(String.t()) :: figures()
  def failed(reason) do
    %{
      estimate_rms: nil,
      valid: nil,
      hold_p95: nil,
      cross_track_p95: nil,
      mission: nil,
      error: reason
    }
  end

  defp figure_row(acc, row, at, missions, settle) do
    t = at.(row, "t")
    {x, y} = {at.(row, "x"), at.(row, "y")}
    valid? = at.(row, "position_valid") == 1 and is_number(at.(row, "north_est"))
    {tn, te} = {at.(row, "target_north"), at.(row, "target_east")}
    done = at.(row, "mission_done")
    leg = at.(row, "leg")

    acc = %{acc | rows: acc.rows + 1, valid: acc.valid + if(valid?, do: 1, else: 0)}

    acc =
      if valid?,
        do: %{
          acc
          | errors: [hypot(at.(row, "north_est") - x, at.(row, "east_est") - y) | acc.errors]
        },
        else: acc

    cond do
      # a mission running (no hold target): its cross-track from the second leg on
      done == 0 and tn == nil ->
        case mission_at(missions, t) do
          {_start, wps} when is_number(leg) and leg >= 2 and leg <= length(wps) ->
            a = Enum.at(wps, trunc(leg) - 2)
            b = Enum.at(wps, trunc(leg) - 1)
            %{acc | cross: [line_distance({x, y}, a, b) | acc.cross]}

          _ ->
            acc
        end

      # paused: neither flying a leg nor holding its own target
      done == 0 ->
        acc

      true ->
        acc = done_at(acc, done, missions, t)

        if is_number(tn) and is_number(te) and t >= settle,
          do: %{acc | radii: [hypot(x - tn, y - te) | acc.radii]},
          else: acc
    end
  end

  defp done_at(%{done_at: nil} = acc, 1, missions, t) do
    {start, _} = mission_at(missions, t)
    %{acc | done_at: t - start}
  end

  defp done_at(acc, _done, _missions, _t), do: acc

  # the mission started last by `t`
  defp mission_at(missions, t) do
    missions |> Enum.filter(fn {start, _} -> start <= t end) |> List.last()
  end

  defp line_distance({x, y}, a, b) do
    {dn, de} = {b.north - a.north, b.east - a.east}
    abs((x - a.north) * de - (y - a.east) * dn) / hypot(dn, de)
  end

  defp hypot(a, b), do: :math.sqrt(a * a + b * b)

  @doc """
  The root mean square of `values` (nil for none).

      iex> Neptunus.Scenario.MonteCarlo.rms([3.0, 4.0, 0.0, 0.0])
      2.5
  """
  @spec rms([number()]) :: float() | nil
  def rms([]), do: nil
  def rms(values), do: :math.sqrt(Enum.sum(Enum.map(values, &(&1 * &1))) / length(values))

  @doc """
  The `p`-th percentile of `values` (nil for none): the value at rank `⌊p/100 · n⌋` (0-based)
  of the sorted values, at most the largest.

      iex> Neptunus.Scenario.MonteCarlo.percentile(Enum.to_list(1..20), 95)
      20
      iex> Neptunus.Scenario.MonteCarlo.percentile([0.3, 0.1, 0.2], 50)
      0.2
  """
  @spec percentile([number()], number()) :: number() | nil
  def percentile([], _p), do: nil

  def percentile(values, p) do
    sorted = Enum.sort(values)
    n = length(sorted)
    Enum.at(sorted, min(n - 1, floor(p / 100 * n)))
  end

  @doc "Mean, p50, p95 and max of `values` (nil for none)."
  @spec stats([number()]) :: stats() | nil
  def stats([]), do: nil

  def stats(values) do
    %{
      n: length(values),
      mean: Enum.sum(values) / length(values),
      p50: percentile(values, 50) * 1.0,
      p95: percentile(values, 95) * 1.0,
      max: Enum.max(values) * 1.0
    }
  end

  @doc """
  The statistics over the runs (`[{draw, figures}]`): each figure's `stats/1` over the runs
  that have it, the missions finished of those with one, and the worst run.
  """
  @spec summary([{draw(), figures()}]) :: %{
          estimate_rms: stats() | nil,
          valid: stats() | nil,
          hold_p95: stats() | nil,
          cross_track_p95: stats() | nil,
          missions: {non_neg_integer(), non_neg_integer()} | nil,
          worst: {draw(), figures()} | nil
        }
  def summary(runs) do
    figures = Enum.map(runs, &elem(&1, 1))
    have = fn key -> for f <- figures, is_number(f[key]), do: f[key] end
    with_mission = Enum.reject(figures, &is_nil(&1.mission))

    %{
      estimate_rms: stats(have.(:estimate_rms)),
      valid: stats(have.(:valid)),
      hold_p95: stats(have.(:hold_p95)),
      cross_track_p95: stats(have.(:cross_track_p95)),
      missions:
        if(with_mission != [],
          do: {Enum.count(with_mission, &match?({:done, _}, &1.mission)), length(with_mission)}
        ),
      worst: worst(runs)
    }
  end

  @doc """
  The worst run: a failed run first, then a mission not finished, then the largest
  cross-track p95, hold p95, then estimate RMS (the first of equals; nil for no runs).
  """
  @spec worst([{draw(), figures()}]) :: {draw(), figures()} | nil
  def worst([]), do: nil

  def worst(runs) do
    runs
    |> Enum.with_index()
    |> Enum.max_by(fn {{_draw, f}, i} ->
      {if(f.error, do: 1, else: 0), if(f.mission == :not_done, do: 1, else: 0),
       f.cross_track_p95 || -1.0, f.hold_p95 || -1.0, f.estimate_rms || -1.0, -i}
    end)
    |> elem(0)
  end

  @doc "The options that run `draw`'s run again alone: `--runs 1 --seed S` and the ranges."
  @spec reproduce(config(), draw()) :: [String.t()]
  def reproduce(config, draw) do
    ["--runs", "1", "--seed", Integer.to_string(draw.seed)] ++
      Enum.flat_map(@ranges, fn key ->
        {lo, hi} = Map.fetch!(config, key)
        [flag(key), "#{show(lo)}:#{show(hi)}"]
      end) ++
      if(config.settle > 0, do: ["--settle", show(config.settle)], else: []) ++
      if(config.every != @defaults.every, do: ["--every", "#{config.every}"], else: [])
  end

  # the shortest text that reads back as the same float
  defp show(x), do: :erlang.float_to_binary(x * 1.0, [:short])
end
