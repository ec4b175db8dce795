defmodule Neptunus.Control.Core do
  @moduledoc """
  A vehicle's control as a pure value: control mode, gain, lights, laser, camera tilt, run
  mode, the pilot's command, the depth and heading autopilots, DP, and the thruster output
  they make together. `Neptunus.Vehicle.Control` runs it live (commands from the helm,
  estimates from navigation, a 50 Hz tick) and `Neptunus.Scenario.Run` runs it headless on
  simulated time — the same decisions either way.

  Every function returns the new value and **actions** for the caller to carry out, in order:

    * `{:go, thrusters}` — command the thrusters (`%{port, vertical, starboard}` in [-1, 1]);
    * `{:stopped, reason}` — a stop happened: tell everyone (and log it);
    * `{:lights, 0..255}`, `{:laser, 0..255}`, `{:tilt, rad}` — set them on the board now
      (never coupled to thrust: the thesis' lights waited for the next thrust command, §13.1);
    * `{:run_mode, :simulator | :normal, seed}` — move commands and telemetry to a simulator
      seeded with `seed` (`%{depth, heading}` or nil), or back to the real board;
    * `{:notice, text}` — tell the pilot: an engaged autopilot stopped acting (its measurement
      went back to initialising after a board reset, or stale, or the estimate stopped) or
      acts again.

  ## Control modes

    * `:motion` — the pilot commands surge, heave and yaw in [-1, 1]; the thesis' allocation
      (eq. 9.3) makes the thruster commands. The gain `k` scales the pilot's axes. An engaged
      autopilot drives its axis (heave for depth, yaw for heading) with its own output, which
      the gain does not scale (a PID keeps its tuning whatever the pilot's sensitivity); while
      the heading autopilot drives yaw, surge gives way to it (`|surge| ≤ 1 − |yaw|`) so the
      heading is held at full speed.
    * `:manual` — the pilot commands each thruster in [-1, 1], scaled by `k`. No autopilots:
      entering manual disengages them (thesis §7.1) and engaging one is refused.
    * `:dp` — position hold (`Neptunus.Control.DP`) with depth and heading held; the pilot
      sends no thrust in DP. Entering DP engages depth and heading hold at their current
      values unless they are engaged already (then their setpoints are kept), and holds the
      current position when there is a position source (an estimate with a `position`).
      Without one DP holds depth and heading only, as the thesis' DP does (ch. 14): surge is
      zero, and it says so (`dp_holds/1`: `["depth", "heading"]` in the control state, and a
      `{:notice, …}`).

  ## Setpoints and tuning

  The autopilots track a rate- and acceleration-limited reference towards their setpoints
  (`Neptunus.Control.Autopilot`, `Neptunus.Control.Reference`; limits per axis, option
  `reference`), so a setpoint step never jerks the vehicle. `retune/2` changes the depth and
  heading PID gains at run time, bumplessly (`Neptunus.Control.Tuning` validates them).

  ## Stops

  Every stop zeroes the pilot's command and tells everyone (`{:stopped, reason}`). What
  happens to the autopilots depends on why:

    * a **handover** (`control_transferred`, `main_station_takeover`) keeps the autopilots and
      DP holding: the new pilot picks their setpoints up from the grant, and the pilot's
      thrust is neutral;
    * a **control-mode change** (`control_mode_changed`) sends neutral thrust first, then
      applies the new mode's rules above;
    * **every other stop** — deadman, pilot left or disconnected, released, the pilot's own
      stop, helm restarted, simulator reset, run-mode change — is a safety stop: the
      autopilots and DP are disengaged (control mode `dp` falls back to `motion`) and the
      thrusters go neutral.

  ## Estimates

  `estimate/3` gives the latest estimate `%{t, depth, depth_rate, heading, yaw_rate,
  position, measurement_state}` (SI, heading in [0, 2π), `position` `%{x, y}` or nil,
  depth/heading nil while not estimated, `measurement_state` `%{depth, heading}` each
  `:initialising | :valid | :stale`, optional) and the time it arrived. Engaging an autopilot
  or DP needs an estimate no older than `stale_after` (default 1 s) in which the axis'
  measurement is valid: engaging on an initialising or stale measurement is refused with a
  reason a pilot can read (`unavailable/2`, e.g. "depth hold: depth is initialising (the
  board's depth sensor has not given consistent readings yet)"). While the estimate is older
  than that, every autopilot's output is zero; while an axis' measurement is not valid (a
  board reset puts it back to initialising), that autopilot's output is zero — setpoints and
  trims kept in both cases — until it is valid again, and the pilot is told
  (`{:notice, text}`, and `waiting` in telemetry's `autopilot`).
  """

  alias Neptunus.Allocation
  alias Neptunus.Control.{Autopilot, Command, Demand, DP}

  @handover_reasons ["control_transferred", "main_station_takeover"]
  @deadband_ramp 0.02

  @default_gains %{
    depth: [kp: 3.0, ki: 0.1, kd: 1.5],
    heading: [kp: 4.0, ki: 0.3, kd: 2.0],
    surge: [kp: 0.4, ki: 0.02, kd: 0.8]
  }

  @enforce_keys [:depth, :heading, :gains]
  defstruct [
    :depth,
    :heading,
    :gains,
    :dp,
    :estimate,
    :estimate_at,
    mode: :motion,
    gain: 0.5,
    lights: 0,
    laser: 0,
    tilt: 0.0,
    run_mode: :normal,
    run_modes: [:normal],
    pilot: %{surge: 0.0, heave: 0.0, yaw: 0.0},
    thrusters: %{port: 0.0, vertical: 0.0, starboard: 0.0},
    stale_after: 1.0,
    deadband: 0.05,
    dp_opts: [],
    actuation: :surge,
    mission_opts: [],
    waiting: %{depth: nil, heading: nil},
    axes: [:surge, :heave, :yaw],
    allocation: :thesis,
    demand: %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
  ]

  @type action ::
          {:go, output()}
          | {:stopped, String.t()}
          | {:lights, 0..255}
          | {:laser, 0..255}
          | {:tilt, float()}
          | {:run_mode, Command.run_mode(), %{depth: float(), heading: float()} | nil}
          | {:notice, String.t()}
          | {:mission, map() | nil}

  @typedoc """
  What a `{:go, output}` action commands: the three thrusters (allocation `:thesis`, and
  always in run mode simulator) or the body-frame demand (allocation `:vehicle`).
  """
  @type output :: Allocation.thrusters() | Demand.t()

  @typedoc """
  * `mode`, `gain`, `lights`, `laser`, `tilt` (rad), `run_mode` — as set by the pilot;
    `run_modes` — the run modes this vehicle has (`[:normal]` on a simulated board)
  * `pilot` — the pilot's command in the current mode's terms (motion or dp:
    `%{surge, heave, yaw}`, manual: `%{port, vertical, starboard}`)
  * `depth`, `heading` — the autopilots; `dp` — DP when in mode dp, else nil
  * `estimate`, `estimate_at` — the latest estimate and when it came (s, the caller's clock)
  * `thrusters` — the output in force
  * `waiting` — per autopilot, why it gives no output now (its measurement initialising or
    stale, no current estimate), nil when it acts or is off
  * `axes` — the body-frame axes the vehicle can be commanded in (the board's,
    `Neptunus.Vehicle.Board.capabilities/1`); `allocation` — where the demand becomes
    thruster commands: `:thesis` here (eq. 9.3), `:vehicle` on the vehicle (ArduSub)
  * `demand` — the body-frame demand in force (`Neptunus.Control.Demand`)
  """
  @type t :: %__MODULE__{
          mode: Command.control_mode(),
          gain: float(),
          lights: 0..255,
          laser: 0..255,
          tilt: float(),
          run_mode: Command.run_mode(),
          run_modes: [Command.run_mode()],
          pilot: map(),
          depth: Autopilot.t(),
          heading: Autopilot.t(),
          dp: DP.t() | nil,
          gains: %{depth: keyword(), heading: keyword(), surge: keyword()},
          estimate: map() | nil,
          estimate_at: number() | nil,
          thrusters: Allocation.thrusters(),
          stale_after: float(),
          deadband: float(),
          dp_opts: keyword(),
          actuation: :full | :surge,
          mission_opts: keyword(),
          waiting: %{depth: String.t() | nil, heading: String.t() | nil},
          axes: [Demand.axis()],
          allocation: :thesis | :vehicle,
          demand: Demand.t()
        }

  @doc """
  Control at rest: mode motion, thrusters neutral, autopilots off. Options: `gain` (default
  0.5), `run_modes` (default `[:normal]`; `[:normal, :simulator]` for a real board), `gains`
  (`%{depth: [kp:, ki:, kd:], heading: …, surge: …}` merged over the defaults), `stale_after`
  (s), `deadband` (the thrusters' deadband the autopilot outputs skip, default 0.05 — the
  vehicle files' and a typical ESC's; 0 turns compensation off), `dp` (`return_radius`,
  `capture_radius`), `reference` (`%{depth: [rate:, accel:], heading: …}`: the setpoint
  reference limits, SI and rad, default `Neptunus.Control.Autopilot.default_limits/0`),
  `axes` (the vehicle's body-frame axes, default `[:surge, :heave, :yaw]`) and `allocation`
  (`:thesis`, the default, or `:vehicle`; see `t:t/0`).
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    gains =
      Map.merge(@default_gains, Map.new(Keyword.get(opts, :gains, %{})), fn _axis, a, b ->
        Keyword.merge(a, Enum.to_list(b))
      end)

    references = Map.new(Keyword.get(opts, :reference, %{}))

    %__MODULE__{
      gain: Keyword.get(opts, :gain, 0.5) * 1.0,
      run_modes: Keyword.get(opts, :run_modes, [:normal]),
      gains: gains,
      depth: Autopilot.new(:depth, gains.depth, references[:depth]),
      heading: Autopilot.new(:heading, gains.heading, references[:heading]),
      stale_after: Keyword.get(opts, :stale_after, 1.0) * 1.0,
      deadband: Keyword.get(opts, :deadband, 0.05) * 1.0,
      dp_opts: Keyword.get(opts, :dp, []),
      actuation: Keyword.get(opts, :actuation, :surge),
      mission_opts: Keyword.get(opts, :mission, []),
      axes: Keyword.get(opts, :axes, [:surge, :heave, :yaw]),
      allocation: Keyword.get(opts, :allocation, :thesis)
    }
  end

  @doc "The default PID gains of the depth, heading and DP surge loops."
  @spec default_gains() :: map()
  def default_gains, do: @default_gains

  # --- commands ---------------------------------------------------------------------------

  @doc """
  Carries out a validated pilot command (`Neptunus.Control.Command`) at time `now` (s).
  `{:error, reason}` changes nothing.
  """
  @spec command(t(), Command.t(), number()) :: {:ok, t(), [action()]} | {:error, String.t()}
  def command(%__MODULE__{mode: mode} = core, {:set_control_mode, mode}, _now),
    do: {:ok, core, []}

  def command(core, {:set_control_mode, :dp}, now) do
    case fresh_estimate(core, now) do
      nil ->
        {:error, "dp needs a current estimate of depth and heading (no board samples)"}

      estimate ->
        case unavailable(estimate, :depth) || unavailable(estimate, :heading) do
          nil ->
            {core, actions} = pilot_stop(core, "control_mode_changed")
            core = enter_dp(core, estimate)
            {:ok, core, actions ++ dp_notice(core)}

          reason ->
            {:error, "dp needs " <> reason}
        end
    end
  end

  def command(core, {:set_control_mode, mode}, _now) do
    ended = if mission(core), do: [{:mission, nil}], else: []
    {core, actions} = pilot_stop(core, "control_mode_changed")
    core = leave_dp(%{core | mode: mode, pilot: zero(mode)})

    core =
      if mode == :manual,
        do: %{
          core
          | depth: Autopilot.disengage(core.depth),
            heading: Autopilot.disengage(core.heading)
        },
        else: core

    {:ok, core, actions ++ ended}
  end

  def command(%__MODULE__{mode: mode}, {:thrust, thrust_mode, _values}, _now)
      when thrust_mode != mode,
      do: {:error, "thrust mode #{thrust_mode} does not match control mode #{mode}"}

  def command(core, {:thrust, :manual, values}, _now) do
    {:ok, %{core | pilot: values}, []} |> remix()
  end

  def command(core, {:thrust, :motion, values}, _now) do
    # an axis the vehicle does not have may only be zero (and is left out)
    {missing, values} = Map.split(values, Map.keys(values) -- axes(core))

    case Enum.find(missing, fn {_axis, v} -> v != 0 end) do
      nil ->
        # a release re-captures at the latest estimate (the stick moved the vehicle there)
        estimate = core.estimate

        core = %{
          core
          | pilot: values,
            depth: pilot_axis(core.depth, values.heave, estimate, :depth, :depth_rate),
            heading: pilot_axis(core.heading, values.yaw, estimate, :heading, :yaw_rate)
        }

        {:ok, core, []} |> remix()

      {axis, _} ->
        {:error,
         "this vehicle has no #{axis} (its axes: #{Enum.join(axes(core), ", ")}): send 0 or leave it out"}
    end
  end

  def command(core, {:set_gain, k}, _now), do: {:ok, %{core | gain: k}, []} |> remix()
  def command(core, {:set_lights, n}, _now), do: {:ok, %{core | lights: n}, [{:lights, n}]}
  def command(core, {:set_laser, n}, _now), do: {:ok, %{core | laser: n}, [{:laser, n}]}
  def command(core, {:set_tilt, rad}, _now), do: {:ok, %{core | tilt: rad}, [{:tilt, rad}]}

  def command(%__MODULE__{mode: :manual}, {:autopilot, _}, _now),
    do: {:error, "autopilots are not available in manual mode: switch to motion or dp"}

  def command(%__MODULE__{mode: :dp}, {:autopilot, %{depth: d, heading: h}}, _now)
      when is_nil(d) or is_nil(h),
      do: {:error, "dp holds depth and heading: switch to motion to release them"}

  def command(%__MODULE__{mode: :dp, dp: %DP{} = dp}, {:autopilot, _}, _now)
      when dp.mission != nil and dp.mission.state == :running,
      do: {:error, "a mission is running: it sets depth and heading (pause or abort it first)"}

  def command(%__MODULE__{mode: mode}, {:mission, _}, _now) when mode != :dp,
    do: {:error, "missions run in control mode dp: switch to dp first"}

  def command(core, {:mission, {:plan, _waypoints}}, _now), do: {:ok, core, []}

  def command(core, {:mission, {:start, waypoints}}, now) do
    estimate = fresh_estimate(core, now)
    position = estimate && estimate[:position]

    with {:ok, p} <- mission_position(position),
         {:ok, waypoints} <- Neptunus.Control.Mission.reachable(waypoints, p, core.mission_opts),
         {:ok, dp} <- DP.start_mission(core.dp, waypoints, position) do
      core = %{core | dp: dp}
      n = length(waypoints)

      {:ok, core,
       [
         {:mission, mission(core)},
         {:notice,
          "mission #{dp.missions}: started, #{n} waypoint#{if n == 1, do: "", else: "s"}"}
       ]}
      |> remix()
    end
  end

  def command(core, {:mission, action}, now) when action in [:pause, :resume, :abort] do
    position = (fresh_estimate(core, now) || %{})[:position]

    result =
      case action do
        :pause -> DP.pause_mission(core.dp, position)
        :resume -> DP.resume_mission(core.dp, position)
        :abort -> DP.abort_mission(core.dp, position)
      end

    with {:ok, dp} <- result do
      core = %{core | dp: dp}
      done = if action == :abort, do: [{:mission, nil}], else: [{:mission, mission(core)}]
      {:ok, core, done ++ [{:notice, "mission: #{action}d by the pilot"}]} |> remix()
    end
  end

  def command(core, {:autopilot, %{depth: depth, heading: heading}}, now) do
    engaging? = Enum.any?([depth, heading], &(&1 not in [nil, :unchanged]))

    case fresh_estimate(core, now) do
      nil when engaging? ->
        {:error, "no current estimate of depth and heading (no board samples): cannot engage"}

      estimate ->
        refused =
          Enum.find_value([depth: depth, heading: heading], fn {axis, value} ->
            if value not in [nil, :unchanged], do: unavailable(estimate, axis)
          end)

        if refused do
          {:error, refused}
        else
          core =
            core
            |> set_axis(:depth, depth, estimate)
            |> set_axis(:heading, heading, estimate)

          {:ok, core, []} |> remix()
        end
    end
  end

  def command(%__MODULE__{run_mode: mode} = core, {:set_run_mode, mode}, _now),
    do: {:ok, core, []}

  def command(core, {:set_run_mode, mode}, now) do
    if mode in core.run_modes do
      seed =
        case fresh_estimate(core, now) || core.estimate do
          %{depth: d, heading: h} when is_number(d) and is_number(h) -> %{depth: d, heading: h}
          _ -> nil
        end

      {core, actions} = safety_stop(core, "run_mode_changed")
      core = %{core | run_mode: mode, estimate: nil, estimate_at: nil}

      {:ok, core,
       actions ++
         [
           {:run_mode, mode, seed},
           {:lights, core.lights},
           {:laser, core.laser},
           {:tilt, core.tilt}
         ]}
    else
      {:error,
       "run mode #{mode} needs a vehicle with a real board: this one is simulated " <>
         "(its normal run mode is the simulator)"}
    end
  end

  @doc """
  New PID gains for the depth and/or heading autopilot (`%{depth: [kp:, ki:, kd:], heading:
  …}`, validated by `Neptunus.Control.Tuning`), applied at once and bumpless: an engaged
  autopilot's output does not jump (its integral absorbs the change, see
  `Neptunus.Control.Autopilot.retune/4`). No actions: the output is unchanged.
  """
  @spec retune(t(), %{optional(:depth) => keyword(), optional(:heading) => keyword()}) :: t()
  def retune(core, gains) do
    estimate = core.estimate || %{}

    Enum.reduce(gains, core, fn
      {axis, axis_gains}, core when axis in [:depth, :heading] ->
        {key, rate_key} =
          if axis == :depth, do: {:depth, :depth_rate}, else: {:heading, :yaw_rate}

        ap = Map.fetch!(core, axis)
        ap = Autopilot.retune(ap, axis_gains, estimate[key], estimate[rate_key])
        gains = Map.put(core.gains, axis, Autopilot.gains(ap))
        core |> Map.put(axis, ap) |> Map.put(:gains, gains)
    end)
  end

  # --- stops, estimates, ticks -------------------------------------------------------------

  @doc "A stop for `reason` (see the moduledoc: handovers keep the autopilots)."
  @spec stop(t(), String.t()) :: {t(), [action()]}
  def stop(core, reason) when reason in @handover_reasons do
    # a mission stops with the pilot who started it: DP holds position where it is
    {dp, ended} =
      case core.dp do
        %DP{mission: %{}} = dp ->
          {:ok, dp} = DP.abort_mission(dp, (core.estimate || %{})[:position])
          {dp, [{:mission, nil}]}

        dp ->
          {dp, []}
      end

    core = release_pilot(%{core | pilot: zero(core.mode), dp: dp})
    core = %{core | thrusters: mix(core), demand: body_demand(core)}
    {core, [{:go, output(core)}, {:stopped, reason}] ++ ended}
  end

  def stop(core, reason), do: safety_stop(core, reason)

  @doc "The latest estimate (see the moduledoc), arrived at `now` (s)."
  @spec estimate(t(), map(), number()) :: t()
  def estimate(core, estimate, now), do: %{core | estimate: estimate, estimate_at: now}

  @doc "The estimate if it is no older than `stale_after` at `now`, else nil."
  @spec fresh_estimate(t(), number()) :: map() | nil
  def fresh_estimate(%__MODULE__{estimate_at: at} = core, now)
      when is_number(at) and now - at <= core.stale_after,
      do: core.estimate

  def fresh_estimate(_core, _now), do: nil

  @doc "Whether anything runs on the control loop (an autopilot or DP engaged)."
  @spec active?(t()) :: boolean()
  def active?(core),
    do: core.dp != nil or Autopilot.engaged?(core.depth) or Autopilot.engaged?(core.heading)

  @doc """
  One control period of `dt` s at `now`: runs DP and the autopilots on the estimate and
  returns `{:go, thrusters}` when the output changed. Nothing to do when nothing is engaged.
  """
  @spec tick(t(), number(), number()) :: {t(), [action()]}
  def tick(core, dt, now) do
    if active?(core) do
      estimate = fresh_estimate(core, now)

      {core, dp_actions} =
        case estimate do
          nil -> {idle(core), []}
          estimate -> run(core, estimate, dt)
        end

      {core, notices} = waiting(core, estimate)
      {core, actions} = emit(core)
      {core, dp_actions ++ notices ++ actions}
    else
      {core, []}
    end
  end

  @doc """
  Why the `axis` (`:depth` or `:heading`) autopilot cannot act on `estimate`, as a sentence a
  pilot can read, or nil when it can: the estimate's `measurement_state` for the axis is not
  `:valid`, or it has no value.
  """
  @spec unavailable(map(), :depth | :heading) :: String.t() | nil
  def unavailable(estimate, axis) do
    state = get_in(estimate, [Access.key(:measurement_state, %{}), Access.key(axis)])
    value = Map.get(estimate, axis)

    case state do
      :initialising ->
        "#{label(axis)}: #{axis} is initialising (#{sensor(axis)} has not given consistent " <>
          "readings yet)"

      :stale ->
        "#{label(axis)}: #{axis} is stale (no plausible reading from #{sensor(axis)} for 2 s)"

      _ when not is_number(value) ->
        "#{label(axis)}: no #{axis} estimate"

      _ ->
        nil
    end
  end

  defp label(:depth), do: "depth hold"
  defp label(:heading), do: "heading hold"
  defp sensor(:depth), do: "the board's depth sensor"
  defp sensor(:heading), do: "the board's compass"

  defp run(core, estimate, dt) do
    heading_ok? = unavailable(estimate, :heading) == nil

    {core, events} =
      case core.dp do
        nil ->
          {core, []}

        dp when heading_ok? ->
          {dp, events} = DP.step(dp, estimate[:position], estimate.heading, dt)
          {apply_dp(%{core | dp: dp}), events}

        dp ->
          {%{core | dp: DP.idle(dp)}, []}
      end

    core = %{
      core
      | depth: run_axis(core.depth, estimate, :depth, :depth_rate, dt),
        heading: run_axis(core.heading, estimate, :heading, :yaw_rate, dt)
    }

    {core, dp_actions(core, events)}
  end

  # DP's setpoints to the autopilots (without a jump: the reference model moves them)
  defp apply_dp(%__MODULE__{dp: dp} = core) do
    heading =
      if dp.heading_setpoint,
        do: Autopilot.retarget(core.heading, dp.heading_setpoint),
        else: core.heading

    depth =
      if dp.depth_setpoint,
        do: Autopilot.retarget(core.depth, dp.depth_setpoint),
        else: core.depth

    %{core | heading: heading, depth: depth}
  end

  defp dp_actions(core, events) do
    Enum.flat_map(events, fn
      {:notice, text} -> [{:notice, text}]
      :mission -> [{:mission, mission(core)}]
    end)
    |> Enum.uniq()
  end

  # an axis whose measurement is not valid (initialising after a board reset, stale) idles
  defp run_axis(ap, estimate, key, rate_key, dt) do
    case unavailable(estimate, key) do
      nil -> Autopilot.step(ap, Map.fetch!(estimate, key), estimate[rate_key], dt)
      _reason -> Autopilot.idle(ap)
    end
  end

  defp idle(core) do
    %{
      core
      | depth: Autopilot.idle(core.depth),
        heading: Autopilot.idle(core.heading),
        dp: core.dp && DP.idle(core.dp)
    }
  end

  # Why each engaged autopilot gives no output now (nil: it acts); a change is told to the
  # pilot as a `{:notice, text}`.
  defp waiting(core, estimate) do
    Enum.reduce([:depth, :heading], {core, []}, fn axis, {core, notices} ->
      reason =
        cond do
          not Autopilot.engaged?(Map.fetch!(core, axis)) -> nil
          estimate == nil -> "#{label(axis)}: no current estimate (no board samples for 1 s)"
          true -> unavailable(estimate, axis)
        end

      before = core.waiting[axis]
      core = %{core | waiting: Map.put(core.waiting, axis, reason)}

      cond do
        reason == before ->
          {core, notices}

        reason != nil ->
          {core, notices ++ [{:notice, reason <> ": output zero until it is valid"}]}

        Autopilot.engaged?(Map.fetch!(core, axis)) ->
          {core, notices ++ [{:notice, "#{label(axis)}: #{axis} valid again, holding"}]}

        true ->
          {core, notices}
      end
    end)
  end

  defp emit(core) do
    before = output(core)
    core = %{core | thrusters: mix(core), demand: body_demand(core)}
    output = output(core)
    if output == before, do: {core, []}, else: {core, [{:go, output}]}
  end

  # --- views ---------------------------------------------------------------------------------

  @doc """
  The control state as the wire shows it (command replies, grants, join snapshot):
  `%{mode, gain, lights, laser, tilt, run_mode, dp_holds, autopilot: %{depth, heading,
  position}, command, thrusters}` — `dp_holds` what DP holds (`dp_holds/1`), `autopilot.depth`/`heading` are the setpoints (nil: disengaged),
  `position` DP's target `%{x, y}` (nil unless in dp); `command` is the pilot's, `thrusters`
  the output with pulse widths.
  """
  @spec status(t()) :: map()
  def status(core) do
    core
    |> control()
    |> Map.merge(%{command: core.pilot, thrusters: Allocation.with_us(core.thrusters)})
  end

  @doc "The control state without command and thrusters (telemetry's `control`)."
  @spec control(t()) :: map()
  def control(core) do
    %{
      mode: Atom.to_string(core.mode),
      gain: core.gain,
      lights: core.lights,
      laser: core.laser,
      tilt: core.tilt,
      run_mode: Atom.to_string(core.run_mode),
      dp_holds: dp_holds(core),
      autopilot: %{
        depth: Autopilot.setpoint(core.depth),
        heading: if(core.dp, do: core.dp.heading, else: Autopilot.setpoint(core.heading)),
        position: dp_target(core.dp)
      },
      mission: mission_state(core.dp)
    }
  end

  defp dp_target(nil), do: nil

  defp dp_target(%DP{} = dp) do
    case DP.target(dp) do
      {x, y} -> %{x: x, y: y}
      nil -> nil
    end
  end

  defp mission_state(%DP{mission: %Neptunus.Control.Mission{} = m}),
    do: %{id: m.id, state: Atom.to_string(m.state), leg: m.leg + 1, count: length(m.waypoints)}

  defp mission_state(_dp), do: nil

  @doc "The mission as the `mission` event shows it (with its waypoints), or nil."
  @spec mission(t()) :: map() | nil
  def mission(%__MODULE__{dp: %DP{mission: %Neptunus.Control.Mission{} = m}}),
    do: Neptunus.Control.Mission.public(m)

  def mission(_core), do: nil

  @doc "The body-frame demand in force (surge, sway, heave, yaw; zero in manual mode)."
  @spec demand(t()) :: Neptunus.Control.Demand.t()
  def demand(%__MODULE__{demand: demand}), do: demand

  @doc """
  Telemetry's `autopilot`: `%{depth, heading, position}`, each nil when disengaged, else
  depth and heading `%{setpoint, output, overridden, waiting}` (`waiting`: why it gives no
  output now, nil when it acts) and position (DP)
  `%{x, y, heading, phase, distance, output}`.
  """
  @spec autopilot(t()) :: map()
  def autopilot(core) do
    %{
      depth: with_waiting(Autopilot.public(core.depth), core.waiting.depth),
      heading: with_waiting(Autopilot.public(core.heading), core.waiting.heading),
      position: core.dp && DP.public(core.dp)
    }
  end

  defp with_waiting(nil, _reason), do: nil
  defp with_waiting(public, reason), do: Map.put(public, :waiting, reason)

  # --- internals -----------------------------------------------------------------------------

  # The pilot's command goes to zero and the thrusters neutral (control-mode change).
  defp pilot_stop(core, reason) do
    core = %{
      core
      | pilot: zero(core.mode),
        thrusters: Allocation.neutral(),
        demand: Demand.zero()
    }

    core = release_pilot(core)
    {core, [{:go, output(core)}, {:stopped, reason}]}
  end

  defp safety_stop(core, reason) do
    ended = if mission(core), do: [{:mission, nil}], else: []

    core = %{
      leave_dp(core)
      | mode: if(core.mode == :dp, do: :motion, else: core.mode),
        pilot: zero(if core.mode == :dp, do: :motion, else: core.mode),
        depth: Autopilot.disengage(core.depth),
        heading: Autopilot.disengage(core.heading),
        waiting: %{depth: nil, heading: nil},
        thrusters: Allocation.neutral(),
        demand: Demand.zero()
    }

    {core, [{:go, output(core)}, {:stopped, reason}] ++ ended}
  end

  # the pilot let go of every axis: overridden autopilots re-capture
  defp release_pilot(core) do
    %{
      core
      | depth: pilot_axis(core.depth, 0.0, core.estimate, :depth, :depth_rate),
        heading: pilot_axis(core.heading, 0.0, core.estimate, :heading, :yaw_rate)
    }
  end

  defp pilot_axis(ap, input, estimate, key, rate_key) do
    case estimate do
      %{^key => value} -> Autopilot.pilot(ap, input != 0, value, estimate[rate_key])
      _ -> Autopilot.pilot(ap, input != 0, nil, nil)
    end
  end

  defp enter_dp(core, estimate) do
    depth =
      if Autopilot.engaged?(core.depth),
        do: core.depth,
        else: Autopilot.engage(core.depth, :hold, estimate.depth, estimate[:depth_rate], false)

    heading =
      if Autopilot.engaged?(core.heading),
        do: core.heading,
        else: Autopilot.engage(core.heading, :hold, estimate.heading, estimate[:yaw_rate], false)

    # without a valid position DP holds depth and heading only (thesis ch. 14)
    dp =
      DP.new(
        estimate[:position],
        Autopilot.setpoint(heading),
        [actuation: core.actuation] ++ core.dp_opts
      )

    %{core | mode: :dp, pilot: zero(:dp), depth: depth, heading: heading, dp: dp}
  end

  defp dp_notice(%__MODULE__{mode: :dp, dp: %DP{waiting: why}}) when is_binary(why),
    do: [{:notice, "dp: no valid position (#{why}): holding depth and heading only"}]

  defp dp_notice(_core), do: []

  defp mission_position(%{valid: true, north: n, east: e}) when is_number(n), do: {:ok, {n, e}}

  defp mission_position(%{reason: reason}) when is_binary(reason),
    do: {:error, "a mission needs a valid position: #{reason}"}

  defp mission_position(_), do: {:error, "a mission needs a valid position: no position source"}

  @doc """
  What DP holds: nil outside control mode dp, else `["depth", "heading", "position"]`, or
  `["depth", "heading"]` on a vehicle without a position source.
  """
  @spec dp_holds(t()) :: [String.t()] | nil
  def dp_holds(%__MODULE__{mode: :dp, dp: %DP{} = dp}), do: DP.holds(dp)
  def dp_holds(%__MODULE__{mode: :dp}), do: ["depth", "heading"]
  def dp_holds(_core), do: nil

  # leaving DP: the heading autopilot goes back to DP's held heading
  defp leave_dp(%__MODULE__{dp: nil} = core), do: core

  defp leave_dp(%__MODULE__{dp: dp} = core),
    do: %{
      core
      | dp: nil,
        heading: Autopilot.retarget(core.heading, dp.heading_setpoint || dp.heading)
    }

  defp set_axis(core, _axis, :unchanged, _estimate), do: core

  defp set_axis(core, axis, value, estimate) when value != nil do
    core
    |> Map.put(:waiting, Map.put(core.waiting, axis, nil))
    |> set_engaged(axis, value, estimate)
  end

  defp set_axis(core, axis, nil, _estimate),
    do:
      core
      |> Map.update!(axis, &Autopilot.disengage/1)
      |> Map.put(:waiting, Map.put(core.waiting, axis, nil))

  defp set_engaged(%__MODULE__{dp: %DP{} = dp} = core, :heading, value, estimate) do
    dp = DP.set_heading(dp, if(value == :hold, do: estimate.heading, else: value))
    ap = Autopilot.engage(core.heading, dp.heading, estimate.heading, estimate[:yaw_rate], false)
    %{core | dp: dp, heading: ap}
  end

  defp set_engaged(core, axis, value, estimate) do
    {key, rate_key, input} =
      case axis do
        :depth -> {:depth, :depth_rate, core.pilot[:heave] || 0.0}
        :heading -> {:heading, :yaw_rate, core.pilot[:yaw] || 0.0}
      end

    ap = Map.fetch!(core, axis)
    ap = Autopilot.engage(ap, value, Map.fetch!(estimate, key), estimate[rate_key], input != 0)
    Map.put(core, axis, ap)
  end

  # recompute the output and always command it (a command re-sends the thrust)
  defp remix({:ok, core, actions}) do
    core = %{core | thrusters: mix(core), demand: body_demand(core)}
    {:ok, core, actions ++ [{:go, output(core)}]}
  end

  @doc """
  What goes to the board now (the `{:go, output}` actions): the three thrusters where the
  allocation is ours (`:thesis`, and always in run mode simulator: the simulator is the
  three-thruster vehicle), else the body-frame demand, each axis in [-1, 1].
  """
  @spec output(t()) :: output()
  def output(core) do
    case allocation(core) do
      :thesis -> core.thrusters
      :vehicle -> Demand.saturate(core.demand)
    end
  end

  @doc "Nothing commanded, in the terms of `output/1`."
  @spec neutral(t()) :: output()
  def neutral(core) do
    case allocation(core) do
      :thesis -> Allocation.neutral()
      :vehicle -> Demand.zero()
    end
  end

  @doc """
  The vehicle's axes changed (its board declared others once its vehicle told them, e.g. an
  ArduSub's frame, `Neptunus.Vehicle.Board.declare_axes/2`). The pilot's motion command keeps
  only the axes the vehicle still has: a value in one it lost is dropped and the output mixed
  again at once (a sway in force stops when the vehicle turns out not to sway); an axis gained
  changes no output. DP's actuation follows (`:full` with sway) from its next engagement.
  """
  @spec set_axes(t(), [Demand.axis()]) :: {t(), [action()]}
  def set_axes(%__MODULE__{axes: axes} = core, axes), do: {core, []}

  def set_axes(core, axes) do
    lost = core.axes -- axes
    actuation = if :sway in axes, do: :full, else: :surge
    core = %{core | axes: axes, actuation: actuation}
    pilot = if core.mode == :motion, do: Map.drop(core.pilot, lost), else: core.pilot

    if pilot == core.pilot do
      {core, []}
    else
      {:ok, core, actions} = remix({:ok, %{core | pilot: pilot}, []})
      {core, actions}
    end
  end

  @doc """
  The body-frame axes the pilot may command now: the vehicle's (`axes` of `new/1`), or the
  three-thruster vehicle's surge, heave and yaw in run mode simulator.
  """
  @spec axes(t()) :: [Demand.axis()]
  def axes(%__MODULE__{run_mode: :simulator}), do: [:surge, :heave, :yaw]
  def axes(%__MODULE__{axes: axes}), do: axes

  defp allocation(%__MODULE__{run_mode: :simulator}), do: :thesis
  defp allocation(%__MODULE__{allocation: allocation}), do: allocation

  @doc false
  # The thruster output of the current mode, pilot command and autopilot outputs.
  @spec mix(t()) :: Allocation.thrusters()
  def mix(%__MODULE__{mode: :manual, gain: k, pilot: p}) do
    %{port: sat(k * p.port), vertical: sat(k * p.vertical), starboard: sat(k * p.starboard)}
  end

  def mix(%__MODULE__{} = core) do
    if pilot_alone?(core) do
      # the thesis' eq. 9.3 exactly
      Allocation.motion(core.pilot, core.gain)
    else
      %{surge: surge, heave: heave, yaw: yaw} = body_demand(core)
      Allocation.motion(%{surge: surge, heave: heave, yaw: yaw}, 1.0)
    end
  end

  # motion mode with no autopilot holding: the pilot's command alone
  defp pilot_alone?(%__MODULE__{mode: :motion, depth: %{state: ds}, heading: %{state: hs}}),
    do: ds != :holding and hs != :holding

  defp pilot_alone?(_core), do: false

  # The body-frame demand of the current mode, pilot command, autopilots and DP (deadband
  # compensated where an autopilot or DP drives the axis). The three-thruster allocation
  # takes its surge, heave and yaw; a vehicle that can sway takes it all. One gain, `k`,
  # scales the pilot's axes, once, here.
  defp body_demand(%__MODULE__{mode: :manual}), do: Demand.zero()

  defp body_demand(core) do
    if pilot_alone?(core) do
      %{gain: k, pilot: p} = core
      %{surge: k * p.surge, sway: k * sway(p), heave: k * p.heave, yaw: k * p.yaw}
    else
      assisted_demand(core)
    end
  end

  defp assisted_demand(%__MODULE__{mode: mode, gain: k, pilot: p} = core) do
    {surge, sway, pilot_k} =
      case {mode, core.dp} do
        {:dp, %DP{demand: d}} -> {compensate(d.surge, core), compensate(d.sway, core), 0.0}
        {:dp, nil} -> {0.0, 0.0, 0.0}
        _ -> {k * p.surge, k * sway(p), k}
      end

    heave =
      case Autopilot.output(core.depth) do
        nil -> pilot_k * p.heave
        u -> compensate(u, core)
      end

    case Autopilot.output(core.heading) do
      nil ->
        %{surge: surge, sway: sway, heave: heave, yaw: pilot_k * p.yaw}

      yaw ->
        yaw = compensate(yaw, core)
        # heading first: surge gives way so that |surge| + |yaw| <= 1
        room = max(1.0 - abs(yaw), 0.0)
        surge = surge |> max(-room) |> min(room)
        %{surge: surge, sway: sway, heave: heave, yaw: yaw}
    end
  end

  defp sway(pilot), do: Map.get(pilot, :sway, 0.0)

  # Thruster deadband compensation of an autopilot output: beyond `ramp` the output skips the
  # deadband δ (δ + (1 − δ)|u|), below it a steeper line through zero (no chatter from noise).
  defp compensate(u, %__MODULE__{deadband: d}) when d == 0, do: u

  defp compensate(u, %__MODULE__{deadband: d}) do
    ramp = @deadband_ramp
    a = abs(u)
    v = if a >= ramp, do: d + (1.0 - d) * a, else: a * (d + (1.0 - d) * ramp) / ramp
    if u < 0, do: -v, else: v
  end

  defp zero(:manual), do: %{port: 0.0, vertical: 0.0, starboard: 0.0}
  defp zero(_mode), do: %{surge: 0.0, heave: 0.0, yaw: 0.0}

  defp sat(x), do: x |> max(-1.0) |> min(1.0) |> Kernel.*(1.0) |> Kernel.+(0.0)
end
