defmodule NeptunusWeb.SnapshotAPI do
  @moduledoc """
  Snapshots over HTTP (routed from `NeptunusWeb.API`), and the work behind the vehicle
  channel's `snapshot` command. A snapshot is the camera's current picture saved as a JPEG
  next to the vehicle's recordings (`Neptunus.Camera.Snapshot`); who may watch the vehicle
  may take one and see them (local mode, any logged-in role, anonymous observers when
  allowed; `NeptunusWeb.API.may_watch/1`).

    * `POST /api/vehicles/<id>/snapshot` → `201 {"snapshot": {"vehicle", "name", "bytes",
      "taken_at", "depth", "heading", "width", "height", "url", "node"}}`; 404 for an unknown
      vehicle or one without camera, 409 when the camera has no picture now or recording is
      off on the vehicle's node (snapshots are saved with the recordings), 403 for a request
      from another site's page (`Origin`), 503 when the vehicle's node is cut off, 500 when
      the picture cannot be decoded or saved.
    * `GET /api/snapshots[?vehicle=<id>]` → `{"snapshots": [snapshot…]}`, every node's (one
      vehicle's: its node's), newest first.
    * `GET /api/snapshots/<vehicle>/<name>` → the JPEG (`image/jpeg`), read on the vehicle's
      node; 404 for an unknown snapshot.

  The work runs on the vehicle's node (its camera and its recordings are there), in the
  request's process or, for the channel, in a process of its own.
  """
  import NeptunusWeb.Yaws

  alias Neptunus.Camera.Snapshot
  alias Neptunus.Fleet
  alias NeptunusWeb.{API, Auth, Settings}

  @doc false
  # routes from NeptunusWeb.API: {status, body} or a yaws response
  @spec route(atom(), String.t(), tuple()) :: term()
  def route(:POST, "/api/vehicles/" <> rest, arg) do
    with [id, "snapshot"] <- String.split(rest, "/"),
         :ok <- watch(arg),
         :ok <- same_site(arg) do
      case take(id) do
        {:ok, snapshot} -> {201, %{snapshot: snapshot}}
        {:error, status, reason} -> {status, %{error: reason}}
      end
    else
      {status, body} -> {status, body}
      _ -> {404, %{error: "no such API endpoint: /api/vehicles/#{rest}"}}
    end
  end

  def route(:GET, "/api/snapshots", arg) do
    with :ok <- watch(arg), do: list(Map.get(query(arg), "vehicle"))
  end

  def route(:GET, "/api/snapshots/" <> rest, arg) do
    with :ok <- watch(arg) do
      case String.split(rest, "/") do
        [vehicle, name] -> file(vehicle, name)
        _ -> {404, %{error: "no such snapshot"}}
      end
    end
  end

  def route(_method, "/api/vehicles/" <> _, _arg),
    do: {405, %{error: "method not allowed: use POST"}}

  def route(_method, _path, _arg), do: {405, %{error: "method not allowed: use GET"}}

  defp watch(arg) do
    case API.may_watch(arg) do
      :ok -> :ok
      {:error, reason} -> {401, %{error: reason}}
    end
  end

  defp same_site(arg) do
    headers = arg(arg, :headers)

    case Auth.check_origin(
           header(headers, "origin"),
           text(headers(headers, :host)),
           Auth.config().origins
         ) do
      :ok -> :ok
      {:error, status, reason} -> {status, %{error: reason}}
    end
  end

  @doc """
  Takes a snapshot of vehicle `id`'s camera (the API's `POST`, the channel's `snapshot`):
  `{:ok, snapshot}` (as the API answers it) or `{:error, status, reason}`.
  """
  @spec take(String.t()) :: {:ok, map()} | {:error, pos_integer(), String.t()}
  def take(id) do
    cond do
      not Fleet.exists?(id) ->
        {:error, 404, "unknown vehicle: #{id}"}

      true ->
        Fleet.on_vehicle_node(
          id,
          __MODULE__,
          :take_local,
          [id],
          {:error, 503, "vehicle unreachable: #{id}"}
        )
    end
  end

  @doc false
  # On the vehicle's node.
  @spec take_local(String.t()) :: {:ok, map()} | {:error, pos_integer(), String.t()}
  def take_local(id) do
    with {:dir, dir} when is_binary(dir) <- {:dir, Settings.get().recording_dir},
         {:camera, true} <- {:camera, Neptunus.Vehicle.Camera.configured?(id)},
         {:ok, snapshot} <- Snapshot.take(id, dir) do
      {:ok, present(snapshot)}
    else
      {:dir, nil} ->
        {:error, 409,
         "recording is off on this server: snapshots are saved with the recordings (NEPTUNUS_RECORDINGS)"}

      {:camera, false} ->
        {:error, 404, "vehicle #{id} has no camera"}

      {:error, "the camera is" <> _ = reason} ->
        {:error, 409, reason}

      {:error, "no keyframe" <> _ = reason} ->
        {:error, 409, reason}

      {:error, reason} ->
        {:error, 500, reason}
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

  defp list(vehicle) do
    if vehicle != nil and not Regex.match?(~r/\A[A-Za-z0-9_-]{1,32}\z/, vehicle) do
      {400, %{error: "vehicle must be a vehicle id"}}
    else
      nodes =
        case vehicle && Fleet.vehicle_node(vehicle) do
          nil -> Fleet.nodes()
          {:ok, node} -> [node]
          {:error, :unreachable} -> []
        end

      snapshots =
        nodes
        |> :erpc.multicall(__MODULE__, :local_list, [vehicle], 5_000)
        |> Enum.flat_map(fn
          {:ok, list} -> list
          _ -> []
        end)
        |> Enum.sort_by(& &1.taken_at, :desc)

      {200, %{snapshots: snapshots}}
    end
  end

  @doc false
  # This node's snapshots (of one vehicle, or all).
  @spec local_list(String.t() | nil) :: [map()]
  def local_list(vehicle) do
    case Settings.get().recording_dir do
      nil -> []
      dir -> dir |> Snapshot.list(vehicle) |> Enum.map(&present/1)
    end
  end

  defp file(vehicle, name) do
    with true <- Snapshot.valid?(vehicle, name) || {404, %{error: "no such snapshot"}},
         {:ok, jpeg} <-
           Fleet.on_vehicle_node(
             vehicle,
             __MODULE__,
             :read_local,
             [vehicle, name],
             {503, %{error: "vehicle unreachable: #{vehicle}"}}
           ) do
      [
        {:status, 200},
        {:header, {:cache_control, ~c"private, max-age=3600"}},
        {:header, {~c"Content-Disposition", String.to_charlist("inline; filename=\"#{name}\"")}},
        {:content, ~c"image/jpeg", jpeg}
      ]
    end
  end

  @doc false
  # On the vehicle's node: the snapshot's bytes.
  @spec read_local(String.t(), String.t()) :: {:ok, binary()} | {pos_integer(), map()}
  def read_local(vehicle, name) do
    with dir when is_binary(dir) <- Settings.get().recording_dir,
         true <- Snapshot.valid?(vehicle, name),
         {:ok, jpeg} <- File.read(Path.join(Snapshot.folder(dir, vehicle), name)) do
      {:ok, jpeg}
    else
      _ -> {404, %{error: "no such snapshot: #{vehicle}/#{name}"}}
    end
  end
end
