defmodule Neptunus.Control.VelocityLoop do
  @moduledoc """
  The inner loop of position hold and path following: a PI controller on the velocity over
  the ground in north and east, whose output is the horizontal force to push with (in the
  demand's units, `[-1, 1]` of full thrust; `Neptunus.Control.Demand.from_ned/2` turns it
  into surge and sway). Pure.

      F = k_v (v_d − v) + I,    İ = k_i (v_d − v)

  The integral is the steady force the vehicle needs where it is — a current's drag, a
  tether's pull — so its direction says where the disturbance comes from (the three-thruster
  vehicle heads into it, see `Neptunus.Control.PositionHold`). It is limited to `i_max` and
  does not grow while the output is saturated in its direction (anti-windup). The output is
  limited to length 1 (a vector: the direction is kept).

  The velocity comes from the position filter. With a DVL it is measured (a few mm/s of
  noise) and the loop is stiff (`kv`, `ki`); with a USBL alone it is the filter's
  differentiation of fixes a few decimetres apart, 0.1–0.2 m/s of noise that stiff gains
  would turn into thrust, and the vehicle's own motion back into estimation error: `step/5`
  then uses the soft gains (`soft_kv`, `soft_ki`). The position hold figures in
  bench/README say what each costs.
  """

  @defaults %{kv: 1.2, ki: 0.15, soft_kv: 0.5, soft_ki: 0.06, i_max: 0.5}

  defstruct kv: 1.2,
            ki: 0.15,
            soft_kv: 0.5,
            soft_ki: 0.06,
            i_max: 0.5,
            integral: {0.0, 0.0},
            output: {0.0, 0.0}

  @type vec :: {float(), float()}

  @typedoc """
  `kv` (per m/s), `ki` (per m) with a measured velocity, `soft_kv`, `soft_ki` without;
  `i_max`; the `integral` and last `output` (north, east).
  """
  @type t :: %__MODULE__{
          kv: float(),
          ki: float(),
          soft_kv: float(),
          soft_ki: float(),
          i_max: float(),
          integral: vec(),
          output: vec()
        }

  @doc "The default gains."
  @spec defaults() :: map()
  def defaults, do: @defaults

  @doc """
  A loop at rest. Options: `kv`, `ki`, `soft_kv`, `soft_ki`, `i_max`, `integral` (to start
  from a known force).
  """
  @spec new(keyword() | map()) :: t()
  def new(opts \\ []) do
    opts = Map.new(opts)

    %__MODULE__{
      kv: Map.get(opts, :kv, @defaults.kv) * 1.0,
      ki: Map.get(opts, :ki, @defaults.ki) * 1.0,
      soft_kv: Map.get(opts, :soft_kv, @defaults.soft_kv) * 1.0,
      soft_ki: Map.get(opts, :soft_ki, @defaults.soft_ki) * 1.0,
      i_max: Map.get(opts, :i_max, @defaults.i_max) * 1.0,
      integral: Map.get(opts, :integral, {0.0, 0.0})
    }
  end

  @doc """
  One period `dt` (s) towards the velocity `desired` from the estimated `velocity` (m/s,
  NED), with the stiff gains when the velocity is `measured?` (default), else the soft ones.
  """
  @spec step(t(), vec(), vec(), float(), boolean()) :: t()
  def step(%__MODULE__{} = loop, {dn, de}, {vn, ve}, dt, measured? \\ true) do
    {kv, ki} = if measured?, do: {loop.kv, loop.ki}, else: {loop.soft_kv, loop.soft_ki}
    {en, ee} = {dn - vn, de - ve}
    {in_, ie} = loop.integral
    raw = {kv * en + in_, kv * ee + ie}
    {output, saturated?} = limit(raw, 1.0)

    integral =
      if saturated? and dot(raw, {en, ee}) > 0 do
        loop.integral
      else
        {in_ + ki * en * dt, ie + ki * ee * dt} |> limit(loop.i_max) |> elem(0)
      end

    %{loop | integral: integral, output: output}
  end

  @doc "No output (no velocity to act on): the integral is kept."
  @spec idle(t()) :: t()
  def idle(loop), do: %{loop | output: {0.0, 0.0}}

  @doc "A vector limited to length `max`, and whether it was longer."
  @spec limit(vec(), float()) :: {vec(), boolean()}
  def limit({a, b}, max) do
    norm = :math.sqrt(a * a + b * b)
    if norm > max, do: {{a * max / norm, b * max / norm}, true}, else: {{a, b}, false}
  end

  defp dot({a, b}, {c, d}), do: a * c + b * d
end
