defmodule Neptunus.Estimator do
  @moduledoc """
  The navigation filter of a vehicle: wild-point rejection at the navigation input and a
  Kalman filter for depth + vertical speed and heading + yaw rate. Pure: a value stepped with
  each board sample (`update/3`) and told each thruster command (`command/2`); run by
  `Neptunus.Vehicle.Navigation` on a live vehicle and by the headless scenario runner on the
  same simulated measurements.

  ## Wild points

  Every measured field (`depth heading roll pitch voltage current`) of every sample goes
  through, in order:

    1. **held values** — a value identical to the field's previous one is the board repeating
       its last reading (the simulated board reports its 20 Hz sensors at 100 Hz, a serial
       board repeats the fields of the line it did not resend), not a new reading: it keeps
       the previous verdict and is neither counted nor filtered again (a held accepted depth or
       heading updates the filter again after `hold` s, so it stays converged on ideal sensors
       at rest);
    2. **range** — outside the field's physical range → `:out_of_range`; not a number →
       `:not_a_number` (`Neptunus.Navigation.WildPoints`);
    3. **rate of change** — farther from the previous *accepted* value than the field's largest
       plausible rate allows → `:rate_of_change`;
    4. **innovation** (depth, heading, roll, pitch) — outside the field's Kalman filter's
       gate: more than 5 σ of the innovation *and* more than `min_gate` from the prediction
       → `:innovation`. This catches what the rate test cannot: a ×0.1 of a 30 cm depth, a
       pitch value in the roll field.

  A reading that passes is *accepted*: it becomes the reference of the next rate check and
  updates the filter. Rejections are counted by field and reason (`wild_points/1`). Voltage
  and current have range and rate tests only (see `Neptunus.Navigation.WildPoints` for the
  limits and what they cannot catch).

  **Re-acquisition.** Wild points are isolated; the truth persists. When the last `confirm`
  (3) rejected new readings of a field (by rate or innovation) agree with each other — each
  plausible after the one before — the field is re-acquired at the newest: it is accepted and
  its filter restarts there (with the rate they show). This recovers from a first reading that
  was itself a wild point, from a filter led astray by something its model does not know (a
  collision, a hand on the vehicle), and from a jump of the simulated vehicle; `reacquired`
  counts it.

  ## Kalman filters

  Two-state filters (`Neptunus.Navigation.Kalman`, the model and its discretisation are
  documented there): depth `z` (m, down) with `ż` (m/s), and heading `ψ` (rad, [0, 2π)) with
  `ψ̇` (rad/s), the heading innovation wrapped to `[-π, π)` — these are the estimate. Roll and
  pitch have constant-velocity filters too, used only to gate their readings.

  With a vehicle model (`Neptunus.Navigation.Model`; by default the `neptunus` parameter set)
  the depth and heading predictions are driven by the **commanded thrust** (`command/2`): the
  vertical thruster's force in heave, the differential moment of the port and starboard
  thrusters in yaw, each through the thrusters' deadband, asymmetry and lag, against the
  axis' effective mass, linear and quadratic damping and (heave) net buoyancy. A thrust step
  then shows in the estimated rate at once, instead of only after the noisy readings have
  moved, and the filter can trust its model more (lower `q`) and the sensors less. On the
  shipped scenarios this cuts the depth and heading errors by a quarter and the rate errors by
  a factor of two to three compared with the constant-velocity model (`vehicle: nil`).

  Noise settings (defaults; options `:depth`, `:heading`, `:roll`, `:pitch` override `q`,
  `r`, `gate`, `min_gate`, `max_rate`):

  | filter  | `r` (variance)                | `q` with model     | `q` without  | `min_gate` |
  |---------|-------------------------------|--------------------|--------------|------------|
  | depth   | σ² of the depth sensor (1 cm) | 0.05 (m/s²)²/Hz    | 0.3          | 3 cm       |
  | heading | σ² of the compass (0.5°)      | 0.05 (rad/s²)²/Hz  | 0.3          | 2°         |
  | roll    | σ² of the IMU (0.2°)          | —                  | 0.5          | 2°         |
  | pitch   | σ² of the IMU (0.2°)          | —                  | 0.5          | 2°         |

  `r` is the sensor noise the vehicle file states (at least 1 mm / 0.1°, so quantised board
  values are not over-trusted). `q` is the spectral density of the white acceleration the
  model leaves out — the tether, the water current, roll/pitch coupling, the model's own
  errors. It was tuned on the shipped scenarios and on runs with unknown external pushes and
  a model 30–40 % off in thrust and damping: 0.02 gives 10–20 % smaller errors when the
  model is exact but starts rejecting good readings (innovation) when it is not; 0.05 rejects
  none there and costs little. Without a model `q` must also cover the thrust itself (a
  thrust step is up to 2 m/s² in heave for a fraction of a second); larger values track that
  no better on the scenarios but let one accepted near-wild point swing the rate so far that
  the next good readings fail the gate. `test/neptunus/estimator_quality_test.exs` asserts the
  accuracy.

  ## Time

  `t` is the sample's time (s, the vehicle clock). Between samples the filters predict over
  `dt`; `dt = 0` (several samples at one instant) only updates. A gap of more than
  `max_gap` (2 s: a link down) or a filter without an accepted reading for `stale_after`
  (2 s) drops that estimate (nil) until the next accepted reading restarts it. Time going
  backwards (a simulator reset, a restarted board clock) starts afresh, keeping the counts.
  """

  alias Neptunus.Dynamics.Params
  alias Neptunus.Navigation.{Kalman, Model, WildPoints}

  @fields WildPoints.fields()
  @filtered [:depth, :heading, :roll, :pitch]
  # sample times beyond this (s, ~30 000 years) are not times: ignored
  @max_time 1.0e12

  # roll and pitch are filtered only to gate their readings, alike
  @attitude_gate %{
    q_free: 0.5,
    min_r: 0.1 * :math.pi() / 180,
    r: 0.2 * :math.pi() / 180,
    max_rate: 3.0,
    min_gate: 2.0 * :math.pi() / 180
  }

  @defaults %{
    depth: %{q_model: 0.05, q_free: 0.3, min_r: 0.001, r: 0.01, max_rate: 2.0, min_gate: 0.03},
    heading: %{
      q_model: 0.05,
      q_free: 0.3,
      min_r: 0.1 * :math.pi() / 180,
      r: 0.5 * :math.pi() / 180,
      max_rate: 3.0,
      min_gate: 2.0 * :math.pi() / 180
    },
    roll: @attitude_gate,
    pitch: @attitude_gate
  }

  defmodule Gate do
    @moduledoc false
    # One field's wild-point state: the last accepted reading `{t, v}`, the last raw value
    # seen and its verdict, and the recent consecutive rejected readings (newest first).
    @type t :: %__MODULE__{
            ref: {float(), float()} | nil,
            last_raw: term(),
            accepted?: boolean(),
            misses: [{float(), float()}]
          }
    defstruct ref: nil, last_raw: :none, accepted?: false, misses: []
  end

  @enforce_keys [:filters, :limits]
  defstruct [
    :filters,
    :limits,
    :model,
    :t,
    gates: %{},
    updated: %{},
    counts: WildPoints.new_counts(),
    verdicts: %{},
    hold: 0.2,
    max_gap: 2.0,
    stale_after: 2.0,
    confirm: 3
  ]

  @typedoc "A field's verdict on the last sample."
  @type verdict :: :accepted | :reacquired | :held | :missing | {:rejected, WildPoints.reason()}

  @typedoc """
  * `filters` — the Kalman filters of `depth`, `heading`, `roll` and `pitch`
  * `limits` — wild-point limits per field (`Neptunus.Navigation.WildPoints.limits/0`)
  * `model` — the vehicle model driving the prediction, or nil (constant velocity)
  * `t` — time of the last sample (nil before the first)
  * `gates` — each field's wild-point state; `counts` — rejections so far
  * `updated` — when each filter last took a reading
  * `verdicts` — each field's verdict on the last sample
  * `hold`, `max_gap`, `stale_after` (s), `confirm` — see the moduledoc
  """
  @type t :: %__MODULE__{
          filters: %{atom() => Kalman.t()},
          limits: %{atom() => WildPoints.limit()},
          model: Model.t() | nil,
          t: float() | nil,
          gates: %{atom() => Gate.t()},
          updated: %{atom() => float() | nil},
          counts: WildPoints.counts(),
          verdicts: %{atom() => verdict()},
          hold: float(),
          max_gap: float(),
          stale_after: float(),
          confirm: pos_integer()
        }

  @typedoc "The estimate: nil where there is none (no plausible reading yet, or stale)."
  @type estimate :: %{
          t: float() | nil,
          depth: float() | nil,
          depth_rate: float() | nil,
          heading: float() | nil,
          yaw_rate: float() | nil
        }

  @doc """
  A new estimator. Options:

    * `:vehicle` — the parameter set (name or `Neptunus.Dynamics.Params`) whose model drives
      the prediction and whose sensor noise sets `r`; default `"neptunus"`; `nil` for a
      model-free (constant-velocity) filter with the default noise
    * `:depth`, `:heading`, `:roll`, `:pitch` — overrides of the filters' `q`, `r`, `gate`,
      `min_gate`, `max_rate`
    * `:limits` — overrides of the wild-point limits, per field (merged)
    * `:hold`, `:max_gap`, `:stale_after` (s), `:confirm` (readings)
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    params = params(Keyword.get(opts, :vehicle, "neptunus"))
    model = if params, do: Model.from_params(params)

    limits =
      Enum.reduce(Keyword.get(opts, :limits, %{}), WildPoints.limits(), fn {field, l}, acc ->
        Map.update!(acc, field, &Map.merge(&1, Map.new(l, fn {k, v} -> {k, float(v)} end)))
      end)

    est = %__MODULE__{
      filters:
        Map.new(@filtered, &{&1, axis(&1, params, model, limits, Keyword.get(opts, &1, []))}),
      updated: Map.new(@filtered, &{&1, nil}),
      limits: limits,
      model: model,
      gates: new_gates()
    }

    Enum.reduce([:hold, :max_gap, :stale_after, :confirm], est, fn key, est ->
      case Keyword.fetch(opts, key) do
        {:ok, value} -> Map.put(est, key, value)
        :error -> est
      end
    end)
  end

  defp new_gates, do: Map.new(@fields, &{&1, %Gate{}})

  defp params(nil), do: nil
  defp params(%Params{} = params), do: params
  defp params(name), do: Params.fetch!(to_string(name))

  defp axis(name, params, model, limits, overrides) do
    d = Map.fetch!(@defaults, name)
    sigma = if params, do: params.sensors.channels[name].noise, else: d.r
    base = %{max_rate: d.max_rate, min_gate: d.min_gate, gate: 5.0, angle: name == :heading}

    # roll and pitch: constant-velocity filters, used to gate their readings only
    dyn =
      case {name, model} do
        {:depth, %Model{heave: heave}} -> Map.put(heave, :q, d.q_model)
        {:heading, %Model{yaw: yaw}} -> Map.put(yaw, :q, d.q_model)
        _ -> %{q: d.q_free}
      end

    r = :math.pow(max(sigma, d.min_r), 2)

    base
    |> Map.merge(dyn)
    |> Map.put(:r, r)
    |> Map.merge(Map.new(overrides, fn {k, v} -> {k, float(v)} end))
    |> Map.update!(:max_rate, &min(&1, limits[name].max_rate))
    |> Kalman.new()
  end

  defp float(v) when is_integer(v), do: v * 1.0
  defp float(v), do: v

  @doc """
  Sets the thruster command in force (`%{port, vertical, starboard}` in [-1, 1], as sent to
  the board; out-of-range values are clamped, anything else is neutral).
  """
  @spec command(t(), term()) :: t()
  def command(%__MODULE__{model: nil} = est, _thrusters), do: est

  def command(%__MODULE__{model: model} = est, thrusters),
    do: %{est | model: Model.command(model, thrusters)}

  @doc """
  Takes a board sample's measurement at time `t` (s): wild-point tests, then the filters'
  prediction to `t` and update. Never raises: a `t` that is not a number (or beyond ±10¹² s)
  leaves the estimator unchanged; a measurement that is not a map counts as all fields
  missing.
  """
  @spec update(t(), term(), term()) :: t()
  def update(%__MODULE__{} = est, t, measurement) when is_number(t) and abs(t) < @max_time do
    t = t * 1.0
    measurement = if is_map(measurement), do: measurement, else: %{}

    est
    |> advance(t)
    |> drop_stale(t)
    |> then(fn est ->
      Enum.reduce(@fields, %{est | verdicts: %{}}, &field(&2, &1, t, Map.get(measurement, &1)))
    end)
  end

  def update(%__MODULE__{} = est, _t, _measurement), do: %{est | verdicts: %{}}

  # time: predict, restart after a gap or a clock going back
  defp advance(%__MODULE__{t: nil} = est, t), do: %{est | t: t}

  defp advance(%__MODULE__{t: t0} = est, t) when t < t0, do: %{restart(est) | t: t}

  defp advance(%__MODULE__{t: t0} = est, t) when t == t0, do: est

  defp advance(%__MODULE__{t: t0, max_gap: gap} = est, t) when t - t0 > gap do
    model = if est.model, do: %{est.model | forces: est.model.targets}

    %{
      est
      | t: t,
        model: model,
        filters: Map.new(est.filters, fn {name, k} -> {name, Kalman.clear(k)} end)
    }
  end

  defp advance(%__MODULE__{t: t0} = est, t) do
    dt = t - t0

    {model, {heave, yaw}} =
      case est.model do
        nil -> {nil, {0.0, 0.0}}
        model -> Model.advance(model, dt)
      end

    %{
      est
      | t: t,
        model: model,
        filters:
          Map.new(est.filters, fn {name, k} ->
            {name, Kalman.predict(k, dt, force(name, heave, yaw))}
          end)
    }
  end

  defp restart(est) do
    %{
      est
      | gates: new_gates(),
        updated: Map.new(@filtered, &{&1, nil}),
        filters: Map.new(est.filters, fn {name, k} -> {name, Kalman.clear(k)} end)
    }
  end

  defp force(:depth, heave, _yaw), do: heave
  defp force(:heading, _heave, yaw), do: yaw
  defp force(_name, _heave, _yaw), do: 0.0

  defp drop_stale(est, t) do
    Enum.reduce(@filtered, est, fn name, est ->
      case est.updated[name] do
        at when is_float(at) and t - at > est.stale_after ->
          %{est | updated: Map.put(est.updated, name, nil)}
          |> put_filter(name, Kalman.clear(est.filters[name]))

        _ ->
          est
      end
    end)
  end

  # one field of one sample
  defp field(est, name, _t, nil), do: verdict(est, name, :missing)

  defp field(est, name, t, raw) do
    gate = est.gates[name]

    if raw === gate.last_raw do
      held(est, name, t, gate)
    else
      gate = %{gate | last_raw: raw}

      case WildPoints.range(est.limits[name], raw) do
        {:error, reason} ->
          est
          |> put_gate(name, %{gate | accepted?: false})
          |> reject(name, reason)

        {:ok, value} ->
          test(est, name, t, value, gate)
      end
    end
  end

  defp held(est, name, t, %Gate{accepted?: true, ref: {_, value}}) when name in @filtered do
    case est.updated[name] do
      at when is_float(at) and t - at < est.hold -> verdict(est, name, :held)
      _ -> est |> filter_update(name, t, value) |> verdict(name, :held)
    end
  end

  defp held(est, name, _t, _gate), do: verdict(est, name, :held)

  defp test(est, name, t, value, %Gate{ref: nil} = gate), do: accept(est, name, t, value, gate)

  defp test(est, name, t, value, gate) do
    limit = est.limits[name]

    cond do
      not WildPoints.plausible?(limit, gate.ref, {t, value}) ->
        miss(est, name, t, value, gate, :rate_of_change)

      name in @filtered and not Kalman.gate?(est.filters[name], value) ->
        miss(est, name, t, value, gate, :innovation)

      true ->
        accept(est, name, t, value, gate)
    end
  end

  defp accept(est, name, t, value, gate) do
    est
    |> put_gate(name, %{gate | ref: {t, value}, accepted?: true, misses: []})
    |> filter_update(name, t, value)
    |> verdict(name, :accepted)
  end

  defp miss(est, name, t, value, gate, reason) do
    misses = Enum.take([{t, value} | gate.misses], est.confirm)
    limit = est.limits[name]

    if length(misses) == est.confirm and consistent?(limit, misses) do
      est
      |> put_gate(name, %{gate | ref: {t, value}, accepted?: true, misses: []})
      |> filter_restart(name, t, value, slope(limit, misses))
      |> Map.update!(:counts, &WildPoints.reacquired/1)
      |> verdict(name, :reacquired)
    else
      est
      |> put_gate(name, %{gate | accepted?: false, misses: misses})
      |> reject(name, reason)
    end
  end

  # newest first: each reading plausible after the one before it
  defp consistent?(limit, [newer, older | rest]),
    do: WildPoints.plausible?(limit, older, newer) and consistent?(limit, [older | rest])

  defp consistent?(_limit, _), do: true

  defp slope(limit, [{t, v} | _] = misses) do
    {t0, v0} = List.last(misses)
    if t > t0, do: WildPoints.change(limit, v0, v) / (t - t0), else: 0.0
  end

  defp filter_update(est, name, t, value) when name in @filtered do
    est
    |> put_filter(name, Kalman.update(est.filters[name], value))
    |> Map.put(:updated, Map.put(est.updated, name, t))
  end

  defp filter_update(est, _name, _t, _value), do: est

  defp filter_restart(est, name, t, value, rate) when name in @filtered do
    est
    |> put_filter(name, Kalman.start(est.filters[name], value, rate))
    |> Map.put(:updated, Map.put(est.updated, name, t))
  end

  defp filter_restart(est, _name, _t, _value, _rate), do: est

  defp put_filter(est, name, k), do: %{est | filters: Map.put(est.filters, name, k)}

  defp put_gate(est, name, gate), do: %{est | gates: Map.put(est.gates, name, gate)}

  defp reject(est, name, reason) do
    %{est | counts: WildPoints.count(est.counts, name, reason)}
    |> verdict(name, {:rejected, reason})
  end

  defp verdict(est, name, verdict), do: %{est | verdicts: Map.put(est.verdicts, name, verdict)}

  @doc """
  The estimate after the last sample: `%{t, depth, depth_rate, heading, yaw_rate}` (SI,
  heading in [0, 2π)); a filter without an estimate gives nil for its two values.
  """
  @spec estimate(t()) :: estimate()
  def estimate(%__MODULE__{t: t, filters: %{depth: depth, heading: heading}}) do
    {z, w} = values(depth)
    {psi, r} = values(heading)
    %{t: t, depth: z, depth_rate: w, heading: psi, yaw_rate: r}
  end

  defp values(%Kalman{x: nil}), do: {nil, nil}
  defp values(%Kalman{x: x, v: v}), do: {x, v}

  @doc """
  The filtered measurement: for each of the six fields the last accepted reading (nil if
  none yet) — what the board measured, without its wild points.
  """
  @spec measurement(t()) :: %{atom() => float() | nil}
  def measurement(%__MODULE__{gates: gates}) do
    Map.new(gates, fn
      {name, %Gate{ref: {_, v}}} -> {name, v}
      {name, _} -> {name, nil}
    end)
  end

  @doc "The wild-point counts so far (`t:Neptunus.Navigation.WildPoints.counts/0`)."
  @spec wild_points(t()) :: WildPoints.counts()
  def wild_points(%__MODULE__{counts: counts}), do: counts

  @doc """
  Each field's verdict on the last sample: `:accepted`, `:reacquired`, `:held`, `:missing` or
  `{:rejected, reason}`.
  """
  @spec verdicts(t()) :: %{atom() => verdict()}
  def verdicts(%__MODULE__{verdicts: verdicts}), do: verdicts
end
