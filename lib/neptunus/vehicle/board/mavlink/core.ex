defmodule Neptunus.Vehicle.Board.MAVLink.Core do
  @moduledoc """
  Every decision of the `mavlink` board (`Neptunus.Vehicle.Board.MAVLink`), pure: the link's
  state, the vehicle's state as its heartbeat tells it, the arming state machine, what to send
  and when, and the samples made of the vehicle's telemetry. The process only carries out the
  actions returned here. Times are integer milliseconds of the monotonic clock
  (`Neptunus.Clock.monotonic_ms/0`), given by the caller.

  ## What it sends (our system/component ids, 255/190 by default)

    * **HEARTBEAT** every second as a ground station (`MAV_TYPE_GCS`, `MAV_AUTOPILOT_INVALID`):
      ArduSub's ground-station failsafe counts it.
    * **MANUAL_CONTROL** to the vehicle's system every `manual_period_ms` (100 ms, the 10 Hz ground
      stations send; ArduSub's pilot-input failsafe fires after 3 s without it), and at once
      whenever the command changes (so a pilot's command or a stop never waits for the next
      period). The command is the body-frame demand `go/3` gets (our gain already in it),
      axis by axis (`manual_control/2`): `x` = 1000·surge, `y` = 1000·sway, `r` = 1000·yaw,
      `z` = 500 − 500·heave (ArduSub: 0..1000, 500 neutral, above 500 up; our heave is
      positive down), each divided by ArduSub's own joystick gain so that it is not applied a
      second time, `buttons` 0. Neutral (`x 0, y 0, z 500, r 0`) is sent whenever the vehicle
      is not commanded: control drives neutral on every stop and while nobody pilots.

  ## One gain

  ArduSub scales MANUAL_CONTROL by its joystick gain (`JS_GAIN_DEFAULT`, 0.5 by default; its
  gain buttons step it), which it reports as NAMED_VALUE_FLOAT `PilotGain`. Our gain is in
  the demand already, so every axis is divided by the last `PilotGain` heard (1.0 until one
  comes: never more thrust than asked) and clamped to MANUAL_CONTROL's range: what the
  vehicle's mixer gets is our demand. A demand beyond ArduSub's gain saturates there (an
  ArduSub at 0.5 gives at most half thrust); the pilot is told once per gain heard (a `log`
  entry) and docs/MAVLINK.md says to set `JS_GAIN_DEFAULT` 1.
    * **Stream requests** each time the link comes up: REQUEST_DATA_STREAM for the streams
      carrying what we show (`@streams`); ArduSub streams them by default too.
    * **TIMESYNC** every second (`tc1 = 0`, `ts1` our clock in ns, from its ms): the vehicle's answer gives
      the round-trip time (`rtt_ms`).
    * **COMMAND_LONG** `MAV_CMD_COMPONENT_ARM_DISARM` (400) for `arm/4`, `MAV_CMD_DO_SET_MODE`
      (176) for `set_mode/4` and `autopilot/4`, `MAV_CMD_DO_SET_SERVO` (183) for the lights and
      `MAV_CMD_DO_MOUNT_CONTROL` (205) for the camera tilt.

  ## The vehicle's frame and its axes

  ArduSub mixes its thrusters by its frame (its `FRAME_CONFIG` parameter), and not every frame
  can strafe: the board asks for it (**PARAM_REQUEST_READ** `FRAME_CONFIG`, `param_index` −1)
  each time the link comes up and again every 900 ms while the link is up until the vehicle
  answers (PARAM_VALUE): nothing else waits for it. The answer gives the axes the vehicle can
  be commanded in (`axes/1`, `frames/0`): surge, heave and yaw always, sway only for a frame
  with lateral thrust. Until the frame is known, and for a frame value it does not know (the
  custom frame: its factors are the user's), sway is left out — a sway demand is never asked
  of a vehicle that may not have it — and the latter is said in a `log` entry. Each change of
  the axes is an action `{:axes, axes}`; a known frame is kept while the link is down and
  checked again when it comes back (a rebooted vehicle may have another).

  ## The link

  Up from the first HEARTBEAT of a vehicle (an autopilot: any type but a ground station, and
  an autopilot other than `MAV_AUTOPILOT_INVALID`, so the companion computer's, camera's or
  gimbal's heartbeats are not taken for it; the first one heard is the target of our
  commands) until none came for `link_timeout_ms` (3 s); every change is an action
  `{:link, %{up, reason}}`. Messages of other systems are ignored.

  ## Arming

  One arm/disarm (or mode) command waits for its COMMAND_ACK at a time; a second is refused.
  The answer is `:ok` for `MAV_RESULT_ACCEPTED`, otherwise the reason: the text of the last
  STATUSTEXT the vehicle sent while the command waited (ArduSub explains a refusal there,
  e.g. "PreArm: Must assign a disarm or arm_toggle button or disarm aux function"; texts
  over 50 bytes come in chunks and are joined), or the result's name. No ACK within
  `command_timeout_ms` (3 s) → `{:error, "no answer from the vehicle within 3.0 s"}`. Refused at
  once while the link is down.

  **Pilot loss** (`pilot/2` with the helm's pilot, `stopped/3` with a stop's reason): a stop for
  one of the `pilot_loss_reasons/0` schedules a disarm `disarm_delay_ms` later (2 s), which a new
  pilot taking the helm before then cancels; a handover never schedules one.
  """

  import Bitwise

  alias Neptunus.Protocol.MAVLink.Message

  # MAVLink constants
  @mav_type_gcs 6
  @mav_type_submarine 12
  @mav_autopilot_invalid 8
  @mav_mode_flag_safety_armed 128
  @mav_cmd_component_arm_disarm 400
  @mav_cmd_do_set_mode 176
  @mav_cmd_do_set_servo 183
  @mav_cmd_do_mount_control 205
  @mav_mode_flag_custom_mode_enabled 1
  @results %{
    0 => "accepted",
    1 => "temporarily rejected",
    2 => "denied",
    3 => "unsupported",
    4 => "failed",
    5 => "in progress",
    6 => "cancelled"
  }
  # ArduSub's FRAME_CONFIG values: name, and whether the frame has lateral thrust (sway)
  @frames %{
    0 => {"BlueROV1", true},
    1 => {"Vectored", true},
    2 => {"Vectored_6DOF", true},
    3 => {"Vectored_6DOF_90", true},
    4 => {"SimpleROV-3", false},
    5 => {"SimpleROV-4", false},
    6 => {"SimpleROV-5", true}
  }
  @frame_param "FRAME_CONFIG"
  # a frame request not answered is repeated this often (ms)
  @frame_retry_ms 900
  @system_status ~w(uninit boot calibrating standby active critical emergency poweroff
                    flight_termination)

  @doc "ArduSub's flight modes by custom mode number."
  @spec modes() :: %{non_neg_integer() => String.t()}
  def modes do
    %{
      0 => "STABILIZE",
      1 => "ACRO",
      2 => "ALT_HOLD",
      3 => "AUTO",
      4 => "GUIDED",
      7 => "CIRCLE",
      9 => "SURFACE",
      16 => "POSHOLD",
      19 => "MANUAL",
      20 => "MOTOR_DETECT",
      21 => "SURFTRAK"
    }
  end

  # MAV_DATA_STREAM id => rate (Hz): RAW_SENSORS (SCALED_PRESSURE), EXTENDED_STATUS
  # (SYS_STATUS), RC_CHANNELS (SERVO_OUTPUT_RAW), POSITION (GLOBAL_POSITION_INT, LOCAL_POSITION_NED), EXTRA1
  # (ATTITUDE), EXTRA2 (VFR_HUD)
  @streams [{1, 5}, {2, 2}, {3, 5}, {6, 3}, {10, 10}, {11, 10}]

  # GLOBAL_POSITION_INT and LOCAL_POSITION_NED this close (ms) are of the same moment
  @same_moment_ms 200

  @pilot_loss_reasons ~w(pilot_left pilot_disconnected deadman released helm_started)

  @typedoc "What the process carries out."
  @type action ::
          {:send, atom(), map()}
          | {:reply, term(), :ok | {:error, String.t()}}
          | {:link, %{up: boolean(), reason: String.t()}}
          | {:log, :info | :warning | :error, String.t(), map()}
          | {:sample, Neptunus.Vehicle.Board.sample()}
          | {:axes, [Neptunus.Control.Demand.axis()]}

  @type control :: %{x: integer(), y: integer(), z: integer(), r: integer(), buttons: 0}

  @type pending :: %{
          kind: :arm | :disarm | :mode,
          command: non_neg_integer(),
          from: term(),
          deadline_ms: integer(),
          text: String.t() | nil
        }

  @type t :: %__MODULE__{
          system: 1..255,
          component: 1..255,
          target: {byte(), byte()} | nil,
          seq: byte(),
          up: boolean(),
          reason: String.t(),
          heard_at_ms: integer() | nil,
          vehicle: %{
            armed: boolean(),
            mode: String.t() | nil,
            custom_mode: non_neg_integer() | nil,
            system_status: String.t() | nil,
            type: non_neg_integer() | nil
          },
          control: control(),
          demand: Neptunus.Control.Demand.t(),
          pilot_gain: float() | nil,
          frame: integer() | nil,
          frame_asked_ms: integer() | nil,
          next_heartbeat_ms: integer(),
          next_manual_ms: integer(),
          next_timesync_ms: integer(),
          pending: pending() | nil,
          pilot: term(),
          disarm_at_ms: integer() | nil,
          started_ms: integer(),
          readings: map(),
          texts: %{optional(pos_integer()) => binary()},
          rtt_ms: float() | nil,
          servo_us: [non_neg_integer()],
          manual_period_ms: pos_integer(),
          link_timeout_ms: pos_integer(),
          command_timeout_ms: pos_integer(),
          disarm_delay_ms: pos_integer(),
          lights_servo: pos_integer()
        }

  @enforce_keys [:started_ms]
  defstruct [
    :target,
    :heard_at_ms,
    :pending,
    :pilot,
    :disarm_at_ms,
    :started_ms,
    :rtt_ms,
    :pilot_gain,
    :frame,
    :frame_asked_ms,
    system: 255,
    component: 190,
    seq: 0,
    up: false,
    reason: "no heartbeat from the vehicle yet",
    vehicle: %{armed: false, mode: nil, custom_mode: nil, system_status: nil, type: nil},
    control: %{x: 0, y: 0, z: 500, r: 0, buttons: 0},
    demand: %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0},
    next_heartbeat_ms: 0,
    next_manual_ms: 0,
    next_timesync_ms: 0,
    readings: %{},
    texts: %{},
    servo_us: [],
    manual_period_ms: 100,
    link_timeout_ms: 3_000,
    command_timeout_ms: 3_000,
    disarm_delay_ms: 2_000,
    lights_servo: 9
  ]

  @doc """
  A board core at time `now_ms`. Options: `:system`, `:component` (ours, 255/190),
  `:manual_period_ms`, `:link_timeout_ms`, `:command_timeout_ms`, `:disarm_delay_ms`,
  `:lights_servo` (the servo output of the lights, default 9).
  """
  @spec new(integer(), keyword()) :: t()
  def new(now_ms, opts \\ []) when is_integer(now_ms) do
    fields =
      Keyword.take(opts, [
        :system,
        :component,
        :manual_period_ms,
        :link_timeout_ms,
        :command_timeout_ms,
        :disarm_delay_ms,
        :lights_servo
      ])

    struct!(
      %__MODULE__{
        started_ms: now_ms,
        next_heartbeat_ms: now_ms,
        next_manual_ms: now_ms,
        next_timesync_ms: now_ms
      },
      fields
    )
  end

  @doc """
  ArduSub's frames by `FRAME_CONFIG` value: `{name, sway?}` — sway where the frame has lateral
  thrust (ArduSub's frame table: BlueROV1, the vectored frames and SimpleROV-5 strafe;
  SimpleROV-3 and -4 do not). Value 7, the custom frame, is not here: its motor factors are
  the user's, so whether it strafes is not known.
  """
  @spec frames() :: %{non_neg_integer() => {String.t(), boolean()}}
  def frames, do: @frames

  @doc """
  The body-frame axes the vehicle can be commanded in, by its frame (see the moduledoc):
  surge, heave and yaw; sway too once its frame is known to have lateral thrust.

      iex> alias Neptunus.Vehicle.Board.MAVLink.Core
      iex> Core.axes(Core.new(0))
      [:surge, :heave, :yaw]
      iex> Core.axes(%{Core.new(0) | frame: 1})
      [:surge, :sway, :heave, :yaw]
      iex> Core.axes(%{Core.new(0) | frame: 4})
      [:surge, :heave, :yaw]
  """
  @spec axes(t()) :: [Neptunus.Control.Demand.axis()]
  def axes(%__MODULE__{frame: frame}) do
    case Map.get(@frames, frame) do
      {_name, true} -> [:surge, :sway, :heave, :yaw]
      _ -> [:surge, :heave, :yaw]
    end
  end

  @doc "The stop reasons that lose the pilot (a disarm follows unless a new pilot comes)."
  @spec pilot_loss_reasons() :: [String.t()]
  def pilot_loss_reasons, do: @pilot_loss_reasons

  @doc """
  MANUAL_CONTROL's `x`, `y`, `z`, `r` for a body-frame demand (each axis in [-1, 1]) on a
  vehicle whose joystick gain is `pilot_gain` (see the moduledoc): each axis divided by the
  gain, then scaled and clamped to MANUAL_CONTROL's range.

      iex> alias Neptunus.Vehicle.Board.MAVLink.Core
      iex> Core.manual_control(%{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}, 1.0)
      %{x: 0, y: 0, z: 500, r: 0, buttons: 0}
      iex> Core.manual_control(%{surge: 0.5, sway: -0.25, heave: -0.2, yaw: 0.25}, 1.0)
      %{x: 500, y: -250, z: 600, r: 250, buttons: 0}
      iex> Core.manual_control(%{surge: 0.25, sway: 0.0, heave: 0.1, yaw: -0.1}, 0.5)
      %{x: 500, y: 0, z: 400, r: -200, buttons: 0}
      iex> Core.manual_control(%{surge: 0.8, sway: 0.0, heave: 0.0, yaw: 0.0}, 0.5)
      %{x: 1000, y: 0, z: 500, r: 0, buttons: 0}
  """
  @spec manual_control(Neptunus.Control.Demand.t(), float()) :: control()
  def manual_control(%{surge: surge, sway: sway, heave: heave, yaw: yaw}, pilot_gain)
      when is_number(pilot_gain) and pilot_gain > 0 do
    %{
      x: scale(surge / pilot_gain, 1000, -1000, 1000),
      y: scale(sway / pilot_gain, 1000, -1000, 1000),
      z: 500 + scale(-heave / pilot_gain, 500, -500, 500),
      r: scale(yaw / pilot_gain, 1000, -1000, 1000),
      buttons: 0
    }
  end

  defp scale(value, factor, low, high),
    do: value |> Kernel.*(factor) |> round() |> max(low) |> min(high)

  # ── time ─────────────────────────────────────────────────────────────────────────────

  @doc "What is due at `now`: heartbeat, MANUAL_CONTROL, TIMESYNC, timeouts, a scheduled disarm."
  @spec tick(t(), integer()) :: {t(), [action()]}
  def tick(%__MODULE__{} = core, now) do
    {core, []}
    |> heartbeat_due(now)
    |> frame_due(now)
    |> manual_due(now)
    |> timesync_due(now)
    |> link_timeout(now)
    |> command_timeout(now)
    |> disarm_due(now)
    |> finish()
  end

  defp heartbeat_due({core, actions}, now) do
    if now >= core.next_heartbeat_ms do
      fields = %{
        type: @mav_type_gcs,
        autopilot: @mav_autopilot_invalid,
        base_mode: 0,
        custom_mode: 0,
        system_status: 4
      }

      {%{core | next_heartbeat_ms: next(core.next_heartbeat_ms, 1_000, now)},
       [{:send, :heartbeat, fields} | actions]}
    else
      {core, actions}
    end
  end

  # the frame asked again until the vehicle answers
  defp frame_due({%__MODULE__{frame_asked_ms: at, up: true} = core, actions}, now)
       when is_integer(at) and now - at >= @frame_retry_ms,
       do: {%{core | frame_asked_ms: now}, [frame_request(core) | actions]}

  defp frame_due(acc, _now), do: acc

  defp frame_request(core) do
    {system, component} = core.target

    {:send, :param_request_read,
     %{
       target_system: system,
       target_component: component,
       param_id: @frame_param,
       param_index: -1
     }}
  end

  defp manual_due({core, actions}, now) do
    if now >= core.next_manual_ms and core.target != nil do
      {core, send} = send_manual(core, now)
      {core, send ++ actions}
    else
      {core, actions}
    end
  end

  defp timesync_due({core, actions}, now) do
    if now >= core.next_timesync_ms and core.up do
      ts1 = now * 1_000_000

      {%{core | next_timesync_ms: next(core.next_timesync_ms, 1_000, now)},
       [{:send, :timesync, %{tc1: 0, ts1: ts1}} | actions]}
    else
      {core, actions}
    end
  end

  defp link_timeout({%__MODULE__{up: true, heard_at_ms: at} = core, actions}, now)
       when now - at > core.link_timeout_ms do
    reason = "no heartbeat from the vehicle for #{seconds(core.link_timeout_ms)} s"
    core = %{core | up: false, reason: reason}
    {core, [{:link, %{up: false, reason: reason}} | actions]}
  end

  defp link_timeout(acc, _now), do: acc

  defp command_timeout({%__MODULE__{pending: %{deadline_ms: d} = p} = core, actions}, now)
       when now >= d do
    reason = "no answer from the vehicle within #{seconds(core.command_timeout_ms)} s"
    {%{core | pending: nil}, [{:reply, p.from, {:error, reason}} | actions]}
  end

  defp command_timeout(acc, _now), do: acc

  defp disarm_due({%__MODULE__{disarm_at_ms: at} = core, actions}, now)
       when is_integer(at) and now >= at do
    core = %{core | disarm_at_ms: nil}

    if core.up and core.vehicle.armed do
      log =
        {:log, :warning, "disarming the vehicle: no pilot for #{seconds(core.disarm_delay_ms)} s",
         %{}}

      {core, [command(core, @mav_cmd_component_arm_disarm, [0.0]), log | actions]}
    else
      {core, actions}
    end
  end

  defp disarm_due(acc, _now), do: acc

  defp finish({core, actions}), do: {core, Enum.reverse(actions)}

  # the next deadline after `now` on the grid of `period` (a late tick does not send a burst)
  defp next(deadline, period, now), do: deadline + (div(now - deadline, period) + 1) * period

  # a duration as the texts say it: seconds (3_000 → 3.0)
  defp seconds(ms), do: ms / 1000

  defp send_manual(core, now) do
    target = elem(core.target, 0)
    fields = Map.put(core.control, :target, target)
    {%{core | next_manual_ms: now + core.manual_period_ms}, [{:send, :manual_control, fields}]}
  end

  @doc "The earliest time something is due (the process sleeps until then)."
  @spec due(t()) :: integer()
  def due(core) do
    [core.next_heartbeat_ms, core.next_manual_ms, core.next_timesync_ms]
    |> then(&if(core.pending, do: [core.pending.deadline_ms | &1], else: &1))
    |> then(&if(core.disarm_at_ms, do: [core.disarm_at_ms | &1], else: &1))
    |> Enum.min()
  end

  # ── commands ─────────────────────────────────────────────────────────────────────────

  @doc """
  The body-frame demand from control (`Neptunus.Control.Demand`, our gain in it):
  MANUAL_CONTROL at once when the command changes.
  """
  @spec go(t(), Neptunus.Control.Demand.t(), integer()) :: {t(), [action()]}
  def go(core, %{surge: _, sway: _, heave: _, yaw: _} = demand, now) do
    command(%{core | demand: demand}, now)
  end

  # MANUAL_CONTROL of the demand in force at ArduSub's gain: sent at once when it changed
  defp command(core, now) do
    control = manual_control(core.demand, core.pilot_gain || 1.0)

    cond do
      control == core.control -> {core, []}
      core.target == nil -> {%{core | control: control}, []}
      true -> send_manual(%{core | control: control}, now)
    end
  end

  @doc "Neutral MANUAL_CONTROL now, changed or not (the board's last word when it stops)."
  @spec neutral(t(), integer()) :: {t(), [action()]}
  def neutral(core, now) do
    demand = Neptunus.Control.Demand.zero()
    core = %{core | demand: demand, control: manual_control(demand, 1.0)}
    if core.target == nil, do: {core, []}, else: send_manual(core, now)
  end

  @doc """
  Arms (`true`) or disarms (`false`) the vehicle; `from` gets the answer as an action
  `{:reply, from, :ok | {:error, reason}}` (see the moduledoc).
  """
  @spec arm(t(), term(), boolean(), integer()) :: {t(), [action()]}
  def arm(core, from, arm?, now) when is_boolean(arm?) do
    kind = if arm?, do: :arm, else: :disarm
    param1 = if arm?, do: 1.0, else: 0.0
    # a disarm asked for by the pilot supersedes a scheduled one
    core = if arm?, do: core, else: %{core | disarm_at_ms: nil}
    request(core, from, kind, @mav_cmd_component_arm_disarm, [param1], now)
  end

  @doc """
  Sets the vehicle's flight mode by name (`modes/0`, e.g. `"ALT_HOLD"`), answered like `arm/4`.
  """
  @spec set_mode(t(), term(), String.t(), integer()) :: {t(), [action()]}
  def set_mode(core, from, name, now) do
    case Enum.find(modes(), fn {_n, mode} -> mode == name end) do
      {number, _} ->
        params = [@mav_mode_flag_custom_mode_enabled * 1.0, number * 1.0]
        request(core, from, :mode, @mav_cmd_do_set_mode, params, now)

      nil ->
        {core, [{:reply, from, {:error, "unknown flight mode #{inspect(name)}"}}]}
    end
  end

  @doc """
  The autopilots as ArduSub's flight modes: `setpoints` as `Neptunus.Control.Command` validates
  them (`%{depth: v, heading: v}`, each `:hold`, nil or `:unchanged`). Depth hold → ALT_HOLD
  (which holds the heading too), heading hold alone → STABILIZE, neither → MANUAL; what the
  current mode holds is what `:unchanged` keeps. Refused with a reason: a numeric setpoint
  (ArduSub holds the depth and heading it has when the mode engages) and depth hold without
  heading hold (ALT_HOLD holds both). Answered like `arm/4`.
  """
  @spec autopilot(t(), term(), map(), integer()) :: {t(), [action()]}
  def autopilot(core, from, %{depth: depth, heading: heading}, now) do
    held = %{
      depth: core.vehicle.mode == "ALT_HOLD",
      heading: core.vehicle.mode in ["ALT_HOLD", "STABILIZE"]
    }

    wanted =
      Map.new([depth: depth, heading: heading], fn
        {axis, :unchanged} -> {axis, Map.fetch!(held, axis)}
        {axis, :hold} -> {axis, true}
        {axis, nil} -> {axis, false}
        {axis, number} when is_number(number) -> {axis, {:setpoint, number}}
      end)

    case wanted do
      %{depth: {:setpoint, _}} ->
        refuse(core, from, "ArduSub holds the depth it has when ALT_HOLD engages: use \"hold\"")

      %{heading: {:setpoint, _}} ->
        refuse(
          core,
          from,
          "ArduSub holds the heading it has when STABILIZE engages: use \"hold\""
        )

      %{depth: true, heading: false} ->
        refuse(core, from, "ArduSub's depth hold (ALT_HOLD) holds the heading too")

      %{depth: true} ->
        set_mode(core, from, "ALT_HOLD", now)

      %{heading: true} ->
        set_mode(core, from, "STABILIZE", now)

      _ ->
        set_mode(core, from, "MANUAL", now)
    end
  end

  defp refuse(core, from, reason), do: {core, [{:reply, from, {:error, reason}}]}

  @doc """
  Whether a validated control command (`Neptunus.Control.Command`) can be flown on an ArduSub
  vehicle: manual per-thruster mode and dp are refused (ArduSub takes no per-thruster input
  in normal flight, and dp needs a position it does not give), the laser too (none), and
  the autopilots are its flight modes (`autopilot/4`), not Neptunus' own.
  """
  @spec vet(term()) :: :ok | {:error, String.t()}
  def vet({:set_control_mode, :manual}),
    do:
      {:error,
       "manual per-thruster mode is not available on an ArduSub vehicle (it takes no " <>
         "per-thruster input in normal flight): fly in motion mode"}

  def vet({:thrust, :manual, _}), do: vet({:set_control_mode, :manual})

  def vet({:set_control_mode, :dp}),
    do: {:error, "dp is not available on an ArduSub vehicle: it needs a position estimate"}

  def vet({:set_laser, _}), do: {:error, "an ArduSub vehicle has no laser"}

  def vet({:autopilot, _}),
    do: {:error, "an ArduSub vehicle's autopilots are its flight modes (ALT_HOLD, STABILIZE)"}

  def vet(_command), do: :ok

  defp request(core, from, kind, command, params, now) do
    cond do
      not core.up ->
        {core, [{:reply, from, {:error, "the vehicle's link is down (#{core.reason})"}}]}

      core.pending != nil ->
        reason = "a #{core.pending.kind} command is still waiting for the vehicle's answer"
        {core, [{:reply, from, {:error, reason}}]}

      true ->
        pending = %{
          kind: kind,
          command: command,
          from: from,
          deadline_ms: now + core.command_timeout_ms,
          text: nil
        }

        {%{core | pending: pending}, [command(core, command, params)]}
    end
  end

  defp command(core, command, params) do
    {system, component} = core.target
    params = params ++ List.duplicate(0.0, 7 - length(params))

    fields =
      params
      |> Enum.with_index(1)
      |> Map.new(fn {value, i} -> {String.to_atom("param#{i}"), value} end)
      |> Map.merge(%{
        target_system: system,
        target_component: component,
        command: command,
        confirmation: 0
      })

    {:send, :command_long, fields}
  end

  @doc """
  Lights 0..255 → `MAV_CMD_DO_SET_SERVO` on the lights' servo output, 1100..1900 µs (ArduSub's
  lights range). Nothing while no vehicle is known.
  """
  @spec lights(t(), 0..255) :: {t(), [action()]}
  def lights(%__MODULE__{target: nil} = core, _n), do: {core, []}

  def lights(core, n) when n in 0..255 do
    us = 1100 + round(n * 800 / 255)
    {core, [command(core, @mav_cmd_do_set_servo, [core.lights_servo * 1.0, us * 1.0])]}
  end

  @doc """
  Camera tilt (rad, positive up) → `MAV_CMD_DO_MOUNT_CONTROL` pitch in degrees, mode
  MAVLINK_TARGETING (2). Nothing while no vehicle is known.
  """
  @spec tilt(t(), number()) :: {t(), [action()]}
  def tilt(%__MODULE__{target: nil} = core, _rad), do: {core, []}

  def tilt(core, rad) when is_number(rad) do
    degrees = rad * 180 / :math.pi()
    params = [degrees, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]
    {core, [command(core, @mav_cmd_do_mount_control, params)]}
  end

  @doc """
  A stop of the vehicle with `reason`: a pilot loss (`pilot_loss_reasons/0`) schedules a
  disarm `disarm_delay_ms` after `now` while the vehicle is armed or being armed.
  """
  @spec stopped(t(), String.t(), integer()) :: t()
  def stopped(core, reason, now) do
    arming? = match?(%{kind: :arm}, core.pending)

    if reason in @pilot_loss_reasons and (core.vehicle.armed or arming?) and
         core.disarm_at_ms == nil,
       do: %{core | disarm_at_ms: now + core.disarm_delay_ms},
       else: core
  end

  @doc """
  The helm's pilot now (any term identifying them, nil when free): a pilot other than the
  last one cancels a scheduled disarm (the helm was handed over or taken).
  """
  @spec pilot(t(), term()) :: t()
  def pilot(core, pilot) do
    core = if pilot != nil and pilot != core.pilot, do: %{core | disarm_at_ms: nil}, else: core
    %{core | pilot: pilot}
  end

  # ── what the vehicle sends ───────────────────────────────────────────────────────────

  @doc "A message from the link."
  @spec receive(t(), Message.t(), integer()) :: {t(), [action()]}
  def receive(
        core,
        %Message{name: :heartbeat, fields: %{type: type, autopilot: autopilot}} = m,
        now
      )
      when type != @mav_type_gcs and autopilot != @mav_autopilot_invalid do
    if core.target == nil or core.target == {m.system, m.component},
      do: heartbeat(core, m, now),
      else: {core, []}
  end

  def receive(%__MODULE__{target: {system, _}} = core, %Message{system: system} = m, now),
    do: from_vehicle(core, m, now)

  def receive(core, _message, _now), do: {core, []}

  defp heartbeat(core, %Message{fields: f} = m, now) do
    armed = (f.base_mode &&& @mav_mode_flag_safety_armed) != 0

    vehicle = %{
      armed: armed,
      custom_mode: f.custom_mode,
      mode: mode_name(f.type, f.custom_mode),
      system_status: Enum.at(@system_status, f.system_status, "unknown"),
      type: f.type
    }

    before = core.vehicle
    core = %{core | target: {m.system, m.component}, heard_at_ms: now, vehicle: vehicle}

    {core, link} =
      if core.up,
        do: {core, []},
        else:
          {%{core | frame_asked_ms: now},
           [{:link, %{up: true, reason: "heartbeat"}}] ++ streams(core) ++ [frame_request(core)]}

    # what changed (everything when the link comes up) goes to the logger
    logs =
      for {key, what} <- [armed: "armed", mode: "mode"],
          link != [] or Map.get(before, key) != Map.get(vehicle, key),
          do: {:log, :info, "vehicle #{what}: #{Map.get(vehicle, key)}", %{}}

    {%{core | up: true, reason: "heartbeat"}, link ++ logs}
  end

  defp mode_name(@mav_type_submarine, custom), do: Map.get(modes(), custom, "MODE #{custom}")
  defp mode_name(_type, custom), do: "MODE #{custom}"

  defp streams(core) do
    {system, component} = core.target

    for {stream, hz} <- @streams do
      {:send, :request_data_stream,
       %{
         target_system: system,
         target_component: component,
         req_stream_id: stream,
         req_message_rate: hz,
         start_stop: 1
       }}
    end
  end

  defp from_vehicle(core, %Message{name: :command_ack, fields: f}, _now) do
    case core.pending do
      %{command: command} = p when command == f.command ->
        reply =
          case f.result do
            0 -> :ok
            result -> {:error, p.text || "#{Map.get(@results, result, "result #{result}")}"}
          end

        {%{core | pending: nil}, [{:reply, p.from, reply}]}

      _ ->
        {core, []}
    end
  end

  # a text longer than 50 bytes comes in chunks of one `id` (MAVLink 2), the last one shorter
  defp from_vehicle(core, %Message{name: :statustext, fields: %{id: id} = f}, now)
       when is_integer(id) and id != 0 do
    text = Map.get(core.texts, id, "") <> f.text

    if byte_size(f.text) < 50 or byte_size(text) >= 50 * 8 do
      core = %{core | texts: Map.delete(core.texts, id)}

      from_vehicle(
        core,
        %Message{
          name: :statustext,
          fields: %{f | id: 0, text: text},
          id: 253,
          system: 0,
          component: 0,
          seq: 0,
          version: 2
        },
        now
      )
    else
      # at most a few texts in flight: an unfinished one is dropped by the next id's start
      {%{core | texts: %{id => text}}, []}
    end
  end

  defp from_vehicle(core, %Message{name: :statustext, fields: f}, _now) do
    text = f.text
    level = severity(f.severity)
    core = if core.pending, do: put_in(core.pending.text, text), else: core
    {core, [{:log, level, text, %{severity: f.severity, source: "vehicle"}}]}
  end

  defp from_vehicle(core, %Message{name: :attitude, fields: f}, now) do
    readings = Map.merge(core.readings, %{roll: f.roll, pitch: f.pitch, heading: wrap(f.yaw)})
    core = %{core | readings: readings}
    {core, [{:sample, sample(core, f.time_boot_ms, now)}]}
  end

  defp from_vehicle(core, %Message{name: :vfr_hud, fields: %{alt: alt}}, _now)
       when is_number(alt),
       do: {put_reading(%{core | readings: Map.put(core.readings, :hud, true)}, :depth, -alt), []}

  defp from_vehicle(core, %Message{name: :global_position_int, fields: f}, _now) do
    core = global(core, f)

    if Map.has_key?(core.readings, :hud),
      do: {core, []},
      else: {put_reading(core, :depth, -f.relative_alt / 1000), []}
  end

  # the vehicle's own position, where its EKF has one (a DVL or a GPS feeding ArduSub):
  # navigation takes it as a position source
  defp from_vehicle(core, %Message{name: :local_position_ned, fields: f}, _now) do
    position = %{x: f.x * 1.0, y: f.y * 1.0, time_boot_ms: f.time_boot_ms, origin: nil}
    {with_origin(%{core | readings: Map.put(core.readings, :position, position)}), []}
  end

  defp from_vehicle(core, %Message{name: :sys_status, fields: f}, _now) do
    core =
      if f.voltage_battery != 0xFFFF,
        do: put_reading(core, :voltage, f.voltage_battery / 1000),
        else: core

    core =
      if f.current_battery >= 0,
        do: put_reading(core, :current, f.current_battery / 100),
        else: core

    {core, []}
  end

  # ArduSub's joystick gain (see "One gain" in the moduledoc): a change re-scales the command
  defp from_vehicle(
         core,
         %Message{name: :named_value_float, fields: %{name: "PilotGain"} = f},
         now
       )
       when is_float(f.value) and f.value >= 0.05 and f.value <= 1.0 do
    if f.value == core.pilot_gain do
      {core, []}
    else
      {core, actions} = command(%{core | pilot_gain: f.value}, now)
      {core, [{:log, :info, gain_text(f.value), %{}} | actions]}
    end
  end

  # the answer to our frame request (see "The vehicle's frame" in the moduledoc)
  defp from_vehicle(
         core,
         %Message{name: :param_value, fields: %{param_id: @frame_param, param_value: v}},
         _now
       )
       when is_float(v) do
    value = round(v)
    before = axes(core)
    logs = if value != core.frame, do: [frame_log(value)], else: []
    core = %{core | frame: value, frame_asked_ms: nil}
    changed = if axes(core) != before, do: [{:axes, axes(core)}], else: []
    {core, logs ++ changed}
  end

  defp from_vehicle(core, %Message{name: :servo_output_raw, fields: f}, _now) do
    servos = for i <- 1..8, do: Map.get(f, String.to_atom("servo#{i}_raw"), 0)
    {%{core | servo_us: servos}, []}
  end

  defp from_vehicle(core, %Message{name: :timesync, fields: %{tc1: tc1, ts1: ts1}}, now)
       when tc1 != 0 do
    rtt_ms = (now * 1_000_000 - ts1) / 1.0e6

    if rtt_ms >= 0 and rtt_ms < 10_000,
      do: {%{core | rtt_ms: Float.round(rtt_ms, 3)}, []},
      else: {core, []}
  end

  defp from_vehicle(core, _message, _now), do: {core, []}

  defp frame_log(value) do
    case Map.get(@frames, value) do
      {name, true} ->
        {:log, :info,
         "vehicle frame: #{name} (FRAME_CONFIG #{value}), it can strafe: sway offered", %{}}

      {name, false} ->
        {:log, :info,
         "vehicle frame: #{name} (FRAME_CONFIG #{value}), no lateral thrust: sway not offered",
         %{}}

      nil ->
        {:log, :warning,
         "vehicle frame FRAME_CONFIG #{value} is not one Neptunus knows (a custom frame?): " <>
           "sway not offered, only surge, heave and yaw", %{}}
    end
  end

  defp gain_text(gain) when gain >= 0.999,
    do: "ArduSub's joystick gain is 100%: our gain is the only one"

  defp gain_text(gain) do
    percent = round(gain * 100)

    "ArduSub's joystick gain is #{percent}%: Neptunus divides its commands by it (our gain is " <>
      "the only one), so an axis gets at most #{percent}% thrust; set JS_GAIN_DEFAULT 1 on " <>
      "the vehicle (and reboot it) for the full range"
  end

  # GLOBAL_POSITION_INT's latitude and longitude, where the vehicle has them: ArduSub sends
  # 0, 0 while its EKF has no origin (no GPS, no origin set)
  defp global(core, %{lat: 0, lon: 0}),
    do: %{core | readings: Map.delete(core.readings, :global)}

  defp global(core, %{lat: lat, lon: lon, time_boot_ms: at})
       when abs(lat) <= 900_000_000 and abs(lon) <= 1_800_000_000 do
    global = %{lat: lat / 1.0e7 * :math.pi() / 180, lon: lon / 1.0e7 * :math.pi() / 180, at: at}
    with_origin(%{core | readings: Map.put(core.readings, :global, global)})
  end

  defp global(core, _fields), do: %{core | readings: Map.delete(core.readings, :global)}

  # the geodetic origin of the vehicle's own frame: its global position less its local one,
  # both of the same moment (ArduSub sends them together, in its POSITION stream)
  defp with_origin(%{readings: %{position: p, global: g}} = core)
       when abs(p.time_boot_ms - g.at) <= @same_moment_ms do
    origin = Neptunus.Navigation.Geo.origin(%{lat: g.lat, lon: g.lon}, p.x, p.y)
    put_in(core.readings.position.origin, origin)
  end

  defp with_origin(core), do: core

  # the codec decodes every numeric field as a number
  defp put_reading(core, key, value),
    do: %{core | readings: Map.put(core.readings, key, value * 1.0)}

  defp sample(core, time_boot_ms, now) do
    measurement = Map.take(core.readings, [:depth, :heading, :roll, :pitch, :voltage, :current])

    board =
      case core.readings do
        %{position: position} -> %{board_time: time_boot_ms / 1000, position: position}
        _ -> %{board_time: time_boot_ms / 1000}
      end

    %{t: (now - core.started_ms) / 1000, measurement: measurement, sim: nil, board: board}
  end

  defp wrap(yaw) when is_number(yaw) do
    two_pi = 2 * :math.pi()
    r = :math.fmod(yaw, two_pi)
    if r < 0, do: r + two_pi, else: r
  end

  defp wrap(_), do: nil

  # MAV_SEVERITY 0..7: emergency alert critical error warning notice info debug
  defp severity(s) when s <= 3, do: :error
  defp severity(4), do: :warning
  defp severity(_), do: :info

  # a servo output as a thruster value: ArduSub's motors run 1100..1900 µs, 1500 neutral
  # (0 µs: an output not driven)
  defp thruster(0), do: nil
  defp thruster(us), do: ((us - 1500) / 400) |> max(-1.0) |> min(1.0) |> Float.round(3)

  defp frame_name(nil), do: nil

  defp frame_name(value) do
    case Map.get(@frames, value) do
      {name, _sway?} -> name
      nil -> "FRAME_CONFIG #{value}"
    end
  end

  # ── status ───────────────────────────────────────────────────────────────────────────

  @doc "The link's state and the vehicle's as the board reports them (`link_status`)."
  @spec status(t()) :: map()
  def status(core) do
    %{
      up: core.up,
      reason: core.reason,
      rtt_ms: core.rtt_ms,
      mavlink: %{
        armed: core.vehicle.armed,
        mode: core.vehicle.mode,
        system_status: core.vehicle.system_status,
        target: core.target && Tuple.to_list(core.target),
        servo_us: core.servo_us,
        thrusters: Enum.map(core.servo_us, &thruster/1),
        control: core.control,
        disarm_pending: core.disarm_at_ms != nil,
        pilot_gain: core.pilot_gain,
        frame: frame_name(core.frame)
      }
    }
  end
end
