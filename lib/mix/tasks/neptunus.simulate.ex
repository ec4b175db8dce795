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

  ## Monte Carlo

      mix neptunus.simulate SCENARIO.json --runs N [--seed S] [--current-speed LO:HI]
        [--current-direction LO:HI] [--dvl-noise LO:HI] [--usbl-noise LO:HI]
        [--settle S] [--every N]

  runs the scenario N times (in parallel, one per scheduler), each with its own draw of the
  current and the position sources' noise, and prints a table (Markdown) of each run and of
  the statistics over the runs instead of CSV (`Neptunus.Scenario.MonteCarlo`):

    * `--runs N` — the number of runs (1..10000); run k has the seed S + k − 1 (`--seed`,
      default 1), which makes both its draw and its simulation;
    * `--current-speed` (m/s, default 0:0.2) and `--current-direction` (degrees the current
      flows towards, from north, default 0:360): the scenario's initial horizontal current;
    * `--dvl-noise`, `--usbl-noise` (default 0.5:2): scales of the simulated DVL's and
      USBL's noise (0: none);
    * a range is `LO:HI` or one number (fixed); `--settle S`: hold radii from S s of
      scenario time on (default 0); `--every N`: the figures from every N-th step (default 10).

  Per run: the draw, the estimate's RMS against the true position (while valid) and how
  often it is valid, DP's hold radius p95, a mission's cross-track p95 and whether it
  finished; then mean, p50, p95 and max of each over the runs, the missions finished, and
  the worst run with the options that run it again alone (`--runs 1 --seed …`). Bad options
  (unknown, `--runs` not positive, a range out of bounds or with LO > HI, `--out` with
  `--runs`, a Monte Carlo option without `--runs`) stop the task before any run, with a
  message naming the option and a non-zero exit status.

  The task loads the project's code and configuration only: no web endpoint, no vehicles.
  """
  use Mix.Task

  alias Neptunus.Scenario
  alias Neptunus.Scenario.MonteCarlo

  @switches [
    out: :string,
    every: :integer,
    runs: :integer,
    seed: :integer,
    current_speed: :string,
    current_direction: :string,
    dvl_noise: :string,
    usbl_noise: :string,
    settle: :string
  ]
  @monte_carlo [:seed, :current_speed, :current_direction, :dvl_noise, :usbl_noise, :settle]

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

    if Keyword.has_key?(opts, :runs) do
      monte_carlo(file, opts)
    else
      one_run(file, opts)
    end
  end

  defp one_run(file, opts) do
    case Enum.find(@monte_carlo, &Keyword.has_key?(opts, &1)) do
      nil -> :ok
      key -> Mix.raise("#{MonteCarlo.flag(key)} is an option of a Monte Carlo: add --runs N")
    end

    every = Keyword.get(opts, :every, 1)
    if every < 1, do: Mix.raise("--every must be a positive integer, got #{every}")

    scenario = load!(file)

    case Keyword.fetch(opts, :out) do
      {:ok, out} -> write_file(scenario, every, out)
      :error -> scenario |> Scenario.Run.csv(every) |> Enum.each(&IO.binwrite/1)
    end
  end

  defp load!(file) do
    # code and config only: the application (endpoint, vehicles) is not started
    Mix.Task.run("app.config")

    with {:ok, json} <- Neptunus.Validate.read_file(file),
         {:ok, scenario} <- Scenario.parse(json) do
      scenario
    else
      {:error, reason} -> Mix.raise("#{file}: #{reason}")
    end
  end

  defp usage,
    do:
      "usage: mix neptunus.simulate SCENARIO.json [--out run.csv] [--every N]\n" <>
        "       mix neptunus.simulate SCENARIO.json --runs N [--seed S] [--current-speed LO:HI]\n" <>
        "         [--current-direction LO:HI] [--dvl-noise LO:HI] [--usbl-noise LO:HI]\n" <>
        "         [--settle S] [--every N]"

  # --- Monte Carlo ---

  defp monte_carlo(file, opts) do
    if Keyword.has_key?(opts, :out),
      do: Mix.raise("--out writes one run's CSV: it does not go with --runs")

    config =
      case MonteCarlo.config(opts) do
        {:ok, config} -> config
        {:error, reason} -> Mix.raise(reason)
      end

    scenario = load!(file)
    shell = Mix.shell()
    started = Neptunus.Clock.monotonic_ms()
    Enum.each(header(file, scenario, config), &shell.info/1)

    runs =
      config
      |> MonteCarlo.seeds()
      |> Task.async_stream(&one_draw(scenario, config, &1),
        max_concurrency: System.schedulers_online(),
        timeout: :infinity
      )
      |> Enum.with_index(1)
      |> Enum.map(fn {{:ok, {draw, figures}}, k} ->
        shell.info(run_line(k, draw, figures))
        {draw, figures}
      end)

    Enum.each(summary_lines(file, config, MonteCarlo.summary(runs), runs), &shell.info/1)
    shell.info("(#{Neptunus.Clock.monotonic_ms() - started} ms)")
  end

  defp one_draw(scenario, config, seed) do
    draw = MonteCarlo.draw(config, seed)
    s = MonteCarlo.apply_draw(scenario, draw)

    figures =
      try do
        s
        |> Scenario.Run.rows(config.every)
        |> MonteCarlo.figures(Scenario.Run.columns(), s, config.settle)
      rescue
        error in ArgumentError -> MonteCarlo.failed(Exception.message(error))
      end

    {draw, figures}
  end

  defp header(file, scenario, config) do
    sources =
      case scenario.position do
        :truth ->
          "the simulator's truth (no sensor noise to scale)"

        %{dvl: dvl, usbl: usbl} ->
          [dvl && "DVL", usbl && "USBL"] |> Enum.reject(&is_nil/1) |> Enum.join(" + ")
      end

    [
      "Monte Carlo of #{file}: #{scenario.vehicle}, #{g(scenario.duration)} s, " <>
        "#{config.runs} runs (seeds #{config.seed}..#{config.seed + config.runs - 1})",
      "current #{range(config.current_speed)} m/s towards #{range(config.current_direction)}°, " <>
        "DVL noise ×#{range(config.dvl_noise)}, USBL noise ×#{range(config.usbl_noise)}; " <>
        "position: #{sources}",
      "",
      "| run | seed | current (m/s) | towards (°) | DVL noise × | USBL noise × | " <>
        "estimate RMS (m) | valid % | hold p95 (m) | cross-track p95 (m) | mission |",
      "|---|---|---|---|---|---|---|---|---|---|---|"
    ]
  end

  defp run_line(k, draw, figures) do
    "| #{k} | #{draw.seed} | #{f(draw.current_speed, 3)} | " <>
      "#{f(Neptunus.PID.wrap_2pi(draw.current_direction) * 180 / :math.pi(), 1)} | " <>
      "#{f(draw.dvl_noise)} | #{f(draw.usbl_noise)} | #{f(figures.estimate_rms, 3)} | " <>
      "#{f(figures.valid && 100 * figures.valid, 1)} | #{f(figures.hold_p95, 3)} | " <>
      "#{f(figures.cross_track_p95, 3)} | #{mission(figures)} |"
  end

  defp mission(%{error: reason}) when is_binary(reason), do: "failed: #{reason}"
  defp mission(%{mission: nil}), do: "—"
  defp mission(%{mission: {:done, s}}), do: "done in #{f(s, 1)} s"
  defp mission(%{mission: :not_done}), do: "not done"

  defp summary_lines(file, config, summary, runs) do
    stats = fn label, stats, scale, decimals ->
      case stats do
        nil ->
          "| #{label} | 0 | — | — | — | — |"

        s ->
          "| #{label} | #{s.n} | #{f(scale * s.mean, decimals)} | #{f(scale * s.p50, decimals)} | " <>
            "#{f(scale * s.p95, decimals)} | #{f(scale * s.max, decimals)} |"
      end
    end

    failed = Enum.count(runs, fn {_draw, f} -> f.error != nil end)

    missions =
      case summary.missions do
        nil -> []
        {done, n} -> ["missions finished: #{done}/#{n}"]
      end

    worst =
      case summary.worst do
        nil ->
          []

        {draw, figures} ->
          [
            "worst run: seed #{draw.seed} (current #{f(draw.current_speed, 3)} m/s towards " <>
              "#{f(Neptunus.PID.wrap_2pi(draw.current_direction) * 180 / :math.pi(), 1)}°, " <>
              "DVL noise ×#{f(draw.dvl_noise)}, USBL noise ×#{f(draw.usbl_noise)}): " <>
              worst_figures(figures),
            "reproduce: mix neptunus.simulate #{file} " <>
              Enum.join(MonteCarlo.reproduce(config, draw), " ")
          ]
      end

    [
      "",
      "| over the runs | runs | mean | p50 | p95 | max |",
      "|---|---|---|---|---|---|",
      stats.("estimate RMS (m)", summary.estimate_rms, 1, 3),
      stats.("valid %", summary.valid, 100, 1),
      stats.("hold p95 (m)", summary.hold_p95, 1, 3),
      stats.("cross-track p95 (m)", summary.cross_track_p95, 1, 3),
      ""
    ] ++
      missions ++
      if(failed > 0, do: ["runs failed: #{failed}/#{length(runs)}"], else: []) ++ worst
  end

  defp worst_figures(figures) do
    [
      figures.error && "failed: #{figures.error}",
      match?(%{mission: :not_done}, figures) && "mission not done",
      figures.cross_track_p95 && "cross-track p95 #{f(figures.cross_track_p95, 3)} m",
      figures.hold_p95 && "hold p95 #{f(figures.hold_p95, 3)} m",
      figures.estimate_rms && "estimate RMS #{f(figures.estimate_rms, 3)} m"
    ]
    |> Enum.filter(&is_binary/1)
    |> Enum.join(", ")
  end

  defp range({lo, hi}) when lo == hi, do: g(lo)
  defp range({lo, hi}), do: "#{g(lo)}–#{g(hi)}"

  defp g(x), do: :erlang.float_to_binary(x * 1.0, [:short])

  defp f(x, decimals \\ 2)
  defp f(nil, _decimals), do: "—"
  defp f(x, decimals), do: :erlang.float_to_binary(x * 1.0, decimals: decimals)

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
