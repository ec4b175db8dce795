defmodule NeptunusWeb.API.Snapshots do
  @moduledoc """
  Snapshots of the vehicles' cameras, of every node of the fleet (`Neptunus.Camera.Snapshots`:
  a snapshot is taken and kept on its vehicle's node, next to its recordings). Who may watch
  the vehicle may take one and see them (local mode, any logged-in role, anonymous observers
  when allowed; `NeptunusWeb.API.Request.may_watch/1`); 401 otherwise.

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
  """
  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Camera.Snapshots
  alias NeptunusWeb.API.{Request, Response}

  @doc "Each node's recordings directory, read on that node (where its snapshots are kept)."
  @spec dir() :: Snapshots.dir()
  def dir, do: {NeptunusWeb.Endpoint.Settings, :recording_dir, []}

  @doc "`POST /api/vehicles/<id>/snapshot` (the path's parts after `vehicles/`)."
  @spec create(tuple(), [String.t()]) :: Response.t()
  def create(arg, [id, "snapshot"]) do
    Request.watching(arg, fn ->
      with :ok <- Request.check_origin(arg),
           {:ok, snapshot} <- Snapshots.take(id, dir()) do
        {201, %{snapshot: snapshot}}
      else
        {:error, status, reason} when is_integer(status) -> {status, %{error: reason}}
        error -> Response.refused(error)
      end
    end)
  end

  def create(_arg, parts),
    do: {404, %{error: "no such API endpoint: /api/vehicles/#{Enum.join(parts, "/")}"}}

  @doc "`GET /api/snapshots[?vehicle=<id>]`."
  @spec index(tuple()) :: Response.t()
  def index(arg) do
    Request.watching(arg, fn ->
      case Snapshots.list(Map.get(query(arg), "vehicle"), dir()) do
        {:ok, snapshots} -> {200, %{snapshots: snapshots}}
        error -> Response.refused(error)
      end
    end)
  end

  @doc "`GET /api/snapshots/<vehicle>/<name>` (the path's parts after `snapshots/`): the JPEG."
  @spec show(tuple(), [String.t()]) :: Response.t()
  def show(arg, [vehicle, name]) do
    Request.watching(arg, fn ->
      case Snapshots.read(vehicle, name, dir()) do
        {:ok, jpeg} ->
          [
            {:status, 200},
            {:header, {:cache_control, ~c"private, max-age=3600"}},
            {:header,
             {~c"Content-Disposition", String.to_charlist("inline; filename=\"#{name}\"")}},
            {:content, ~c"image/jpeg", jpeg}
          ]

        error ->
          Response.refused(error)
      end
    end)
  end

  def show(arg, _parts), do: Request.watching(arg, fn -> {404, %{error: "no such snapshot"}} end)
end
