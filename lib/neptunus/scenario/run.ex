defmodule Neptunus.Scenario.Run do
  @moduledoc """
  Runs a `Neptunus.Scenario` on `Neptunus.Sim` — the same simulator as the live simulated
  board — and produces one row per integration step, lazily (a `Stream`), so long runs
  use constant memory.

  Row `k` is the simulation at `t = k · dt` (`k = 0 … round(duration / dt)`): events with
  `t_event ≤ t` (within half a step) have been applied, and the thruster command shown is
  the one in force for the following step. Columns (`columns/0`):

      t, x, y, z, phi, theta, psi, u, v, w, p, q, r          true state (SI, rad)
      depth_meas, heading_meas, roll_meas, pitch_meas,        what the sensors report
      voltage_meas, current_meas                              (true values unless noise)
      depth_est, depth_rate_est, heading_est, yaw_rate_est    navigation's estimate
      port, vertical, starboard                               thruster commands in [-1, 1]

  The estimate is `Neptunus.Estimator` — the same filter as a live vehicle's
  `Neptunus.Vehicle.Navigation` — run on every step's measurements (wild points and all) and
  told every thruster command, with the scenario's vehicle as its model. An estimate that does
  not exist (no plausible reading yet) is an empty field.
  """

  alias Neptunus.{Allocation, Estimator, Scenario, Sim}

  @state_columns ~w(x y z phi theta psi u v w p q r)a
  @meas_columns ~w(depth heading roll pitch voltage current)a
  @est_columns ~w(depth depth_rate heading yaw_rate)a
  @thruster_columns ~w(port vertical starboard)a

  @doc "The CSV columns, in order."
  @spec columns() :: [String.t()]
  def columns do
    ["t"] ++
      Enum.map(@state_columns, &Atom.to_string/1) ++
      Enum.map(@meas_columns, &"#{&1}_meas") ++
      Enum.map(@est_columns, &"#{&1}_est") ++ Enum.map(@thruster_columns, &Atom.to_string/1)
  end

  @doc "The rows as lists of floats (nil for a missing estimate) in the order of `columns/0` (every `every`-th step)."
  @spec rows(Scenario.t(), pos_integer()) :: Enumerable.t()
  def rows(%Scenario{} = scenario, every \\ 1) when is_integer(every) and every >= 1 do
    last = Scenario.steps(scenario)
    sim = Sim.new(Scenario.sim_options(scenario))
    control = %{gain: scenario.gain, thrust: {:motion, %{surge: 0.0, heave: 0.0, yaw: 0.0}}}
    est = [vehicle: scenario.params] |> Estimator.new() |> observe(sim)

    Stream.unfold({0, sim, scenario.events, control, est}, fn
      {k, _sim, _events, _control, _est} when k > last ->
        nil

      {k, sim, events, control, est} ->
        {sim, events, control} = apply_due(sim, events, control, k)
        row = row(sim, est, k)
        next = min(k + every, last)

        if next > k do
          {sim, events, control, est} = advance(sim, events, control, est, k, next)
          {row, {next, sim, events, control, est}}
        else
          {row, {last + 1, sim, events, control, est}}
        end
    end)
  end

  # the estimator sees each step's measurement, and the command in force over each step
  defp observe(est, sim) do
    %{t: t, measurement: m} = Sim.sample(sim)
    Estimator.update(est, t, m)
  end

  # from step j to step `target`, applying the events due at each step on the way (those
  # due at `target` itself are applied when its row is produced)
  defp advance(sim, events, control, est, j, target) when j == target,
    do: {sim, events, control, est}

  defp advance(sim, events, control, est, j, target) do
    est = Estimator.command(est, sim.thrusters)
    sim = Sim.step(sim)
    est = observe(est, sim)

    {sim, events, control} =
      if j + 1 < target,
        do: apply_due(sim, events, control, j + 1),
        else: {sim, events, control}

    advance(sim, events, control, est, j + 1, target)
  end

  @doc "The CSV text: the header line, then one line per row (iodata chunks)."
  @spec csv(Scenario.t(), pos_integer()) :: Enumerable.t()
  def csv(%Scenario{} = scenario, every \\ 1) do
    Stream.concat(
      [[Enum.intersperse(columns(), ","), "\n"]],
      scenario |> rows(every) |> Stream.map(&csv_line/1)
    )
  end

  defp csv_line([t | rest]) do
    [format_t(t) | Enum.map(rest, &[?, | format(&1)])] ++ ["\n"]
  end

  defp row(%Sim{} = sim, est, k) do
    %{measurement: m, sim: truth} = Sim.sample(sim)
    thr = sim.thrusters
    e = Estimator.estimate(est)

    [k * sim.dt] ++
      Enum.map(@state_columns, &Map.fetch!(truth, &1)) ++
      Enum.map(@meas_columns, &Map.fetch!(m, &1)) ++
      Enum.map(@est_columns, &Map.fetch!(e, &1)) ++
      Enum.map(@thruster_columns, &(Map.get(thr, &1, 0.0) * 1.0))
  end

  # events with t_event ≤ k·dt, within half a step
  defp apply_due(sim, events, control, k),
    do: apply_until(sim, events, control, (k + 0.5) * sim.dt)

  defp apply_until(sim, [%{t: t} = event | rest], control, until) when t <= until do
    {sim, control} = apply_event(sim, event, control)
    apply_until(sim, rest, control, until)
  end

  defp apply_until(sim, events, control, _until), do: {sim, events, control}

  defp apply_event(sim, event, control) do
    control = if event.gain, do: %{control | gain: event.gain}, else: control
    control = if event.thrust, do: %{control | thrust: event.thrust}, else: control
    sim = if event.gain || event.thrust, do: Sim.command(sim, thrusters(control)), else: sim
    sim = if event.tau, do: Sim.external_force(sim, event.tau), else: sim
    sim = if event.current, do: Sim.set_current(sim, event.current), else: sim
    {sim, control}
  end

  defp thrusters(%{gain: k, thrust: {:motion, motion}}), do: Allocation.motion(motion, k)

  defp thrusters(%{gain: k, thrust: {:manual, m}}) do
    %{port: sat(k * m.port), vertical: sat(k * m.vertical), starboard: sat(k * m.starboard)}
  end

  defp sat(x), do: x |> max(-1.0) |> min(1.0) |> Kernel.+(0.0)

  # t on a fixed grid: at most 9 decimals, no binary noise (0.30000000000000004 → 0.3)
  defp format_t(t), do: :erlang.float_to_binary(t * 1.0, [{:decimals, 9}, :compact])

  defp format(x) when is_float(x), do: :erlang.float_to_binary(x, [:short])
  defp format(x) when is_integer(x), do: Integer.to_string(x)
  defp format(nil), do: ""
end
