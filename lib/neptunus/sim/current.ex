defmodule Neptunus.Sim.Current do
  @moduledoc """
  The water current: a constant vector in NED (m/s) plus an optional slow random variation
  of its horizontal components. Pure; the random state (`:rand`, `exsss`, seeded) lives in
  the value.

  The variation is a first-order Gauss–Markov process per horizontal axis,

      ḃ = −b / T + w,     stationary standard deviation σ,

  discretised exactly over each step of `dt`: `b ← a b + σ √(1 − a²) n`, `a = e^(−dt/T)`,
  `n ~ N(0, 1)`. `T` (s) sets how slowly it wanders (default 60 s); `σ = 0` turns it off.
  """

  @enforce_keys [:mean, :sigma, :time_constant]
  defstruct [:mean, :sigma, :time_constant, :rand, a: 1.0, b: 0.0, offset: {0.0, 0.0}]

  @type vector :: {float(), float(), float()}

  @type t :: %__MODULE__{
          mean: vector(),
          sigma: float(),
          time_constant: float(),
          rand: :rand.state() | nil,
          a: float(),
          b: float(),
          offset: {float(), float()}
        }

  @doc """
  A current of `mean` (NED, m/s) for steps of `dt` s. Options: `:sigma` (m/s, default 0),
  `:time_constant` (s, default 60), `:seed` (integer, default 0).
  """
  @spec new(vector() | [number()], float(), keyword()) :: t()
  def new(mean, dt, opts \\ []) do
    sigma = Keyword.get(opts, :sigma, 0.0) * 1.0
    tc = Keyword.get(opts, :time_constant, 60.0) * 1.0
    a = :math.exp(-dt / tc)

    %__MODULE__{
      mean: vector(mean),
      sigma: sigma,
      time_constant: tc,
      rand: if(sigma > 0.0, do: :rand.seed_s(:exsss, {Keyword.get(opts, :seed, 0), 0xC0, 0x2E})),
      a: a,
      b: sigma * :math.sqrt(1.0 - a * a)
    }
  end

  @doc "Advances the variation by one step."
  @spec step(t()) :: t()
  def step(%__MODULE__{sigma: sigma} = c) when sigma == 0.0, do: c

  def step(%__MODULE__{a: a, b: b, offset: {on, oe}, rand: rand} = c) do
    {n1, rand} = :rand.normal_s(rand)
    {n2, rand} = :rand.normal_s(rand)
    %{c | offset: {a * on + b * n1, a * oe + b * n2}, rand: rand}
  end

  @doc "The current now, NED m/s."
  @spec ned(t()) :: vector()
  def ned(%__MODULE__{mean: {n, e, d}, offset: {on, oe}}), do: {n + on, e + oe, d}

  @doc "The same current with another mean (the variation continues)."
  @spec set_mean(t(), vector() | [number()]) :: t()
  def set_mean(%__MODULE__{} = c, mean), do: %{c | mean: vector(mean)}

  defp vector({n, e, d}), do: {n * 1.0, e * 1.0, d * 1.0}
  defp vector([n, e, d]), do: vector({n, e, d})
end
