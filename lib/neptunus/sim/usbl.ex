defmodule Neptunus.Sim.USBL do
  @moduledoc """
  A simulated acoustic positioning system (Water Linked Underwater GPS-like: a topside with
  receivers, a locator on the vehicle) measuring the simulated vehicle's true position, with
  what makes a real one hard. Pure: `step/3` returns the fixes that became available by the
  given time, in the shape of `Neptunus.Protocol.UnderwaterGPS`'s decoded fix, so
  `Neptunus.Sim.UGPSServer` serves them over the real HTTP API and the headless runner hands
  them to the same driver core. Randomness is a seeded `:rand` state inside the value.

  ## Geometry

  The topside sits at `topside` `{north, east}` (m, default the origin of the simulation's
  NED frame) at the surface; its `x` axis points `rotation` rad from north (default 0), so a
  fix is the vehicle's position relative to the topside, rotated into the topside's frame.
  `z` is the vehicle's depth as the vehicle itself last told the topside (`depth/3`).

  ## What makes it hard

    * **Rate**: one acoustic fix every `1/rate` s with ±`jitter` (default 2 Hz ± 30 %: 1.5 to
      2.9 Hz);
    * **Delay**: a fix becomes available `delay` ± `delay_jitter` s after the time it
      measured (default 0.5 ± 0.1 s) and carries no time of its own;
    * **Noise**: each axis with standard deviation `noise + noise_per_m · slant range` (default
      0.15 m + 1 % of the range); the fix's `std` reports it;
    * **Outliers**: with probability `outlier` (default 0.03) a fix is off by 2–10 m in a
      random direction (multipath) while its `std` claims the usual accuracy;
    * **Dropouts**: with probability `dropout` (default 0.05) a fix has
      `position_valid: false`;
    * **Depth**: with `needs_depth` (default true, as a Locator-A1 system) there is no valid
      fix unless the vehicle sent its depth in the last `depth_timeout` s (default 5).
  """

  @defaults %{
    rate: 2.0,
    jitter: 0.3,
    delay: 0.5,
    delay_jitter: 0.1,
    noise: 0.15,
    noise_per_m: 0.01,
    outlier: 0.03,
    dropout: 0.05,
    needs_depth: true,
    depth_timeout: 5.0,
    topside: {0.0, 0.0},
    rotation: 0.0
  }

  @enforce_keys [:config, :rand]
  defstruct [:config, :rand, :next_fix, :depth, queue: [], fixes: 0, outliers: 0]

  @type fix :: Neptunus.Protocol.UnderwaterGPS.fix()

  @typedoc """
  * `config`, `rand` — settings and random state
  * `next_fix` — when the next fix is measured
  * `depth` — `{t, depth, temperature}` the vehicle last sent, or nil
  * `queue` — `{available_at, fix}` measured, not yet available
  * `fixes`, `outliers` — counts so far
  """
  @type t :: %__MODULE__{
          config: map(),
          rand: :rand.state(),
          next_fix: float() | nil,
          depth: {float(), float(), float()} | nil,
          queue: [{float(), fix()}],
          fixes: non_neg_integer(),
          outliers: non_neg_integer()
        }

  @doc "The default settings."
  @spec defaults() :: map()
  def defaults, do: @defaults

  @doc "A topside with settings overriding `defaults/0`, seeded with `seed`."
  @spec new(keyword() | map(), integer()) :: t()
  def new(opts \\ [], seed \\ 0) do
    config = Neptunus.Sim.device_settings(@defaults, opts, "USBL")
    %__MODULE__{config: config, rand: :rand.seed_s(:exsss, {seed, 0x05B, 0x1A7})}
  end

  @doc "The vehicle told the topside its depth (m) and the water temperature (°C) at `t`."
  @spec depth(t(), float(), {float(), float()}) :: t()
  def depth(usbl, t, {depth, temp}), do: %{usbl | depth: {t, depth, temp}}

  @doc """
  Advances to `t` (s) with the vehicle's true state (`x`, `y`, `z`): measures what is due
  and returns the fixes that became available by `t`, oldest first.
  """
  @spec step(t(), float(), %{x: float(), y: float(), z: float()}) :: {[fix()], t()}
  def step(%__MODULE__{next_fix: nil} = usbl, t, truth), do: step(%{usbl | next_fix: t}, t, truth)

  def step(%__MODULE__{} = usbl, t, truth) do
    usbl = if t >= usbl.next_fix, do: measure(usbl, t, truth), else: usbl
    {due, later} = Enum.split_while(usbl.queue, fn {at, _} -> at <= t end)
    {Enum.map(due, &elem(&1, 1)), %{usbl | queue: later}}
  end

  defp measure(usbl, t, truth) do
    c = usbl.config
    {tn, te} = c.topside
    {dn, de} = {truth.x - tn, truth.y - te}
    range = :math.sqrt(dn * dn + de * de + truth.z * truth.z)
    sigma = c.noise + c.noise_per_m * range
    {[n1, n2], rand} = normals(usbl.rand, 2)
    {outlier?, rand} = chance(rand, c.outlier)
    {dropout?, rand} = chance(rand, c.dropout)
    {[u1, u2, u3, u4], rand} = uniforms(rand, 4)

    {on, oe} =
      if outlier? do
        angle = 2.0 * :math.pi() * u1
        size = 2.0 + 8.0 * u2
        {size * :math.cos(angle), size * :math.sin(angle)}
      else
        {0.0, 0.0}
      end

    {mn, me} = {dn + sigma * n1 + on, de + sigma * n2 + oe}
    # NED → the topside's frame (x at `rotation` from north)
    {cr, sr} = {:math.cos(c.rotation), :math.sin(c.rotation)}

    depth_known =
      case usbl.depth do
        {at, depth, _temp} when t - at <= c.depth_timeout -> depth
        _ -> nil
      end

    valid = not dropout? and (depth_known != nil or not c.needs_depth)

    fix = %{
      x: cr * mn + sr * me,
      y: -sr * mn + cr * me,
      z: depth_known || 0.0,
      std: sigma,
      valid: valid,
      receivers:
        for _ <- 1..4 do
          %{distance: range, rssi: if(valid, do: -40.0, else: -90.0), nsd: -95.0, valid: valid}
        end
    }

    delay = c.delay + c.delay_jitter * (2.0 * u3 - 1.0)
    period = 1.0 / c.rate * (1.0 + c.jitter * (2.0 * u4 - 1.0))

    %{
      usbl
      | rand: rand,
        next_fix: t + period,
        queue: usbl.queue ++ [{t + delay, fix}],
        fixes: usbl.fixes + 1,
        outliers: usbl.outliers + if(outlier?, do: 1, else: 0)
    }
    |> sort_queue()
  end

  defp sort_queue(usbl), do: %{usbl | queue: Enum.sort_by(usbl.queue, &elem(&1, 0))}

  defp chance(rand, p) when p <= 0, do: {false, rand}

  defp chance(rand, p) do
    {x, rand} = :rand.uniform_s(rand)
    {x < p, rand}
  end

  defp normals(rand, n), do: Enum.map_reduce(1..n, rand, fn _, r -> :rand.normal_s(r) end)
  defp uniforms(rand, n), do: Enum.map_reduce(1..n, rand, fn _, r -> :rand.uniform_s(r) end)
end
