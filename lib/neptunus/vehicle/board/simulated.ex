defmodule Neptunus.Vehicle.Board.Simulated do
  @moduledoc """
  The built-in simulator standing in for a board: steps a `Neptunus.Sim` at `sim_hz`
  (default 100 Hz) on absolute deadlines of the monotonic clock (`Neptunus.Periodic`),
  applies the last thruster command, and reports each tick as a board sample.

  Every tick runs all steps whose deadline has passed, so simulated time keeps pace with the
  wall clock when a timer fires late, at most #{20} at a time; after a longer stall of the VM
  the missing time is skipped and counted in `skipped_steps`, not replayed in a burst.
  """
  use GenServer

  alias Neptunus.{Periodic, Sim}
  alias Neptunus.Vehicle.{Board, Telemetry}

  @behaviour Board

  @max_catch_up 20

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            sim: Neptunus.Sim.t(),
            periodic: Neptunus.Periodic.t(),
            skipped_steps: non_neg_integer()
          }
    @enforce_keys [:id, :sim, :periodic]
    defstruct [:id, :sim, :periodic, skipped_steps: 0]
  end

  @doc """
  Options: `:id` (required), `:hz` (integration rate, default from config `:sim_hz`),
  `:initial` (keyword of `Dynamics.State` fields, see `Neptunus.Sim.new/1`).
  """
  @impl Board
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Board.via(id))
  end

  @doc "Current simulator state (for tests and diagnostics)."
  @spec state(String.t()) :: State.t()
  def state(id), do: GenServer.call(Board.via(id), :state)

  # Callbacks

  @impl true
  def init(opts) do
    hz = Keyword.get(opts, :hz, Application.get_env(:neptunus, :sim_hz, 100))

    state = %State{
      id: Keyword.fetch!(opts, :id),
      sim: Sim.new(Keyword.take(opts, [:initial]) ++ [dt: 1.0 / hz]),
      periodic: Periodic.new(hz)
    }

    Periodic.arm(state.periodic, :tick)
    {:ok, state}
  end

  @impl true
  def handle_cast({:go, thrusters}, state),
    do: {:noreply, %{state | sim: Sim.command(state.sim, thrusters)}}

  @impl true
  def handle_call(:state, _from, state), do: {:reply, state, state}

  @impl true
  def handle_info(:tick, state) do
    {due, periodic} = Periodic.advance(state.periodic, System.monotonic_time())
    steps = min(due, @max_catch_up)
    sim = Sim.step(state.sim, steps)
    Telemetry.sample(state.id, Sim.sample(sim))
    Periodic.arm(periodic, :tick)

    {:noreply,
     %{state | sim: sim, periodic: periodic, skipped_steps: state.skipped_steps + due - steps}}
  end
end
