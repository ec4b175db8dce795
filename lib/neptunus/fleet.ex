defmodule Neptunus.Fleet do
  @moduledoc """
  The vehicles of this node, and the directory of the cluster's.

  This node's vehicles: a `Registry` for their processes and a `DynamicSupervisor` with one
  `Neptunus.Vehicle.Supervisor` per vehicle. Vehicle processes are named
  `{:via, Registry, {Neptunus.Fleet.Registry, {module, id}}}`, see `via/2`.

  The cluster's: every vehicle's helm joins the group `{:vehicle, id, board}` of the
  fleet's own `:pg` scope (`publish/1`), which spans the connected nodes; each node's
  `Neptunus.Fleet.Directory` follows it and remembers the vehicles of a node that went
  away as unreachable. `locate/1` finds a vehicle's node and helm anywhere in the cluster
  (a remote helm is called like a local one, `GenServer.call` works across nodes);
  `directory/0` lists every vehicle with its node, board, helm state, pilot and link.
  Vehicle ids are unique across the fleet (a node's own vehicle wins over a remote one of
  the same id).

  `:rest_for_one`, in order: the scope (a crash empties it: everything after restarts and
  joins again, the vehicles neutral), the registry, the vehicles, then the directory, the
  overview's feed (`Neptunus.Fleet.Overview`) and the camera relays
  (`NeptunusWeb.CameraRelay`, in the registry too): a crash of these restarts nothing that
  moves a vehicle.
  """
  use Supervisor

  alias Neptunus.Fleet.Directory
  alias Neptunus.Vehicle

  @registry Neptunus.Fleet.Registry
  @vehicles Neptunus.Fleet.Vehicles
  @scope Neptunus.Fleet.Scope

  @type vehicle_id :: String.t()

  @spec start_link([Neptunus.Config.Vehicles.vehicle()]) :: Supervisor.on_start()
  def start_link(vehicles), do: Supervisor.start_link(__MODULE__, vehicles, name: __MODULE__)

  @doc """
  The `:via` name of a vehicle's process `module` (or `{module, name}` where a vehicle has
  several of a kind: its position sources).
  """
  @spec via(module() | {module(), atom()}, vehicle_id()) ::
          {:via, Registry, {module(), {module() | {module(), atom()}, vehicle_id()}}}
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
  @spec local?(vehicle_id()) :: boolean()
  def local?(id), do: whereis(Vehicle.Supervisor, id) != nil

  @doc "Whether a vehicle with this id runs on this node or on a reachable node of the cluster."
  @spec exists?(vehicle_id()) :: boolean()
  def exists?(id), do: local?(id) or match?({:ok, _, _}, locate(id))

  @doc """
  Where vehicle `id` runs: `{:ok, node, helm_pid}`, `{:error, :unreachable}` (its node was
  seen and is cut off) or `{:error, :not_found}`.
  """
  @spec locate(vehicle_id()) :: {:ok, node(), pid()} | {:error, :unreachable | :not_found}
  def locate(id) do
    case Directory.lookup(id) do
      %{status: :up, node: node, pid: pid} -> {:ok, node, pid}
      %{status: :unreachable} -> {:error, :unreachable}
      nil -> {:error, :not_found}
    end
  end

  @doc """
  Publishes the calling process (a vehicle's helm, on the vehicle's node) as vehicle `id`
  in the cluster's directory, until it exits.
  """
  @spec publish(vehicle_id()) :: :ok
  def publish(id) do
    board =
      case Registry.lookup(@registry, {Vehicle.Supervisor, id}) do
        [{_pid, board}] -> board
        [] -> :unknown
      end

    :pg.join(@scope, {:vehicle, id, board}, self())
  end

  @typedoc """
  A vehicle of the cluster: `status` `"up"` or `"unreachable"` (its node is cut off: then
  the rest is nil, `recording` false); `helm` the helm's state, `pilot` the pilot's name,
  `link` the board link `%{up, reason}` (nil before the first telemetry), `depth` (m) and
  `heading` (rad) measured, `recording` whether its recorder records (a fleet overview).
  """
  @type entry :: %{
          id: vehicle_id(),
          board: atom(),
          node: String.t(),
          status: String.t(),
          helm: String.t() | nil,
          pilot: String.t() | nil,
          link: map() | nil,
          depth: float() | nil,
          heading: float() | nil,
          recording: boolean()
        }

  @doc """
  Every vehicle of the cluster, sorted by id (one `:erpc` call per other node hosting
  vehicles; a node that does not answer within 2 s has its vehicles shown unreachable).
  """
  @spec directory() :: [entry()]
  def directory do
    entries = Directory.entries()

    remote = for %{status: :up, node: node} <- entries, node != node(), uniq: true, do: node

    details =
      remote
      |> :erpc.multicall(__MODULE__, :local_details, [], 2_000)
      |> Enum.zip(remote)
      |> Enum.reduce(local_details(), fn
        {{:ok, details}, _node}, acc -> Map.merge(acc, details)
        {_failed, _node}, acc -> acc
      end)

    Enum.map(entries, fn entry ->
      detail = Map.get(details, entry.id)

      base = %{
        id: entry.id,
        board: entry.board,
        node: Atom.to_string(entry.node),
        status: "unreachable",
        helm: nil,
        pilot: nil,
        link: nil,
        depth: nil,
        heading: nil,
        recording: false
      }

      if entry.status == :up and detail != nil,
        do: Map.merge(base, Map.put(detail, :status, "up")),
        else: base
    end)
  end

  @doc """
  Runs `module.fun(args)` on vehicle `id`'s node (here when it runs here, or is not known
  anywhere: then the call decides); `default` when its node is cut off or does not answer
  within 5 s. For reads of a vehicle's processes from any node (camera, recorder).
  """
  @spec on_vehicle_node(vehicle_id(), module(), atom(), list(), term()) :: term()
  def on_vehicle_node(id, module, fun, args, default) do
    case vehicle_node(id) do
      {:ok, node} when node == node() -> apply(module, fun, args)
      {:ok, node} -> :erpc.call(node, module, fun, args, 5_000)
      {:error, :unreachable} -> default
    end
  catch
    :error, {:erpc, _} -> default
    :exit, {:timeout, _} -> default
  end

  @doc """
  The node of vehicle `id`: `{:ok, node}` (this node for a vehicle known nowhere, whose
  leftovers, e.g. recordings, would be here) or `{:error, :unreachable}`.
  """
  @spec vehicle_node(vehicle_id()) :: {:ok, node()} | {:error, :unreachable}
  def vehicle_node(id) do
    cond do
      local?(id) ->
        {:ok, node()}

      true ->
        case locate(id) do
          {:ok, node, _helm} -> {:ok, node}
          {:error, :unreachable} -> {:error, :unreachable}
          {:error, :not_found} -> {:ok, node()}
        end
    end
  end

  @doc "This node and every reachable node hosting vehicles (for cluster-wide reads)."
  @spec nodes() :: [node()]
  def nodes do
    remote = for %{status: :up, node: node} <- Directory.entries(), node != node(), do: node
    Enum.uniq([node() | remote])
  end

  @doc """
  The nodes to read what is kept of vehicle `id` from (its recordings, its snapshots): its
  node, none while it is unreachable; for `nil`, every node (`nodes/0`).
  """
  @spec nodes_of(vehicle_id() | nil) :: [node()]
  def nodes_of(nil), do: nodes()

  def nodes_of(id) do
    case vehicle_node(id) do
      {:ok, node} -> [node]
      {:error, :unreachable} -> []
    end
  end

  @doc false
  # This node's vehicles' helm state, pilot and link (called by directory/0 on every node).
  @spec local_details() :: %{optional(vehicle_id()) => map()}
  def local_details do
    for %{id: id} <- list(), into: %{} do
      {helm, pilot} = helm_detail(id)
      {id, Map.merge(%{helm: helm, pilot: pilot}, telemetry_detail(id))}
    end
  end

  defp helm_detail(id) do
    case Vehicle.Helm.status(id) do
      %{state: state, pilot: %{name: name}} -> {state, name}
      %{state: state} -> {state, nil}
    end
  catch
    :exit, _ -> {nil, nil}
  end

  # the link, depth (m), heading (rad) and whether it records, from the latest telemetry
  defp telemetry_detail(id) do
    latest = Vehicle.Telemetry.latest(id) || %{}
    measurement = Map.get(latest, :measurement) || %{}

    %{
      link: latest |> Map.get(:link) |> then(&(&1 && Map.take(&1, [:up, :reason]))),
      depth: Map.get(measurement, :depth),
      heading: Map.get(measurement, :heading),
      recording: match?(%{recording: %{on: true}}, latest)
    }
  catch
    :exit, _ -> %{link: nil, depth: nil, heading: nil, recording: false}
  end

  @impl true
  def init(vehicles) do
    children = [
      %{id: @scope, start: {:pg, :start_link, [@scope]}},
      {Registry, keys: :unique, name: @registry},
      {DynamicSupervisor, strategy: :one_for_one, name: @vehicles},
      %{id: :configured, start: {__MODULE__, :start_configured, [vehicles]}, restart: :transient},
      {Directory, @scope},
      Neptunus.Fleet.Overview,
      # one relay per camera of another node that this node's viewers watch
      {DynamicSupervisor, strategy: :one_for_one, name: Neptunus.Fleet.Relays}
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
