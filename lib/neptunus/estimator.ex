defmodule Neptunus.Estimator do
  @moduledoc """
  The navigation filter of a vehicle: wild-point rejection at the navigation input and a
  Kalman filter for depth + vertical speed and heading + yaw rate. Pure: a value stepped with
  each board sample (`update/3`) and told each thruster command (`command/2`); run by
  `Neptunus.Vehicle.Navigation` on a live vehicle and by the headless scenario runner on the
  same simulated measurements.

  ## Initialising, valid, stale

  No reading is trusted on its own. Each field (`depth heading roll pitch voltage current`)
  starts **initialising** — at `new/1`, at `reset/1` (the board link came up, or saw the
  board reset), when the board's uptime (`board_time`, see `update/4`) goes backwards, and
  when the sample clock goes backwards — and becomes **valid** only when both

    * the **settle time** (`settle`, 1.2 s) is over since then, and
    * the last `agree` (3) in-range readings agree with each other (each a plausible
      successor of the one before, see below), **repeats included**;

  it is then valid at the newest of them, and its filter starts there at rest. Until then
  its value (`measurement/1`) and estimate (`estimate/1`) are nil. The numbers: an OpenROV
  board prints `deap:0.00` (and a heading of 0.00 from an IMU that has not started) for about
  1 s after it boots, until its pressure sensor's first reading, so a board's first second is
  never taken for the truth; 1.2 s leaves two 10 Hz lines of margin. That board then prints
  its depth (read once a second) ten times a second, so three readings come 0.2 s after the
  first true one: valid again 1.2–1.4 s after a board reset. When the reset shows in
  `board_time`, the settle time counts from the board's boot (`t − board_time`), so a reset
  seen late (its clock is printed once a second) is not held up longer.

  A valid field with no accepted reading for `stale_after` (2 s) is **stale**: it keeps its
  last value, its filter's estimate is dropped, and the next accepted reading makes it valid
  again. `states/1` gives each field's state.

  ## Wild points

  Every reading of a field that is not initialising goes through, in order:

    1. **held values** — a value identical to the field's previous one is the board repeating
       its last reading (a serial board prints its 1 Hz depth ten times a second, the
       simulated board its 20 Hz sensors at 100 Hz), not a new reading: it keeps the
       previous verdict and is not counted again. A held accepted depth or heading updates
       the filter again after `hold` s (so it stays converged on ideal sensors at rest); a
       held rejected reading still counts towards re-acquisition (below);
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

  **Re-acquisition.** Wild points are isolated; the truth persists. The rejected readings
  (by rate or innovation) that agree with each other — each plausible after the one before —
  form a run; the field is re-acquired at the newest (accepted, its filter restarted there
  with the rate the run shows) when the run holds `confirm` (3) *new* values, or when it has
  lasted `lockout` (1.1 s), repeats included. So no gate locks out a consistent signal for
  more than 1.1 s — not even a board repeating one value ten times a second that changes once
  a second — while a single wild reading that the board repeats until its next reading
  (at most ~0.9 s of repeats at 1 Hz) is still rejected. This recovers from a filter led
  astray by something its model does not know (a collision, a hand on the vehicle), from a
  re-zeroed sensor, and from a jump of the simulated vehicle; `reacquired` counts it.

  ## Kalman filters

  Two-state filters (`Neptunus.Navigation.Kalman`, the model and its discretisation are
  documented there): depth `z` (m, down) with `ż` (m/s), and heading `ψ` (rad, [0, 2π)) with
  `ψ̇` (rad/s), the heading innovation wrapped to `[-π, π)`. Roll `φ` and pitch `θ` (rad) with
  their rates have constant-velocity filters (no model: the vehicle does not command roll or
  pitch, they are its metacentric restoring and the thrusters' coupling): they gate their
  readings and are the attitude estimate (the thesis' table 7.3, third column). All four are
  the estimate (`estimate/1`).

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
  backwards (a simulator reset, a restarted clock) re-initialises every field, keeping the
  counts.
  """

  alias Neptunus.Dynamics.Params
  alias Neptunus.Navigation.{Kalman, Model, WildPoints}

  @fields WildPoints.fields()
  @filtered [:depth, :heading, :roll, :pitch]
  # sample times beyond this (s, ~30 000 years) are not times: ignored
  @max_time 1.0e12

  # roll and pitch: constant-velocity filters (gates and the attitude estimate), alike
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
    # One field's wild-point state: its status, the last accepted reading `{t, v}`, the last
    # raw value seen and whether it was accepted, when the field last had an accepted (or
    # held accepted) reading, and the run of readings not (yet) accepted that agree with
    # each other: its first and last reading, how many new values and how many readings
    # (repeats included) it holds.
    @type run :: %{
            first: {float(), float()},
            last: {float(), float()},
            new: pos_integer(),
            readings: pos_integer()
          }
    @type t :: %__MODULE__{
            status: :initialising | :valid | :stale,
            ref: {float(), float()} | nil,
            last_raw: term(),
            accepted?: boolean(),
            fresh_at: float() | nil,
            run: run() | nil
          }
    defstruct status: :initialising,
              ref: nil,
              last_raw: :none,
              accepted?: false,
              fresh_at: nil,
              run: nil
  end

  @enforce_keys [:filters, :limits]
  defstruct [
    :filters,
    :limits,
    :model,
    :t,
    :since,
    :board_time,
    gates: %{},
    updated: %{},
    counts: WildPoints.new_counts(),
    verdicts: %{},
    hold: 0.2,
    max_gap: 2.0,
    stale_after: 2.0,
    confirm: 3,
    settle: 1.2,
    agree: 3,
    lockout: 1.1
  ]

  @typedoc "A field's verdict on the last sample."
  @type verdict ::
          :accepted
          | :reacquired
          | :held
          | :missing
          | :initialising
          | {:rejected, WildPoints.reason()}

  @typedoc "A measurement's state (see the moduledoc)."
  @type status :: :initialising | :valid | :stale

  @typedoc """
  * `filters` — the Kalman filters of `depth`, `heading`, `roll` and `pitch`
  * `limits` — wild-point limits per field (`Neptunus.Navigation.WildPoints.limits/0`)
  * `model` — the vehicle model driving the prediction, or nil (constant velocity)
  * `t` — time of the last sample (nil before the first)
  * `since` — when the settle time started (the first sample after `new/1`, `reset/1` or a
    clock going back; the board's boot when a board reset is seen in its `board_time`), nil
    until the next sample; `board_time` — the board's uptime in the last sample that had it
  * `gates` — each field's wild-point state; `counts` — rejections so far
  * `updated` — when each filter last took a reading
  * `verdicts` — each field's verdict on the last sample
  * `hold`, `max_gap`, `stale_after`, `settle`, `lockout` (s), `confirm`, `agree`
    (readings) — see the moduledoc
  """
  @type t :: %__MODULE__{
          filters: %{atom() => Kalman.t()},
          limits: %{atom() => WildPoints.limit()},
          model: Model.t() | nil,
          t: float() | nil,
          since: float() | nil,
          board_time: float() | nil,
          gates: %{atom() => Gate.t()},
          updated: %{atom() => float() | nil},
          counts: WildPoints.counts(),
          verdicts: %{atom() => verdict()},
          hold: float(),
          max_gap: float(),
          stale_after: float(),
          confirm: pos_integer(),
          settle: float(),
          agree: pos_integer(),
          lockout: float()
        }

  @typedoc "The estimate: nil where there is none (no plausible reading yet, or stale)."
  @type estimate :: %{
          t: float() | nil,
          depth: float() | nil,
          depth_rate: float() | nil,
          heading: float() | nil,
          yaw_rate: float() | nil,
          roll: float() | nil,
          roll_rate: float() | nil,
          pitch: float() | nil,
          pitch_rate: float() | nil
        }

  @doc """
  A new estimator. Options:

    * `:vehicle` — the parameter set (name or `Neptunus.Dynamics.Params`) whose model drives
      the prediction and whose sensor noise sets `r`; default `"neptunus"`; `nil` for a
      model-free (constant-velocity) filter with the default noise
    * `:depth`, `:heading`, `:roll`, `:pitch` — overrides of the filters' `q`, `r`, `gate`,
      `min_gate`, `max_rate`
    * `:limits` — overrides of the wild-point limits, per field (merged)
    * `:hold`, `:max_gap`, `:stale_after`, `:settle`, `:lockout` (s), `:confirm`, `:agree`
      (readings) — see the moduledoc
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

    [:hold, :max_gap, :stale_after, :confirm, :settle, :agree, :lockout]
    |> Enum.reduce(est, fn key, est ->
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

    # roll and pitch: constant-velocity filters (no model)
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
  prediction to `t` and update. `board_time` is the board's uptime (s) when the sample has it
  (nil otherwise): going backwards, the board has reset, and every measurement starts
  initialising again (see the moduledoc). Never raises: a `t` that is not a number (or beyond
  ±10¹² s) leaves the estimator unchanged; a measurement that is not a map counts as all
  fields missing; a `board_time` that is not a number is ignored.
  """
  @spec update(t(), term(), term(), term()) :: t()
  def update(est, t, measurement, board_time \\ nil)

  def update(%__MODULE__{} = est, t, measurement, board_time)
      when is_number(t) and abs(t) < @max_time do
    t = t * 1.0
    measurement = if is_map(measurement), do: measurement, else: %{}

    est
    |> board_clock(t, board_time)
    |> advance(t)
    |> then(&%{&1 | since: &1.since || t})
    |> drop_stale(t)
    |> then(fn est ->
      Enum.reduce(@fields, %{est | verdicts: %{}}, &field(&2, &1, t, Map.get(measurement, &1)))
    end)
  end

  def update(%__MODULE__{} = est, _t, _measurement, _board_time), do: %{est | verdicts: %{}}

  @doc """
  The board was reset or its link (re)opened: every measurement is initialising again, the
  estimate is dropped, and the settle time starts again at the next sample. The wild-point
  counts are kept.
  """
  @spec reset(t()) :: t()
  def reset(%__MODULE__{} = est), do: %{reinitialise(est, nil) | board_time: nil}

  # the board's uptime going backwards: it reset, and booted `board_time` s before `t`
  defp board_clock(est, t, board_time)
       when is_number(board_time) and abs(board_time) < @max_time do
    board_time = board_time * 1.0

    case est.board_time do
      before when is_float(before) and board_time < before ->
        %{reinitialise(est, t - max(board_time, 0.0)) | board_time: board_time}

      _ ->
        %{est | board_time: board_time}
    end
  end

  defp board_clock(est, _t, _board_time), do: est

  # time: predict, re-initialise on a clock going back, restart the filters after a gap
  defp advance(%__MODULE__{t: nil} = est, t), do: %{est | t: t}

  defp advance(%__MODULE__{t: t0} = est, t) when t < t0, do: %{reinitialise(est, nil) | t: t}

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

  defp reinitialise(est, since) do
    %{
      est
      | gates: new_gates(),
        since: since,
        updated: Map.new(@filtered, &{&1, nil}),
        filters: Map.new(est.filters, fn {name, k} -> {name, Kalman.clear(k)} end)
    }
  end

  defp force(:depth, heave, _yaw), do: heave
  defp force(:heading, _heave, yaw), do: yaw
  defp force(_name, _heave, _yaw), do: 0.0

  # filters without a reading for `stale_after` drop their estimate; a valid field without an
  # accepted reading for as long is stale
  defp drop_stale(est, t) do
    est =
      Enum.reduce(@filtered, est, fn name, est ->
        case est.updated[name] do
          at when is_float(at) and t - at > est.stale_after ->
            %{est | updated: Map.put(est.updated, name, nil)}
            |> put_filter(name, Kalman.clear(est.filters[name]))

          _ ->
            est
        end
      end)

    gates =
      Map.new(est.gates, fn
        {name, %Gate{status: :valid, fresh_at: at} = gate} when t - at > est.stale_after ->
          {name, %{gate | status: :stale}}

        other ->
          other
      end)

    %{est | gates: gates}
  end

  # one field of one sample
  defp field(est, name, _t, nil), do: verdict(est, name, :missing)

  defp field(est, name, t, raw) do
    gate = est.gates[name]
    repeat? = raw === gate.last_raw
    gate = %{gate | last_raw: raw}

    case WildPoints.range(est.limits[name], raw) do
      {:error, reason} ->
        est = put_gate(est, name, %{gate | accepted?: false})
        if repeat?, do: verdict(est, name, :held), else: reject(est, name, reason)

      {:ok, value} ->
        cond do
          gate.status == :initialising -> initialise(est, name, t, value, gate, repeat?)
          repeat? and gate.accepted? -> held(est, name, t, gate)
          repeat? -> held_miss(est, name, t, value, gate)
          true -> test(est, name, t, value, gate)
        end
    end
  end

  # no valid reading since start or reset: valid once `agree` readings (repeats included)
  # agree and the settle time is over, at the newest of them
  defp initialise(est, name, t, value, gate, repeat?) do
    run = extend(est.limits[name], gate.run, {t, value}, repeat?)

    if t - est.since >= est.settle and run.readings >= est.agree do
      est
      |> put_gate(name, valid(gate, t, value))
      |> filter_restart(name, t, value, 0.0)
      |> verdict(name, :accepted)
    else
      est
      |> put_gate(name, %{gate | run: run, accepted?: false})
      |> verdict(name, :initialising)
    end
  end

  defp valid(gate, t, value),
    do: %{gate | status: :valid, ref: {t, value}, accepted?: true, fresh_at: t, run: nil}

  defp held(est, name, t, gate) do
    gate = %{gate | fresh_at: t, status: :valid}
    est = put_gate(est, name, gate)
    {_, value} = gate.ref

    case est.updated[name] do
      _ when name not in @filtered -> verdict(est, name, :held)
      at when is_float(at) and t - at < est.hold -> verdict(est, name, :held)
      _ -> est |> filter_update(name, t, value) |> verdict(name, :held)
    end
  end

  # a rejected reading repeated: not counted again, but it goes on agreeing with the run
  defp held_miss(est, name, t, value, gate) do
    run = extend(est.limits[name], gate.run, {t, value}, true)

    if locked_out?(est, run),
      do: reacquire(est, name, t, value, gate, run),
      else: est |> put_gate(name, %{gate | run: run}) |> verdict(name, :held)
  end

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
    |> put_gate(name, valid(gate, t, value))
    |> filter_update(name, t, value)
    |> verdict(name, :accepted)
  end

  defp miss(est, name, t, value, gate, reason) do
    run = extend(est.limits[name], gate.run, {t, value}, false)

    if run.new >= est.confirm or locked_out?(est, run) do
      reacquire(est, name, t, value, gate, run)
    else
      est
      |> put_gate(name, %{gate | accepted?: false, run: run})
      |> reject(name, reason)
    end
  end

  defp reacquire(est, name, t, value, gate, run) do
    est
    |> put_gate(name, valid(gate, t, value))
    |> filter_restart(name, t, value, slope(est.limits[name], run))
    |> Map.update!(:counts, &WildPoints.reacquired/1)
    |> verdict(name, :reacquired)
  end

  # the readings not accepted, as long as each agrees with the one before it (a plausible
  # successor); one that does not starts a new run
  defp extend(_limit, nil, reading, _repeat?),
    do: %{first: reading, last: reading, new: 1, readings: 1}

  defp extend(limit, run, reading, repeat?) do
    if WildPoints.plausible?(limit, run.last, reading) do
      %{
        run
        | last: reading,
          new: if(repeat?, do: run.new, else: run.new + 1),
          readings: run.readings + 1
      }
    else
      extend(limit, nil, reading, repeat?)
    end
  end

  defp locked_out?(est, %{first: {t0, _}, last: {t, _}}), do: t - t0 >= est.lockout

  defp slope(limit, %{first: {t0, v0}, last: {t, v}}) do
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
  The estimate after the last sample: `%{t, depth, depth_rate, heading, yaw_rate, roll,
  roll_rate, pitch, pitch_rate}` (SI, heading in [0, 2π), roll and pitch in rad, positive
  starboard down and bow up); a filter without an estimate gives nil for its two values.
  """
  @spec estimate(t()) :: estimate()
  def estimate(%__MODULE__{t: t, filters: filters}) do
    {z, w} = values(filters.depth)
    {psi, r} = values(filters.heading)
    {phi, p} = values(filters.roll)
    {theta, q} = values(filters.pitch)

    %{
      t: t,
      depth: z,
      depth_rate: w,
      heading: psi,
      yaw_rate: r,
      roll: phi,
      roll_rate: p,
      pitch: theta,
      pitch_rate: q
    }
  end

  defp values(%Kalman{x: nil}), do: {nil, nil}
  defp values(%Kalman{x: x, v: v}), do: {x, v}

  @doc """
  The standard deviation of the `:depth` or `:heading` estimate (m, rad), nil without one.
  """
  @spec std(t(), :depth | :heading) :: float() | nil
  def std(%__MODULE__{filters: filters}, field) when field in [:depth, :heading] do
    case Kalman.std(Map.fetch!(filters, field)) do
      {sigma, _rate} -> sigma
      nil -> nil
    end
  end

  @doc """
  The filtered measurement: for each of the six fields the last accepted reading — what the
  board measured, without its wild points — or nil while the field is initialising (no valid
  reading since start, link up or board reset).
  """
  @spec measurement(t()) :: %{atom() => float() | nil}
  def measurement(%__MODULE__{gates: gates}) do
    Map.new(gates, fn
      {name, %Gate{status: :initialising}} -> {name, nil}
      {name, %Gate{ref: {_, v}}} -> {name, v}
      {name, _} -> {name, nil}
    end)
  end

  @doc """
  Each field's state: `:initialising` (no valid reading yet since start, link up or board
  reset), `:valid`, or `:stale` (valid before, but no accepted reading for `stale_after`).
  """
  @spec states(t()) :: %{atom() => status()}
  def states(%__MODULE__{gates: gates}), do: Map.new(gates, fn {name, g} -> {name, g.status} end)

  @doc "The wild-point counts so far (`t:Neptunus.Navigation.WildPoints.counts/0`)."
  @spec wild_points(t()) :: WildPoints.counts()
  def wild_points(%__MODULE__{counts: counts}), do: counts

  @doc """
  Each field's verdict on the last sample: `:accepted`, `:reacquired`, `:held`, `:missing`,
  `:initialising` (taken while the field is initialising, not yet valid) or
  `{:rejected, reason}`.
  """
  @spec verdicts(t()) :: %{atom() => verdict()}
  def verdicts(%__MODULE__{verdicts: verdicts}), do: verdicts
end
