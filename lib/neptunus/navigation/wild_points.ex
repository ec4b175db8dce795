defmodule Neptunus.Navigation.WildPoints do
  @moduledoc """
  Wild-point tests at the navigation input (thesis §8.3 and its further work): the physical
  range of each measured field and the largest plausible change since the previous accepted
  value. Pure; `Neptunus.Estimator` applies them, with the Kalman filter's innovation gate
  for depth and heading on top.

  ## Limits (SI units)

  | field     | range        | max rate | tolerance | why                                    |
  |-----------|--------------|----------|-----------|----------------------------------------|
  | `depth`   | −10 .. 200 m | 2 m/s    | 0.1 m     | the vertical thruster gives ≤ 0.6 m/s  |
  | `heading` | 0 .. 2π rad  | 3 rad/s  | 0.1 rad   | full differential thrust: ~1.3 rad/s   |
  | `roll`    | −π .. π rad  | 3 rad/s  | 0.1 rad   | roll/pitch periods of 4–5 s, small     |
  | `pitch`   | −π/2 .. π/2  | 3 rad/s  | 0.1 rad   |                                        |
  | `voltage` | 5 .. 20 V    | 2 V/s    | 2 V       | the battery sags ~1.5 V under thrust   |
  | `current` | 0 .. 10 A    | 20 A/s   | 6.5 A     | all thrusters on at once draw ~6 A     |

  The ranges are those of the OpenROV parser (`Neptunus.Vehicle.Board.OpenROV.Protocol.si_range/1`),
  so a simulated board's readings are held to the same limits as a real board's. A reading `v`
  at `t` is *plausible* after the accepted `(t₀, v₀)` when

      |v − v₀| ≤ max_rate · (t − t₀) + tolerance

  (the difference wrapped to `[-π, π)` for `heading` and `roll`). The tolerance covers the
  sensor noise and the largest real step between two readings; for current it is a step of
  all three thrusters, so only its range catches current wild points reliably (a ×10 of an
  idle 0.3 A is a legitimate 3 A).

  Rejection reasons: `:not_a_number` (not a number), `:out_of_range`, `:rate_of_change`,
  and `:innovation` (the Kalman filter's gate, see `Neptunus.Navigation.Kalman`).
  """

  alias Neptunus.Dynamics

  @fields [:depth, :heading, :roll, :pitch, :voltage, :current]
  @reasons [:not_a_number, :out_of_range, :rate_of_change, :innovation]
  @pi :math.pi()

  @typedoc "The limits of one field (see the moduledoc)."
  @type limit :: %{
          min: float(),
          max: float(),
          max_rate: float(),
          tolerance: float(),
          angle: boolean()
        }

  @type reason :: :not_a_number | :out_of_range | :rate_of_change | :innovation

  @typedoc """
  Rejections so far: `total`, `by_field` (each of the six fields), `by_reason` (each
  reason), and `reacquired`: how often a field was re-acquired — several consecutive readings
  that agreed with each other but not with the previous accepted value, taken as the truth
  (see `Neptunus.Estimator`).
  """
  @type counts :: %{
          total: non_neg_integer(),
          by_field: %{atom() => non_neg_integer()},
          by_reason: %{reason() => non_neg_integer()},
          reacquired: non_neg_integer()
        }

  @doc "The measured fields, in order."
  @spec fields() :: [atom()]
  def fields, do: @fields

  @doc "The rejection reasons."
  @spec reasons() :: [reason()]
  def reasons, do: @reasons

  @doc "The default limits of every field."
  @spec limits() :: %{atom() => limit()}
  def limits do
    %{
      depth: limit(:depth, 2.0, 0.1, false),
      heading: %{min: 0.0, max: 2 * @pi, max_rate: 3.0, tolerance: 0.1, angle: true},
      roll: %{min: -@pi, max: @pi, max_rate: 3.0, tolerance: 0.1, angle: true},
      pitch: %{min: -@pi / 2, max: @pi / 2, max_rate: 3.0, tolerance: 0.1, angle: false},
      voltage: limit(:voltage, 2.0, 2.0, false),
      current: limit(:current, 20.0, 6.5, false)
    }
  end

  defp limit(field, max_rate, tolerance, angle) do
    {min, max} = Neptunus.Vehicle.Board.OpenROV.Protocol.si_range(field)
    %{min: min, max: max, max_rate: max_rate, tolerance: tolerance, angle: angle}
  end

  @doc """
  The range test: `{:ok, float}` (a heading of exactly 2π becomes 0) or
  `{:error, :not_a_number | :out_of_range}`.

      iex> limits = Neptunus.Navigation.WildPoints.limits()
      iex> Neptunus.Navigation.WildPoints.range(limits.depth, 12)
      {:ok, 12.0}
      iex> Neptunus.Navigation.WildPoints.range(limits.depth, 1200.0)
      {:error, :out_of_range}
      iex> Neptunus.Navigation.WildPoints.range(limits.heading, "pitc")
      {:error, :not_a_number}
  """
  @spec range(limit(), term()) :: {:ok, float()} | {:error, :not_a_number | :out_of_range}
  def range(%{min: min, max: max} = limit, value) when is_number(value) do
    if value >= min and value <= max,
      do: {:ok, normalise(limit, value * 1.0)},
      else: {:error, :out_of_range}
  end

  def range(_limit, _value), do: {:error, :not_a_number}

  defp normalise(%{angle: true, min: min, max: max}, value) when value == max and min == 0.0,
    do: 0.0

  defp normalise(_limit, value), do: value

  @doc """
  The change from `a` to `b` (wrapped to `[-π, π)` for an angle field).

      iex> limits = Neptunus.Navigation.WildPoints.limits()
      iex> Float.round(Neptunus.Navigation.WildPoints.change(limits.heading, 6.2, 0.1), 4)
      0.1832
  """
  @spec change(limit(), float(), float()) :: float()
  def change(%{angle: true}, a, b), do: Dynamics.wrap_pi(b - a)
  def change(_limit, a, b), do: b - a

  @doc """
  Whether reading `{t, v}` is a plausible successor of the accepted `{t0, v0}`.

      iex> limits = Neptunus.Navigation.WildPoints.limits()
      iex> Neptunus.Navigation.WildPoints.plausible?(limits.depth, {1.0, 2.0}, {1.05, 2.1})
      true
      iex> Neptunus.Navigation.WildPoints.plausible?(limits.depth, {1.0, 2.0}, {1.05, 20.0})
      false
  """
  @spec plausible?(limit(), {float(), float()}, {float(), float()}) :: boolean()
  def plausible?(limit, {t0, v0}, {t, v}) do
    abs(change(limit, v0, v)) <= limit.max_rate * max(t - t0, 0.0) + limit.tolerance
  end

  @doc "No rejections yet."
  @spec new_counts() :: counts()
  def new_counts do
    %{
      total: 0,
      by_field: Map.new(@fields, &{&1, 0}),
      by_reason: Map.new(@reasons, &{&1, 0}),
      reacquired: 0
    }
  end

  @doc "Counts a rejection of `field` for `reason`."
  @spec count(counts(), atom(), reason()) :: counts()
  def count(counts, field, reason) do
    %{
      counts
      | total: counts.total + 1,
        by_field: Map.update(counts.by_field, field, 1, &(&1 + 1)),
        by_reason: Map.update(counts.by_reason, reason, 1, &(&1 + 1))
    }
  end

  @doc "Counts a re-acquisition."
  @spec reacquired(counts()) :: counts()
  def reacquired(counts), do: %{counts | reacquired: counts.reacquired + 1}
end
