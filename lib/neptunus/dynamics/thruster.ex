defmodule Neptunus.Dynamics.Thruster do
  @moduledoc """
  One thruster: where it is, which way it pushes, and how its force follows the command.
  Pure; used by `Neptunus.Dynamics` (static thrust) and `Neptunus.Sim` (thrust dynamics).

  ## Parameters (SI, body frame)

    * `name` — `:port`, `:vertical` or `:starboard` (the keys of a thruster command)
    * `position` — `r`, point of application from the body origin (m)
    * `direction` — unit vector `d` of the force for a positive command
    * `forward` — force at command +1 (N); `reverse` — magnitude at command −1 (N).
      Propellers push less in reverse; `reverse < forward` models that asymmetry.
    * `deadband` — commands with `|c| ≤ deadband` give no thrust (ESC/propeller dead zone);
      beyond it the force grows linearly to full at `|c| = 1`
    * `time_constant` — `T` (s) of the first-order lag `Ḟ = (F_cmd − F)/T` from the static
      force of the command to the actual force (motor and propeller spin-up). The 10–90 %
      rise time is `2.2 T`; `T = 0` is instantaneous.

  Static force of a command `c` (clamped to `[-1, 1]`), with `δ` the deadband:

      F(c) =  forward · (c − δ)/(1 − δ)      c >  δ
              0                              |c| ≤ δ
             −reverse · (−c − δ)/(1 − δ)     c < −δ

  The generalised force of a thruster pushing with `F` is `F · w` with the unit wrench
  `w = [d; r × d]`.

  The thesis' "port motor reversed" is wiring (the sign of its PWM signal), handled by the
  board layer: here a positive command always pushes along `direction`.
  """

  @enforce_keys [
    :name,
    :position,
    :direction,
    :forward,
    :reverse,
    :deadband,
    :time_constant,
    :wrench
  ]
  defstruct @enforce_keys

  @type t :: %__MODULE__{
          name: atom(),
          position: [float()],
          direction: [float()],
          forward: float(),
          reverse: float(),
          deadband: float(),
          time_constant: float(),
          wrench: {float(), float(), float(), float(), float(), float()}
        }

  @doc "A thruster from its parameters (keyword); `direction` must be a unit vector."
  @spec new(keyword()) :: t()
  def new(opts) do
    [rx, ry, rz] = position = Enum.map(Keyword.fetch!(opts, :position), &(&1 * 1.0))
    [dx, dy, dz] = direction = Enum.map(Keyword.fetch!(opts, :direction), &(&1 * 1.0))

    %__MODULE__{
      name: Keyword.fetch!(opts, :name),
      position: position,
      direction: direction,
      forward: Keyword.fetch!(opts, :forward) * 1.0,
      reverse: Keyword.fetch!(opts, :reverse) * 1.0,
      deadband: Keyword.get(opts, :deadband, 0.0) * 1.0,
      time_constant: Keyword.get(opts, :time_constant, 0.0) * 1.0,
      wrench: {dx, dy, dz, ry * dz - rz * dy, rz * dx - rx * dz, rx * dy - ry * dx}
    }
  end

  @doc """
  Static force (N) for a command (clamped to `[-1, 1]`).

      iex> t = Neptunus.Dynamics.Thruster.new(name: :port, position: [0, 0, 0], direction: [1, 0, 0],
      ...>   forward: 6, reverse: 4, deadband: 0.0, time_constant: 0.0)
      iex> {Neptunus.Dynamics.Thruster.force(t, 0.5), Neptunus.Dynamics.Thruster.force(t, -1.0)}
      {3.0, -4.0}
  """
  @spec force(t(), number()) :: float()
  def force(%__MODULE__{forward: fwd, reverse: rev, deadband: db}, command)
      when is_number(command) do
    c = command |> max(-1.0) |> min(1.0)

    cond do
      c > db -> fwd * ((c - db) / (1.0 - db))
      c < -db -> -rev * ((-c - db) / (1.0 - db))
      true -> 0.0
    end
  end

  @doc """
  The lag over one step of `dt` as `{decay, mean}`: with a static target `F_c` held over
  the step and force `F₀` at its start, the force at its end is `F_c + (F₀ − F_c)·decay`
  and its mean over the step `F_c + (F₀ − F_c)·mean` (exact for the first-order lag).
  """
  @spec lag(t(), float()) :: {float(), float()}
  def lag(%__MODULE__{time_constant: tc}, _dt) when tc == 0.0, do: {0.0, 0.0}

  def lag(%__MODULE__{time_constant: tc}, dt) do
    decay = :math.exp(-dt / tc)
    {decay, tc / dt * (1.0 - decay)}
  end
end
