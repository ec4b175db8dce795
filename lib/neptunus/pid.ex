defmodule Neptunus.PID do
  @moduledoc """
  A discrete PID controller for the autopilots (`Neptunus.Control.Autopilot`,
  `Neptunus.Control.DP`). Pure: the state is the value.

      u = clamp(kp·e + I − kd·ẏ, min, max)        e = setpoint − y (wrapped to [−π, π) for angles)
      I ← I + ki·e·dt                             unless that drives a saturated output further

  * **Derivative on measurement.** The D term uses the measured rate `ẏ` — from the estimate
    when the caller has one (`rate`), else the finite difference of successive measurements —
    never the rate of the error, so a setpoint change causes no derivative kick.
  * **Anti-windup.** The integral is kept in output units and clamped to `[min, max]`, and it
    does not integrate while the output is saturated in the direction the error pushes
    (conditional integration), so a long saturation (a big step, a blocked thruster) does not
    wind it up and the output comes off the limit as soon as the error changes sign.
  * **Bumpless engage.** `engage/3` starts from a measurement and an output: the integral is
    set so that the first output at zero error equals it, and the derivative's memory is the
    current measurement (no spike from a stale one). Changing the setpoint of a running PID
    keeps the integral (the learnt trim).
  * **Angles.** With `wrap: true` the error is wrapped to `[−π, π)` and finite differences of
    the measurement are wrapped too, so a heading hold turns the short way across north.

      iex> pid = Neptunus.PID.new(kp: 2.0, ki: 0.0, kd: 0.0)
      iex> {u, _pid} = Neptunus.PID.update(pid, 1.0, 0.75, 0.02)
      iex> u
      0.5

      iex> pid = Neptunus.PID.new(kp: 1.0, ki: 0.0, kd: 0.0, wrap: true)
      iex> {u, _pid} = Neptunus.PID.update(pid, 0.1, 2 * :math.pi() - 0.1, 0.02)
      iex> Float.round(u, 6)
      0.2
  """

  @two_pi 2 * :math.pi()

  @enforce_keys [:kp, :ki, :kd]
  defstruct [:kp, :ki, :kd, :last, min: -1.0, max: 1.0, wrap: false, integral: 0.0]

  @typedoc """
  * `kp` (output per unit of error), `ki` (per unit of error and second), `kd` (per unit of
    measured rate); `min`, `max` — output limits; `wrap` — the measured quantity is an angle
  * `integral` — the I term in output units; `last` — the previous measurement (nil: none yet)
  """
  @type t :: %__MODULE__{
          kp: float(),
          ki: float(),
          kd: float(),
          min: float(),
          max: float(),
          wrap: boolean(),
          integral: float(),
          last: float() | nil
        }

  @doc """
  A PID at rest. Options: `kp`, `ki`, `kd` (required, ≥ 0), `min` (default −1), `max`
  (default 1, > min), `wrap` (default false). Raises `ArgumentError` on bad gains.
  """
  @spec new(keyword()) :: t()
  def new(opts) do
    [kp, ki, kd] = for key <- [:kp, :ki, :kd], do: gain!(opts, key)
    min = Keyword.get(opts, :min, -1.0) * 1.0
    max = Keyword.get(opts, :max, 1.0) * 1.0
    if min >= max, do: raise(ArgumentError, "PID min must be < max, got #{min}, #{max}")

    %__MODULE__{
      kp: kp,
      ki: ki,
      kd: kd,
      min: min,
      max: max,
      wrap: Keyword.get(opts, :wrap, false)
    }
  end

  defp gain!(opts, key) do
    case Keyword.fetch(opts, key) do
      {:ok, x} when is_number(x) and x >= 0 -> x * 1.0
      other -> raise ArgumentError, "PID #{key} must be a number >= 0, got #{inspect(other)}"
    end
  end

  @doc """
  Bumpless start from `measurement`: the integral becomes `output` (clamped to the limits),
  so the first output at zero error and rest is `output`, and the derivative starts from
  this measurement.

      iex> pid = Neptunus.PID.new(kp: 1.0, ki: 0.5, kd: 1.0) |> Neptunus.PID.engage(2.0, 0.3)
      iex> {u, _} = Neptunus.PID.update(pid, 2.0, 2.0, 0.02)
      iex> u
      0.3
  """
  @spec engage(t(), number(), number()) :: t()
  def engage(%__MODULE__{} = pid, measurement, output \\ 0.0),
    do: %{pid | integral: clamp(output * 1.0, pid), last: measurement * 1.0}

  @doc """
  New gains (`kp`, `ki`, `kd`, each ≥ 0; absent ones kept), **bumpless**: the integral is
  set so that the output at error `e` and measured rate `d` (those of the last step) is
  `output` as before, `kp'·e − kd'·d + I' = output` (clamped to the limits). Raises
  `ArgumentError` on a bad gain.

      iex> pid = Neptunus.PID.new(kp: 1.0, ki: 0.1, kd: 0.0)
      iex> pid = Neptunus.PID.retune(pid, [kp: 3.0], 0.1, 0.0, 0.25)
      iex> {u, _} = Neptunus.PID.update(pid, 0.1, 0.0, 0.0)
      iex> Float.round(u, 12)
      0.25
  """
  @spec retune(t(), keyword(), number(), number(), number()) :: t()
  def retune(%__MODULE__{} = pid, gains, e, d, output) do
    opts =
      Keyword.merge([kp: pid.kp, ki: pid.ki, kd: pid.kd], Keyword.take(gains, [:kp, :ki, :kd]))

    [kp, ki, kd] = for key <- [:kp, :ki, :kd], do: gain!(opts, key)
    pid = %{pid | kp: kp, ki: ki, kd: kd}
    %{pid | integral: clamp(output - (kp * e - kd * d), pid)}
  end

  @doc """
  Keeps the integral but follows the measurement without acting (while a pilot overrides the
  axis): the next `update/5` differentiates from here.
  """
  @spec track(t(), number()) :: t()
  def track(%__MODULE__{} = pid, measurement), do: %{pid | last: measurement * 1.0}

  @doc "The error `setpoint − measurement` (wrapped to `[−π, π)` for an angle PID)."
  @spec error(t(), number(), number()) :: float()
  def error(%__MODULE__{wrap: false}, setpoint, measurement), do: (setpoint - measurement) * 1.0
  def error(%__MODULE__{wrap: true}, setpoint, measurement), do: wrap_pi(setpoint - measurement)

  @doc """
  One step of `dt` seconds: returns the output in `[min, max]` and the PID advanced.
  `rate` is the measured rate of the measurement (unit/s) if known; otherwise the finite
  difference from the previous measurement is used (none on the first step, or with
  `dt == 0`, which computes the output without integrating). With `integrate` false the
  integral is kept as it is (an autopilot's reference on the move: the integral learns the
  steady trim, not the lag of tracking a moving reference).
  """
  @spec update(t(), number(), number(), number(), number() | nil, boolean()) :: {float(), t()}
  def update(%__MODULE__{} = pid, setpoint, measurement, dt, rate \\ nil, integrate \\ true)
      when dt >= 0 do
    e = error(pid, setpoint, measurement)
    d = derivative(pid, measurement, dt, rate)
    p_d = pid.kp * e - pid.kd * d
    candidate = if integrate, do: pid.integral + pid.ki * e * dt, else: pid.integral
    unsat = p_d + candidate

    integral =
      cond do
        unsat > pid.max and e > 0 -> pid.integral
        unsat < pid.min and e < 0 -> pid.integral
        true -> clamp(candidate, pid)
      end

    {clamp(p_d + integral, pid), %{pid | integral: integral, last: measurement * 1.0}}
  end

  defp derivative(_pid, _measurement, _dt, rate) when is_number(rate), do: rate * 1.0
  defp derivative(%__MODULE__{last: nil}, _measurement, _dt, nil), do: 0.0
  defp derivative(_pid, _measurement, dt, nil) when dt == 0, do: 0.0

  defp derivative(%__MODULE__{wrap: true, last: last}, measurement, dt, nil),
    do: wrap_pi(measurement - last) / dt

  defp derivative(%__MODULE__{last: last}, measurement, dt, nil), do: (measurement - last) / dt

  defp clamp(x, %__MODULE__{min: min, max: max}), do: x |> max(min) |> min(max) |> Kernel.+(0.0)

  @doc """
  An angle wrapped to `[−π, π)`.

      iex> Neptunus.PID.wrap_pi(3 * :math.pi() / 2)
      -1.5707963267948966
  """
  @spec wrap_pi(number()) :: float()
  def wrap_pi(angle) do
    a = :math.fmod(angle + :math.pi(), @two_pi)
    if a < 0, do: a + @two_pi - :math.pi(), else: a - :math.pi()
  end

  @doc """
  An angle wrapped to `[0, 2π)` (headings).

      iex> Neptunus.PID.wrap_2pi(-:math.pi() / 2)
      4.71238898038469
  """
  @spec wrap_2pi(number()) :: float()
  def wrap_2pi(angle) do
    a = :math.fmod(angle * 1.0, @two_pi)
    a = if a < 0, do: a + @two_pi, else: a
    if a >= @two_pi, do: 0.0, else: a + 0.0
  end
end
