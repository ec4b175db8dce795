defmodule Neptunus.Sim do
  @moduledoc """
  The simulated vehicle as a pure value: the dynamics' state and parameters, the thrusters,
  the water current and the sensors. Every simulator — the live simulated board, the SITL
  board behind a pseudo-terminal, the headless scenario runner (`mix neptunus.simulate`) —
  steps the same `t:t/0` with `step/2` and reads it with `sample/1`, so what runs headless is
  what the pilot sees. All randomness (sensor noise and faults, current variation) comes from
  `:rand` states seeded from `:seed` and kept inside the value: the same options and the same
  commands give the same run, bit for bit.

  Each step of `dt`:

    1. the current's slow variation advances (`Neptunus.Sim.Current`);
    2. each thruster's force follows its static target (the commanded force after deadband
       and forward/reverse asymmetry, `Neptunus.Dynamics.Thruster`) with its first-order
       lag; the mean force over the step drives the dynamics;
    3. `Neptunus.Dynamics.step/5` integrates the 6-DOF model (RK4) under thrust plus any
       external force (`external_force/2`), tether drag and the current;
    4. the water surface holds the vehicle at `z ≥ 0` (upward heave is cancelled there);
    5. at the sensor rate (`sensors.rate` of the vehicle file; every step if faster) the
       sensors are read (`Neptunus.Sim.Sensors`).

  With `noise: false` (the default) the sensors are ideal: `sample/1` reports the true values
  at every step. With `noise: true` it reports the last sensor reading — noise, bias, wild
  points and field mix-ups as configured — held between readings like a real board's.

  Voltage and current come from a simple power model (`power` in the vehicle file): battery
  voltage minus internal resistance × current, current = idle + per-thruster current × the
  sum of the thrusters' |command|.
  """

  alias Neptunus.{Allocation, Dynamics}
  alias Neptunus.Dynamics.{Native, Params, State, Thruster}
  alias Neptunus.Sim.{Current, Sensors}

  @zero_tau {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}

  @enforce_keys [:params, :dyn, :thrusters, :dt]
  defstruct [
    :params,
    :dyn,
    :thrusters,
    :dt,
    :opts,
    :targets,
    :forces,
    :lags,
    :current,
    :sensors,
    :measurement,
    sensor_every: 1,
    steps: 0,
    native: false,
    tau_ext: @zero_tau
  ]

  @typedoc """
  * `params` — the vehicle parameter set; `dyn` — the true state
  * `thrusters` — the command in force (`%{port, vertical, starboard}` in [-1, 1])
  * `targets`, `forces` — each thruster's static target force and actual force (N), in the
    order of `params.thrusters`; `lags` — their per-step `{decay, mean}` factors
  * `tau_ext` — external generalised force added to the thrust (scenario `tau` events)
  * `current` — the water current; `sensors` — sensor state, nil when ideal;
    `measurement` — the last sensor reading (nil when ideal)
  * `dt` — the integration step (s); `steps` — steps since start (t = steps · dt)
  * `native` — whether `step/2` runs the C loop (`Neptunus.Dynamics.Native`)
  * `opts` — the options of `new/1` (with later `set_current/2`, `set_tether_length/2`),
    which `reset/1` starts from again
  """
  @type t :: %__MODULE__{
          params: Params.t(),
          dyn: State.t(),
          thrusters: Allocation.thrusters(),
          dt: float(),
          opts: keyword(),
          targets: [float()] | nil,
          forces: [float()],
          lags: [{float(), float()}],
          current: Current.t(),
          sensors: Sensors.t() | nil,
          measurement: Sensors.measurement() | nil,
          sensor_every: pos_integer(),
          steps: non_neg_integer(),
          native: boolean(),
          tau_ext: Dynamics.tau()
        }

  @default_hz 100

  @doc """
  The default integration rate (Hz) of a simulation, and of the simulators the vehicles
  run (`Board.Simulated`, `Board.OpenROV.SITL.Device`; `config :neptunus, :sim_hz` overrides it).
  """
  @spec default_hz() :: pos_integer()
  def default_hz, do: @default_hz

  @doc """
  The settings of a simulated device fitted to the vehicle (`Neptunus.Sim.DVL`,
  `Neptunus.Sim.USBL`): `overrides` (a keyword or map) over its `defaults`. Raises
  `ArgumentError` naming `device` on a setting it does not have or a `rate` that is not > 0
  (scenarios are validated before, see `Neptunus.Scenario`).

      iex> Neptunus.Sim.device_settings(%{rate: 8.0, noise: 0.1}, [noise: 0.2], "DVL")
      %{rate: 8.0, noise: 0.2}

      iex> Neptunus.Sim.device_settings(%{rate: 8.0}, %{fast: true}, "DVL")
      ** (ArgumentError) unknown DVL setting :fast

      iex> Neptunus.Sim.device_settings(%{rate: 2.0}, [rate: 0], "USBL")
      ** (ArgumentError) USBL rate must be > 0
  """
  @spec device_settings(map(), keyword() | map(), String.t()) :: map()
  def device_settings(defaults, overrides, device) do
    settings =
      Enum.reduce(overrides, defaults, fn {key, value}, acc ->
        if Map.has_key?(defaults, key),
          do: Map.put(acc, key, value),
          else: raise(ArgumentError, "unknown #{device} setting #{inspect(key)}")
      end)

    if settings.rate <= 0, do: raise(ArgumentError, "#{device} rate must be > 0")
    settings
  end

  @doc """
  A new simulation, at rest with the thrusters neutral. Options:

    * `:vehicle` — parameter set name (`"thesis-4dof"`, `"neptunus"`, see
      `Neptunus.Dynamics.Params.available/0`; atoms like `:thesis_4dof` work too) or a
      `Neptunus.Dynamics.Params`; default `"thesis-4dof"`. (`:params` is accepted as an alias.)
    * `:dt` — integration step in s, default `1 / default_hz()` (0.01)
    * `:initial` — keyword or map of `Dynamics.State` fields, default `[z: 1.0]` (1 m deep);
      a 4-DOF set rejects non-zero `phi`, `theta`, `p`, `q`
    * `:current` — water current `{n, e, d}` or `[n, e, d]`, m/s NED, default zero
    * `:current_variation` — keyword/map `sigma` (m/s), `time_constant` (s): slow random
      variation (see `Neptunus.Sim.Current`), default none
    * `:tether_length` — deployed tether (m), default the vehicle file's
    * `:noise` — realistic sensors (noise, bias, wild points, mix-ups), default `false`
    * `:sensors` — overrides of the vehicle's sensor settings: `rate`, `wild_rate`,
      `mixup_rate` and per-channel `%{noise:, bias:}` maps (merged)
    * `:seed` — integer seed of all randomness, default 0
    * `:native` — step with the C loop (`Neptunus.Dynamics.Native`, bit-identical results,
      about ten times faster) when it is loaded; default `false`. `true` falls back to
      Elixir when the library is not available.

  Raises `ArgumentError` on invalid options (scenarios are validated before, see
  `Neptunus.Scenario`).
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    params = opts |> vehicle() |> tether_override(opts[:tether_length])
    dt = Keyword.get(opts, :dt, 1 / @default_hz) * 1.0
    if dt <= 0.0, do: raise(ArgumentError, "dt must be > 0, got #{dt}")
    seed = Keyword.get(opts, :seed, 0)
    dyn = initial(Keyword.get(opts, :initial, z: 1.0), params)

    variation = Keyword.get(opts, :current_variation, []) |> Enum.to_list()

    current =
      Current.new(Keyword.get(opts, :current, {0.0, 0.0, 0.0}), dt, [seed: seed] ++ variation)

    sim = %__MODULE__{
      params: params,
      dyn: dyn,
      dt: dt,
      opts: opts,
      thrusters: Allocation.neutral(),
      forces: Enum.map(params.thrusters, fn _ -> 0.0 end),
      lags: Enum.map(params.thrusters, &Thruster.lag(&1, dt)),
      current: current,
      native: Keyword.get(opts, :native, false) == true and Native.available?()
    }

    sim = command(sim, Allocation.neutral())

    if Keyword.get(opts, :noise, false) do
      config = sensor_config(params.sensors, Keyword.get(opts, :sensors, %{}))
      every = max(1, round(1.0 / (config.rate * dt)))
      sensors = Sensors.new(config, seed)
      {measurement, sensors} = Sensors.measure(sensors, truth(sim))
      %{sim | sensors: sensors, measurement: measurement, sensor_every: every}
    else
      sim
    end
  end

  @doc "Starts again from the options of `new/1` (keeping the current and tether set since)."
  @spec reset(t()) :: t()
  def reset(%__MODULE__{opts: opts}), do: new(opts)

  @doc "Sets the thruster command in force (values in [-1, 1]; missing thrusters are neutral)."
  @spec command(t(), Allocation.thrusters() | %{atom() => float()}) :: t()
  def command(%__MODULE__{params: params} = sim, thrusters) do
    targets = Enum.map(params.thrusters, &Thruster.force(&1, Map.get(thrusters, &1.name, 0.0)))
    %{sim | thrusters: thrusters, targets: targets}
  end

  @doc "Sets an external generalised force `{X, Y, Z, K, M, N}` (N, N·m, body) added to the thrust."
  @spec external_force(t(), Dynamics.tau()) :: t()
  def external_force(sim, {_, _, _, _, _, _} = tau) do
    %{sim | tau_ext: tau |> Tuple.to_list() |> Enum.map(&(&1 * 1.0)) |> List.to_tuple()}
  end

  @doc "Sets the mean water current (NED, m/s)."
  @spec set_current(t(), Current.vector() | [number()]) :: t()
  def set_current(%__MODULE__{} = sim, current) do
    current = Current.set_mean(sim.current, current)
    %{sim | current: current, opts: Keyword.put(sim.opts, :current, current.mean)}
  end

  @doc "Sets the deployed tether length (m, ≥ 0; 0 removes the tether's drag)."
  @spec set_tether_length(t(), number()) :: t()
  def set_tether_length(%__MODULE__{} = sim, length) when is_number(length) and length >= 0 do
    %{
      sim
      | params: Params.with_tether_length(sim.params, length),
        opts: Keyword.put(sim.opts, :tether_length, length)
    }
  end

  @doc "Advances the simulation by `n` steps of `dt`."
  @spec step(t(), pos_integer()) :: t()
  def step(%__MODULE__{} = sim, n \\ 1) when is_integer(n) and n >= 1, do: loop(sim, n)

  # at most this many steps per call of the C loop (≈ 1 ms: a scheduler's timeslice)
  @native_chunk 1_000

  defp loop(sim, 0), do: sim
  defp loop(%__MODULE__{native: true} = sim, n), do: native_loop(sim, n)
  defp loop(sim, n), do: sim |> step_once() |> loop(n - 1)

  # The same steps in C, as many at once as no sensor reading falls due. A varying current
  # is stepped here first, and the C loop gets its value for each step.
  defp native_loop(sim, 0), do: sim

  defp native_loop(%__MODULE__{params: params} = sim, n) do
    chunk = min(n, until_reading(sim))
    {current, currents} = currents(sim.current, chunk)

    case Native.run(
           params.compiled.native,
           State.to_tuple(sim.dyn),
           sim.forces,
           sim.targets,
           sim.lags,
           sim.tau_ext,
           currents,
           sim.dt,
           chunk
         ) do
      {:singular, theta} ->
        Dynamics.singular!(theta)

      {dyn, forces} ->
        steps = sim.steps + chunk
        sim = %{sim | dyn: State.from_tuple(dyn), forces: forces, current: current, steps: steps}
        sim |> read_sensors() |> native_loop(n - chunk)
    end
  end

  # the current after `n` steps, and the current of each step (one value if constant)
  defp currents(%Current{sigma: sigma} = current, _n) when sigma == 0.0,
    do: {current, Current.ned(current)}

  defp currents(current, n) do
    {values, current} =
      Enum.map_reduce(1..n, current, fn _, c ->
        c = Current.step(c)
        {Current.ned(c), c}
      end)

    {current, values}
  end

  defp until_reading(%__MODULE__{sensors: nil}), do: @native_chunk

  defp until_reading(%__MODULE__{steps: steps, sensor_every: every}),
    do: min(every - rem(steps, every), @native_chunk)

  defp step_once(%__MODULE__{params: params, dt: dt} = sim) do
    current = Current.step(sim.current)
    {mean_forces, forces} = lag(sim.targets, sim.forces, sim.lags, [], [])
    tau = mean_forces |> Dynamics.tau_from_forces(params) |> Dynamics.add_tau(sim.tau_ext)
    dyn = sim.dyn |> Dynamics.step(tau, dt, params, Current.ned(current)) |> surface()
    steps = sim.steps + 1
    read_sensors(%{sim | dyn: dyn, forces: forces, current: current, steps: steps})
  end

  defp read_sensors(%__MODULE__{sensors: sensors, steps: steps} = sim) do
    if sensors != nil and rem(steps, sim.sensor_every) == 0 do
      {measurement, sensors} = Sensors.measure(sensors, truth(sim))
      %{sim | sensors: sensors, measurement: measurement}
    else
      sim
    end
  end

  # first-order lag of each thruster's force towards its target, exact over the step
  defp lag([target | ts], [force | fs], [{decay, mean} | ls], means, ends) do
    diff = force - target
    lag(ts, fs, ls, [target + diff * mean | means], [target + diff * decay | ends])
  end

  defp lag([], [], [], means, ends), do: {Enum.reverse(means), Enum.reverse(ends)}

  @doc "Simulated time in s."
  @spec time(t()) :: float()
  def time(%__MODULE__{steps: steps, dt: dt}), do: steps * dt

  @doc """
  What a board would report now (see `Neptunus.Vehicle.Board`): `t`, the `measurement`
  (the last sensor reading, or the true values with ideal sensors) and the true state as
  `sim` (the 12 fields of `Neptunus.Dynamics.State`).
  """
  @spec sample(t()) :: Neptunus.Vehicle.Board.sample()
  def sample(%__MODULE__{dyn: dyn} = sim) do
    %{
      t: time(sim),
      measurement: sim.measurement || truth(sim),
      sim: Map.from_struct(dyn)
    }
  end

  @doc "The true values of the measured channels (what ideal sensors read)."
  @spec truth(t()) :: Sensors.measurement()
  def truth(%__MODULE__{dyn: dyn, thrusters: thr, params: %{power: power}}) do
    load = Enum.reduce(Map.values(Map.take(thr, [:port, :vertical, :starboard])), 0.0, &sum_abs/2)
    current = power.idle + power.per_thruster * load

    %{
      depth: dyn.z,
      heading: Dynamics.heading(dyn),
      roll: dyn.phi,
      pitch: dyn.theta,
      voltage: power.battery - power.resistance * current,
      current: current
    }
  end

  @doc "Each thruster's actual force now (N), by name."
  @spec thrust_forces(t()) :: %{atom() => float()}
  def thrust_forces(%__MODULE__{params: params, forces: forces}) do
    params.thrusters |> Enum.map(& &1.name) |> Enum.zip(forces) |> Map.new()
  end

  @doc "The water current now (NED, m/s), variation included."
  @spec current(t()) :: Current.vector()
  def current(%__MODULE__{current: current}), do: Current.ned(current)

  @doc "Wild points and field mix-ups injected so far by the sensors."
  @spec fault_counts(t()) :: %{wild: non_neg_integer(), mixup: non_neg_integer()}
  def fault_counts(%__MODULE__{sensors: nil}), do: %{wild: 0, mixup: 0}
  def fault_counts(%__MODULE__{sensors: sensors}), do: sensors.counts

  @doc "A summary of the simulation's settings, for status replies."
  @spec status(t()) :: map()
  def status(%__MODULE__{} = sim) do
    {n, e, d} = sim.current.mean

    %{
      vehicle: sim.params.name,
      t: time(sim),
      dt: sim.dt,
      current: [n, e, d],
      tether_length: sim.params.tether.length,
      noise: sim.sensors != nil,
      seed: Keyword.get(sim.opts, :seed, 0)
    }
  end

  defp sum_abs(x, acc) when is_number(x), do: acc + min(abs(x), 1.0)

  defp vehicle(opts) do
    case Keyword.get(opts, :vehicle, Keyword.get(opts, :params, "thesis-4dof")) do
      %Params{} = params ->
        params

      name when is_binary(name) or is_atom(name) ->
        case Params.load_cached(name) do
          {:ok, params} -> params
          {:error, reason} -> raise ArgumentError, reason
        end
    end
  end

  defp tether_override(params, nil), do: params

  defp tether_override(params, length) when is_number(length) and length >= 0,
    do: Params.with_tether_length(params, length)

  defp tether_override(_params, length),
    do: raise(ArgumentError, "tether_length must be a number >= 0, got #{inspect(length)}")

  defp initial(fields, %Params{dof: dof, name: name}) do
    fields = Map.new(fields, fn {k, v} -> {k, v * 1.0} end)

    if dof == 4 do
      for key <- [:phi, :theta, :p, :q], Map.get(fields, key, 0.0) != 0.0 do
        raise ArgumentError,
              "#{name} has roll and pitch fixed at zero: initial #{key} must be 0"
      end
    end

    struct!(State, fields)
  end

  defp sensor_config(config, overrides) do
    Enum.reduce(overrides, config, fn
      {key, value}, acc when key in [:rate, :wild_rate, :mixup_rate] ->
        Map.put(acc, key, value * 1.0)

      {key, %{} = channel}, acc ->
        if Map.has_key?(acc.channels, key) do
          merged = Map.merge(acc.channels[key], Map.new(channel, fn {k, v} -> {k, v * 1.0} end))
          %{acc | channels: Map.put(acc.channels, key, merged)}
        else
          raise ArgumentError, "unknown sensor setting #{inspect(key)}"
        end

      {key, _}, _acc ->
        raise ArgumentError, "unknown sensor setting #{inspect(key)}"
    end)
  end

  defp surface(%State{z: z} = dyn) when z < 0.0, do: %{dyn | z: 0.0, w: max(dyn.w, 0.0)}
  defp surface(dyn), do: dyn
end
