defmodule Neptunus.Scenario do
  @moduledoc """
  A headless simulation scenario (`mix neptunus.simulate`): parsed from JSON and validated
  here (pure), run by `Neptunus.Scenario.Run`. The format is documented in the README
  ("Headless simulation"); examples are in `priv/scenarios/`.

      {
        "description": "free text (optional)",
        "vehicle": "neptunus",               // parameter set in priv/vehicles/ (required)
        "duration": 60,                      // s, > 0 (required)
        "dt": 0.01,                          // s, integration step, default 0.01
        "seed": 42,                          // integer, default 0
        "noise": true,                       // realistic sensors, default false
        "current": [0.1, 0, 0],              // m/s NED, default [0, 0, 0]
        "current_variation": {"sigma": 0.02, "time_constant": 60},   // optional
        "tether_length": 20,                 // m, default the vehicle's
        "sensors": {"wild_rate": 0.01, "depth": {"noise": 0.02}},      // optional overrides
        "initial": {"z": 1.0, "psi": 0.5},   // state fields (SI, rad), default z = 1
        "gain": 0.5,                         // k of the allocation, default 0.5
        "events": [
          {"t": 0, "thrust": {"mode": "motion", "surge": 1, "heave": 0, "yaw": 0}},
          {"t": 10, "gain": 1.0},
          {"t": 20, "thrust": {"mode": "manual", "port": 0.2, "vertical": -0.5, "starboard": 0.2}},
          {"t": 30, "tau": [0, 0, 0, 0, 0, 0.5]},
          {"t": 40, "current": [0, 0.2, 0]},
          {"t": 45, "thrust": {"mode": "motion", "surge": 0, "heave": 0, "yaw": 0},
                    "autopilot": {"depth": "hold", "heading": 90}},
          {"t": 50, "control_mode": "dp"}
        ]
      }

  Events are in time order; each has `t` (s, within the duration) and at least one action:

    * `thrust` — `{"mode": "motion", "surge", "heave", "yaw"}` allocated by the thesis'
      eq. 9.3 with the gain, or `{"mode": "manual", "port", "vertical", "starboard"}` scaled
      by the gain; every value in [-1, 1]. It stays in force until the next `thrust`.
    * `gain` — the gain k in [0, 1] (re-applied to the thrust in force).
    * `tau` — `[X, Y, Z, K, M, N]` (N, N·m, body frame): an external generalised force added
      to the thrusters' (which are neutral unless commanded), until the next `tau`.
    * `current` — a new mean current `[n, e, d]` (m/s NED).
    * `autopilot` — `{"depth": m | "hold" | null, "heading": deg | "hold" | null}` (either
      or both): a number engages that autopilot at that setpoint (depth in [0, 200] m,
      heading in degrees, [-360, 360]), `"hold"` at the current estimated value, null
      disengages it (see `Neptunus.Control.Core`: pilot thrust on the held axis overrides
      it and it re-captures on release, exactly as on a live vehicle).
    * `control_mode` — `"motion"`, `"manual"` or `"dp"` (position hold at the current
      position; the simulator's truth is the position source). A `thrust` in another mode
      than the current one first switches to its mode, as the pilot's page does.

  The control — modes, gain, allocation, autopilots, DP — is `Neptunus.Control.Core`, the
  same as a live vehicle's, with its control loop at #{50} Hz of simulated time and
  `Neptunus.Estimator` (navigation's filter) as its estimate. Like a live vehicle, a change
  of control mode stops the thrusters first, entering manual mode disengages the autopilots
  (an `autopilot` event in manual mode is refused), and DP holds depth and heading (an
  `autopilot` event that disengages either in DP is refused). Within an event the actions
  apply in the order `control_mode`, `gain`, `thrust`, `autopilot`, `tau`, `current`.

  A scenario's `model` (a struct field, not in the JSON) is the parameter set navigation's
  estimator assumes, when the simulated vehicle (`params`) differs from it: robustness runs
  scale the vehicle (`Neptunus.Dynamics.Params.scaled/2`) and keep the nominal model.

  `parse/1` and `validate/1` never raise; errors name the field
  (see `Neptunus.Validate`), e.g. `events[2].thrust.surge must be a number in [-1, 1], got 2`.
  """

  alias Neptunus.Dynamics.Params
  alias Neptunus.Dynamics.State
  alias Neptunus.Validate, as: V

  @max_steps 10_000_000

  @enforce_keys [:vehicle, :params, :duration]
  defstruct [
    :vehicle,
    :params,
    :duration,
    :description,
    :current_variation,
    :tether_length,
    dt: 0.01,
    seed: 0,
    noise: false,
    current: {0.0, 0.0, 0.0},
    sensors: %{},
    initial: [z: 1.0],
    gain: 0.5,
    events: [],
    model: nil,
    position: :truth,
    dp: []
  ]

  @typedoc "The thrust of a `thrust` event."
  @type thrust ::
          {:motion, %{surge: float(), heave: float(), yaw: float()}}
          | {:manual, %{port: float(), vertical: float(), starboard: float()}}

  @typedoc "A timed event; absent actions are nil."
  @type event :: %{
          t: float(),
          thrust: thrust() | nil,
          gain: float() | nil,
          tau: Neptunus.Dynamics.tau() | nil,
          current: {float(), float(), float()} | nil,
          control_mode: :motion | :manual | :dp | nil,
          autopilot: %{depth: setpoint(), heading: setpoint()} | nil,
          mission: [Neptunus.Control.Mission.waypoint()] | nil,
          mission_control: :pause | :resume | :abort | nil
        }

  @typedoc """
  The position sources: `:truth` (the simulator's true position, a perfect source), or the
  simulated DVL and USBL with their settings (nil: not fitted).
  """
  @type position :: :truth | %{dvl: map() | nil, usbl: map() | nil}

  @typedoc "An autopilot setpoint of an `autopilot` event (heading in rad)."
  @type setpoint :: :unchanged | :hold | nil | float()

  @type t :: %__MODULE__{
          vehicle: String.t(),
          params: Params.t(),
          description: String.t() | nil,
          duration: float(),
          dt: float(),
          seed: integer(),
          noise: boolean(),
          current: {float(), float(), float()},
          current_variation: %{sigma: float(), time_constant: float()} | nil,
          tether_length: float() | nil,
          sensors: map(),
          initial: keyword(),
          gain: float(),
          events: [event()],
          model: Params.t() | nil,
          position: position(),
          dp: keyword()
        }

  @top_required ~w(vehicle duration)
  @top_optional ~w(description dt seed noise current current_variation tether_length sensors
                   initial gain events position dp)
  @channels ~w(depth heading roll pitch voltage current)
  @actions ~w(thrust gain tau current autopilot control_mode mission mission_control)
  @control_modes %{"motion" => :motion, "manual" => :manual, "dp" => :dp}

  @doc "Parses and validates a scenario from JSON text."
  @spec parse(binary()) :: {:ok, t()} | {:error, String.t()}
  def parse(json) when is_binary(json) do
    with {:ok, map} <- Neptunus.JSON.decode(json), do: validate(map)
  end

  @doc "Validates a decoded scenario (string keys)."
  @spec validate(term()) :: {:ok, t()} | {:error, String.t()}
  def validate(map) do
    with :ok <- V.object(map, "", @top_required, @top_optional),
         {:ok, description} <- V.optional(map, "", "description", nil, &V.string/2),
         {:ok, {vehicle, params}} <- V.required(map, "", "vehicle", &vehicle/2),
         {:ok, duration} <- V.required(map, "", "duration", &V.number(&1, &2, greater_than: 0)),
         {:ok, dt} <- V.optional(map, "", "dt", 0.01, &V.number(&1, &2, greater_than: 0, max: 1)),
         :ok <- steps(duration, dt),
         {:ok, seed} <- V.optional(map, "", "seed", 0, &V.integer/2),
         {:ok, noise} <- V.optional(map, "", "noise", false, &V.boolean/2),
         {:ok, current} <- V.optional(map, "", "current", {0.0, 0.0, 0.0}, &current/2),
         {:ok, variation} <- V.optional(map, "", "current_variation", nil, &variation/2),
         {:ok, tether} <- V.optional(map, "", "tether_length", nil, &V.number(&1, &2, min: 0)),
         {:ok, sensors} <- V.optional(map, "", "sensors", %{}, &sensors/2),
         {:ok, initial} <- V.optional(map, "", "initial", [z: 1.0], &initial(&1, &2, params)),
         {:ok, gain} <- V.optional(map, "", "gain", 0.5, &V.number(&1, &2, min: 0, max: 1)),
         {:ok, position} <- V.optional(map, "", "position", :truth, &position/2),
         {:ok, dp} <- V.optional(map, "", "dp", [], &dp/2),
         {:ok, events} <- V.optional(map, "", "events", [], &events(&1, &2, duration)) do
      {:ok,
       %__MODULE__{
         vehicle: vehicle,
         params: params,
         description: description,
         duration: duration,
         dt: dt,
         seed: seed,
         noise: noise,
         current: current,
         current_variation: variation,
         tether_length: tether,
         sensors: sensors,
         initial: initial,
         gain: gain,
         events: events,
         position: position,
         dp: dp
       }}
    end
  end

  @doc "Number of integration steps: `round(duration / dt)`."
  @spec steps(t()) :: non_neg_integer()
  def steps(%__MODULE__{duration: duration, dt: dt}), do: round(duration / dt)

  @doc "The options of `Neptunus.Sim.new/1` for this scenario."
  @spec sim_options(t()) :: keyword()
  def sim_options(%__MODULE__{} = s) do
    [
      vehicle: s.params,
      dt: s.dt,
      seed: s.seed,
      noise: s.noise,
      current: s.current,
      initial: s.initial,
      sensors: s.sensors
    ] ++
      if(s.current_variation, do: [current_variation: Map.to_list(s.current_variation)], else: []) ++
      if(s.tether_length, do: [tether_length: s.tether_length], else: [])
  end

  # --- fields ---

  defp vehicle(value, path) do
    with {:ok, name} <- V.string(value, path) do
      case Params.load_cached(name) do
        {:ok, params} -> {:ok, {name, params}}
        {:error, reason} -> {:error, "#{path}: #{reason}"}
      end
    end
  end

  defp steps(duration, dt) do
    if duration / dt > @max_steps,
      do:
        {:error,
         "duration / dt must be at most #{@max_steps} steps, got #{round(duration / dt)} " <>
           "(shorten duration or raise dt)"},
      else: :ok
  end

  defp current(value, path) do
    with {:ok, [n, e, d]} <- V.vector(value, path, 3, min: -10, max: 10), do: {:ok, {n, e, d}}
  end

  defp variation(map, path) do
    with :ok <- V.object(map, path, ["sigma"], ["time_constant"]),
         {:ok, sigma} <- V.required(map, path, "sigma", &V.number(&1, &2, min: 0, max: 5)),
         {:ok, tc} <-
           V.optional(map, path, "time_constant", 60.0, &V.number(&1, &2, greater_than: 0)) do
      {:ok, %{sigma: sigma, time_constant: tc}}
    end
  end

  defp sensors(map, path) do
    with :ok <- V.object(map, path, [], ~w(rate wild_rate mixup_rate) ++ @channels) do
      Enum.reduce_while(Enum.sort(map), {:ok, %{}}, fn {key, value}, {:ok, acc} ->
        kpath = V.join(path, key)

        result =
          case key do
            "rate" -> V.number(value, kpath, greater_than: 0)
            "wild_rate" -> V.number(value, kpath, min: 0, max: 1)
            "mixup_rate" -> V.number(value, kpath, min: 0, max: 1)
            _channel -> channel(value, kpath)
          end

        case result do
          {:ok, checked} -> {:cont, {:ok, Map.put(acc, String.to_atom(key), checked)}}
          error -> {:halt, error}
        end
      end)
      |> case do
        {:ok, acc} ->
          if Map.get(acc, :wild_rate, 0.0) + Map.get(acc, :mixup_rate, 0.0) > 1.0,
            do: {:error, "#{path}.wild_rate + #{path}.mixup_rate must be at most 1"},
            else: {:ok, acc}

        error ->
          error
      end
    end
  end

  defp channel(map, path) do
    with :ok <- V.object(map, path, [], ~w(noise bias)),
         {:ok, noise} <- V.optional(map, path, "noise", nil, &V.number(&1, &2, min: 0)),
         {:ok, bias} <- V.optional(map, path, "bias", nil, &V.number/2) do
      {:ok, %{noise: noise, bias: bias} |> Enum.reject(&is_nil(elem(&1, 1))) |> Map.new()}
    end
  end

  defp initial(map, path, params) do
    fields = Enum.map(State.fields(), &Atom.to_string/1)

    with :ok <- V.object(map, path, [], fields) do
      map
      |> Enum.sort_by(fn {key, _} -> Enum.find_index(fields, &(&1 == key)) end)
      |> V.map_ok(fn {key, value}, _ ->
        with {:ok, x} <- initial_field(key, value, V.join(path, key), params),
             do: {:ok, {String.to_atom(key), x}}
      end)
    end
  end

  defp initial_field(key, value, path, %Params{dof: 4, name: name})
       when key in ~w(phi theta p q) do
    with {:ok, x} <- V.number(value, path) do
      if x == 0.0,
        do: {:ok, x},
        else: {:error, "#{path} must be 0 for vehicle #{name} (roll and pitch are fixed)"}
    end
  end

  defp initial_field("theta", value, path, _params),
    do: V.number(value, path, min: -1.5, max: 1.5)

  defp initial_field("z", value, path, _params), do: V.number(value, path, min: 0)
  defp initial_field(_key, value, path, _params), do: V.number(value, path)

  defp events(list, path, duration) when is_list(list) do
    list
    |> Enum.with_index()
    |> Enum.reduce_while({:ok, [], 0.0}, fn {map, i}, {:ok, acc, last_t} ->
      epath = V.join(path, i)

      case event(map, epath, duration) do
        {:ok, %{t: t}} when t < last_t ->
          {:halt,
           {:error,
            "#{epath}.t must not be before #{V.join(path, i - 1)}.t " <>
              "(events are in time order), got #{V.show(map["t"])}"}}

        {:ok, event} ->
          {:cont, {:ok, [event | acc], event.t}}

        error ->
          {:halt, error}
      end
    end)
    |> case do
      {:ok, acc, _} -> modes(Enum.reverse(acc), path)
      error -> error
    end
  end

  defp events(value, path, _duration),
    do: {:error, "#{path} must be a list, got #{V.show(value)}"}

  defp event(map, path, duration) do
    with :ok <- V.object(map, path, ["t"], @actions),
         :ok <- some_action(map, path),
         {:ok, t} <- V.required(map, path, "t", &V.number(&1, &2, min: 0, max: duration)),
         {:ok, thrust} <- V.optional(map, path, "thrust", nil, &thrust/2),
         {:ok, gain} <- V.optional(map, path, "gain", nil, &V.number(&1, &2, min: 0, max: 1)),
         {:ok, tau} <- V.optional(map, path, "tau", nil, &tau/2),
         {:ok, current} <- V.optional(map, path, "current", nil, &current/2),
         {:ok, mode} <- V.optional(map, path, "control_mode", nil, &control_mode/2),
         {:ok, autopilot} <- V.optional(map, path, "autopilot", nil, &autopilot/2),
         {:ok, mission} <- V.optional(map, path, "mission", nil, &mission/2),
         {:ok, mission_control} <-
           V.optional(map, path, "mission_control", nil, &mission_control/2),
         :ok <- same_mode(mode, thrust, path) do
      {:ok,
       %{
         t: t,
         thrust: thrust,
         gain: gain,
         tau: tau,
         current: current,
         control_mode: mode,
         autopilot: autopilot,
         mission: mission,
         mission_control: mission_control
       }}
    end
  end

  defp mission(value, path) do
    case Neptunus.Control.Mission.parse(value) do
      {:ok, waypoints} -> {:ok, waypoints}
      {:error, reason} -> {:error, "#{path}: #{reason}"}
    end
  end

  defp mission_control(value, path) do
    case value do
      "pause" -> {:ok, :pause}
      "resume" -> {:ok, :resume}
      "abort" -> {:ok, :abort}
      _ -> {:error, ~s(#{path} must be "pause", "resume" or "abort", got #{V.show(value)})}
    end
  end

  # position sources: the simulated DVL and USBL (true: default settings, an object: some
  # settings changed, false or absent: not fitted)
  defp position(map, path) do
    with :ok <- V.object(map, path, [], ["dvl", "usbl"]),
         {:ok, dvl} <- V.optional(map, path, "dvl", nil, &sensor(&1, &2, Neptunus.Sim.DVL)),
         {:ok, usbl} <- V.optional(map, path, "usbl", nil, &sensor(&1, &2, Neptunus.Sim.USBL)) do
      {:ok, %{dvl: dvl, usbl: usbl}}
    end
  end

  defp sensor(false, _path, _module), do: {:ok, nil}
  defp sensor(true, _path, _module), do: {:ok, %{}}

  defp sensor(map, path, module) when is_map(map) do
    defaults = module.defaults()
    keys = defaults |> Map.keys() |> Enum.map(&Atom.to_string/1) |> List.delete("epoch_us")

    with :ok <- V.object(map, path, [], keys) do
      map
      |> Enum.sort()
      |> V.map_ok(fn {key, value}, _ ->
        kpath = V.join(path, key)
        atom = String.to_existing_atom(key)

        checked =
          case Map.fetch!(defaults, atom) do
            b when is_boolean(b) -> V.boolean(value, kpath)
            {_, _} -> with {:ok, [a, b]} <- V.vector(value, kpath, 2), do: {:ok, {a, b}}
            _ -> V.number(value, kpath, min: 0)
          end

        with {:ok, v} <- checked, do: {:ok, {atom, v}}
      end)
      |> case do
        {:ok, pairs} -> {:ok, Map.new(pairs)}
        error -> error
      end
    end
  end

  defp sensor(value, path, _module),
    do: {:error, "#{path} must be true, false or an object of settings, got #{V.show(value)}"}

  defp dp(map, path) do
    keys = ~w(kp v_max radius vane_min)

    with :ok <- V.object(map, path, [], keys) do
      map
      |> Enum.sort()
      |> V.map_ok(fn {key, value}, _ ->
        with {:ok, v} <- V.number(value, V.join(path, key), greater_than: 0),
             do: {:ok, {String.to_existing_atom(key), v}}
      end)
    end
  end

  defp control_mode(value, path) do
    case Map.fetch(@control_modes, value) do
      {:ok, mode} -> {:ok, mode}
      :error -> {:error, ~s(#{path} must be "motion", "manual" or "dp", got #{V.show(value)})}
    end
  end

  defp same_mode(mode, {thrust_mode, _}, path) when mode != nil and mode != thrust_mode,
    do:
      {:error,
       "#{path}.thrust.mode must be the event's control_mode (#{mode}), got #{thrust_mode}"}

  defp same_mode(_mode, _thrust, _path), do: :ok

  defp autopilot(map, path) do
    with :ok <- V.object(map, path, [], ["depth", "heading"]),
         :ok <- some_axis(map, path),
         {:ok, depth} <- setpoint(map, path, "depth", &V.number(&1, &2, min: 0, max: 200)),
         {:ok, heading} <- setpoint(map, path, "heading", &degrees/2) do
      {:ok, %{depth: depth, heading: heading}}
    end
  end

  defp some_axis(map, path) do
    if map_size(map) > 0,
      do: :ok,
      else: {:error, "#{path} needs depth and/or heading (a setpoint, \"hold\" or null)"}
  end

  defp setpoint(map, path, key, check) do
    case Map.fetch(map, key) do
      :error -> {:ok, :unchanged}
      {:ok, nil} -> {:ok, nil}
      {:ok, "hold"} -> {:ok, :hold}
      {:ok, value} -> check.(value, V.join(path, key))
    end
  end

  defp degrees(value, path) do
    with {:ok, deg} <- V.number(value, path, min: -360, max: 360),
         do: {:ok, Neptunus.PID.wrap_2pi(deg * :math.pi() / 180)}
  end

  # the control mode along the events (a thrust switches to its mode): autopilots are
  # refused in manual mode, and DP holds depth and heading
  defp modes(events, path) do
    events
    |> Enum.with_index()
    |> Enum.reduce_while(:motion, fn {event, i}, mode ->
      mode = event.control_mode || mode
      mode = if event.thrust, do: elem(event.thrust, 0), else: mode
      epath = V.join(V.join(path, i), "autopilot")

      case {event.autopilot, mode} do
        _ when mode != :dp and (event.mission != nil or event.mission_control != nil) ->
          {:halt,
           {:error,
            "#{V.join(path, i)}: missions run in control mode dp (add \"control_mode\": \"dp\")"}}

        {nil, _} ->
          {:cont, mode}

        {_, :manual} ->
          {:halt, {:error, "#{epath}: autopilots are not available in manual mode"}}

        {%{depth: d, heading: h}, :dp} when is_nil(d) or is_nil(h) ->
          {:halt,
           {:error,
            "#{epath}: dp holds depth and heading (switch control_mode to motion to release them)"}}

        _ ->
          {:cont, mode}
      end
    end)
    |> case do
      {:error, _} = error -> error
      _mode -> {:ok, events}
    end
  end

  defp some_action(map, path) do
    if Enum.any?(@actions, &Map.has_key?(map, &1)),
      do: :ok,
      else:
        {:error,
         "#{path} must have at least one of: #{@actions |> Enum.sort() |> Enum.join(", ")}"}
  end

  defp tau(value, path) do
    with {:ok, list} <- V.vector(value, path, 6, min: -10_000, max: 10_000),
         do: {:ok, List.to_tuple(list)}
  end

  defp thrust(%{"mode" => "motion"} = map, path),
    do: thrust_values(map, path, :motion, ~w(surge heave yaw))

  defp thrust(%{"mode" => "manual"} = map, path),
    do: thrust_values(map, path, :manual, ~w(port vertical starboard))

  defp thrust(%{"mode" => mode}, path),
    do: {:error, "#{path}.mode must be \"motion\" or \"manual\", got #{V.show(mode)}"}

  defp thrust(map, path) when is_map(map), do: {:error, "missing field: #{path}.mode"}
  defp thrust(value, path), do: {:error, "#{path} must be an object, got #{V.show(value)}"}

  defp thrust_values(map, path, mode, keys) do
    with :ok <- V.object(map, path, ["mode" | keys]) do
      keys
      |> Enum.reduce_while({:ok, %{}}, fn key, {:ok, acc} ->
        case V.required(map, path, key, &V.number(&1, &2, min: -1, max: 1)) do
          {:ok, x} -> {:cont, {:ok, Map.put(acc, String.to_atom(key), x)}}
          error -> {:halt, error}
        end
      end)
      |> case do
        {:ok, values} -> {:ok, {mode, values}}
        error -> error
      end
    end
  end
end
