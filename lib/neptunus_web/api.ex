defmodule NeptunusWeb.API do
  @moduledoc """
  The HTTP API under `/api` (a yaws appmod). JSON in, JSON out; errors are
  `{"error": reason}` with a 4xx status.

    * `GET /api/health` → `{"status": "ok", "version": v, "vehicles": [{"id", "board", "node", "status", "helm", "pilot", "link", "depth", "heading", "recording"}]}`
      (every vehicle of the fleet, `Neptunus.Fleet.directory/0`)
    * `POST /api/login` `{"name", "password"}` → `{"token", "expires_at", "user": {"name",
      "role"}}`; 400 in local mode or for a malformed body, 401 for a wrong name or password,
      403 for a foreign `Origin`, 429 (with `Retry-After`) after too many attempts from one
      address.
    * `GET /api/session` (token in `Authorization: Bearer …` or `?token=`) →
      `{"mode", "anonymous_observers", "user": {"name", "role"} | null, "expires_at"}`;
      401 with the same fields and `error` for an invalid or expired token.
    * `GET /api/recordings[?vehicle=id]` → `{"recording": bool, "recordings": [{"vehicle",
      "name", "bytes", "started_at", "modified_at"}]}` (newest first; times in ms)
    * `GET /api/recordings/<vehicle>/<name>[?format=csv|jsonl][&every=N][&max=M]` → every
      N-th telemetry entry as CSV (a download), or every entry as JSON lines with only every
      N-th telemetry entry — or as few as keep at most M telemetry entries (what the
      developer page replays); 404 for an unknown recording. Exports are streamed (chunked):
      the file is read twice (columns and counts, then the rows), never held in memory, so a
      recording of many hours exports on a vehicle computer with little memory.

  Recordings need what watching needs: local mode, a token (any role), or anonymous observers
  allowed; 401 otherwise.

    * `DELETE /api/recordings/<vehicle>/<name>` → `{"deleted": {"vehicle", "name"}}`; local
      mode, a pilot or the main station only (403 for observers), 409 for the file being
      recorded now, 404 for an unknown recording.

  The user's own settings (`Neptunus.Settings`; the gamepad mapping, the developer page's
  plots), for local mode (one user, `"local"`) or a token of any role (the token's user);
  401 otherwise (anonymous observers keep nothing). A request with an `Origin` of another
  site is refused (403), as for logins:

    * `GET /api/settings` → `{"user": name, "settings": {key: value}}`
    * `GET /api/settings/<key>` → `{"key", "value"}`; 404 when none is stored
    * `PUT /api/settings/<key>` `{"value": v}` → `{"key", "value"}`; 400 for a bad key, value
      or body, 413 for a body over `max_settings_body/0` bytes, 500 when it cannot be written
      (the previous value stays)
    * `DELETE /api/settings/<key>` → `{"deleted": key}` (also when none was stored)

  Snapshots (`POST /api/vehicles/<id>/snapshot`, `GET /api/snapshots…`):
  `NeptunusWeb.SnapshotAPI`. See `NeptunusWeb.Auth` and docs/API.md.
  """
  import NeptunusWeb.Yaws

  require Logger

  alias Neptunus.{JSON, Recording}
  alias NeptunusWeb.Auth

  @max_body 4096

  @doc false
  def out(arg) do
    method = http_request(arg(arg, :req), :method)
    path = arg(arg, :server_path) |> to_string()
    respond(route(method, path, arg))
  rescue
    exception ->
      Logger.error(
        "API request failed: " <>
          Neptunus.Log.safe(Exception.format(:error, exception, __STACKTRACE__))
      )

      respond({500, %{error: "internal error"}})
  end

  # The body of `GET /api/health` (see the moduledoc).
  @spec health() :: map()
  defp health do
    %{
      status: "ok",
      version: Application.spec(:neptunus, :vsn) |> to_string(),
      # every vehicle of the fleet, with its node (unreachable ones too)
      vehicles: Neptunus.Fleet.directory()
    }
  end

  defp route(:GET, "/api/health", _arg), do: {200, health()}
  defp route(_method, "/api/health", _arg), do: {405, %{error: "method not allowed: use GET"}}
  defp route(:POST, "/api/login", arg), do: login(arg)
  defp route(_method, "/api/login", _arg), do: {405, %{error: "method not allowed: use POST"}}
  defp route(:GET, "/api/session", arg), do: session(arg)
  defp route(_method, "/api/session", _arg), do: {405, %{error: "method not allowed: use GET"}}
  defp route(:GET, "/api/recordings", arg), do: authorized(arg, &recordings/1)

  defp route(:GET, "/api/recordings/" <> rest, arg),
    do: authorized(arg, &recording(&1, String.split(rest, "/")))

  defp route(:DELETE, "/api/recordings/" <> rest, arg),
    do: delete_recording(arg, String.split(rest, "/"))

  defp route(_method, "/api/recordings" <> _, _arg),
    do: {405, %{error: "method not allowed: use GET (or DELETE for one recording)"}}

  defp route(:GET, "/api/settings", arg),
    do: with_user(arg, &{200, %{user: elem(&1, 1), settings: Neptunus.Settings.all(&1)}})

  defp route(_method, "/api/settings", _arg),
    do: {405, %{error: "method not allowed: use GET (or GET, PUT, DELETE for one setting)"}}

  defp route(method, "/api/settings/" <> key, arg) when method in [:GET, :PUT, :DELETE],
    do: with_user(arg, &setting(method, &1, key, arg))

  defp route(_method, "/api/settings/" <> _, _arg),
    do: {405, %{error: "method not allowed: use GET, PUT or DELETE"}}

  # snapshots (NeptunusWeb.SnapshotAPI)
  defp route(method, "/api/snapshots" <> _ = path, arg),
    do: NeptunusWeb.SnapshotAPI.route(method, path, arg)

  defp route(method, "/api/vehicles/" <> _ = path, arg),
    do: NeptunusWeb.SnapshotAPI.route(method, path, arg)

  defp route(_method, path, _arg), do: {404, %{error: "no such API endpoint: #{path}"}}

  # the largest body yaws hands over whole (its partial_post_size): a value of
  # Neptunus.Settings.Rules.max_value_bytes/0 and its {"value": …} wrapper fit
  @max_settings_body 10_240

  @doc "The largest `PUT /api/settings/<key>` body accepted, in bytes."
  @spec max_settings_body() :: pos_integer()
  def max_settings_body, do: @max_settings_body

  @doc """
  Whose settings a request reads and writes (`Neptunus.Settings`): in local mode the node's
  one user `{:user, "local"}`; in secure mode the token's user (any role); otherwise the
  HTTP status and reason to refuse with (401). A foreign `Origin` is refused (403).
  """
  @spec user_scope(tuple()) :: {:ok, Neptunus.Settings.scope()} | {401 | 403, map()}
  def user_scope(arg) do
    headers = arg(arg, :headers)
    host = headers |> headers(:host) |> text()

    with {:origin, :ok} <-
           {:origin, Auth.check_origin(header(headers, "origin"), host, Auth.config().origins)} do
      case Auth.session(token(arg)) do
        {:ok, %{mode: "local"}} -> {:ok, {:user, Neptunus.Settings.local_user()}}
        {:ok, %{user: %{name: name}}} -> {:ok, {:user, name}}
        {:ok, _} -> {401, %{error: "log in to keep settings"}}
        {:error, %{error: reason}} -> {401, %{error: reason}}
      end
    else
      {:origin, {:error, status, reason}} -> {status, %{error: reason}}
    end
  end

  defp with_user(arg, fun) do
    case user_scope(arg) do
      {:ok, scope} -> fun.(scope)
      refused -> refused
    end
  end

  defp setting(:GET, scope, key, _arg) do
    case Neptunus.Settings.get(scope, key) do
      {:ok, value} ->
        {200, %{key: key, value: value}}

      :error ->
        case Neptunus.Settings.Rules.key(key) do
          :ok -> {404, %{error: "no setting #{key}"}}
          {:error, reason} -> {400, %{error: reason}}
        end
    end
  end

  defp setting(:PUT, scope, key, arg) do
    with {:ok, value} <- setting_body(arg) do
      case Neptunus.Settings.put(scope, key, value) do
        :ok -> {200, %{key: key, value: value}}
        {:error, "cannot " <> _ = reason} -> {500, %{error: reason}}
        {:error, reason} -> {400, %{error: reason}}
      end
    end
  end

  defp setting(:DELETE, scope, key, _arg) do
    case Neptunus.Settings.delete(scope, key) do
      :ok -> {200, %{deleted: key}}
      {:error, "cannot " <> _ = reason} -> {500, %{error: reason}}
      {:error, reason} -> {400, %{error: reason}}
    end
  end

  defp setting_body(arg) do
    case arg(arg, :clidata) do
      data when is_binary(data) and byte_size(data) <= @max_settings_body ->
        case JSON.decode(data) do
          {:ok, %{"value" => value} = body} when map_size(body) == 1 -> {:ok, value}
          {:ok, _} -> {400, %{error: "body must be {\"value\": …}"}}
          {:error, reason} -> {400, %{error: "body must be JSON {\"value\": …}: #{reason}"}}
        end

      _ ->
        # the rest of the body is not read: the connection cannot carry another request
        {413, %{error: "body must be at most #{@max_settings_body} bytes"},
         [{"Connection", "close"}]}
    end
  end

  defp login(arg) do
    headers = arg(arg, :headers)
    host = headers |> headers(:host) |> text()
    {address, _port} = arg(arg, :client_ip_port)

    with :ok <- Auth.check_origin(header(headers, "origin"), host, Auth.config().origins),
         {:ok, %{"name" => name, "password" => password}} <- body(arg),
         {:ok, session} <- Auth.login(name, password, address) do
      {200, session}
    else
      {:ok, _other} -> {400, %{error: "body must be {\"name\": …, \"password\": …}"}}
      {:error, 429, reason, retry_s} -> {429, %{error: reason}, [{"Retry-After", retry_s}]}
      {:error, status, reason} -> {status, %{error: reason}}
    end
  end

  defp session(arg) do
    case Auth.session(token(arg)) do
      {:ok, session} -> {200, session}
      {:error, session} -> {401, session}
    end
  end

  defp token(arg) do
    case arg |> arg(:headers) |> headers(:authorization) do
      {_user, _password, ~c"Bearer " ++ token} -> token |> to_string() |> String.trim()
      _ -> Map.get(query(arg), "token")
    end
  end

  defp authorized(arg, fun) do
    case may_watch(arg) do
      :ok -> fun.(arg)
      {:error, reason} -> {401, %{error: reason}}
    end
  end

  @doc """
  Whether the request may see what observers see (recordings, the camera): local mode, a
  valid token (`Authorization: Bearer …` or `?token=`), or anonymous observers allowed.
  """
  @spec may_watch(tuple()) :: :ok | {:error, String.t()}
  def may_watch(arg) do
    case Auth.session(token(arg)) do
      {:ok, %{mode: "local"}} -> :ok
      {:ok, %{user: %{}}} -> :ok
      {:ok, %{anonymous_observers: true}} -> :ok
      {:ok, _} -> {:error, "log in to see recordings and the camera"}
      {:error, %{error: reason}} -> {:error, reason}
    end
  end

  defp recording_dir, do: NeptunusWeb.Settings.get().recording_dir

  # Every node's recordings (a vehicle's: its node's), each with its node: a vehicle on
  # another node of the fleet records there, and its recordings are listed, exported and
  # deleted from any node.
  defp recordings(arg) do
    vehicle = Map.get(query(arg), "vehicle")

    if vehicle != nil and not Recording.valid?(vehicle, "00000000-000000Z-1.log") do
      {400, %{error: "vehicle must be a vehicle id"}}
    else
      nodes =
        case vehicle && Neptunus.Fleet.vehicle_node(vehicle) do
          nil -> Neptunus.Fleet.nodes()
          {:ok, node} -> [node]
          {:error, :unreachable} -> []
        end

      results = on_nodes(nodes, :local_recordings, [vehicle])
      list = Enum.flat_map(results, & &1.recordings)
      list = if length(results) > 1, do: Enum.sort_by(list, & &1.modified_at, :desc), else: list
      {200, %{recording: Enum.any?(results, & &1.recording), recordings: list}}
    end
  end

  @doc false
  # This node's recordings (of one vehicle, or all), each with this node's name.
  @spec local_recordings(String.t() | nil) :: %{recording: boolean(), recordings: [map()]}
  def local_recordings(vehicle) do
    case recording_dir() do
      nil ->
        %{recording: false, recordings: []}

      dir ->
        here = Atom.to_string(node())

        %{
          recording: true,
          recordings: Enum.map(Recording.list(dir, vehicle), &Map.put(&1, :node, here))
        }
    end
  end

  # `fun(args)` of this module on each of `nodes` (this one directly); nodes that fail or do
  # not answer within 5 s are left out.
  defp on_nodes(nodes, fun, args) do
    {here, remote} = Enum.split_with(nodes, &(&1 == node()))
    local = if here == [], do: [], else: [apply(__MODULE__, fun, args)]

    remote_results =
      remote
      |> :erpc.multicall(__MODULE__, fun, args, 5_000)
      |> Enum.flat_map(fn
        {:ok, result} -> [result]
        _ -> []
      end)

    local ++ remote_results
  end

  # GET /api/recordings/<vehicle>/<name>?format=csv|jsonl&every=N&max=M, on the vehicle's
  # node: planned there (`export_plan/3`), read there, streamed from here.
  defp recording(arg, [vehicle, name]) do
    params = query(arg)

    case vehicle_call(vehicle, :export_plan, [vehicle, name, params]) do
      {:ok, node, {:ok, plan}} when node == node() -> export(arg, plan, lines(plan))
      {:ok, node, {:ok, plan}} -> export(arg, plan, remote_lines(node, plan))
      {:ok, _node, {status, body}} -> {status, body}
      {:error, response} -> response
    end
  end

  defp recording(_arg, _parts), do: {404, %{error: "no such recording"}}

  # `fun(args)` of this module on vehicle's node: `{:ok, node, result}`, or the response
  # when that node is cut off.
  defp vehicle_call(vehicle, fun, args) do
    case Neptunus.Fleet.vehicle_node(vehicle) do
      {:ok, node} when node == node() ->
        {:ok, node, apply(__MODULE__, fun, args)}

      {:ok, node} ->
        {:ok, node, :erpc.call(node, __MODULE__, fun, args, 10_000)}

      {:error, :unreachable} ->
        {:error, {503, %{error: "vehicle unreachable: #{vehicle}"}}}
    end
  catch
    :error, {:erpc, _} -> {:error, {503, %{error: "vehicle unreachable: #{vehicle}"}}}
    :exit, {:timeout, _} -> {:error, {503, %{error: "vehicle unreachable: #{vehicle}"}}}
  end

  @typedoc "What an export reads, decided on the recording's node."
  @type plan :: %{
          path: Path.t(),
          format: String.t(),
          every: pos_integer(),
          count: non_neg_integer(),
          columns: term(),
          file: String.t()
        }

  @doc false
  # Checks an export's request against this node's recordings: `{:ok, plan}` or
  # `{status, body}`.
  @spec export_plan(String.t(), String.t(), map()) :: {:ok, plan()} | {pos_integer(), map()}
  def export_plan(vehicle, name, params) do
    dir = recording_dir()

    with true <- dir != nil || {404, %{error: "recording is off on this server"}},
         true <- Recording.valid?(vehicle, name) || {404, %{error: "no such recording"}},
         path = Recording.path(dir, vehicle, name),
         true <- File.regular?(path) || {404, %{error: "no such recording: #{vehicle}/#{name}"}},
         {:ok, format} <- format(Map.get(params, "format", "csv")),
         {:ok, every} <- every(Map.get(params, "every", "1")),
         {:ok, max} <- max_rows(Map.get(params, "max")) do
      # what the vehicle's recorder still buffers goes to disk first
      Neptunus.Vehicle.Recorder.sync(vehicle)
      # first pass: the columns and counts; the second pass (streamed) stops where this one
      # did, though the recorder may have written more since
      summary = path |> Recording.entries() |> Recording.scan()
      every = if max, do: max(every, ceil_div(summary.telemetry, max)), else: every

      {:ok,
       %{
         path: path,
         format: format,
         every: every,
         count: summary.entries,
         columns: summary.columns,
         file: "#{vehicle}-#{Path.rootname(name)}"
       }}
    end
  end

  # The export's lines, read on this node.
  defp lines(plan) do
    entries = plan.path |> Recording.entries() |> Stream.take(plan.count)

    case plan.format do
      "csv" -> Recording.csv_stream(entries, plan.columns, plan.every)
      "jsonl" -> Recording.json_lines_stream(entries, plan.every)
    end
  end

  @remote_batch 256

  # The export's lines, read on `node` by a process there that sends a batch of lines each
  # time this one asks for more (so a slow client holds back the reading, not a mailbox).
  defp remote_lines(node, plan) do
    Stream.resource(
      fn ->
        pid = Node.spawn(node, __MODULE__, :serve_lines, [self(), plan])
        {pid, Process.monitor(pid)}
      end,
      fn {pid, ref} = acc ->
        send(pid, {:more, self()})

        receive do
          {:lines, ^pid, batch} -> {batch, acc}
          {:done, ^pid} -> {:halt, acc}
          {:DOWN, ^ref, :process, _, reason} -> :erlang.error({:recording_node, reason})
        after
          30_000 -> :erlang.error({:recording_node, :timeout})
        end
      end,
      fn {pid, ref} ->
        Process.demonitor(ref, [:flush])
        Process.exit(pid, :kill)
      end
    )
  end

  @doc false
  # On the recording's node: sends `to` the export's lines, a batch per `{:more, to}`, then
  # `{:done, self()}`; ends when `to` does.
  @spec serve_lines(pid(), plan()) :: :ok
  def serve_lines(to, plan) do
    ref = Process.monitor(to)

    plan
    |> lines()
    |> Stream.chunk_every(@remote_batch)
    |> Stream.concat([:done])
    |> Enum.each(fn batch ->
      receive do
        {:more, ^to} ->
          if batch == :done,
            do: send(to, {:done, self()}),
            else: send(to, {:lines, self(), batch})

        {:DOWN, ^ref, :process, _, _} ->
          exit(:normal)
      end
    end)
  end

  # DELETE /api/recordings/<vehicle>/<name>: who may pilot may delete (local mode, a pilot or
  # the main station); never the file being written.
  defp delete_recording(arg, [vehicle, name]) do
    with :ok <- may_delete(arg),
         {:ok, _node, response} <- vehicle_call(vehicle, :delete_local, [vehicle, name]) do
      response
    else
      {:error, {status, body}} -> {status, body}
      {status, body} -> {status, body}
    end
  end

  defp delete_recording(_arg, _parts), do: {404, %{error: "no such recording"}}

  @doc false
  # Deletes a recording of this node (never the file being written): `{status, body}`.
  @spec delete_local(String.t(), String.t()) :: {pos_integer(), map()}
  def delete_local(vehicle, name) do
    dir = recording_dir()

    with true <- dir != nil || {404, %{error: "recording is off on this server"}},
         true <- Recording.valid?(vehicle, name) || {404, %{error: "no such recording"}},
         path = Recording.path(dir, vehicle, name),
         true <- File.regular?(path) || {404, %{error: "no such recording: #{vehicle}/#{name}"}},
         :ok <-
           if(writing?(vehicle, path),
             do: {409, %{error: "#{name} is being recorded now"}},
             else: :ok
           ),
         :ok <- File.rm(path) do
      Logger.info("recording #{Neptunus.Log.safe(vehicle)}/#{Neptunus.Log.safe(name)} deleted")
      {200, %{deleted: %{vehicle: vehicle, name: name}}}
    else
      {:error, posix} when is_atom(posix) -> {500, %{error: "cannot delete: #{posix}"}}
      {status, body} -> {status, body}
    end
  end

  defp may_delete(arg) do
    case Auth.session(token(arg)) do
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

  defp writing?(vehicle, path) do
    Neptunus.Vehicle.Recorder.status(vehicle).file == path
  catch
    :exit, _ -> false
  end

  defp max_rows(nil), do: {:ok, nil}
  defp max_rows(text), do: count("max", text)

  defp ceil_div(a, b), do: max(1, div(a + b - 1, b))

  defp format(format) when format in ["csv", "jsonl"], do: {:ok, format}
  defp format(other), do: {400, %{error: "format must be csv or jsonl, got #{inspect(other)}"}}

  defp every(text), do: count("every", text)

  # a query parameter that counts entries
  defp count(name, text) do
    case Integer.parse(text) do
      {n, ""} when n in 1..1_000_000 -> {:ok, n}
      _ -> {400, %{error: "#{name} must be an integer in 1..1000000, got #{inspect(text)}"}}
    end
  end

  defp export(arg, %{format: "csv", file: file}, lines) do
    [
      {:status, 200},
      {:header, {:cache_control, ~c"no-store"}},
      {:header,
       {~c"Content-Disposition", String.to_charlist("attachment; filename=\"#{file}.csv\"")}}
      | stream(arg, ~c"text/csv; charset=utf-8", lines)
    ]
  end

  defp export(arg, %{format: "jsonl"}, lines) do
    [
      {:status, 200},
      {:header, {:cache_control, ~c"no-store"}}
      | stream(arg, ~c"application/x-ndjson", lines)
    ]
  end

  @export_chunk_bytes 65_536

  # The body from `lines` (a lazy enumerable of iodata), sent by a process of its own in
  # chunks of about 64 KiB (HTTP/1.1 chunked encoding), at the pace the client reads.
  defp stream(arg, mime, lines) do
    socket = arg(arg, :clisock)
    pid = spawn(fn -> stream_body(socket, lines) end)
    [{:streamcontent_from_pid, mime, pid}]
  end

  defp stream_body(socket, lines) do
    NeptunusWeb.Yaws.await_stream(
      socket,
      fn yaws ->
        case deliver(socket, lines) do
          :ok ->
            :yaws_api.stream_process_deliver_final_chunk(socket, [])
            :yaws_api.stream_process_end(socket, yaws)

          {:error, reason} ->
            Logger.warning("recording export ended early: #{inspect(reason)}")
            :yaws_api.stream_process_end(:closed, yaws)
        end
      end,
      30_000
    )
  end

  defp deliver(socket, lines) do
    lines
    |> Stream.chunk_while(
      {[], 0},
      fn line, {acc, size} ->
        size = size + IO.iodata_length(line)

        if size >= @export_chunk_bytes,
          do: {:cont, Enum.reverse([line | acc]), {[], 0}},
          else: {:cont, {[line | acc], size}}
      end,
      fn
        {[], _} -> {:cont, {[], 0}}
        {acc, _} -> {:cont, Enum.reverse(acc), {[], 0}}
      end
    )
    |> Enum.reduce_while(:ok, fn chunk, :ok ->
      case :yaws_api.stream_process_deliver_chunk(socket, chunk) do
        :ok -> {:cont, :ok}
        {:error, reason} -> {:halt, {:error, reason}}
      end
    end)
  rescue
    # the file went away or broke between the two passes
    error in [File.Error, ErlangError] -> {:error, Exception.message(error)}
  end

  defp body(arg) do
    case arg(arg, :clidata) do
      data when is_binary(data) and byte_size(data) <= @max_body ->
        case JSON.decode(data) do
          {:ok, json} -> {:ok, json}
          {:error, _} -> {:error, 400, "body must be JSON: {\"name\": …, \"password\": …}"}
        end

      _ ->
        {:error, 400, "body missing or too large"}
    end
  end

  def respond([{:status, _} | _] = response), do: response
  @doc false
  # a JSON error or answer as yaws' out/1 result (also for NeptunusWeb.CameraStream)
  def respond({status, body}), do: respond({status, body, []})

  def respond({status, body, headers}) do
    [
      {:status, status},
      {:header, {:cache_control, ~c"no-store"}}
      | Enum.map(headers, fn {name, value} ->
          {:header, {String.to_charlist(name), header_value(value)}}
        end)
    ] ++ [{:content, ~c"application/json", JSON.encode!(body)}]
  end

  defp header_value(value) when is_integer(value), do: Integer.to_charlist(value)
  defp header_value(value), do: String.to_charlist(value)
end
