defmodule Neptunus.Allocation do
  @moduledoc """
  Motion-mode thrust allocation for the three-thruster vehicle (thesis ch. 9.3).

  A motion command `τ_motion = [X Z M]` (surge, heave, yaw, each in `[-1, 1]`) and
  a scalar gain `k` in `[0, 1]` are mapped to the normalised thruster commands
  `u = [u_port u_vertical u_starboard]` by the thesis' eq. 9.3:

      u = [sat(k(X + M)), sat(k Z), sat(k(X − M))]

  where `sat` clamps to `[-1, 1]`. The thesis does not saturate the vertical
  thruster; we do, so that no output ever leaves `[-1, 1]`.

  ## Sign convention

  Thruster values are in the *physical* sense: a positive port or starboard value
  pushes the vehicle forward (+surge), a positive vertical value pushes it down
  (+z in NED, i.e. deeper). A positive yaw command `M` drives port harder than
  starboard and so turns the bow to starboard (positive yaw rate `r`, NED).

  The port propeller is mounted reversed on the real vehicle; inverting its PWM
  signal is wiring configuration handled by the board layer, **not** here.

  ## PWM

  `to_us/1` maps `[-1, 1]` linearly onto the OpenROV motor range `1000..2000` µs
  with `1500` µs as neutral (thesis ch. 8.4).
  """

  @typedoc "Motion command: surge `X`, heave `Z` and yaw `M`, each in `[-1, 1]`."
  @type motion :: %{surge: float, heave: float, yaw: float}

  @typedoc """
  Normalised thruster commands in `[-1, 1]`, physical sense: positive pushes the
  vehicle forward (port, starboard) or down (vertical).
  """
  @type thrusters :: %{port: float, vertical: float, starboard: float}

  @typedoc "Thruster commands as PWM pulse widths in microseconds."
  @type thrusters_us :: %{port: 1000..2000, vertical: 1000..2000, starboard: 1000..2000}

  @neutral_us 1500
  @half_range_us 500

  @doc """
  Allocates a motion command to the three thrusters with gain `k` (eq. 9.3).

  Always returns floats in `[-1, 1]`, even for out-of-range input.

  ## Examples

      iex> Neptunus.Allocation.motion(%{surge: 0.5, heave: -0.2, yaw: 0.25}, 1.0)
      %{port: 0.75, vertical: -0.2, starboard: 0.25}

      iex> Neptunus.Allocation.motion(%{surge: 1.0, heave: 0.0, yaw: 1.0}, 1.0)
      %{port: 1.0, vertical: 0.0, starboard: 0.0}

      iex> Neptunus.Allocation.motion(%{surge: 1, heave: 1, yaw: 0}, 0.5)
      %{port: 0.5, vertical: 0.5, starboard: 0.5}
  """
  @spec motion(motion(), number()) :: thrusters()
  def motion(%{surge: x, heave: z, yaw: m}, gain)
      when is_number(x) and is_number(z) and is_number(m) and is_number(gain) do
    %{
      port: sat(gain * (x + m)),
      vertical: sat(gain * z),
      starboard: sat(gain * (x - m))
    }
  end

  @doc """
  All thrusters stopped.

      iex> Neptunus.Allocation.neutral()
      %{port: 0.0, vertical: 0.0, starboard: 0.0}
  """
  @spec neutral() :: thrusters()
  def neutral, do: %{port: 0.0, vertical: 0.0, starboard: 0.0}

  @doc """
  Maps a normalised thruster value in `[-1, 1]` to a PWM pulse width in µs.

  Linear, `-1 → 1000`, `0 → 1500`, `1 → 2000`; rounded to the nearest integer
  (halves away from zero, `Kernel.round/1`); values outside `[-1, 1]` are clamped.

  ## Examples

      iex> Neptunus.Allocation.to_us(0.0)
      1500

      iex> Neptunus.Allocation.to_us(-1.0)
      1000

      iex> Neptunus.Allocation.to_us(0.5)
      1750

      iex> Neptunus.Allocation.to_us(3.0)
      2000
  """
  @spec to_us(number()) :: 1000..2000
  def to_us(value) when is_number(value) do
    round(@neutral_us + @half_range_us * sat(value))
  end

  @doc """
  Maps all three thruster values to PWM pulse widths with `to_us/1`.

      iex> Neptunus.Allocation.thrusters_to_us(%{port: 1.0, vertical: 0.0, starboard: -0.5})
      %{port: 2000, vertical: 1500, starboard: 1250}
  """
  @spec thrusters_to_us(thrusters()) :: thrusters_us()
  def thrusters_to_us(%{port: p, vertical: v, starboard: s}) do
    %{port: to_us(p), vertical: to_us(v), starboard: to_us(s)}
  end

  @doc """
  The thruster values with their pulse widths beside them, as published on the wire.

      iex> Neptunus.Allocation.with_us(%{port: 1.0, vertical: 0.0, starboard: -0.5})
      %{port: 1.0, vertical: 0.0, starboard: -0.5, port_us: 2000, vertical_us: 1500, starboard_us: 1250}
  """
  @spec with_us(thrusters()) :: %{
          port: float(),
          vertical: float(),
          starboard: float(),
          port_us: 1000..2000,
          vertical_us: 1000..2000,
          starboard_us: 1000..2000
        }
  def with_us(%{port: p, vertical: v, starboard: s} = thrusters) do
    Map.merge(thrusters, %{port_us: to_us(p), vertical_us: to_us(v), starboard_us: to_us(s)})
  end

  # Clamp to [-1, 1] and return a float; `+ 0.0` turns -0.0 into 0.0.
  defp sat(value), do: value |> max(-1.0) |> min(1.0) |> Kernel.*(1.0) |> Kernel.+(0.0)
end
