defmodule Neptunus.Vehicle.Supervisor do
  @moduledoc """
  One vehicle's process tree, `:rest_for_one`, registered in the fleet registry as
  `{Neptunus.Vehicle.Supervisor, id}` with the board type as value:

    1. the board link (`Neptunus.Vehicle.Board` implementation),
    2. `Neptunus.Vehicle.Navigation` (board samples → wild-point filter, Kalman estimate →
       telemetry and control; only casts, so it never waits on what starts after it),
    3. `Neptunus.Vehicle.Telemetry` (latest state, telemetry broadcast),
    4. `Neptunus.Vehicle.Control` (commands → allocation → board; neutral on start),
    5. `Neptunus.Vehicle.Helm` (who is in control; authorises every command, deadman;
       neutral on start),
    6. `Neptunus.Vehicle.Recorder` (everything on the vehicle's topic to disk),
    7. `Neptunus.Vehicle.Camera` (the camera program and its frames).

  The recorder and the camera come last, so their failures restart nothing that moves
  the vehicle.

  A crash restarts the crashed process and everything after it, so every crash ends with the
  thrusters neutral: a crash of the board, navigation, telemetry or control restarts Control
  (neutral on start) and the Helm (which forgets the pilot); a crash of the Helm alone
  restarts it, and it stops the vehicle through Control as it starts. The Helm comes after Control because it
  calls Control (never the other way round) and must not outlive a Control that forgot the
  pilot's commands.
  """
  use Supervisor

  alias Neptunus.Vehicle.{Board, Camera, Control, Helm, Navigation, Recorder, Telemetry}

  @spec start_link(Neptunus.Config.Vehicles.vehicle()) :: Supervisor.on_start()
  def start_link(%{id: id, board: board} = vehicle) do
    name = {:via, Registry, {Neptunus.Fleet.Registry, {__MODULE__, id}, board}}
    Supervisor.start_link(__MODULE__, vehicle, name: name)
  end

  @spec child_spec(Neptunus.Config.Vehicles.vehicle()) :: Supervisor.child_spec()
  def child_spec(%{id: id} = vehicle) do
    %{id: {__MODULE__, id}, start: {__MODULE__, :start_link, [vehicle]}, type: :supervisor}
  end

  @impl true
  def init(%{id: id, board: board} = vehicle) do
    opts = [id: id] ++ Map.to_list(Map.drop(vehicle, [:id, :board]))

    children = [
      {Board.module(board), opts},
      {Navigation, opts},
      {Telemetry, opts},
      {Control, opts},
      {Helm, opts},
      {Recorder, opts},
      {Camera, opts}
    ]

    Supervisor.init(children, strategy: :rest_for_one, max_restarts: 10, max_seconds: 10)
  end
end
