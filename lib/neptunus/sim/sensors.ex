defmodule Neptunus.Sim.Sensors do
  @moduledoc """
  The simulated vehicle's sensors: depth (pressure), heading/roll/pitch (IMU), battery
  voltage and current. Pure; the random state (`:rand`, algorithm `exsss`, seeded) lives in
  the value, so a run is reproducible from its seed.

  Every `1/rate` s of simulated time (`measure/3`) each channel reads

      measured = true value + bias + N(0, noise²)

  (heading wrapped to `[0, 2π)`), and then, with probability `wild_rate`, becomes a *wild
  point* — the value multiplied by 0.1, 10 or 100 (equally likely) — or, with probability
  `mixup_rate`, a *field mix-up* — it carries another channel's measured value instead of
  its own. These are the faults the thesis saw on the real vehicle's serial link (§8.3).
  A channel is at most one of the two per sample. Wild points and mix-ups injected so far
  are counted in `counts` (for checking a filter against ground truth).

  Configuration (the `sensors` section of a vehicle file, `Neptunus.Dynamics.Params`):
  `rate` (Hz), `wild_rate`, `mixup_rate` (probability per channel per sample) and for each
  channel `noise` (standard deviation) and `bias` in the channel's SI unit (m, rad, V, A).
  """

  @channels [:depth, :heading, :roll, :pitch, :voltage, :current]
  @factors {0.1, 10.0, 100.0}

  @enforce_keys [:config, :rand]
  defstruct [:config, :rand, counts: %{wild: 0, mixup: 0}]

  @typedoc "A set of the six measured values (SI units, heading in [0, 2π))."
  @type measurement :: Neptunus.Vehicle.Board.measurement()

  @type t :: %__MODULE__{
          config: Neptunus.Dynamics.Params.sensors(),
          rand: :rand.state(),
          counts: %{wild: non_neg_integer(), mixup: non_neg_integer()}
        }

  @doc "The measured channels, in order."
  @spec channels() :: [atom()]
  def channels, do: @channels

  @doc "Sensors with `config`, seeded with the integer `seed`."
  @spec new(Neptunus.Dynamics.Params.sensors(), integer()) :: t()
  def new(config, seed) when is_integer(seed) do
    %__MODULE__{config: config, rand: :rand.seed_s(:exsss, {seed, 0x5E45, 0x0125})}
  end

  @doc "Reads the sensors: the true values with noise, bias and injected faults."
  @spec measure(t(), measurement()) :: {measurement(), t()}
  def measure(%__MODULE__{config: config, rand: rand, counts: counts} = sensors, truth) do
    {noisy, rand} =
      Enum.reduce(@channels, {%{}, rand}, fn ch, {acc, rand} ->
        %{noise: sigma, bias: bias} = Map.fetch!(config.channels, ch)

        {value, rand} =
          if sigma > 0.0 do
            {n, rand} = :rand.normal_s(rand)
            {Map.fetch!(truth, ch) + bias + sigma * n, rand}
          else
            {Map.fetch!(truth, ch) + bias, rand}
          end

        value = if ch == :heading, do: Neptunus.Dynamics.wrap_2pi(value), else: value
        {Map.put(acc, ch, value), rand}
      end)

    {measured, rand, counts} = faults(noisy, config, rand, counts)
    {measured, %{sensors | rand: rand, counts: counts}}
  end

  defp faults(noisy, %{wild_rate: wild, mixup_rate: mixup}, rand, counts)
       when wild == 0.0 and mixup == 0.0,
       do: {noisy, rand, counts}

  defp faults(noisy, %{wild_rate: wild, mixup_rate: mixup}, rand, counts) do
    Enum.reduce(@channels, {noisy, rand, counts}, fn ch, {acc, rand, counts} ->
      {x, rand} = :rand.uniform_s(rand)

      cond do
        x < wild ->
          {i, rand} = :rand.uniform_s(3, rand)
          value = Map.fetch!(noisy, ch) * elem(@factors, i - 1)
          {Map.put(acc, ch, value), rand, %{counts | wild: counts.wild + 1}}

        x < wild + mixup ->
          others = List.delete(@channels, ch)
          {i, rand} = :rand.uniform_s(length(others), rand)
          value = Map.fetch!(noisy, Enum.at(others, i - 1))
          {Map.put(acc, ch, value), rand, %{counts | mixup: counts.mixup + 1}}

        true ->
          {acc, rand, counts}
      end
    end)
  end
end
