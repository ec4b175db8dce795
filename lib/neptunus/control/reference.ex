defmodule Neptunus.Control.Reference do
  @moduledoc """
  A setpoint reference model: the value an autopilot actually tracks on its way to the
  setpoint. A step in the pilot's setpoint (typed, from the headset, from a gamepad button)
  would otherwise reach the PID whole, and the vehicle would jerk: full thrust at once, then a
  hard brake. The reference instead moves towards the setpoint with its **rate** limited to
  `rate` (unit/s) and its **acceleration** to `accel` (unit/s²) — a trapezoidal velocity
  profile that starts gently, cruises, and brakes in time to arrive at the setpoint at rest.
  Pure: the state is the value.

  Each `step/3`:

      e  = setpoint − r                               (wrapped to [−π, π) for an angle)
      v* = sign(e) · min(rate, b(|e|), |e|/dt)          the fastest speed that can still stop
      v  ← v + clamp(v* − v, −accel·dt, accel·dt)       acceleration-limited
      r  ← r + v·dt                                   (wrapped to [0, 2π) for an angle)

  where `b(|e|)` solves `v²/(2·accel) + v·dt/2 = |e|` (the distance braking at `accel` in steps
  of `dt` takes), and when the reference is within one step's braking of the setpoint it lands on it at rest.
  So `|v| ≤ rate` and `|Δv/dt| ≤ accel` at every step, whatever the setpoints do. An angle
  reference (`wrap: true`) turns the short way across north.

  The autopilot uses `value` as the PID's setpoint and `rate` as the feed-forward of the
  derivative term (the PID damps the error's rate, not the vehicle's, while the reference
  moves), so the vehicle follows the profile instead of lagging it.

      iex> ref = Neptunus.Control.Reference.new(0.0, rate: 0.5, accel: 0.25)
      iex> ref = Neptunus.Control.Reference.step(ref, 1.0, 0.1)
      iex> {Float.round(ref.value, 6), Float.round(ref.rate, 6)}
      {0.0025, 0.025}
  """

  alias Neptunus.PID

  @enforce_keys [:value, :max_rate, :max_accel]
  defstruct [:value, :max_rate, :max_accel, rate: 0.0, wrap: false]

  @typedoc """
  * `value` — the reference now (m, or rad in `[0, 2π)` when `wrap`); `rate` — its rate (unit/s)
  * `max_rate` (unit/s, > 0), `max_accel` (unit/s², > 0) — the limits
  """
  @type t :: %__MODULE__{
          value: float(),
          rate: float(),
          max_rate: float(),
          max_accel: float(),
          wrap: boolean()
        }

  @doc """
  A reference at rest at `value`. Options: `rate`, `accel` (required, > 0), `wrap` (default
  false: an angle in `[0, 2π)`). Raises `ArgumentError` on bad limits.
  """
  @spec new(number(), keyword()) :: t()
  def new(value, opts) do
    wrap = Keyword.get(opts, :wrap, false)

    %__MODULE__{
      value: normalize(value, wrap),
      max_rate: limit!(opts, :rate),
      max_accel: limit!(opts, :accel),
      wrap: wrap
    }
  end

  @doc """
  Checks reference limits `%{rate, accel}` (or a keyword): `:ok` or `{:error, reason}`.
  """
  @spec validate(keyword()) :: :ok | {:error, String.t()}
  def validate(opts) do
    Enum.reduce_while([:rate, :accel], :ok, fn key, :ok ->
      case Keyword.fetch(opts, key) do
        {:ok, x} when is_number(x) and x > 0 -> {:cont, :ok}
        other -> {:halt, {:error, "reference #{key} must be a number > 0, got #{show(other)}"}}
      end
    end)
  end

  defp show({:ok, x}), do: inspect(x)
  defp show(:error), do: "nothing"

  defp limit!(opts, key) do
    case Keyword.fetch(opts, key) do
      {:ok, x} when is_number(x) and x > 0 -> x * 1.0
      other -> raise ArgumentError, "reference #{key} must be a number > 0, got #{show(other)}"
    end
  end

  @doc "The same limits, at rest at `value` (re-capture: the reference starts where the vehicle is)."
  @spec reset(t(), number()) :: t()
  def reset(%__MODULE__{} = ref, value), do: %{ref | value: normalize(value, ref.wrap), rate: 0.0}

  @doc "New limits (`rate`, `accel`), keeping the value and rate (clamped to the new rate limit)."
  @spec limits(t(), keyword()) :: t()
  def limits(%__MODULE__{} = ref, opts) do
    rate = limit!(opts, :rate)
    %{ref | max_rate: rate, max_accel: limit!(opts, :accel), rate: clamp(ref.rate, rate)}
  end

  @doc "One step of `dt` s (≥ 0) towards `setpoint` (see the moduledoc)."
  @spec step(t(), number(), number()) :: t()
  def step(%__MODULE__{} = ref, _setpoint, dt) when dt == 0, do: ref

  def step(%__MODULE__{} = ref, setpoint, dt) when dt > 0 do
    e = error(ref, setpoint)
    a_dt = ref.max_accel * dt

    if abs(e) <= a_dt * dt and abs(ref.rate) <= a_dt do
      # within one step's braking: arrive at rest
      %{ref | value: normalize(setpoint, ref.wrap), rate: 0.0}
    else
      # the fastest rate that still stops at the setpoint when braking at max_accel in steps of
      # dt (v²/2a + v·dt/2 = |e|), and no faster than the setpoint is away in one step
      half = a_dt / 2
      braking = :math.sqrt(half * half + 2 * ref.max_accel * abs(e)) - half
      wanted = sign(e) * Enum.min([ref.max_rate, braking, abs(e) / dt])

      rate = ref.rate + clamp(wanted - ref.rate, a_dt)
      %{ref | rate: rate, value: normalize(ref.value + rate * dt, ref.wrap)}
    end
  end

  defp error(%__MODULE__{wrap: true, value: r}, setpoint), do: PID.wrap_pi(setpoint - r)
  defp error(%__MODULE__{value: r}, setpoint), do: (setpoint - r) * 1.0

  defp normalize(x, true), do: PID.wrap_2pi(x)
  defp normalize(x, false), do: x * 1.0

  defp clamp(x, limit), do: x |> max(-limit) |> min(limit)
  defp sign(x) when x < 0, do: -1.0
  defp sign(_x), do: 1.0
end
