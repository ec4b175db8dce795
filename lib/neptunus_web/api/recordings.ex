defmodule NeptunusWeb.API.Recordings do
  @moduledoc """
  The vehicles' dives (recordings), of every node of the fleet (`Neptunus.Recording.Pull`: a
  vehicle's dives are on its node, and any node lists, reads, exports, annotates and deletes
  them; `Neptunus.Dive` for what a dive holds):

    * `GET /api/recordings[?vehicle=id]` → `{"recording": bool, "recordings": [dive…]}`,
      newest first; a dive is `{"vehicle", "name", "node", "legacy", "recording", "bytes",
      "started_at", "ended_at", "duration_ms", "modified_at", "max_depth", "pilots", "stops",
      "snapshots", "entries", "telemetry", "closed", "interrupted", "video", "title",
      "notes", "problems"}` (times in ms since the epoch; `video` `{codec, segments, bytes}`
      or null);
    * `GET /api/recordings/<vehicle>/<name>/summary` → the dive as listed, with `segments`:
      its video's segments (`{n, codec, width, height, fps, generation, avc, first_us,
      last_us, frames, keyframes}`), for a replay;
    * `GET /api/recordings/<vehicle>/<name>/video?from=MS&to=MS` → the frames to show the
      video from `from` to `to` (at most 120 s), from the keyframe before `from`: each a
      4-byte big-endian length and the frame as the video WebSocket sends it (28-byte header,
      then the H.264 access unit or JPEG), `application/octet-stream`;
    * `GET /api/recordings/<vehicle>/<name>[?format=csv|jsonl|ass|mp4|mcap][&every=N][&max=M]`
      → an export, as a download (`Content-Disposition`): CSV of the telemetry (every N-th
      entry), JSON lines of every entry (with only every N-th telemetry entry, or as few as
      keep at most M: what the pages replay), the `.ass` telemetry subtitles, the MP4 (the
      video copied, the subtitles as a track), the MCAP for Foxglove
      (`Neptunus.Dive.Export`; the telemetry channel's JSON schema is the wire schema's).
      Streamed (chunked), never held in memory; 409 for an MP4 of a dive without video.

  Reading needs what watching needs (observers may replay): local mode, a token (any role),
  or anonymous observers allowed; 401 otherwise (`NeptunusWeb.API.Request.may_watch/1`).
  Changing needs what piloting needs — local mode, a pilot or the main station (403 for
  observers), and the request from the server's own pages (`Origin`):

    * `PUT /api/recordings/<vehicle>/<name>` with `{"title": …, "notes": …}` (either; null
      clears it) → `{"notes": {"title", "notes", "edited_at", "edited_by"}}`; 400 for text
      too long or with control characters, 409 for a recording from before dives;
    * `DELETE /api/recordings/<vehicle>/<name>` → `{"deleted": {"vehicle", "name"}}`; 409 for
      the dive being recorded now.

  404 for an unknown dive; a vehicle whose node is cut off is answered 503; a malformed
  request 400.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.Recording.Pull
  alias NeptunusWeb.API.{Request, Response}
  alias NeptunusWeb.WireSchema.JSONSchema

  # each node's recordings directory, read on that node
  @dir {NeptunusWeb.Endpoint.Settings, :recording_dir, []}
  @max_body 64 * 1024

  @doc "`GET /api/recordings[?vehicle=id]`: the dives of every node, or one vehicle's."
  @spec index(tuple()) :: Response.t()
  def index(arg) do
    Request.watching(arg, fn ->
      case Pull.list(Map.get(query(arg), "vehicle"), @dir) do
        {:ok, listing} -> {200, listing}
        error -> Response.refused(error)
      end
    end)
  end

  @doc """
  `GET /api/recordings/<vehicle>/<name>[/summary|/video]` (the path's parts after
  `recordings/`): an export, the dive's summary and video layout, or video frames.
  """
  @spec show(tuple(), [String.t()]) :: Response.t()
  def show(arg, parts) do
    Request.watching(arg, fn ->
      case parts do
        [vehicle, name] -> export(arg, vehicle, name)
        [vehicle, name, "summary"] -> summary(vehicle, name)
        [vehicle, name, "video"] -> video(arg, vehicle, name)
        _parts -> {404, %{error: "no such recording"}}
      end
    end)
  end

  defp export(arg, vehicle, name) do
    options = Map.put(query(arg), "schemas", %{"telemetry" => telemetry_schema()})

    case Pull.export(vehicle, name, options, @dir) do
      {:ok, plan, stream} ->
        [
          {:status, 200},
          {:header, {:cache_control, ~c"no-store"}},
          {:header,
           {~c"Content-Disposition", String.to_charlist("attachment; filename=\"#{plan.file}\"")}}
          | Response.stream(arg, String.to_charlist(plan.mime), stream, "recording export")
        ]

      error ->
        Response.refused(error)
    end
  end

  @doc "The telemetry's JSON Schema, from the wire schema (MCAP's telemetry channel)."
  @spec telemetry_schema() :: map()
  def telemetry_schema, do: JSONSchema.schema(:telemetry, "neptunus.Telemetry")

  defp summary(vehicle, name) do
    case Pull.details(vehicle, name, @dir) do
      {:ok, details} -> {200, details}
      error -> Response.refused(error)
    end
  end

  defp video(arg, vehicle, name) do
    query = query(arg)

    case Pull.video(vehicle, name, query["from"], query["to"], @dir) do
      {:ok, frames} ->
        [
          {:status, 200},
          {:header, {:cache_control, ~c"no-store"}}
          | Response.stream(arg, ~c"application/octet-stream", frames, "recording video")
        ]

      error ->
        Response.refused(error)
    end
  end

  @doc """
  `PUT /api/recordings/<vehicle>/<name>`: a dive's title and notes (who may pilot may edit).
  """
  @spec update(tuple(), [String.t()]) :: Response.t()
  def update(arg, [vehicle, name]) do
    with {:ok, by} <- may_change(arg, "edit recordings"),
         {:ok, changes} <- body(arg),
         {:ok, notes} <- Pull.put_notes(vehicle, name, changes, by, @dir) do
      {200, %{notes: notes}}
    else
      {:error, _, _} = error -> Response.refused(error)
      {status, body} -> {status, body}
    end
  end

  def update(_arg, _parts), do: {404, %{error: "no such recording"}}

  defp body(arg) do
    case Request.json_body(arg, @max_body) do
      {:ok, %{} = changes} -> {:ok, changes}
      {:ok, _} -> {400, %{error: "send a JSON object with title and/or notes"}}
      {:error, :too_large} -> {413, %{error: "the body is missing or over #{@max_body} bytes"}}
      {:error, {:json, reason}} -> {400, %{error: reason}}
    end
  end

  @doc """
  `DELETE /api/recordings/<vehicle>/<name>` (the path's parts after `recordings/`): who may
  pilot may delete (local mode, a pilot or the main station); never the dive being written.
  """
  @spec delete(tuple(), [String.t()]) :: Response.t()
  def delete(arg, [vehicle, name]) do
    with {:ok, _by} <- may_change(arg, "delete recordings"),
         :ok <- Pull.delete(vehicle, name, @dir) do
      {200, %{deleted: %{vehicle: vehicle, name: name}}}
    else
      {:error, _, _} = error -> Response.refused(error)
      {status, body} -> {status, body}
    end
  end

  def delete(_arg, _parts), do: {404, %{error: "no such recording"}}

  # who may change a dive: local mode, a pilot or the main station; their name
  defp may_change(arg, what) do
    case Request.checked_session(arg) do
      {:ok, %{mode: "local"}} ->
        {:ok, "local"}

      {:ok, %{user: %{role: role, name: name}}} when role in ["pilot", "main_station"] ->
        {:ok, name}

      {:ok, %{user: %{}}} ->
        {403, %{error: "only a pilot or the main station may #{what}"}}

      {:ok, _} ->
        {401, %{error: "log in to #{what}"}}

      refused ->
        refused
    end
  end
end
