defmodule Neptunus.Camera.Snapshots do
  @moduledoc """
  The snapshots of a whole fleet, from any of its nodes. A snapshot is taken and kept on its
  vehicle's node, next to that node's recordings (`Neptunus.Camera.Snapshot`); this module
  takes one there, lists every node's and reads one from its node, so that any node can serve
  them (the HTTP API, `NeptunusWeb.API.Snapshots`, and the vehicle channel's `snapshot` are
  the edges that call it).

    * `take/2` — the camera's current picture saved on the vehicle's node;
    * `list/2` — every node's snapshots (one `:erpc` call per node, at once; a node that
      fails or does not answer within 5 s is left out), or one vehicle's, from its node;
      newest first;
    * `read/3` — one snapshot's JPEG, read on its vehicle's node.

  Each node keeps its recordings (and so its snapshots) in its own directory: the caller says
  where with `dir`, as for `Neptunus.Recording.Pull` — `{module, function, args}`, applied on
  each node, giving the directory or nil when recording is off there.

  Errors are `{:error, kind, reason}` with a reason a person can read and the kind of
  refusal, which the edge turns into its own status.
  """
  alias Neptunus.Camera.Snapshot
  alias Neptunus.Fleet

  @typedoc "Where a node keeps its recordings (see `Neptunus.Recording.Pull`)."
  @type dir :: Neptunus.Recording.Pull.dir()

  @typedoc """
  Why a request is refused: `:invalid` (malformed), `:not_found` (no such vehicle, camera or
  snapshot), `:conflict` (no picture now, or recording off on the vehicle's node),
  `:unreachable` (the vehicle's node is cut off), `:failed` (decoding or saving failed).
  """
  @type error ::
          {:error, :invalid | :not_found | :conflict | :unreachable | :failed, String.t()}

  @doc """
  Takes a snapshot of vehicle `id`'s camera on the vehicle's node: the snapshot as listed
  (`Neptunus.Camera.Snapshot.t/0` with its `url` and `node`).
  """
  @spec take(String.t(), dir()) :: {:ok, map()} | error()
  def take(id, dir) do
    if Fleet.exists?(id) do
      Fleet.on_vehicle_node(
        id,
        __MODULE__,
        :take_here,
        [id, dir],
        {:error, :unreachable, "vehicle unreachable: #{id}"}
      )
    else
      {:error, :not_found, "unknown vehicle: #{id}"}
    end
  end

  @doc false
  # On the vehicle's node.
  @spec take_here(String.t(), dir()) :: {:ok, map()} | error()
  def take_here(id, {m, f, a}) do
    with {:dir, dir} when is_binary(dir) <- {:dir, apply(m, f, a)},
         {:camera, true} <- {:camera, Neptunus.Vehicle.Camera.configured?(id)},
         {:ok, snapshot} <- Snapshot.take(id, dir) do
      {:ok, present(snapshot)}
    else
      {:dir, nil} ->
        {:error, :conflict,
         "recording is off on this server: snapshots are saved with the recordings (NEPTUNUS_RECORDINGS)"}

      {:camera, false} ->
        {:error, :not_found, "vehicle #{id} has no camera"}

      {:error, "the camera is" <> _ = reason} ->
        {:error, :conflict, reason}

      {:error, "no keyframe" <> _ = reason} ->
        {:error, :conflict, reason}

      {:error, reason} ->
        {:error, :failed, reason}
    end
  end

  @doc "Every node's snapshots, or vehicle `vehicle`'s (from its node); newest first."
  @spec list(String.t() | nil, dir()) :: {:ok, [map()]} | error()
  def list(vehicle, dir) do
    if vehicle != nil and not Regex.match?(~r/\A[A-Za-z0-9_-]{1,32}\z/, vehicle) do
      {:error, :invalid, "vehicle must be a vehicle id"}
    else
      nodes = Fleet.nodes_of(vehicle)

      snapshots =
        nodes
        |> :erpc.multicall(__MODULE__, :list_here, [vehicle, dir], 5_000)
        |> Enum.flat_map(fn
          {:ok, list} -> list
          _ -> []
        end)
        |> Enum.sort_by(& &1.taken_at, :desc)

      {:ok, snapshots}
    end
  end

  @doc false
  # This node's snapshots (of one vehicle, or all).
  @spec list_here(String.t() | nil, dir()) :: [map()]
  def list_here(vehicle, {m, f, a}) do
    case apply(m, f, a) do
      nil -> []
      dir -> dir |> Snapshot.list(vehicle) |> Enum.map(&present/1)
    end
  end

  @doc "The JPEG of snapshot `name` of vehicle `vehicle`, read on the vehicle's node."
  @spec read(String.t(), String.t(), dir()) :: {:ok, binary()} | error()
  def read(vehicle, name, dir) do
    if Snapshot.valid?(vehicle, name) do
      Fleet.on_vehicle_node(
        vehicle,
        __MODULE__,
        :read_here,
        [vehicle, name, dir],
        {:error, :unreachable, "vehicle unreachable: #{vehicle}"}
      )
    else
      {:error, :not_found, "no such snapshot"}
    end
  end

  @doc false
  # On the vehicle's node: the snapshot's bytes.
  @spec read_here(String.t(), String.t(), dir()) :: {:ok, binary()} | error()
  def read_here(vehicle, name, {m, f, a}) do
    with dir when is_binary(dir) <- apply(m, f, a),
         path when is_binary(path) <- Snapshot.find(dir, vehicle, name),
         {:ok, jpeg} <- File.read(path) do
      {:ok, jpeg}
    else
      _ -> {:error, :not_found, "no such snapshot: #{vehicle}/#{name}"}
    end
  end

  defp present(snapshot) do
    snapshot
    |> Map.put(
      :url,
      "/api/snapshots/#{URI.encode(snapshot.vehicle)}/#{URI.encode(snapshot.name)}"
    )
    |> Map.put(:node, Atom.to_string(node()))
  end
end
