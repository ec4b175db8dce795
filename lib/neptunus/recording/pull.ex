defmodule Neptunus.Recording.Pull do
  @moduledoc """
  The recordings of a whole fleet, from any of its nodes. A vehicle records on its own node
  (`Neptunus.Vehicle.Recorder`); this module lists every node's recordings, exports one from
  its vehicle's node and deletes one there, so that any node can serve them (the HTTP API,
  `NeptunusWeb.API.Recordings`, is the edge that calls it).

    * `list/2` — every node's recordings (one `:erpc` call per node, at once; a node that
      fails or does not answer within 5 s is left out), or one vehicle's, from its node;
    * `export/4` — an export is planned on the recording's node (`plan/4`: the request
      checked, the columns and counts read in a first pass) and its lines read there. From
      another node they are pulled: a process on the recording's node (`serve/2`) sends a
      batch of 256 lines each time the exporting process asks for more, so a slow client
      holds back the reading, never a mailbox, and the file is never held in memory;
    * `delete/3` — deletes a finished recording on its node (`delete_here/3`), never the
      one being written.

  Each node keeps its recordings in its own directory: the caller says where with `dir`, a
  function `{module, function, args}` that gives a node's directory (nil: recording is off
  there) and is applied on each node.

  Bad requests change nothing and say why: errors are `{:error, kind, reason}`, with a
  reason a person can read and the kind of refusal (`t:error/0`), which the edge turns into
  its own status.
  """
  require Logger

  alias Neptunus.{Fleet, Recording}
  alias Neptunus.Vehicle.Recorder

  @typedoc """
  Where a node keeps its recordings: `{module, function, args}`, applied on that node; it
  returns the directory, or nil when recording is off there.
  """
  @type dir :: {module(), atom(), [term()]}

  @typedoc """
  Why a request is refused: `:invalid` (a malformed request), `:not_found` (no such
  recording, or recording off), `:conflict` (the recording is being written),
  `:unreachable` (its vehicle's node is cut off), `:failed` (the file system refused).
  """
  @type error ::
          {:error, :invalid | :not_found | :conflict | :unreachable | :failed, String.t()}

  @typedoc "Recordings, as listed (`Recording.info/0`), each with its node's name."
  @type listing :: %{recording: boolean(), recordings: [map()]}

  @typedoc """
  What an export reads, decided on the recording's node: the file, the format (`"csv"` or
  `"jsonl"`), every how many telemetry entries to keep, how many entries to read (the first
  pass's), the CSV columns, and the name of the file for a download (without extension).
  """
  @type plan :: %{
          path: Path.t(),
          format: String.t(),
          every: pos_integer(),
          count: non_neg_integer(),
          columns: [String.t()],
          file: String.t()
        }

  @list_timeout_ms 5_000
  @call_timeout_ms 10_000
  @pull_timeout_ms 30_000
  @batch 256

  # a recording name, to check a vehicle id alone with Recording.valid?/2
  @any_name "00000000-000000Z-1.log"

  @doc """
  Every node's recordings, newest first, or only those of `vehicle` (from its node; none when
  that node is cut off). `recording` is whether any node records.
  """
  @spec list(String.t() | nil, dir()) :: {:ok, listing()} | error()
  def list(vehicle, dir) do
    if vehicle != nil and not Recording.valid?(vehicle, @any_name) do
      {:error, :invalid, "vehicle must be a vehicle id"}
    else
      nodes =
        case vehicle && Fleet.vehicle_node(vehicle) do
          nil -> Fleet.nodes()
          {:ok, node} -> [node]
          {:error, :unreachable} -> []
        end

      results = on_nodes(nodes, :list_here, [vehicle, dir])
      list = Enum.flat_map(results, & &1.recordings)
      list = if length(results) > 1, do: Enum.sort_by(list, & &1.modified_at, :desc), else: list
      {:ok, %{recording: Enum.any?(results, & &1.recording), recordings: list}}
    end
  end

  @doc """
  This node's recordings (of one vehicle, or all), each with this node's name (`list/2` on
  each node).
  """
  @spec list_here(String.t() | nil, dir()) :: listing()
  def list_here(vehicle, dir) do
    case dir_here(dir) do
      nil ->
        %{recording: false, recordings: []}

      path ->
        here = Atom.to_string(node())

        %{
          recording: true,
          recordings: Enum.map(Recording.list(path, vehicle), &Map.put(&1, :node, here))
        }
    end
  end

  @doc """
  Exports recording `name` of `vehicle` from its node: the plan (`plan/4`) and the export's
  lines, a lazy enumerable of iodata read on that node as it is enumerated (in batches
  pulled from there, when it is another node). `options` are as a query string gives them
  (`"format"`, `"every"`, `"max"`; see `plan/4`).
  """
  @spec export(String.t(), String.t(), %{optional(String.t()) => String.t()}, dir()) ::
          {:ok, plan(), Enumerable.t()} | error()
  def export(vehicle, name, options, dir) do
    case on_vehicle_node(vehicle, :plan, [vehicle, name, options, dir]) do
      {:ok, node, {:ok, plan}} when node == node() -> {:ok, plan, lines(plan)}
      {:ok, node, {:ok, plan}} -> {:ok, plan, pull(node, plan)}
      {:ok, _node, {:error, _, _} = error} -> error
      {:error, _, _} = error -> error
    end
  end

  @doc """
  Plans an export of this node's recording `name` of `vehicle` (`export/4` on its node):
  the recording must exist; then `options` (text, as a query string gives them):

    * `"format"` — `"csv"` (default: the telemetry, one column per numeric series) or
      `"jsonl"` (every entry as a JSON line);
    * `"every"` — every how many telemetry entries to keep, 1..1 000 000 (default 1);
    * `"max"` — at most this many telemetry entries (1..1 000 000): `every` is raised to
      keep no more.

  What the vehicle's recorder still buffers goes to disk first. The plan's `count` bounds
  the second pass to what the first one read, though the recorder may have written more.
  """
  @spec plan(String.t(), String.t(), %{optional(String.t()) => String.t()}, dir()) ::
          {:ok, plan()} | error()
  def plan(vehicle, name, options, dir) do
    with {:ok, path} <- recording_here(vehicle, name, dir),
         {:ok, format} <- format(Map.get(options, "format", "csv")),
         {:ok, every} <- count("every", Map.get(options, "every", "1")),
         {:ok, max} <- max_rows(Map.get(options, "max")) do
      Recorder.sync(vehicle)
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

  @doc "The export's lines, read on this node: a lazy enumerable of iodata."
  @spec lines(plan()) :: Enumerable.t()
  def lines(plan) do
    entries = plan.path |> Recording.entries() |> Stream.take(plan.count)

    case plan.format do
      "csv" -> Recording.csv_stream(entries, plan.columns, plan.every)
      "jsonl" -> Recording.json_lines_stream(entries, plan.every)
    end
  end

  @doc """
  The export's lines, read on `node` by a process there (`serve/2`), pulled a batch at a
  time as they are enumerated. Raises `ErlangError` with `{:recording_node, reason}` when
  that process ends before the last batch or does not answer within 30 s; the process ends
  when the enumeration does.
  """
  @spec pull(node(), plan()) :: Enumerable.t()
  def pull(node, plan) do
    Stream.resource(
      fn ->
        pid = Node.spawn(node, __MODULE__, :serve, [self(), plan])
        {pid, Process.monitor(pid)}
      end,
      fn {pid, ref} = acc ->
        send(pid, {:more, self()})

        receive do
          {:lines, ^pid, batch} -> {batch, acc}
          {:done, ^pid} -> {:halt, acc}
          {:DOWN, ^ref, :process, _, reason} -> :erlang.error({:recording_node, reason})
        after
          @pull_timeout_ms -> :erlang.error({:recording_node, :timeout})
        end
      end,
      fn {pid, ref} ->
        Process.demonitor(ref, [:flush])
        Process.exit(pid, :kill)
      end
    )
  end

  @doc """
  On the recording's node (`pull/2`): sends `to` the export's lines, a batch of up to
  #{@batch} for each `{:more, to}` as `{:lines, self(), batch}`, then `{:done, self()}`;
  ends when `to` does.
  """
  @spec serve(pid(), plan()) :: :ok
  def serve(to, plan) do
    ref = Process.monitor(to)

    plan
    |> lines()
    |> Stream.chunk_every(@batch)
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

  @doc """
  Deletes recording `name` of `vehicle` on its node (`delete_here/3` there): `:ok`, or why
  not.
  """
  @spec delete(String.t(), String.t(), dir()) :: :ok | error()
  def delete(vehicle, name, dir) do
    case on_vehicle_node(vehicle, :delete_here, [vehicle, name, dir]) do
      {:ok, _node, result} -> result
      {:error, _, _} = error -> error
    end
  end

  @doc """
  Deletes this node's recording `name` of `vehicle`, never the file being written
  (`:conflict`), and logs it.
  """
  @spec delete_here(String.t(), String.t(), dir()) :: :ok | error()
  def delete_here(vehicle, name, dir) do
    with {:ok, path} <- recording_here(vehicle, name, dir),
         :ok <- not_writing(vehicle, name, path) do
      case File.rm(path) do
        :ok ->
          Logger.info(
            "recording #{Neptunus.Log.safe(vehicle)}/#{Neptunus.Log.safe(name)} deleted"
          )

          :ok

        {:error, posix} ->
          {:error, :failed, "cannot delete: #{posix}"}
      end
    end
  end

  # The path of this node's recording, if there is one.
  defp recording_here(vehicle, name, dir) do
    dir = dir_here(dir)

    with true <- dir != nil || {:error, :not_found, "recording is off on this server"},
         true <- Recording.valid?(vehicle, name) || {:error, :not_found, "no such recording"},
         path = Recording.path(dir, vehicle, name),
         true <-
           File.regular?(path) ||
             {:error, :not_found, "no such recording: #{vehicle}/#{name}"} do
      {:ok, path}
    end
  end

  defp dir_here({module, fun, args}), do: apply(module, fun, args)

  defp not_writing(vehicle, name, path) do
    if writing?(vehicle, path),
      do: {:error, :conflict, "#{name} is being recorded now"},
      else: :ok
  end

  defp writing?(vehicle, path) do
    Recorder.status(vehicle).file == path
  catch
    :exit, _ -> false
  end

  # `fun(args)` of this module on each of `nodes` (this one directly); nodes that fail or do
  # not answer in time are left out.
  defp on_nodes(nodes, fun, args) do
    {here, remote} = Enum.split_with(nodes, &(&1 == node()))
    local = if here == [], do: [], else: [apply(__MODULE__, fun, args)]

    remote_results =
      remote
      |> :erpc.multicall(__MODULE__, fun, args, @list_timeout_ms)
      |> Enum.flat_map(fn
        {:ok, result} -> [result]
        _ -> []
      end)

    local ++ remote_results
  end

  # `fun(args)` of this module on the vehicle's node: `{:ok, node, result}`, or unreachable
  # when that node is cut off.
  defp on_vehicle_node(vehicle, fun, args) do
    case Fleet.vehicle_node(vehicle) do
      {:ok, node} when node == node() -> {:ok, node, apply(__MODULE__, fun, args)}
      {:ok, node} -> {:ok, node, :erpc.call(node, __MODULE__, fun, args, @call_timeout_ms)}
      {:error, :unreachable} -> unreachable(vehicle)
    end
  catch
    :error, {:erpc, _} -> unreachable(vehicle)
    :exit, {:timeout, _} -> unreachable(vehicle)
  end

  defp unreachable(vehicle), do: {:error, :unreachable, "vehicle unreachable: #{vehicle}"}

  defp format(format) when format in ["csv", "jsonl"], do: {:ok, format}

  defp format(other),
    do: {:error, :invalid, "format must be csv or jsonl, got #{inspect(other)}"}

  defp max_rows(nil), do: {:ok, nil}
  defp max_rows(text), do: count("max", text)

  # an option that counts entries
  defp count(name, text) do
    case is_binary(text) && Integer.parse(text) do
      {n, ""} when n in 1..1_000_000 ->
        {:ok, n}

      _ ->
        {:error, :invalid, "#{name} must be an integer in 1..1000000, got #{inspect(text)}"}
    end
  end

  defp ceil_div(a, b), do: max(1, div(a + b - 1, b))
end
