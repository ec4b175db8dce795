defmodule Neptunus.Vehicle.Board.Simulated do
  @moduledoc """
  The built-in simulator standing in for a board: steps a `Neptunus.Sim` at `sim_hz`
  (default 100 Hz) on absolute deadlines of the monotonic clock (`Neptunus.Periodic`),
  applies the last thruster command, and reports each tick as a board sample.

  By default it simulates the `neptunus` parameter set (6 DOF, thruster dynamics, tether)
  with realistic sensors (noise, bias, wild points, field mix-ups) from a random seed; the
  `:sim` option overrides any `Neptunus.Sim.new/1` option.

  Every tick runs all steps whose deadline has passed, so simulated time keeps pace with the
  wall clock when a timer fires late, at most #{20} at a time; after a longer stall of the VM
  the missing time is skipped and counted in `skipped_steps`, not replayed in a burst.

  While paused (`command/2` `{:set, %{paused: true}}`) ticks keep coming but the simulation
  does not step: the last sample is reported again, with the same `t`.

  With `stats: true` each tick records its lateness — wall-clock time of the tick minus the
  deadline it was scheduled for, in µs — and how long the tick's work took (`stats/1`).

  Lights, laser and camera tilt (`Board.lights/2`, `laser/2`, `tilt/2`) are recorded and
  reported in every sample as `board: %{lights, laser, tilt}`. Each tick also publishes the
  true pose and these devices for the simulated camera (`Neptunus.Camera.Pose`).

  `Neptunus.Vehicle.Control` also starts one beside a real board for run mode simulator:
  options `name:` (instead of `Board.via(id)`) and `source: :simulator` (its samples go
  through `Board.sample/3` as the simulator's).
  """
  use GenServer

  alias Neptunus.{Periodic, Sim}
  alias Neptunus.Camera.Pose
  alias Neptunus.Vehicle.Board

  @behaviour Board

  @max_catch_up 20
  @max_stats 100_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            sim: Neptunus.Sim.t(),
            periodic: Neptunus.Periodic.t(),
            paused: boolean(),
            skipped_steps: non_neg_integer(),
            source: :board | :simulator,
            devices: %{lights: 0..255, laser: 0..255, tilt: float()},
            stats: nil | %{lateness: [integer()], work: [integer()], count: non_neg_integer()}
          }
    @enforce_keys [:id, :sim, :periodic]
    defstruct [
      :id,
      :sim,
      :periodic,
      :stats,
      paused: false,
      skipped_steps: 0,
      source: :board,
      devices: %{lights: 0, laser: 0, tilt: 0.0}
    ]
  end

  @typedoc "A command from `Neptunus.Sim.Live` (validated there)."
  @type command :: :reset | {:set, %{optional(:paused | :current | :tether_length) => term()}}

  @doc """
  Options: `:id` (required), `:sim_hz` (integration rate, default `Neptunus.Sim.default_hz/0`),
  `:initial` (keyword of `Dynamics.State` fields), `:sim` (keyword of `Neptunus.Sim.new/1`
  options; defaults `vehicle: "neptunus"`, `noise: true`, a random `seed`), `:stats`
  (record tick lateness, default false), `:name` (default `Board.via(id)`), `:source`
  (`:board`, or `:simulator` for the run-mode simulator).
  """
  @impl Board
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Keyword.get(opts, :name, Board.via(id)))
  end

  @doc """
  The built-in simulator flies the three-thruster vehicle (surge, heave, yaw) with our
  allocation; a parameter set with a lateral thruster (`neptunus-sway`, `sim: [vehicle: …]`)
  sways too: its lateral thruster gets the demand's sway (`Neptunus.Vehicle.Control`).

      iex> Neptunus.Vehicle.Board.Simulated.capabilities([]).axes
      [:surge, :heave, :yaw]
      iex> Neptunus.Vehicle.Board.Simulated.capabilities(sim: [vehicle: "neptunus-sway"]).axes
      [:surge, :sway, :heave, :yaw]
  """
  @impl Board
  @spec capabilities(keyword()) :: Board.capabilities()
  def capabilities(opts) do
    capabilities = %{Board.thesis_capabilities() | real: false}

    if lateral?(opts),
      do: %{capabilities | axes: [:surge, :sway, :heave, :yaw]},
      else: capabilities
  end

  @doc "The simulator's camera and position sources: its vehicle lives in `Neptunus.Sim`."
  @impl Board
  @spec settings() :: [Board.setting()]
  def settings, do: [:sim_sources]

  # whether the simulated parameter set has a lateral thruster
  defp lateral?(opts) do
    sim = Keyword.get(opts, :sim, [])
    model = if Keyword.keyword?(sim), do: Keyword.get(sim, :vehicle, "neptunus"), else: "neptunus"

    case Neptunus.Dynamics.Params.load_cached(to_string(model)) do
      {:ok, params} -> Enum.any?(params.thrusters, &(&1.name == :lateral))
      {:error, _} -> false
    end
  end

  @impl Board
  @spec go(String.t(), Neptunus.Allocation.thrusters()) :: :ok
  def go(id, thrusters), do: GenServer.cast(Board.via(id), {:go, thrusters})

  @impl Board
  @spec lights(String.t(), 0..255) :: :ok
  def lights(id, n), do: GenServer.cast(Board.via(id), {:lights, n})

  @impl Board
  @spec laser(String.t(), 0..255) :: :ok
  def laser(id, n), do: GenServer.cast(Board.via(id), {:laser, n})

  @impl Board
  @spec tilt(String.t(), float()) :: :ok
  def tilt(id, rad), do: GenServer.cast(Board.via(id), {:tilt, rad})

  @doc "Current simulator state (for tests and diagnostics)."
  @spec state(String.t()) :: State.t()
  def state(id), do: GenServer.call(Board.via(id), :state)

  @doc """
  Resets the simulation (`:reset`) or changes it (`{:set, changes}`: `paused` boolean,
  `current` `{n, e, d}` m/s NED, `tether_length` m). Replies with `Neptunus.Sim.status/1`
  plus `paused`. Callers go through `Neptunus.Sim.Live`, which validates and authorises.
  """
  @spec command(String.t(), command()) :: {:ok, map()}
  def command(id, command), do: GenServer.call(Board.via(id), {:sim, command})

  @doc """
  Tick statistics since start (or since the last call with `reset: true`): `lateness` and
  `work` in µs, most recent first, at most #{@max_stats}; nil unless started with
  `stats: true`.
  """
  @spec stats(String.t(), keyword()) :: nil | %{lateness: [integer()], work: [integer()]}
  def stats(id, opts \\ []), do: GenServer.call(Board.via(id), {:stats, opts})

  # Callbacks

  @impl true
  def init(opts) do
    hz = Keyword.get(opts, :sim_hz, Sim.default_hz())

    sim_opts =
      [vehicle: "neptunus", noise: true, seed: :erlang.unique_integer([:positive])]
      |> Keyword.merge(Keyword.take(opts, [:initial]))
      |> Keyword.merge(Keyword.get(opts, :sim, []))
      |> Keyword.put(:dt, 1.0 / hz)

    state = %State{
      id: Keyword.fetch!(opts, :id),
      sim: Sim.new(sim_opts),
      periodic: Periodic.new(hz),
      source: Keyword.get(opts, :source, :board),
      stats: if(Keyword.get(opts, :stats, false), do: %{lateness: [], work: [], count: 0})
    }

    Periodic.arm(state.periodic, :tick)
    {:ok, state}
  end

  @impl true
  def handle_cast({:go, thrusters}, state),
    do: {:noreply, %{state | sim: Sim.command(state.sim, thrusters)}}

  def handle_cast({device, value}, state) when device in [:lights, :laser, :tilt],
    do: {:noreply, %{state | devices: Map.put(state.devices, device, value)}}

  @impl true
  def handle_call(:state, _from, state), do: {:reply, state, state}

  def handle_call({:sim, :reset}, _from, state) do
    # the thruster command survives a reset: Control decides thrust, not the simulator
    sim = state.sim |> Sim.reset() |> Sim.command(state.sim.thrusters)
    state = %{state | sim: sim}
    report(state, sim)
    {:reply, {:ok, status(state)}, state}
  end

  def handle_call({:sim, {:set, changes}}, _from, state) do
    state =
      Enum.reduce(changes, state, fn
        {:paused, paused}, state -> %{state | paused: paused}
        {:current, current}, state -> %{state | sim: Sim.set_current(state.sim, current)}
        {:tether_length, l}, state -> %{state | sim: Sim.set_tether_length(state.sim, l)}
      end)

    {:reply, {:ok, status(state)}, state}
  end

  def handle_call({:stats, _opts}, _from, %State{stats: nil} = state),
    do: {:reply, nil, state}

  def handle_call({:stats, opts}, _from, %State{stats: stats} = state) do
    reply = Map.take(stats, [:lateness, :work])

    if Keyword.get(opts, :reset, false),
      do: {:reply, reply, %{state | stats: %{lateness: [], work: [], count: 0}}},
      else: {:reply, reply, state}
  end

  @impl true
  def handle_info(:tick, state) do
    now_native = Neptunus.Clock.monotonic_native()
    deadline_native = state.periodic.next
    {due, periodic} = Periodic.advance(state.periodic, now_native)
    steps = min(due, @max_catch_up)
    sim = if state.paused, do: state.sim, else: Sim.step(state.sim, steps)
    report(state, sim)
    Periodic.arm(periodic, :tick)

    state = %{
      state
      | sim: sim,
        periodic: periodic,
        skipped_steps: state.skipped_steps + due - steps
    }

    {:noreply, record(state, now_native, deadline_native)}
  end

  defp report(state, sim) do
    Board.sample(state.id, Map.put(Sim.sample(sim), :board, state.devices), state.source)
    # for the simulated camera, if one renders this vehicle (nothing built when none does)
    Pose.publish(state.id, sim.dyn, state.devices)
  end

  defp record(%State{stats: nil} = state, _now_native, _deadline_native), do: state

  defp record(%State{stats: %{count: count} = stats} = state, now_native, deadline_native)
       when count < @max_stats do
    late = System.convert_time_unit(now_native - deadline_native, :native, :microsecond)

    work =
      System.convert_time_unit(
        Neptunus.Clock.monotonic_native() - now_native,
        :native,
        :microsecond
      )

    %{
      state
      | stats: %{lateness: [late | stats.lateness], work: [work | stats.work], count: count + 1}
    }
  end

  defp record(state, _now, _deadline), do: state

  defp status(state), do: Map.put(Sim.status(state.sim), :paused, state.paused)
end
