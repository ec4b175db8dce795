defmodule Neptunus.Navigation.Kalman do
  @moduledoc """
  A two-state Kalman filter for one axis: a position-like quantity `x` (depth in m, or
  heading in rad) and its rate `v` (m/s, rad/s), measured in `x` only. Pure.

  ## Process model

  `ẋ = v` and `m · v̇ = F + f₀ − d_l · v − d_q · |v| · v + w`: the axis equation of
  `Neptunus.Navigation.Model` driven by the thrust `F`, plus white acceleration noise of
  spectral density `q` ((unit/s²)²/Hz) for everything the model leaves out. With `mass: 1`
  and no damping or force it is the constant-velocity (white-noise acceleration) model.

  The prediction over `dt` is done in sub-steps of at most `#{0.02}` s (and short enough for
  the damping: `dt · (d_l + 2 d_q |v|) / m ≤ 0.5`) as an extended Kalman filter: the mean
  follows the non-linear equation (midpoint rule for `v`, trapezoid for `x`), the covariance its
  Jacobian `A = [[1, h], [0, 1 − h·(d_l + 2 d_q |v|)/m]]`, `P = A P Aᵀ + Q` with the
  discretised white-noise-acceleration `Q = q · [[h³/3, h²/2], [h²/2, h]]`. The rate is
  kept within `±max_rate` (what the vehicle can physically do), so a bad input can never
  make the state run away.

  ## Measurement update

  `z = x + n`, `n ~ N(0, r)`. The innovation `y = z − x` is wrapped to `[-π, π)` on an
  `angle` axis (so 359° → 1° is a 2° step, not −358°), with variance `S = P₁₁ + r`. `gate/2`
  tells whether `y² ≤ g² · S` or `|y| ≤ min_gate` (a reading within `g` standard deviations,
  or within an absolute tolerance for when the filter is very sure of itself); `update/2`
  applies the standard gain `K = P Hᵀ / S` with the covariance in Joseph form
  `P = (I − KH) P (I − KH)ᵀ + K r Kᵀ`, which stays symmetric positive definite. An angle axis
  keeps `x` in `[0, 2π)`.
  """

  alias Neptunus.Dynamics

  @max_substep 0.02

  @enforce_keys [:q, :r, :max_rate]
  defstruct [
    :q,
    :r,
    :max_rate,
    mass: 1.0,
    d_l: 0.0,
    d_q: 0.0,
    f0: 0.0,
    angle: false,
    gate: 5.0,
    min_gate: 0.0,
    rate_var0: 0.25,
    x: nil,
    v: 0.0,
    p: {0.0, 0.0, 0.0}
  ]

  @typedoc """
  * `q` — process noise spectral density; `r` — measurement noise variance
  * `max_rate` — bound on `|v|`
  * `mass`, `d_l`, `d_q`, `f0` — the axis equation (see the moduledoc)
  * `angle` — `x` is an angle in `[0, 2π)` (wrapped innovation)
  * `gate`, `min_gate` — the innovation gate (standard deviations, absolute)
  * `rate_var0` — variance of `v` when (re)started from a single reading
  * `x`, `v` — the estimate (`x` nil before the first reading); `p` — the covariance
    `{P₁₁, P₁₂, P₂₂}`
  """
  @type t :: %__MODULE__{
          q: float(),
          r: float(),
          max_rate: float(),
          mass: float(),
          d_l: float(),
          d_q: float(),
          f0: float(),
          angle: boolean(),
          gate: float(),
          min_gate: float(),
          rate_var0: float(),
          x: float() | nil,
          v: float(),
          p: {float(), float(), float()}
        }

  @doc """
  A filter with no estimate yet. Options: `:q`, `:r`, `:max_rate` (required), `:mass`,
  `:d_l`, `:d_q`, `:f0` (an axis of `Neptunus.Navigation.Model`; defaults: constant
  velocity), `:angle`, `:gate` (default 5), `:min_gate` (default 0), `:rate_var0` (default 0.25).
  """
  @spec new(keyword() | map()) :: t()
  def new(opts) do
    opts = Map.new(opts, fn {k, v} -> {k, if(is_integer(v), do: v * 1.0, else: v)} end)
    struct!(__MODULE__, opts)
  end

  @doc "Whether the filter has an estimate."
  @spec started?(t()) :: boolean()
  def started?(%__MODULE__{x: x}), do: x != nil

  @doc "Forgets the estimate (keeps the settings)."
  @spec clear(t()) :: t()
  def clear(%__MODULE__{} = k), do: %{k | x: nil, v: 0.0, p: {0.0, 0.0, 0.0}}

  @doc """
  (Re)starts the estimate at reading `z` with rate `v` (default 0, clamped to `±max_rate`):
  variance `r` in `x` and `rate_var0` in `v`.
  """
  @spec start(t(), float(), float()) :: t()
  def start(%__MODULE__{} = k, z, v \\ 0.0) do
    x = if k.angle, do: Dynamics.wrap_2pi(z), else: z * 1.0
    %{k | x: x, v: bound(v * 1.0, k.max_rate), p: {k.r, 0.0, k.rate_var0}}
  end

  @doc """
  Predicts `dt` s ahead (`dt > 0`) under the mean thrust `force` (N or N·m) over that time.
  Does nothing before the first reading.
  """
  @spec predict(t(), float(), float()) :: t()
  def predict(%__MODULE__{x: nil} = k, _dt, _force), do: k

  def predict(%__MODULE__{} = k, dt, force) when dt > 0 do
    stiff = (k.d_l + 2.0 * k.d_q * k.max_rate) / k.mass
    n = max(ceil(dt / @max_substep), ceil(dt * stiff / 0.5)) |> max(1)
    h = dt / n
    k = substeps(k, h, force * 1.0, n)
    if k.angle, do: %{k | x: Dynamics.wrap_2pi(k.x)}, else: k
  end

  defp substeps(k, _h, _force, 0), do: k

  defp substeps(%__MODULE__{x: x, v: v0, p: {p11, p12, p22}, q: q} = k, h, force, n) do
    # the mean by the midpoint rule (second order): one long step ≈ many short ones
    v_mid = v0 + 0.5 * h * acceleration(k, v0, force)
    v = bound(v0 + h * acceleration(k, v_mid, force), k.max_rate)
    x = x + 0.5 * h * (v0 + v)

    # A = [[1, h], [0, f]]
    f = 1.0 - h * (k.d_l + 2.0 * k.d_q * abs(v)) / k.mass
    n11 = p11 + 2.0 * h * p12 + h * h * p22 + q * h * h * h / 3.0
    n12 = f * (p12 + h * p22) + q * h * h / 2.0
    n22 = f * f * p22 + q * h

    substeps(%{k | x: x, v: v, p: {n11, n12, n22}}, h, force, n - 1)
  end

  defp acceleration(k, v, force),
    do: (force + k.f0 - k.d_l * v - k.d_q * abs(v) * v) / k.mass

  @doc "The innovation of reading `z` (wrapped on an angle axis) and its variance `S`."
  @spec innovation(t(), float()) :: {float(), float()}
  def innovation(%__MODULE__{x: x, p: {p11, _, _}, r: r} = k, z) when is_float(x) do
    y = z - x
    y = if k.angle, do: Dynamics.wrap_pi(y), else: y
    {y, p11 + r}
  end

  @doc "Whether reading `z` passes the innovation gate (always true before the first reading)."
  @spec gate?(t(), float()) :: boolean()
  def gate?(%__MODULE__{x: nil}, _z), do: true

  def gate?(%__MODULE__{} = k, z) do
    {y, s} = innovation(k, z)
    y * y <= k.gate * k.gate * s or abs(y) <= k.min_gate
  end

  @doc """
  The measurement update with reading `z` (ungated: check `gate?/2` first). Before the first
  reading it starts the estimate at `z`.
  """
  @spec update(t(), float()) :: t()
  def update(%__MODULE__{x: nil} = k, z), do: start(k, z)

  def update(%__MODULE__{p: {p11, p12, p22}, r: r} = k, z) do
    {y, s} = innovation(k, z)
    k1 = p11 / s
    k2 = p12 / s

    # Joseph form with I − KH = [[1 − k1, 0], [−k2, 1]]
    a = 1.0 - k1
    n11 = a * a * p11 + k1 * k1 * r
    n12 = a * (p12 - k2 * p11) + k1 * k2 * r
    n22 = p22 - 2.0 * k2 * p12 + k2 * k2 * p11 + k2 * k2 * r

    x = k.x + k1 * y
    x = if k.angle, do: Dynamics.wrap_2pi(x), else: x
    %{k | x: x, v: bound(k.v + k2 * y, k.max_rate), p: {n11, n12, n22}}
  end

  @doc "Standard deviations of `x` and `v` (nil before the first reading)."
  @spec std(t()) :: {float(), float()} | nil
  def std(%__MODULE__{x: nil}), do: nil

  def std(%__MODULE__{p: {p11, _, p22}}),
    do: {:math.sqrt(max(p11, 0.0)), :math.sqrt(max(p22, 0.0))}

  defp bound(v, max_rate), do: v |> max(-max_rate) |> min(max_rate)
end
