defmodule Neptunus.Control.Autopilot do
  @moduledoc """
  One autopilot axis — **depth hold** (output: heave) or **heading hold** (output: yaw) — as a
  pure value around a `Neptunus.PID`. `Neptunus.Control.Core` runs one of each.

  ## States

    * `:off` — disengaged; the pilot has the axis.
    * `:holding` — the PID drives the axis towards `setpoint`.
    * `:overridden` — engaged, but the pilot is moving the axis: the pilot's input drives it,
      the PID follows the measurement without integrating (its trim is kept).

  ## Events

    * `engage(ap, :hold, …)` — hold the **current estimated value** (bumpless: the setpoint is
      where the vehicle is, the derivative starts from the current measurement and the
      integral from zero, so engaging never kicks the vehicle — it never inherits the pilot's
      stick either, which is how ArduSub dived on engage, #32056). On an engaged axis it
      re-captures the current value and keeps the trim.
    * `engage(ap, value, …)` — hold `value` (m, or rad wrapped to `[0, 2π)`); on an engaged
      axis the setpoint changes and the integral (the learnt trim) is kept.
    * `disengage(ap)` — off; the output is gone.
    * `pilot(ap, active?, …)` — the pilot's input on this axis (heave for depth, yaw for
      heading) became non-zero (`active? = true`) or zero again. Non-zero input while holding
      **overrides**; when it returns to zero the axis **re-captures**: it holds the value
      estimated at that moment (the vehicle stays where the pilot left it) — or, if a setpoint
      was commanded during the override, that setpoint. Engaging while the pilot's input is
      non-zero starts overridden.

  ## Reference

  The PID does not chase the setpoint directly: a `Neptunus.Control.Reference` (rate- and
  acceleration-limited, limits per axis, `new/3`) moves from where the vehicle was towards
  the setpoint, and the PID tracks the reference, with the reference's rate as the
  feed-forward of its derivative term (`kd · (ṙ − ẏ)`: it damps the error's rate, not the
  vehicle's). A step of the setpoint therefore never jerks the vehicle, and engaging at a
  setpoint away from the vehicle starts from where it is (no output jump). The reference
  starts at the measured value at rest on every capture (engage from off, hold, the pilot's
  release); a new setpoint on a holding axis takes the reference from where it is now, so a
  setpoint changed mid-move continues smoothly.

  `step/4` runs the reference and the PID once per control period while holding. Headings use a wrapped PID: the
  error is in `[−π, π)`, so the vehicle turns the short way.
  """

  alias Neptunus.Control.Reference
  alias Neptunus.PID

  @default_limits %{depth: [rate: 0.3, accel: 0.2], heading: [rate: 0.4, accel: 0.3]}

  @enforce_keys [:axis, :pid, :reference]
  defstruct [:axis, :pid, :reference, :setpoint, :pending, state: :off, output: 0.0]

  @type axis :: :depth | :heading
  @type state :: :off | :holding | :overridden

  @typedoc """
  * `axis` — `:depth` (m, output heave, positive down) or `:heading` (rad, output yaw,
    positive turns to starboard)
  * `state` — see the moduledoc; `setpoint` — the held value (nil when off)
  * `pending` — a setpoint commanded while overridden, taken on release (nil: re-capture)
  * `output` — the last PID output in `[-1, 1]` (0 unless holding)
  * `reference` — what the PID tracks on its way to the setpoint (see the moduledoc)
  """
  @type t :: %__MODULE__{
          axis: axis(),
          pid: PID.t(),
          reference: Reference.t(),
          state: state(),
          setpoint: float() | nil,
          pending: float() | nil,
          output: float()
        }

  @doc """
  An axis at rest (off) with PID gains `gains` (`kp`, `ki`, `kd`, see `Neptunus.PID.new/1`)
  and reference limits `limits` (`rate`, `accel`: m/s and m/s² for depth, rad/s and rad/s²
  for heading; default `default_limits/0`).
  """
  @spec new(axis(), keyword(), keyword() | nil) :: t()
  def new(axis, gains, limits \\ nil) when axis in [:depth, :heading] do
    wrap = axis == :heading
    limits = limits || Map.fetch!(@default_limits, axis)

    %__MODULE__{
      axis: axis,
      pid: PID.new(Keyword.put(gains, :wrap, wrap)),
      reference: Reference.new(0.0, Keyword.put(limits, :wrap, wrap))
    }
  end

  @doc "The default reference limits per axis (`rate`, `accel`; SI, rad for heading)."
  @spec default_limits() :: %{depth: keyword(), heading: keyword()}
  def default_limits, do: @default_limits

  @doc "Whether the axis is engaged (holding or overridden)."
  @spec engaged?(t()) :: boolean()
  def engaged?(%__MODULE__{state: state}), do: state != :off

  @doc "Whether the PID drives the axis now."
  @spec holding?(t()) :: boolean()
  def holding?(%__MODULE__{state: state}), do: state == :holding

  @doc """
  Engages (or changes the setpoint of) the axis. `value` is `:hold` or a setpoint; `measured`
  the current estimated value, `rate` its rate (or nil), `pilot_active?` whether the pilot is
  moving this axis now.
  """
  @spec engage(t(), :hold | number(), number(), number() | nil, boolean()) :: t()
  def engage(%__MODULE__{state: :overridden} = ap, :hold, measured, _rate, true),
    do: %{ap | setpoint: normalize(ap, measured), pending: nil}

  def engage(%__MODULE__{state: :overridden} = ap, value, _measured, _rate, true),
    do: %{ap | pending: normalize(ap, value)}

  def engage(%__MODULE__{state: :off} = ap, value, measured, rate, pilot_active?) do
    setpoint = if value == :hold, do: measured, else: value
    pid = PID.engage(ap.pid, measured, 0.0)
    reference = Reference.reset(ap.reference, measured)
    ap = %{ap | pid: pid, reference: reference, setpoint: normalize(ap, setpoint), pending: nil}

    if pilot_active?,
      do: %{ap | state: :overridden, output: 0.0},
      else: capture(%{ap | state: :holding}, measured, rate)
  end

  def engage(%__MODULE__{} = ap, value, measured, rate, _pilot_active?) do
    setpoint = if value == :hold, do: measured, else: value

    # a new setpoint while holding goes on from the reference where it is; a hold, or the
    # end of an override, starts it where the vehicle is
    reference =
      if value != :hold and ap.state == :holding,
        do: ap.reference,
        else: Reference.reset(ap.reference, measured)

    ap = %{
      ap
      | state: :holding,
        setpoint: normalize(ap, setpoint),
        pending: nil,
        reference: reference
    }

    capture(%{ap | pid: PID.track(ap.pid, measured)}, measured, rate)
  end

  @doc """
  Moves the setpoint of an engaged axis without anything else (DP steering the heading while
  it returns to its target); no effect when off.
  """
  @spec retarget(t(), number()) :: t()
  def retarget(%__MODULE__{state: :off} = ap, _value), do: ap
  def retarget(%__MODULE__{} = ap, value), do: %{ap | setpoint: normalize(ap, value)}

  @doc """
  New PID gains (`kp`, `ki`, `kd`), bumpless: while holding, the integral is re-set so that
  the output at the current `measured` value and `rate` stays what it is
  (`Neptunus.PID.retune/5`); off, overridden or without an estimate (no output to keep), the
  gains simply apply from the next step, the integral kept.
  """
  @spec retune(t(), keyword(), number() | nil, number() | nil) :: t()
  def retune(%__MODULE__{state: :holding} = ap, gains, measured, rate) when is_number(measured) do
    e = PID.error(ap.pid, ap.reference.value, measured)
    d = relative(rate, ap.reference) || 0.0
    %{ap | pid: PID.retune(ap.pid, gains, e, d, ap.output)}
  end

  def retune(%__MODULE__{} = ap, gains, _measured, _rate) do
    pid = PID.retune(ap.pid, gains, 0.0, 0.0, ap.pid.integral)
    %{ap | pid: pid}
  end

  @doc "The PID gains in force: `[kp:, ki:, kd:]`."
  @spec gains(t()) :: keyword()
  def gains(%__MODULE__{pid: pid}), do: [kp: pid.kp, ki: pid.ki, kd: pid.kd]

  @doc "Disengages the axis (the trim is forgotten)."
  @spec disengage(t()) :: t()
  def disengage(%__MODULE__{} = ap),
    do: %{ap | state: :off, setpoint: nil, pending: nil, output: 0.0, pid: reset_pid(ap.pid)}

  defp reset_pid(pid), do: %{pid | integral: 0.0, last: nil}

  @doc """
  The pilot's input on this axis is now `active?` (non-zero) or not. Overrides a holding axis,
  re-captures an overridden one on release (see the moduledoc); no effect when off.
  """
  @spec pilot(t(), boolean(), number() | nil, number() | nil) :: t()
  def pilot(%__MODULE__{state: :holding} = ap, true, _measured, _rate),
    do: %{ap | state: :overridden, output: 0.0}

  def pilot(%__MODULE__{state: :overridden} = ap, false, measured, rate)
      when is_number(measured) do
    setpoint = ap.pending || measured
    reference = Reference.reset(ap.reference, measured)

    ap = %{
      ap
      | state: :holding,
        setpoint: normalize(ap, setpoint),
        pending: nil,
        reference: reference
    }

    capture(%{ap | pid: PID.track(ap.pid, measured)}, measured, rate)
  end

  def pilot(%__MODULE__{} = ap, _active?, _measured, _rate), do: ap

  @doc """
  One control period of `dt` s with the estimated value `measured` and its rate (or nil):
  the reference moves towards the setpoint and the PID's output tracks it while holding; an
  overridden axis only follows the measurement.
  """
  @spec step(t(), number(), number() | nil, number()) :: t()
  def step(%__MODULE__{state: :holding} = ap, measured, rate, dt) do
    reference = Reference.step(ap.reference, ap.setpoint, dt)
    moving? = reference.rate != 0.0

    {output, pid} =
      PID.update(ap.pid, reference.value, measured, dt, relative(rate, reference), not moving?)

    %{ap | pid: pid, output: output, reference: reference}
  end

  def step(%__MODULE__{state: :overridden} = ap, measured, _rate, _dt),
    do: %{
      ap
      | pid: PID.track(ap.pid, measured),
        reference: Reference.reset(ap.reference, measured)
    }

  def step(%__MODULE__{} = ap, _measured, _rate, _dt), do: ap

  @doc "No estimate to act on (stale or lost): the output is zero, the trim is kept."
  @spec idle(t()) :: t()
  def idle(%__MODULE__{} = ap), do: %{ap | output: 0.0, pid: %{ap.pid | last: nil}}

  @doc "The output driving the axis now, or nil when the pilot has it (off or overridden)."
  @spec output(t()) :: float() | nil
  def output(%__MODULE__{state: :holding, output: output}), do: output
  def output(%__MODULE__{}), do: nil

  @doc """
  As telemetry shows it: nil when off, else `%{setpoint, reference, reference_rate, output,
  overridden}` (output 0 while overridden; `reference` is what the PID tracks now, m or rad,
  and `reference_rate` its rate, m/s or rad/s).
  """
  @spec public(t()) ::
          nil
          | %{
              setpoint: float(),
              reference: float(),
              reference_rate: float(),
              output: float(),
              overridden: boolean()
            }
  def public(%__MODULE__{state: :off}), do: nil

  def public(%__MODULE__{} = ap) do
    %{
      setpoint: ap.pending || ap.setpoint,
      reference: ap.reference.value,
      reference_rate: ap.reference.rate,
      output: if(ap.state == :holding, do: ap.output, else: 0.0),
      overridden: ap.state == :overridden
    }
  end

  @doc "The setpoint shown in the control state: nil when off."
  @spec setpoint(t()) :: float() | nil
  def setpoint(%__MODULE__{state: :off}), do: nil
  def setpoint(%__MODULE__{} = ap), do: ap.pending || ap.setpoint

  # the output at the moment of capture (no integration): bumpless, no derivative kick
  defp capture(ap, measured, rate) do
    reference = ap.reference
    {output, pid} = PID.update(ap.pid, reference.value, measured, 0.0, relative(rate, reference))
    %{ap | pid: pid, output: output}
  end

  # the measured rate relative to the reference's: the derivative term's feed-forward
  defp relative(nil, _reference), do: nil
  defp relative(rate, %Reference{rate: r}), do: rate - r

  defp normalize(%__MODULE__{axis: :heading}, angle), do: PID.wrap_2pi(angle)
  defp normalize(%__MODULE__{axis: :depth}, depth), do: depth * 1.0
end
