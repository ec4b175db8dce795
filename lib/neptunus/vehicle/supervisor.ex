defmodule Neptunus.Vehicle.Supervisor do
  @moduledoc """
  One vehicle's process tree, registered in the fleet registry as
  `{Neptunus.Vehicle.Supervisor, id}` with the board type as value. `:rest_for_one` over

    * the control chain (`Neptunus.Vehicle.Supervisor.Control`, its own `:rest_for_one`
      supervisor), which moves the vehicle:

        1. the board link (`Neptunus.Vehicle.Board` implementation),
        2. `Neptunus.Vehicle.Navigation` (board samples → wild-point filter, Kalman estimate →
           telemetry and control; only casts, so it never waits on what starts after it),
        3. `Neptunus.Vehicle.Telemetry` (latest state, telemetry broadcast),
        4. `Neptunus.Vehicle.Control` (commands → allocation → board; neutral on start),
        5. `Neptunus.Vehicle.Helm` (who is in control; authorises every command, deadman;
           neutral on start);
    * `Neptunus.Vehicle.Position` (the position sources: DVL, USBL drivers, the simulated
      ones; they report to navigation),
    * `Neptunus.Vehicle.Recorder` (everything on the vehicle's topic to disk),
    * `Neptunus.Vehicle.Camera` (the camera program and its frames).

  The position sources, the recorder and the camera come after the control chain, so their
  failures restart nothing that moves the vehicle; and they are outside it, so a crash in the chain neither
  restarts them nor waits for them: a supervisor stops the children after the crashed one
  before it restarts any, and the recorder's last sync or the camera program's stop (tens
  of ms on a busy machine, up to their shutdown timeout when stuck) would otherwise come
  before Control starts again at neutral.

  A crash in the chain restarts the crashed process and everything after it in the chain, so
  every crash there ends with the thrusters neutral: a crash of the board, navigation,
  telemetry or control restarts Control (neutral on start) and the Helm (which forgets the
  pilot); a crash of the Helm alone restarts it, and it stops the vehicle through Control as
  it starts. The Helm comes after Control because it calls Control (never the other way
  round) and must not outlive a Control that forgot the pilot's commands.
  """
  use Supervisor

  alias Neptunus.Vehicle.{Board, Camera, Control, Helm, Navigation, Position, Recorder, Telemetry}

  @intensity [max_restarts: 10, max_seconds: 10]

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
    # what the vehicle can do, for everyone (Board.capabilities/1), before anything starts
    :ok = Board.register_capabilities(id, Board.capabilities(board, opts))

    chain = [
      {Board.module(board), opts},
      {Navigation, opts},
      {Telemetry, opts},
      {Control, opts},
      {Helm, opts}
    ]

    control = %{
      id: __MODULE__.Control,
      start: {Supervisor, :start_link, [chain, @intensity ++ [strategy: :rest_for_one]]},
      type: :supervisor
    }

    children = [control, {Position, opts}, {Recorder, opts}, {Camera, opts}]
    Supervisor.init(children, [strategy: :rest_for_one] ++ @intensity)
  end
end
