defmodule NeptunusWeb.API.Recordings do
  @moduledoc """
  The vehicles' recordings, of every node of the fleet (`Neptunus.Recording.Pull`: a
  vehicle's recordings are on its node, and any node lists, exports and deletes them):

    * `GET /api/recordings[?vehicle=id]` → `{"recording": bool, "recordings": [{"vehicle",
      "name", "node", "bytes", "started_at", "modified_at"}]}` (newest first; times in ms)
    * `GET /api/recordings/<vehicle>/<name>[?format=csv|jsonl][&every=N][&max=M]` → every
      N-th telemetry entry as CSV (a download), or every entry as JSON lines with only every
      N-th telemetry entry — or as few as keep at most M telemetry entries (what the
      developer page replays); 404 for an unknown recording. Exports are streamed (chunked):
      the file is read twice (columns and counts, then the rows), never held in memory, so a
      recording of many hours exports on a vehicle computer with little memory.

  Recordings need what watching needs: local mode, a token (any role), or anonymous observers
  allowed; 401 otherwise (`NeptunusWeb.API.Request.may_watch/1`).

    * `DELETE /api/recordings/<vehicle>/<name>` → `{"deleted": {"vehicle", "name"}}`; local
      mode, a pilot or the main station only (403 for observers), 409 for the file being
      recorded now, 404 for an unknown recording.

  A vehicle whose node is cut off is answered 503; a malformed request 400.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Recording.Pull
  alias NeptunusWeb.API.{Request, Response}
  alias NeptunusWeb.Auth

  # each node's recordings directory, read on that node
  @dir {NeptunusWeb.Endpoint.Settings, :recording_dir, []}

  @doc "`GET /api/recordings[?vehicle=id]`: the recordings of every node, or one vehicle's."
  @spec index(tuple()) :: Response.t()
  def index(arg) do
    Request.watching(arg, fn ->
      case Pull.list(Map.get(query(arg), "vehicle"), @dir) do
        {:ok, listing} -> {200, listing}
        error -> Response.refused(error)
      end
    end)
  end

  @doc "`GET /api/recordings/<vehicle>/<name>` (the path's parts after `recordings/`): an export."
  @spec show(tuple(), [String.t()]) :: Response.t()
  def show(arg, parts) do
    Request.watching(arg, fn ->
      with [vehicle, name] <- parts,
           {:ok, plan, lines} <- Pull.export(vehicle, name, query(arg), @dir) do
        export(arg, plan, lines)
      else
        {:error, _, _} = error -> Response.refused(error)
        _parts -> {404, %{error: "no such recording"}}
      end
    end)
  end

  @doc """
  `DELETE /api/recordings/<vehicle>/<name>` (the path's parts after `recordings/`): who may
  pilot may delete (local mode, a pilot or the main station); never the file being written.
  """
  @spec delete(tuple(), [String.t()]) :: Response.t()
  def delete(arg, [vehicle, name]) do
    with :ok <- may_delete(arg),
         :ok <- Pull.delete(vehicle, name, @dir) do
      {200, %{deleted: %{vehicle: vehicle, name: name}}}
    else
      {:error, _, _} = error -> Response.refused(error)
      {status, body} -> {status, body}
    end
  end

  def delete(_arg, _parts), do: {404, %{error: "no such recording"}}

  defp may_delete(arg) do
    case Auth.session(Request.token(arg)) do
      {:ok, %{mode: "local"}} ->
        :ok

      {:ok, %{user: %{role: role}}} when role in ["pilot", "main_station"] ->
        :ok

      {:ok, %{user: %{}}} ->
        {403, %{error: "only a pilot or the main station may delete recordings"}}

      {:ok, _} ->
        {401, %{error: "log in to delete recordings"}}

      {:error, %{error: reason}} ->
        {401, %{error: reason}}
    end
  end

  defp export(arg, %{format: "csv", file: file}, lines) do
    [
      {:status, 200},
      {:header, {:cache_control, ~c"no-store"}},
      {:header,
       {~c"Content-Disposition", String.to_charlist("attachment; filename=\"#{file}.csv\"")}}
      | Response.stream(arg, ~c"text/csv; charset=utf-8", lines, "recording export")
    ]
  end

  defp export(arg, %{format: "jsonl"}, lines) do
    [
      {:status, 200},
      {:header, {:cache_control, ~c"no-store"}}
      | Response.stream(arg, ~c"application/x-ndjson", lines, "recording export")
    ]
  end
end
