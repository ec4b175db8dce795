defmodule Neptunus.Vehicle.Board do
  @moduledoc """
  The board link of a vehicle: the behaviour every board implements, and the API the rest of
  the vehicle uses to talk to whichever board is configured.

  A board process is registered as `Neptunus.Fleet.via(Neptunus.Vehicle.Board, id)` whatever
  its implementation, and

    * accepts `go/2` (thruster values in [-1, 1], physical sense: positive pushes the vehicle
      forward for port/starboard, down for vertical) and `neutral/1`;
    * sends every sample it reads to the vehicle's telemetry process with
      `Neptunus.Vehicle.Telemetry.sample/2`;
    * drives the thrusters neutral when it (re)starts.

  Implementations: `Neptunus.Vehicle.Board.Simulated` (the built-in simulator). The real UART
  link and the test double arrive with the vehicle-core work.
  """

  alias Neptunus.Allocation

  @typedoc "A board sample: time (s, vehicle clock), measurements, and the simulator's truth if any."
  @type sample :: %{
          t: float(),
          measurement: %{
            depth: float(),
            heading: float(),
            roll: float(),
            pitch: float(),
            voltage: float(),
            current: float()
          },
          sim: map() | nil
        }

  @doc "Starts the board for vehicle `opts[:id]`; must register under `via/1`."
  @callback start_link(opts :: keyword()) :: GenServer.on_start()

  @boards %{simulated: Neptunus.Vehicle.Board.Simulated}

  @doc "The implementation module for a configured board type."
  @spec module(atom()) :: module()
  def module(board), do: Map.fetch!(@boards, board)

  @doc "Registered name of the board process of vehicle `id`."
  @spec via(String.t()) :: GenServer.name()
  def via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  @doc "Commands the thrusters (asynchronous; never blocks the caller)."
  @spec go(String.t(), Allocation.thrusters()) :: :ok
  def go(id, thrusters), do: GenServer.cast(via(id), {:go, thrusters})

  @doc "Drives all thrusters neutral."
  @spec neutral(String.t()) :: :ok
  def neutral(id), do: go(id, Allocation.neutral())
end
