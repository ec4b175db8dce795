defmodule Neptunus.Vehicle.Control do
  @moduledoc """
  A vehicle's control: control modes (motion, manual, DP), gain, lights, laser, camera tilt,
  run mode (normal ↔ simulator), the depth and heading autopilots and DP, and the thruster
  commands to the board. Every decision is `Neptunus.Control.Core`'s (pure; the same core runs
  headless in `mix neptunus.simulate`); this process validates commands
  (`Neptunus.Control.Command`), carries out the core's actions, and runs the control loop.

  A validated command the board's vehicle cannot fly (`Neptunus.Vehicle.Board.vet/2`, e.g.
  manual per-thruster mode on an ArduSub vehicle) is refused with the board's reason.

  What the vehicle can do comes from its board (`Neptunus.Vehicle.Board.capabilities/1`): the
  axes the pilot may command (a thrust in another is refused), whether the three-thruster
  allocation is ours (the board gets thruster values) or the vehicle's (it gets the body-frame
  demand, `Neptunus.Control.Core.output/1`), and whether run mode simulator exists (a real
  vehicle).

  It decides nothing about *who* may command: `Neptunus.Vehicle.Helm` authorises every
  command and is the only caller of `thrust/2`, `command/3` and `stop/2` (tests aside).

  * **Estimates** come from `Neptunus.Vehicle.Navigation` (`estimate/2`, a cast, on every
    sample and on a board reset): `%{t, depth, depth_rate, heading, yaw_rate, position,
    measurement_state}`. Autopilots and DP act on the latest; one older than a second counts
    as none, an axis whose measurement is initialising or stale cannot be engaged (the reply
    says why) and an engaged one gives zero output until it is valid (see
    `Neptunus.Control.Core`). Such changes are told to the pilot: telemetry's
    `autopilot.depth.waiting` / `heading.waiting`, and a `log` entry (category `autopilot`)
    on `"log:<id>"`.
  * **Control loop**: while an autopilot or DP is engaged it runs at `control: [hz: …]` (default
    #{50} Hz) on absolute deadlines of the monotonic clock (`Neptunus.Periodic`): each tick
    steps the PIDs by the time elapsed and commands the board when the output changes.
  * **Run mode `simulator`** (vehicles with a real board): the thrusters stop, and a
    `Neptunus.Vehicle.Board.Simulated` is started beside the real board, seeded with the
    current estimated depth and heading. Commands, lights, laser and tilt go to it, and its
    samples — not the real board's — go to navigation (`Neptunus.Vehicle.Board.sample/3`), so
    telemetry, estimates and autopilots follow the simulated vehicle. The real board is kept
    neutral and its deadman fed (`Board.keepalive/1` goes on). Back to `normal`: thrusters
    stop, the simulator is stopped, the real board's samples count again. The simulator is
    linked to this process: if either dies, the vehicle restarts in run mode normal.

  Safety: it drives the thrusters neutral when it starts, so a restart after any crash in the
  vehicle's tree leaves the thrusters neutral. Every stop is broadcast with its reason:
  `stopped` `%{reason: reason}` on `"vehicle:<id>"`, and a `safety` entry on `"log:<id>"`.
  """
  use GenServer

  require Logger

  alias Neptunus.{Fleet, Periodic, PID, PubSub, Settings}
  alias Neptunus.Control.{Autopilot, Command, Core, Tuning}
  alias Neptunus.Vehicle.{Board, Navigation, Telemetry}

  @default_gain 0.5
  @default_hz 50
  @max_catch_up 5
  # how often control tells the board it is alive (Board.keepalive/1: deadman pings)
  @board_keepalive_ms 1_000
  # the vehicle setting that keeps its autopilot tuning (Neptunus.Settings)
  @tuning_key "tuning"

  @type reply :: {:ok, map()} | {:error, String.t()}

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            core: Neptunus.Control.Core.t(),
            periodic: Neptunus.Periodic.t(),
            simulator: pid() | nil,
            simulator_opts: keyword(),
            lateral?: boolean()
          }
    @enforce_keys [:id, :topic, :core, :periodic]
    defstruct [:id, :topic, :core, :periodic, :simulator, simulator_opts: [], lateral?: false]
  end

  @doc """
  Options: `:id` (required), `:gain` (k in [0, 1], default #{@default_gain}), `:control` —
  keyword of `hz` (control loop rate, default #{@default_hz}),
  `gains`, `stale_after`, `deadband`, `dp`, `reference` (see `Neptunus.Control.Core.new/1`) and
  `simulator` (options of the run-mode simulator, `Board.Simulated.start_link/1`).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :id)))
  end

  @doc """
  Thrust command: `params` is the untrusted JSON object `%{"mode" => "motion", "surge",
  "heave", "yaw"}` or `%{"mode" => "manual", "port", "vertical", "starboard"}`, values in
  [-1, 1]; the mode must be the control mode.

  Replies `{:ok, %{command, thrusters, control}}` or `{:error, reason}` (nothing changed).
  """
  @spec thrust(String.t(), map()) :: reply()
  def thrust(id, params), do: GenServer.call(via(id), {:command, "thrust", params})

  @doc """
  A control command other than thrust — `set_control_mode`, `set_gain`, `set_lights`,
  `set_laser`, `set_tilt`, `autopilot`, `set_run_mode` (`events/0`) — with its untrusted JSON
  payload (`Neptunus.Control.Command`). Replies `{:ok, %{control: status}}` with the new
  control state (`status/1`) or `{:error, reason}` (nothing changed).
  """
  @spec command(String.t(), String.t(), term()) :: reply()
  def command(id, event, payload), do: GenServer.call(via(id), {:command, event, payload})

  @doc """
  New PID gains for the depth and/or heading autopilot: `payload` is the untrusted tuning
  (`Neptunus.Control.Tuning`: `%{"depth" => %{"kp", "ki", "kd"}, "heading" => …}`), applied
  at once and bumpless (`Neptunus.Control.Core.retune/2`), then stored for the vehicle
  (`Neptunus.Settings`, scope `{:vehicle, id}`, key `"tuning"`) so it applies at the next
  start too. Who may tune is the caller's business (the vehicle channel: the pilot or the
  main station). The change is logged (a `log` entry of category `autopilot` on
  `"log:<id>"`, so recordings keep it). Replies `{:ok, %{tuning: %{"depth" => …, "heading" =>
  …}}}` (the gains in force) or `{:error, reason}` (nothing changed; a failed store is reported after the gains
  were applied: `{:error, "tuning applied but not stored: …"}`).
  """
  @spec tune(String.t(), term()) :: reply()
  def tune(id, payload) do
    with {:ok, gains} <- Tuning.validate(payload),
         {:ok, json} <- GenServer.call(via(id), {:tune, gains}) do
      case Settings.put({:vehicle, id}, @tuning_key, json) do
        :ok -> {:ok, %{tuning: json}}
        {:error, reason} -> {:error, "tuning applied but not stored: #{reason}"}
      end
    end
  end

  @doc """
  The tuning in force: `%{gains, defaults, ranges, model}` — `gains` and `defaults` as
  `Neptunus.Control.Tuning.to_json/1`, `ranges` `%{"kp" => [min, max], …}`, `model` the
  vehicle's simulator parameter set (the step response runs on it).
  """
  @spec tuning(String.t()) :: map()
  def tuning(id) do
    %{gains: gains, model: model} = GenServer.call(via(id), :tuning)

    %{
      gains: Tuning.to_json(gains),
      defaults: Tuning.to_json(Core.default_gains()),
      ranges: Map.new(Tuning.ranges(), fn {k, {lo, hi}} -> {k, [lo, hi]} end),
      model: model
    }
  end

  @doc """
  The limits of the depth and heading references (`Neptunus.Control.Reference`), as
  configured: `%{depth: %{rate, accel}, heading: %{rate, accel}}` (m/s and m/s², rad/s and
  rad/s²).
  """
  @spec limits(String.t()) :: %{depth: map(), heading: map()}
  def limits(id) do
    %{reference: reference} = GenServer.call(via(id), :tuning)
    Map.new(reference, fn {axis, kw} -> {axis, Map.new(kw)} end)
  end

  @doc """
  The step response of the untrusted request `payload` (`Neptunus.Control.Tuning.validate_step/1`:
  `%{"axis", "step", "gains"?}`) on the vehicle's simulator model with the gains in force
  and the proposed ones over them — run headless in the caller's process, the vehicle's
  control untouched. Replies `{:ok, curve}` (`Neptunus.Control.Tuning.step_response/4`) or
  `{:error, reason}`.
  """
  @spec step_response(String.t(), term()) :: reply()
  def step_response(id, payload) do
    with {:ok, axis, step, gains} <- Tuning.validate_step(payload) do
      %{gains: current, model: model, reference: reference} = GenServer.call(via(id), :tuning)
      control = [gains: Tuning.merge(current, gains), reference: reference]
      Tuning.step_response(model, axis, step, control)
    end
  end

  @doc "The events `command/3` takes."
  @spec events() :: [String.t()]
  def events, do: List.delete(Command.events(), "thrust")

  @doc """
  Drives the thrusters neutral and broadcasts `stopped` with `reason` (shown to everyone
  watching); see `Neptunus.Control.Core` for what it does to the autopilots (a handover keeps
  them, any other stop disengages them). Replies `{:ok, %{command, thrusters, control}}`.
  """
  @spec stop(String.t(), String.t()) :: {:ok, map()}
  def stop(id, reason), do: GenServer.call(via(id), {:stop, reason})

  @doc """
  Control state — what a new pilot picks up (`Vehicle.Helm` sends it with every grant):
  `%{mode, gain, lights, laser, tilt, run_mode, autopilot: %{depth, heading, position},
  command, thrusters}` (`Neptunus.Control.Core.status/1`).
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(via(id), :status)

  @doc """
  The latest navigation estimate (asynchronous; from `Neptunus.Vehicle.Navigation`):
  `%{t, depth, depth_rate, heading, yaw_rate, position: %{x, y} | nil, measurement_state:
  %{depth, heading}}`, SI, heading in [0, 2π), depth/heading nil while not estimated,
  states `:initialising | :valid | :stale`.
  """
  @spec estimate(String.t(), map()) :: :ok
  def estimate(id, estimate), do: GenServer.cast(via(id), {:estimate, estimate})

  @doc """
  Where vehicle `id`'s samples come from now: `:board`, or `:simulator` while in run mode
  simulator (see `Neptunus.Vehicle.Board.sample/3`). `:board` when control is not running.
  """
  @spec sample_source(String.t()) :: :board | :simulator
  def sample_source(id) do
    case Registry.lookup(Fleet.Registry, {__MODULE__, id}) do
      [{_pid, :simulator}] -> :simulator
      _ -> :board
    end
  end

  @doc "The mission in dp with its waypoints (`Neptunus.Control.Core.mission/1`), or nil."
  @spec mission(String.t()) :: map() | nil
  def mission(id), do: GenServer.call(via(id), :mission)

  @doc """
  The vehicle's axes changed (asynchronous; its board declared them,
  `Neptunus.Vehicle.Board.declare_axes/2`): thrust in an axis it no longer has is refused,
  one in force is dropped (`Neptunus.Control.Core.set_axes/2`), and telemetry's `axes` follow.
  """
  @spec axes(String.t(), [Neptunus.Control.Demand.axis()]) :: :ok
  def axes(id, axes) when is_list(axes), do: GenServer.cast(via(id), {:axes, axes})

  @doc "The run-mode simulator's pid, or nil (for tests and diagnostics)."
  @spec simulator(String.t()) :: pid() | nil
  def simulator(id), do: GenServer.call(via(id), :simulator)

  defp via(id), do: Fleet.via(__MODULE__, id)

  # the run-mode simulator flies the vehicle's own parameter set (`sim: [vehicle: …]`, from
  # NEPTUNUS_MODELS) at the vehicle's `sim_hz` unless `control: [simulator: …]` says otherwise
  defp simulator_opts(opts, control) do
    model = opts |> Keyword.get(:sim, []) |> Keyword.take([:vehicle])
    simulator = Keyword.merge(Keyword.take(opts, [:sim_hz]), Keyword.get(control, :simulator, []))
    Keyword.put(simulator, :sim, Keyword.merge(model, Keyword.get(simulator, :sim, [])))
  end

  # Callbacks

  @impl true
  def init(opts) do
    # the control path runs before the web fan-out (see Neptunus.Vehicle.Helm)
    Process.flag(:priority, :high)
    id = Keyword.fetch!(opts, :id)
    control = Keyword.get(opts, :control, [])
    hz = Keyword.get(control, :hz, @default_hz)

    # what the vehicle can do (its board's declaration); a control started on its own, outside
    # a vehicle, drives the three-thruster vehicle
    capabilities = Board.capabilities(id) || %{Board.thesis_capabilities() | real: false}
    run_modes = if capabilities.real, do: [:normal, :simulator], else: [:normal]

    # a vehicle that sways with our allocation has a lateral thruster (a simulated
    # neptunus-sway): it gets the demand's sway, the others the three-thruster allocation
    lateral? = capabilities.allocation == :thesis and :sway in capabilities.axes

    core =
      control
      |> Keyword.take([:gains, :stale_after, :deadband, :dp, :reference, :mission])
      |> Keyword.put(
        :actuation,
        if(:sway in capabilities.axes, do: :full, else: :surge)
      )
      |> Keyword.update(:gains, stored_gains(id), &Tuning.merge(Map.new(&1), stored_gains(id)))
      |> Keyword.merge(gain: Keyword.get(opts, :gain, @default_gain), run_modes: run_modes)
      |> Keyword.merge(axes: capabilities.axes, allocation: capabilities.allocation)
      |> Core.new()

    state = %State{
      id: id,
      topic: Telemetry.topic(id),
      core: core,
      lateral?: lateral?,
      periodic: Periodic.new(hz),
      simulator_opts: simulator_opts(opts, control)
    }

    send(self(), :board_keepalive)
    Periodic.arm(state.periodic, :tick)
    {:ok, state, {:continue, :neutral}}
  end

  @impl true
  def handle_continue(:neutral, state) do
    Board.go(state.id, Core.neutral(state.core))
    {:noreply, publish(state)}
  end

  @impl true
  def handle_call({:command, event, payload}, _from, state) do
    with {:ok, command} <- Command.validate(event, payload),
         :ok <- Board.vet(state.id, command),
         {:ok, core, actions} <- Core.command(state.core, command, now_s()) do
      state = state |> Map.put(:core, core) |> perform(actions) |> publish()
      {:reply, {:ok, planned(reply(event, state), command)}, state}
    else
      {:error, reason} -> {:reply, {:error, reason}, state}
    end
  end

  def handle_call({:stop, reason}, _from, state) do
    {core, actions} = Core.stop(state.core, reason)
    state = %{state | core: core} |> perform(actions) |> publish()
    {:reply, {:ok, reply("thrust", state)}, state}
  end

  def handle_call({:tune, gains}, _from, state) do
    state = %{state | core: Core.retune(state.core, gains)} |> publish()
    json = Tuning.to_json(state.core.gains)
    autopilot_log(state, "info", "autopilot tuning: " <> Tuning.describe(json))
    {:reply, {:ok, json}, state}
  end

  def handle_call(:tuning, _from, %State{core: core} = state) do
    model = state.simulator_opts |> Keyword.get(:sim, []) |> Keyword.get(:vehicle, "neptunus")

    reference = %{
      depth: reference_limits(core.depth),
      heading: reference_limits(core.heading)
    }

    {:reply, %{gains: core.gains, model: to_string(model), reference: reference}, state}
  end

  def handle_call(:status, _from, state), do: {:reply, Core.status(state.core), state}
  def handle_call(:mission, _from, state), do: {:reply, Core.mission(state.core), state}
  def handle_call(:simulator, _from, state), do: {:reply, state.simulator, state}

  @impl true
  def handle_cast({:axes, axes}, state) do
    {core, actions} = Core.set_axes(state.core, axes)
    {:noreply, %{state | core: core} |> perform(actions) |> publish()}
  end

  def handle_cast({:estimate, estimate}, state),
    do: {:noreply, %{state | core: Core.estimate(state.core, estimate, now_s())}}

  # The board feeds its deadman (ping) only while this keeps coming: if control dies or hangs,
  # the board's own deadman stops the motors (Board.keepalive/1). It goes on in run mode
  # simulator: the real board is kept neutral and alive.
  @impl true
  def handle_info(:board_keepalive, state) do
    Board.keepalive(state.id)
    Process.send_after(self(), :board_keepalive, @board_keepalive_ms)
    {:noreply, state}
  end

  def handle_info(:tick, state) do
    {due, periodic} = Periodic.advance(state.periodic, Neptunus.Clock.monotonic_native())
    Periodic.arm(periodic, :tick)
    state = %{state | periodic: periodic}

    if Core.active?(state.core) do
      # after a stall of the VM the loop runs once over at most @max_catch_up periods, so
      # the integrators do not take one huge step
      periods = min(due, @max_catch_up)
      dt = periods * System.convert_time_unit(periodic.period, :native, :microsecond) / 1.0e6
      {core, actions} = Core.tick(state.core, dt, now_s())
      {:noreply, %{state | core: core} |> perform(actions) |> publish()}
    else
      {:noreply, state}
    end
  end

  # --- actions -----------------------------------------------------------------------------

  defp perform(state, actions), do: Enum.reduce(actions, state, &act/2)

  # an autopilot entry for the developer page's logger (and the recording), and the node's log
  defp autopilot_log(state, level, text) do
    Telemetry.log(state.id, "autopilot", level, text)
    Logger.info("vehicle #{state.id}: #{text}")
  end

  # thruster values or the demand, as the board's allocation says (Control.Core.output/1);
  # a simulated vehicle with a lateral thruster also gets the demand's sway
  defp act({:go, output}, %State{simulator: nil} = state) do
    Board.go(state.id, with_lateral(output, state))
    state
  end

  defp act({:go, thrusters}, %State{simulator: sim} = state) do
    # navigation's model follows the vehicle it estimates: the simulated one
    Navigation.command(state.id, thrusters)
    GenServer.cast(sim, {:go, thrusters})
    state
  end

  defp act({:stopped, reason}, state) do
    PubSub.broadcast(state.topic, "stopped", %{reason: reason})

    PubSub.broadcast(Telemetry.log_topic(state.id), "log", %{
      category: "safety",
      level: "warning",
      message: "stopped: #{reason}",
      reason: reason,
      at: Neptunus.Clock.wall_ms()
    })

    Logger.info("vehicle #{state.id} stopped: #{Neptunus.Log.safe(reason)}")
    state
  end

  defp act({:mission, mission}, state) do
    PubSub.broadcast(state.topic, "mission", %{mission: mission})
    state
  end

  defp act({:notice, text}, state) do
    autopilot_log(state, "warning", text)
    state
  end

  defp act({kind, value}, state) when kind in [:lights, :laser, :tilt] do
    case state.simulator do
      nil -> apply(Board, kind, [state.id, value])
      sim -> GenServer.cast(sim, {kind, value})
    end

    state
  end

  defp act({:run_mode, :simulator, seed}, %State{simulator: nil} = state) do
    opts =
      [vehicle: "neptunus", noise: true, seed: :erlang.unique_integer([:positive])]
      |> Keyword.merge(Keyword.get(state.simulator_opts, :sim, []))

    initial =
      case seed do
        %{depth: depth, heading: heading} -> [z: max(depth, 0.0), psi: PID.wrap_pi(heading)]
        nil -> [z: 0.0]
      end

    {:ok, sim} =
      Board.Simulated.start_link(
        [
          id: state.id,
          name: Fleet.via(Board.Simulated, state.id),
          source: :simulator,
          initial: initial,
          sim: opts
        ] ++ Keyword.take(state.simulator_opts, [:sim_hz])
      )

    set_source(state.id, :simulator)
    Board.neutral(state.id)
    Logger.info("vehicle #{state.id}: run mode simulator (seeded #{inspect(initial)})")
    %{state | simulator: sim}
  end

  defp act({:run_mode, :normal, _seed}, %State{simulator: sim} = state) when is_pid(sim) do
    set_source(state.id, :board)
    GenServer.stop(sim, :normal)
    Board.neutral(state.id)
    Logger.info("vehicle #{state.id}: run mode normal")
    %{state | simulator: nil}
  end

  defp act({:run_mode, _mode, _seed}, state), do: state

  defp reference_limits(%Autopilot{reference: r}), do: [rate: r.max_rate, accel: r.max_accel]

  # the tuning stored for this vehicle (Control.tune/2), validated again: a bad or missing one
  # is no tuning (the defaults, or the configured gains, apply)
  defp stored_gains(id) do
    with {:ok, json} <- Settings.get({:vehicle, id}, @tuning_key),
         {:ok, gains} <- Tuning.validate(json) do
      gains
    else
      _ -> %{}
    end
  catch
    :exit, _ -> %{}
  end

  # the sample source is the value of this process' registration (Board.sample/3 reads it)
  defp set_source(id, source) do
    {_, _} = Registry.update_value(Fleet.Registry, {__MODULE__, id}, fn _ -> source end)
    :ok
  end

  defp publish(%State{core: core} = state) do
    Telemetry.control(state.id, %{
      axes: Core.axes(core),
      command: core.pilot,
      thrusters: core.thrusters,
      control: Core.control(core),
      autopilot: Core.autopilot(core)
    })

    state
  end

  defp reply("thrust", %State{core: core}) do
    status = Core.status(core)

    %{
      command: status.command,
      thrusters: status.thrusters,
      control: status
    }
  end

  defp reply("mission", %State{core: core}),
    do: %{control: Core.status(core), mission: Core.mission(core)}

  defp reply(_event, %State{core: core}), do: %{control: Core.status(core)}

  # a mission's `plan` answers the waypoints it would fly
  defp planned(reply, {:mission, {:plan, waypoints}}), do: Map.put(reply, :waypoints, waypoints)
  defp planned(reply, _command), do: reply

  defp with_lateral(thrusters, %State{lateral?: true, core: core}),
    do: Map.put(thrusters, :lateral, Core.demand(core).sway)

  defp with_lateral(thrusters, _state), do: thrusters

  # Control.Core runs on seconds (it also runs on a scenario's simulated time)
  defp now_s, do: Neptunus.Clock.monotonic_ms() / 1000
end
