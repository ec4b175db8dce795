defmodule Neptunus.Fleet do
  @moduledoc """
  The vehicles of this node: a `Registry` for their processes and a `DynamicSupervisor` with
  one `Neptunus.Vehicle.Supervisor` per vehicle, under `:rest_for_one` (the registry first).

  Vehicle processes are named `{:via, Registry, {Neptunus.Fleet.Registry, {module, id}}}`,
  see `via/2`.
  """
  use Supervisor

  alias Neptunus.Vehicle

  @registry Neptunus.Fleet.Registry
  @vehicles Neptunus.Fleet.Vehicles

  @type vehicle_id :: String.t()

  @spec start_link([Neptunus.Config.Vehicles.vehicle()]) :: Supervisor.on_start()
  def start_link(vehicles), do: Supervisor.start_link(__MODULE__, vehicles, name: __MODULE__)

  @doc "The `:via` name of a vehicle's process `module`."
  @spec via(module(), vehicle_id()) :: {:via, Registry, {module(), {module(), vehicle_id()}}}
  def via(module, id), do: {:via, Registry, {@registry, {module, id}}}

  @doc "Pid of a vehicle's process, or nil."
  @spec whereis(module(), vehicle_id()) :: pid() | nil
  def whereis(module, id) do
    case Registry.lookup(@registry, {module, id}) do
      [{pid, _}] -> pid
      [] -> nil
    end
  end

  @doc "Starts a vehicle under the fleet."
  @spec start_vehicle(Neptunus.Config.Vehicles.vehicle()) :: DynamicSupervisor.on_start_child()
  def start_vehicle(%{id: _, board: _} = vehicle) do
    DynamicSupervisor.start_child(@vehicles, {Vehicle.Supervisor, vehicle})
  end

  @doc "Stops a vehicle (thrusters are driven neutral as its processes shut down)."
  @spec stop_vehicle(vehicle_id()) :: :ok | {:error, :not_found}
  def stop_vehicle(id) do
    case whereis(Vehicle.Supervisor, id) do
      nil -> {:error, :not_found}
      pid -> DynamicSupervisor.terminate_child(@vehicles, pid)
    end
  end

  @doc "The configured vehicles running on this node, sorted by id."
  @spec list() :: [%{id: vehicle_id(), board: atom()}]
  def list do
    @registry
    |> Registry.select([{{{Vehicle.Supervisor, :"$1"}, :_, :"$2"}, [], [{{:"$1", :"$2"}}]}])
    |> Enum.map(fn {id, board} -> %{id: id, board: board} end)
    |> Enum.sort_by(& &1.id)
  end

  @doc "Whether a vehicle with this id runs on this node."
  @spec exists?(vehicle_id()) :: boolean()
  def exists?(id), do: whereis(Vehicle.Supervisor, id) != nil

  @impl true
  def init(vehicles) do
    children = [
      {Registry, keys: :unique, name: @registry},
      {DynamicSupervisor, strategy: :one_for_one, name: @vehicles},
      %{id: :configured, start: {__MODULE__, :start_configured, [vehicles]}, restart: :transient}
    ]

    Supervisor.init(children, strategy: :rest_for_one)
  end

  @doc false
  # Starts the configured vehicles synchronously (so they exist before the endpoint opens)
  # and again whenever the DynamicSupervisor restarts (rest_for_one).
  @spec start_configured([Neptunus.Config.Vehicles.vehicle()]) :: :ignore
  def start_configured(vehicles) do
    Enum.each(vehicles, fn vehicle -> {:ok, _} = start_vehicle(vehicle) end)
    :ignore
  end
end
