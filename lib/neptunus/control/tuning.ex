defmodule Neptunus.Control.Tuning do
  @moduledoc """
  Autopilot tuning at run time: validation of PID gains sent by a developer, their JSON form
  (as stored per vehicle in `Neptunus.Settings` under `"tuning"`), and the **step response**
  helper — the same step run headless on the vehicle's simulator model with the proposed
  gains, so the curve can be looked at before the gains go to the real vehicle. Pure.

  ## Gains

  A tuning is `%{"depth" => %{"kp", "ki", "kd"}, "heading" => %{…}}`, either axis or gain
  absent to keep the one in force. Ranges (`ranges/0`): `kp` in [0, 20], `ki` in [0, 5],
  `kd` in [0, 20] (output per metre or radian, per unit·s, per unit/s; the output is in
  [-1, 1], so larger values only saturate). Errors name the field:
  `depth.kp must be a number in [0, 20], got 30`.

  ## Step response

  `step_response/4` runs a `Neptunus.Scenario` on the vehicle's parameter set with realistic
  sensors (fixed seed) and navigation's estimator, and the control core with the proposed
  gains (`Neptunus.Scenario.Run`), exactly as the acceptance scenarios do:

    * depth: held at 1 m (1 m below `-step` for a step up), heading held, the setpoint steps
      by `step` m at t = 1 s;
    * heading: held at 0 (depth held at 2 m), the setpoint steps by `step` rad at t = 1 s.

  It returns the curve sampled every 0.1 s — `t` (s), `setpoint`, `reference`, `value` (the
  true depth or heading, heading unwrapped around the start), `output` (the thruster
  command on the axis) — and the figures `overshoot` (in the step's direction, ≥ 0) and
  `settle` (s after the step to stay within `band`: 5 cm or 2°), nil when it does not settle
  within the run.
  """

  alias Neptunus.{PID, Scenario}
  alias Neptunus.Scenario.Run

  @axes ~w(depth heading)
  @ranges %{"kp" => {0, 20}, "ki" => {0, 5}, "kd" => {0, 20}}
  @step_at 1.0
  @duration 21.0
  @every 10
  @max_step %{"depth" => 10.0, "heading" => 3.0}

  @type gains :: %{optional(:depth) => keyword(), optional(:heading) => keyword()}

  @doc "The allowed range of each gain: `%{\"kp\" => {min, max}, …}`."
  @spec ranges() :: %{String.t() => {number(), number()}}
  def ranges, do: @ranges

  @doc """
  Validates a tuning payload (see the moduledoc): `{:ok, gains}` with only the axes and gains
  given (`%{depth: [kp: …]}`), or `{:error, reason}`.
  """
  @spec validate(term()) :: {:ok, gains()} | {:error, String.t()}
  def validate(payload) when is_map(payload) do
    with :ok <- known(payload, @axes, "tuning"),
         :ok <- some(payload, @axes, "tuning needs depth and/or heading") do
      Enum.reduce_while(@axes, {:ok, %{}}, fn axis, {:ok, acc} ->
        case Map.fetch(payload, axis) do
          :error ->
            {:cont, {:ok, acc}}

          {:ok, value} ->
            case axis_gains(value, axis) do
              {:ok, gains} -> {:cont, {:ok, Map.put(acc, String.to_atom(axis), gains)}}
              error -> {:halt, error}
            end
        end
      end)
    end
  end

  def validate(payload), do: {:error, "tuning must be an object, got #{show(payload)}"}

  defp axis_gains(map, axis) when is_map(map) do
    with :ok <- known(map, Map.keys(@ranges), axis),
         :ok <- some(map, Map.keys(@ranges), "#{axis} needs kp, ki and/or kd") do
      @ranges
      |> Enum.sort()
      |> Enum.reduce_while({:ok, []}, fn {key, {lo, hi}}, {:ok, acc} ->
        case Map.fetch(map, key) do
          :error ->
            {:cont, {:ok, acc}}

          {:ok, x} when is_number(x) and x >= lo and x <= hi ->
            {:cont, {:ok, acc ++ [{String.to_atom(key), x * 1.0}]}}

          {:ok, x} ->
            {:halt, {:error, "#{axis}.#{key} must be a number in [#{lo}, #{hi}], got #{show(x)}"}}
        end
      end)
    end
  end

  defp axis_gains(value, axis), do: {:error, "#{axis} must be an object, got #{show(value)}"}

  defp known(map, keys, path) do
    case Enum.find(Map.keys(map) |> Enum.sort(), &(&1 not in keys)) do
      nil -> :ok
      key -> {:error, "unknown field: #{path}.#{show_key(key)}"}
    end
  end

  defp some(map, keys, message),
    do: if(Enum.any?(keys, &Map.has_key?(map, &1)), do: :ok, else: {:error, message})

  defp show_key(key) when is_binary(key), do: key
  defp show_key(key), do: inspect(key)

  defp show(x) when is_binary(x), do: inspect(x)
  defp show(x) when is_number(x) or is_boolean(x) or is_nil(x), do: inspect(x)
  defp show(x) when is_map(x), do: "an object"
  defp show(x) when is_list(x), do: "a list"
  defp show(_x), do: "a value of another type"

  @doc "Merges validated `gains` over `current` (`%{depth: kw, heading: kw, …}`)."
  @spec merge(map(), gains()) :: map()
  def merge(current, gains) do
    Enum.reduce(gains, current, fn {axis, kw}, acc ->
      Map.update(acc, axis, kw, fn current ->
        kept = for {k, v} <- current, do: {k, Keyword.get(kw, k, v)}
        kept ++ Enum.reject(kw, fn {k, _} -> Keyword.has_key?(current, k) end)
      end)
    end)
  end

  @doc "The JSON form of the depth and heading gains of `gains` (stored, replied)."
  @spec to_json(map()) :: %{String.t() => %{String.t() => float()}}
  def to_json(gains) do
    for axis <- [:depth, :heading], Map.has_key?(gains, axis), into: %{} do
      kw = Map.fetch!(gains, axis)
      {Atom.to_string(axis), Map.new([:kp, :ki, :kd], &{Atom.to_string(&1), kw[&1] * 1.0})}
    end
  end

  @doc """
  The gains of `to_json/1` in words, for the log.

      iex> Neptunus.Control.Tuning.describe(%{"depth" => %{"kp" => 3.0, "ki" => 0.1, "kd" => 1.5}})
      "depth kp 3.0 ki 0.1 kd 1.5"
  """
  @spec describe(map()) :: String.t()
  def describe(json) do
    json
    |> Enum.sort()
    |> Enum.map_join("; ", fn {axis, g} -> "#{axis} kp #{g["kp"]} ki #{g["ki"]} kd #{g["kd"]}" end)
  end

  @doc """
  Validates a step-response request `%{"axis" => "depth" | "heading", "step" => x,
  "gains"? => tuning}` (`step` in m, or rad for heading, non-zero, at most 10 m or 3 rad;
  no `gains`: those in force):
  `{:ok, axis, step, gains}`.
  """
  @spec validate_step(term()) :: {:ok, :depth | :heading, float(), gains()} | {:error, String.t()}
  def validate_step(%{"axis" => axis, "step" => step} = payload) when axis in @axes do
    max = Map.fetch!(@max_step, axis)

    with :ok <- known(payload, ~w(axis step gains), "step_response"),
         :ok <- step_size(step, max),
         {:ok, gains} <- step_gains(payload) do
      {:ok, String.to_atom(axis), step * 1.0, gains}
    end
  end

  def validate_step(%{"axis" => axis}) when axis not in @axes,
    do: {:error, ~s(axis must be "depth" or "heading", got #{show(axis)})}

  def validate_step(payload) when is_map(payload),
    do: {:error, "step_response needs axis and step"}

  def validate_step(payload),
    do: {:error, "step_response payload must be an object, got #{show(payload)}"}

  # no gains given: the gains in force
  defp step_gains(%{"gains" => gains}), do: validate(gains)
  defp step_gains(_payload), do: {:ok, %{}}

  defp step_size(step, max) when is_number(step) and step != 0 and abs(step) <= max, do: :ok

  defp step_size(step, max),
    do:
      {:error,
       "step must be a non-zero number in [-#{Float.round(max * 1.0, 4)}, " <>
         "#{Float.round(max * 1.0, 4)}], got #{show(step)}"}

  @doc """
  The step response of `axis` to a setpoint step of `step` (m or rad) on vehicle parameter
  set `vehicle` with control options `control` (`Neptunus.Control.Core.new/1`: `gains`,
  `reference`, …). See the moduledoc for the curve and figures.
  """
  @spec step_response(String.t(), :depth | :heading, float(), keyword()) ::
          {:ok, map()} | {:error, String.t()}
  def step_response(vehicle, axis, step, control) do
    with {:ok, scenario} <- Scenario.validate(scenario(vehicle, axis, step)) do
      {:ok, curve(scenario, axis, step, control)}
    end
  end

  defp scenario(vehicle, :depth, step) do
    # a step up starts from the surface's neighbourhood, a step down deep enough for it
    start = 1.0 + max(-step, 0.0)

    %{
      "vehicle" => vehicle,
      "duration" => @duration,
      "seed" => 7,
      "noise" => true,
      "initial" => %{"z" => start},
      "events" => [
        %{"t" => 0, "autopilot" => %{"depth" => start, "heading" => "hold"}},
        %{"t" => @step_at, "autopilot" => %{"depth" => start + step}}
      ]
    }
  end

  defp scenario(vehicle, :heading, step) do
    %{
      "vehicle" => vehicle,
      "duration" => @duration,
      "seed" => 7,
      "noise" => true,
      "initial" => %{"z" => 2.0},
      "events" => [
        %{"t" => 0, "autopilot" => %{"depth" => 2.0, "heading" => 0}},
        %{"t" => @step_at, "autopilot" => %{"heading" => step * 180 / :math.pi()}}
      ]
    }
  end

  defp curve(scenario, axis, step, control) do
    columns = Enum.map(Run.columns(), &String.to_atom/1)

    rows =
      scenario
      |> Run.rows(@every, control)
      |> Enum.map(&(columns |> Enum.zip(&1) |> Map.new()))

    {value, sp, ref, out, band} =
      case axis do
        :depth ->
          {& &1.z, :depth_setpoint, :depth_reference, & &1.vertical, 0.05}

        :heading ->
          {&PID.wrap_pi(&1.psi), :heading_setpoint, :heading_reference, &yaw/1,
           2 * :math.pi() / 180}
      end

    unwrap = if axis == :heading, do: &PID.wrap_pi/1, else: & &1
    target = Map.fetch!(hd(rows), sp) |> Kernel.||(0.0) |> unwrap.() |> Kernel.+(step)

    curve = %{
      t: Enum.map(rows, &Float.round(&1.t, 3)),
      setpoint: Enum.map(rows, &maybe(Map.fetch!(&1, sp), unwrap)),
      reference: Enum.map(rows, &maybe(Map.fetch!(&1, ref), unwrap)),
      value: Enum.map(rows, value),
      output: Enum.map(rows, out)
    }

    after_step = Enum.filter(rows, &(&1.t >= @step_at))
    errors = Enum.map(after_step, &{&1.t, value.(&1) - target})
    sign = if step > 0, do: 1.0, else: -1.0
    overshoot = errors |> Enum.map(fn {_t, e} -> e * sign end) |> Enum.max() |> max(0.0)
    last_out = for {t, e} <- errors, abs(e) > band, do: t

    settle =
      case last_out do
        [] ->
          0.0

        ts ->
          if List.last(ts) >= List.last(after_step).t,
            do: nil,
            else: Enum.max(ts) + 0.1 - @step_at
      end

    Map.merge(curve, %{
      axis: Atom.to_string(axis),
      step: step,
      target: target,
      band: band,
      overshoot: overshoot,
      settle: settle && Float.round(settle, 2)
    })
  end

  defp maybe(nil, _f), do: nil
  defp maybe(x, f), do: f.(x)

  # the yaw command from the stern thrusters (port − starboard) / 2
  defp yaw(row), do: (row.port - row.starboard) / 2
end
