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
      depth_est, depth_rate_est, heading_est, yaw_rate_est,   navigation's estimate
      roll_est, pitch_est
      depth_setpoint, heading_setpoint                        autopilot setpoints (m, rad;
                                                              empty while disengaged)
      depth_reference, heading_reference                      what the autopilots track on
                                                              the way (m, rad; the
                                                              setpoint reference model)
      port, vertical, starboard                               thruster commands in [-1, 1]
      lateral                                                 the lateral thruster's command
                                                              (a vehicle with one; else empty)
      north_est, east_est, velocity_north_est,                navigation's position estimate
      velocity_east_est, position_std, position_valid         (m, m/s; the larger 1-σ
                                                              semi-axis; 1 valid, 0 not)
      target_north, target_east                               DP's position target (m)
      cross_track, leg                                        a mission's cross-track error
                                                              (m) and the waypoint steered
                                                              to (1-based)
      mission_done                                            1 once the mission's last
                                                              waypoint is reached, 0 while
                                                              it runs or is paused (empty
                                                              without a mission)

  The estimate is `Neptunus.Estimator` — the same filter as a live vehicle's
  `Neptunus.Vehicle.Navigation` — run on every step's measurements (wild points and all) and
  told every thruster command, with the scenario's vehicle as its model (or the scenario's
  `model`, when set: a vehicle that differs from the model its navigation has). The scenario starts
  with the vehicle's sensors up (it has been running before; there is no board boot to wait
  out), so the first reading is valid at once (`settle: 0`, `agree: 1`); everything after
  that — wild points, re-acquisition — is the live filter's. An estimate that does not exist
  (no plausible reading) is an empty field.

  The position is the scenario's `position`: by default the simulator's true position and
  velocity (a perfect source, valid from the start); with simulated sources
  (`"position": {"dvl": …, "usbl": …}`) navigation's position estimate from them
  (`Neptunus.Scenario.Sources`: the simulated DVL and USBL, read as the live drivers read
  them, fused by `Neptunus.Navigation.Position` with the heading estimate above).

  The control is `Neptunus.Control.Core` — the live vehicle's — fed with that estimate:
  scenario events are its commands, and its control loop ticks every #{0.02} s of simulated
  time (the tick due at a step runs after that step's events, before its row). A vehicle
  with a lateral thruster (`neptunus-sway`) is fully actuated (`actuation: :full`): its
  lateral thruster gets the demand's sway; the others get the three-thruster allocation.
  """

  alias Neptunus.{Estimator, Scenario, Sim}
  alias Neptunus.Control.{Core, DP}
  alias Neptunus.Navigation.Kalman
  alias Neptunus.Scenario.Sources

  @control_period 0.02
  # the scenario's vehicle has been running before it starts: its sensors are up, there is no
  # boot placeholder to wait out, so its first reading is valid (a live vehicle's are not)
  @sensors_up [settle: 0.0, agree: 1]

  @state_columns ~w(x y z phi theta psi u v w p q r)a
  @meas_columns ~w(depth heading roll pitch voltage current)a
  @est_columns ~w(depth depth_rate heading yaw_rate roll pitch)a
  @setpoint_columns ~w(depth heading)a
  @reference_columns ~w(depth heading)a
  @thruster_columns ~w(port vertical starboard)a
  @position_columns ~w(north_est east_est velocity_north_est velocity_east_est position_std
                       position_valid target_north target_east cross_track leg mission_done)

  @doc "The CSV columns, in order."
  @spec columns() :: [String.t()]
  def columns do
    ["t"] ++
      Enum.map(@state_columns, &Atom.to_string/1) ++
      Enum.map(@meas_columns, &"#{&1}_meas") ++
      Enum.map(@est_columns, &"#{&1}_est") ++
      Enum.map(@setpoint_columns, &"#{&1}_setpoint") ++
      Enum.map(@reference_columns, &"#{&1}_reference") ++
      Enum.map(@thruster_columns, &Atom.to_string/1) ++ ["lateral"] ++ @position_columns
  end

  @doc """
  The rows as lists of floats (nil for a missing estimate) in the order of `columns/0` (every
  `every`-th step). `control` are options of the control (`Neptunus.Control.Core.new/1`:
  `gains`, `reference`, … — a tuning's step response runs on them); the scenario's gain wins.
  """
  @spec rows(Scenario.t(), pos_integer(), keyword()) :: Enumerable.t()
  def rows(%Scenario{} = scenario, every \\ 1, control \\ [])
      when is_integer(every) and every >= 1 do
    last = Scenario.steps(scenario)
    sim = Sim.new(Scenario.sim_options(scenario) ++ [native: true])

    est =
      [vehicle: scenario.model || scenario.params]
      |> Keyword.merge(@sensors_up)
      |> Estimator.new()
      |> observe(sim)

    lateral? = Enum.any?(sim.params.thrusters, &(&1.name == :lateral))

    core =
      control
      |> Keyword.put(:gain, scenario.gain)
      |> Keyword.put(:actuation, if(lateral?, do: :full, else: :surge))
      |> Keyword.put(:dp, scenario.dp)
      |> Core.new()

    sources =
      case scenario.position do
        :truth -> nil
        position -> Sources.new(position, scenario.seed)
      end

    control =
      %{core: core, next_tick: 0, sources: sources, lateral?: lateral?} |> estimate(est, sim)

    Stream.unfold({0, sim, scenario.events, control, est}, fn
      {k, _sim, _events, _control, _est} when k > last ->
        nil

      {k, sim, events, control, est} ->
        {sim, events, control} = apply_due(sim, events, control, k)
        row = row(sim, est, control, k)
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

  # control gets navigation's estimate when it has depth and heading, with the position
  defp estimate(control, est, %Sim{} = sim) do
    t = Sim.time(sim)

    case Estimator.estimate(est) do
      %{depth: d, heading: h} = e when is_number(d) and is_number(h) ->
        states = Map.take(Estimator.states(est), [:depth, :heading])
        e = Map.merge(e, %{position: position(control, sim, t), measurement_state: states})
        %{control | core: Core.estimate(control.core, e, t)}

      _ ->
        control
    end
  end

  # the truth as a perfect source, or navigation's estimate from the simulated sources
  defp position(%{sources: nil}, %Sim{dyn: dyn}, _t) do
    {c, s} = {:math.cos(dyn.psi), :math.sin(dyn.psi)}

    %{
      valid: true,
      reason: nil,
      north: dyn.x,
      east: dyn.y,
      velocity_north: c * dyn.u - s * dyn.v,
      velocity_east: s * dyn.u + c * dyn.v,
      frame: :truth,
      epoch: 1,
      shift: nil
    }
  end

  defp position(%{sources: sources}, _sim, t), do: Sources.estimate(sources, t)

  # the simulated sources measure the true state; navigation's heading and depth go with them
  defp sense(%{sources: nil} = control, _est, _sim), do: control

  defp sense(%{sources: sources} = control, est, %Sim{dyn: dyn} = sim) do
    e = Estimator.estimate(est)

    heading =
      case {e.heading, Kalman.std(est.filters.heading)} do
        {psi, {std, _}} when is_number(psi) -> {psi, std}
        _ -> nil
      end

    truth = Map.from_struct(dyn)
    %{control | sources: Sources.step(sources, Sim.time(sim), truth, heading, e.depth)}
  end

  # from step j to step `target`, applying the events due at each step on the way (those
  # due at `target` itself are applied when its row is produced)
  defp advance(sim, events, control, est, j, target) when j == target,
    do: {sim, events, control, est}

  defp advance(sim, events, control, est, j, target) do
    est = Estimator.command(est, sim.thrusters)
    sim = Sim.step(sim)
    est = observe(est, sim)
    control = control |> sense(est, sim) |> estimate(est, sim)

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

  defp row(%Sim{} = sim, est, control, k) do
    %{measurement: m, sim: truth} = Sim.sample(sim)
    thr = sim.thrusters
    e = Estimator.estimate(est)
    setpoints = Core.control(control.core).autopilot
    autopilots = Core.autopilot(control.core)

    [k * sim.dt] ++
      Enum.map(@state_columns, &Map.fetch!(truth, &1)) ++
      Enum.map(@meas_columns, &Map.fetch!(m, &1)) ++
      Enum.map(@est_columns, &Map.fetch!(e, &1)) ++
      Enum.map(@setpoint_columns, &Map.fetch!(setpoints, &1)) ++
      Enum.map(@reference_columns, &reference(autopilots, &1)) ++
      Enum.map(@thruster_columns, &(Map.get(thr, &1, 0.0) * 1.0)) ++
      [if(control.lateral?, do: Map.get(thr, :lateral, 0.0) * 1.0)] ++
      position_row(control, k * sim.dt, sim)
  end

  defp position_row(control, t, sim) do
    p = position(control, sim, t)
    std = if p[:std_north], do: max(p.std_north, p.std_east)

    {tn, te, cross, leg, done} =
      case control.core.dp do
        %DP{} = dp ->
          {tn, te} = DP.target(dp) || {nil, nil}
          mission = DP.public(dp).mission
          done = mission && if(mission.state == "done", do: 1, else: 0)
          {tn, te, mission && mission.cross_track, mission && mission.leg, done}

        nil ->
          {nil, nil, nil, nil, nil}
      end

    [
      p.north,
      p.east,
      p.velocity_north,
      p.velocity_east,
      if(p.frame == :truth, do: 0.0, else: std),
      if(p.valid, do: 1, else: 0),
      tn,
      te,
      cross,
      leg,
      done
    ]
  end

  defp reference(autopilots, axis) do
    case Map.fetch!(autopilots, axis) do
      %{reference: r} -> r
      nil -> nil
    end
  end

  # events with t_event ≤ k·dt, within half a step, then the control ticks due by then
  defp apply_due(sim, events, control, k) do
    until = (k + 0.5) * sim.dt
    {sim, events, control} = apply_until(sim, events, control, until)
    {sim, control} = tick(sim, control, until)
    {sim, events, control}
  end

  defp apply_until(sim, [%{t: t} = event | rest], control, until) when t <= until do
    {sim, control} = apply_event(sim, event, control)
    apply_until(sim, rest, control, until)
  end

  defp apply_until(sim, events, control, _until), do: {sim, events, control}

  defp apply_event(sim, event, control) do
    t = Sim.time(sim)

    {sim, control} =
      [
        event.control_mode && {:set_control_mode, event.control_mode},
        event.gain && {:set_gain, event.gain},
        event.thrust && {:set_control_mode, elem(event.thrust, 0)},
        event.thrust && {:thrust, elem(event.thrust, 0), elem(event.thrust, 1)},
        event.autopilot && {:autopilot, event.autopilot},
        event[:mission] && {:mission, {:start, event.mission}},
        event[:mission_control] && {:mission, event.mission_control}
      ]
      |> Enum.reject(&(&1 in [nil, false]))
      |> Enum.reduce({sim, control}, fn command, {sim, control} ->
        case Core.command(control.core, command, t) do
          {:ok, core, actions} ->
            control = %{control | core: core}
            {carry_out(sim, actions, control), control}

          {:error, reason} ->
            raise ArgumentError, "scenario event at t = #{event.t} s: #{reason}"
        end
      end)

    sim = if event.tau, do: Sim.external_force(sim, event.tau), else: sim
    sim = if event.current, do: Sim.set_current(sim, event.current), else: sim
    {sim, control}
  end

  # the control loop's ticks due by `until` (s): one tick per step at most, over the periods
  # elapsed (a step longer than the period runs the loop once over the whole of it)
  defp tick(sim, %{next_tick: n} = control, until) do
    due = floor(until / @control_period) - n + 1

    if due >= 1 do
      {core, actions} = Core.tick(control.core, due * @control_period, Sim.time(sim))
      control = %{control | core: core, next_tick: n + due}
      {carry_out(sim, actions, control), control}
    else
      {sim, control}
    end
  end

  # a vehicle with a lateral thruster gets the demand's sway on it
  defp carry_out(sim, actions, control) do
    Enum.reduce(actions, sim, fn
      {:go, thrusters}, sim when control.lateral? ->
        Sim.command(sim, Map.put(thrusters, :lateral, Core.demand(control.core).sway))

      {:go, thrusters}, sim ->
        Sim.command(sim, thrusters)

      _other, sim ->
        sim
    end)
  end

  # t on a fixed grid: at most 9 decimals, no binary noise (0.30000000000000004 → 0.3)
  defp format_t(t), do: :erlang.float_to_binary(t * 1.0, [{:decimals, 9}, :compact])

  defp format(x) when is_float(x), do: :erlang.float_to_binary(x, [:short])
  defp format(x) when is_integer(x), do: Integer.to_string(x)
  defp format(nil), do: ""
end
