defmodule Neptunus.Vehicle.Supervisor do
  @moduledoc """
  One vehicle's process tree, `:rest_for_one`, registered in the fleet registry as
  `{Neptunus.Vehicle.Supervisor, id}` with the board type as value:

    1. the board link (`Neptunus.Vehicle.Board` implementation),
    2. `Neptunus.Vehicle.Telemetry` (latest state, telemetry broadcast),
    3. `Neptunus.Vehicle.Control` (commands → allocation → board; neutral on start).

  A crash restarts the crashed process and everything after it, so Control always restarts
  and drives the thrusters neutral.
  """
  use Supervisor

  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  @spec start_link(Neptunus.Config.vehicle()) :: Supervisor.on_start()
  def start_link(%{id: id, board: board} = vehicle) do
    name = {:via, Registry, {Neptunus.Fleet.Registry, {__MODULE__, id}, board}}
    Supervisor.start_link(__MODULE__, vehicle, name: name)
  end

  @spec child_spec(Neptunus.Config.vehicle()) :: Supervisor.child_spec()
  def child_spec(%{id: id} = vehicle) do
    %{id: {__MODULE__, id}, start: {__MODULE__, :start_link, [vehicle]}, type: :supervisor}
  end

  @impl true
  def init(%{id: id, board: board} = vehicle) do
    opts = [id: id] ++ Map.to_list(Map.drop(vehicle, [:id, :board]))

    children = [
      {Board.module(board), opts},
      {Telemetry, opts},
      {Control, opts}
    ]

    Supervisor.init(children, strategy: :rest_for_one, max_restarts: 10, max_seconds: 10)
  end
end
