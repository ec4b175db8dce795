defmodule Neptunus.Vehicle.Board.Simulated do
  @moduledoc """
  The built-in simulator standing in for a board: integrates `Neptunus.Dynamics` at
  `sim_hz` (default 100 Hz) on absolute deadlines of the monotonic clock, applies the last
  thruster command, and reports each tick as a board sample.

  Scheduling: every tick runs all steps whose deadline has passed (so simulated time keeps
  pace with the wall clock even when a timer fires late), at most `#{20}` at a time; if the
  VM stalled longer than that, the missing time is skipped and counted in `skipped_steps`
  instead of being replayed in a burst.

  Not part of the 4-DOF model, applied here: the water surface (the vehicle cannot rise
  above z = 0; upward speed is cancelled there) and a simple power model for the
  voltage/current measurements (12.6 V battery with 0.25 Ω internal resistance, 0.3 A idle,
  2 A per thruster at full command).
  """
  use GenServer

  alias Neptunus.{Allocation, Dynamics, Periodic}
  alias Neptunus.Vehicle.{Board, Telemetry}

  @behaviour Board

  @max_catch_up 20

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            params: Dynamics.Params.t(),
            dyn: Dynamics.State.t(),
            thrusters: Allocation.thrusters(),
            dt: float(),
            periodic: Periodic.t(),
            steps: non_neg_integer(),
            skipped_steps: non_neg_integer()
          }
    @enforce_keys [:id, :params, :dyn, :thrusters, :dt, :periodic]
    defstruct [:id, :params, :dyn, :thrusters, :dt, :periodic, steps: 0, skipped_steps: 0]
  end

  @doc """
  Options: `:id` (required), `:hz` (integration rate, default from config `:sim_hz`),
  `:initial` (keyword of `Dynamics.State` fields, default depth 1 m at rest).
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
      params: Dynamics.params(:thesis_4dof),
      dyn: struct(Dynamics.State, Keyword.get(opts, :initial, z: 1.0)),
      thrusters: Allocation.neutral(),
      dt: 1.0 / hz,
      periodic: Periodic.new(hz)
    }

    Periodic.arm(state.periodic, :tick)
    {:ok, state}
  end

  @impl true
  def handle_cast({:go, thrusters}, state), do: {:noreply, %{state | thrusters: thrusters}}

  @impl true
  def handle_call(:state, _from, state), do: {:reply, state, state}

  @impl true
  def handle_info(:tick, state) do
    {due, periodic} = Periodic.advance(state.periodic, System.monotonic_time())
    steps = min(due, @max_catch_up)
    tau = Dynamics.tau_from_thrusters(state.thrusters, state.params)

    dyn =
      Enum.reduce(1..steps, state.dyn, fn _, dyn ->
        dyn |> Dynamics.step(tau, state.dt, state.params) |> surface()
      end)

    state = %{
      state
      | dyn: dyn,
        steps: state.steps + steps,
        skipped_steps: state.skipped_steps + (due - steps),
        periodic: periodic
    }

    Telemetry.sample(state.id, sample(state))
    Periodic.arm(periodic, :tick)
    {:noreply, state}
  end

  # The hull floats at the surface instead of flying: clamp z at 0 and stop rising there.
  defp surface(%Dynamics.State{z: z} = dyn) when z < 0.0, do: %{dyn | z: 0.0, w: max(dyn.w, 0.0)}
  defp surface(dyn), do: dyn

  defp sample(%State{dyn: dyn, thrusters: thr} = state) do
    current = 0.3 + 2.0 * (abs(thr.port) + abs(thr.vertical) + abs(thr.starboard))

    %{
      t: state.steps * state.dt,
      measurement: %{
        depth: dyn.z,
        heading: Dynamics.heading(dyn),
        roll: dyn.phi,
        pitch: dyn.theta,
        voltage: 12.6 - 0.25 * current,
        current: current
      },
      sim: Map.from_struct(dyn)
    }
  end
end
