defmodule Neptunus.Recording.Pull do
  @moduledoc """
  The dives of a whole fleet, from any of its nodes. A vehicle records on its own node
  (`Neptunus.Vehicle.Recorder`, `Neptunus.Dive`); this module lists every node's dives,
  reads, exports, annotates and deletes one on its vehicle's node, so that any node can
  serve them (the HTTP API, `NeptunusWeb.API.Recordings`, and `mix neptunus.export` are the
  edges that call it).

    * `list/2` — every node's dives (one `:erpc` call per node, at once; a node that fails
      or does not answer within 5 s is left out), or one vehicle's, from its node;
    * `details/3` — one dive as listed, with its video's segments and keyframes
      (`Neptunus.Dive.Replay.video/1`);
    * `export/4` — an export is planned on the dive's node (`plan/4`: the request checked,
      what a first pass must know read; `Neptunus.Dive.Export`) and read there. From another
      node it is pulled: a process on the dive's node (`serve/2`) sends a batch of up to 256
      pieces (or 1 MB) each time the exporting process asks for more, so a slow client
      holds back the reading, never a mailbox, and the dive is never held in memory;
    * `video/5` — the frames of a time window, read on the dive's node the same way;
    * `put_notes/5` — a dive's title and notes, saved on its node;
    * `delete/3` — deletes a finished dive on its node (`delete_here/3`), never the one
      being recorded.

  Each node keeps its dives in its own directory: the caller says where with `dir`, a
  function `{module, function, args}` that gives a node's directory (nil: recording is off
  there) and is applied on each node.

  Bad requests change nothing and say why: errors are `{:error, kind, reason}`, with a
  reason a person can read and the kind of refusal (`t:error/0`), which the edge turns into
  its own status.
  """
  require Logger

  alias Neptunus.{Dive, Fleet}
  alias Neptunus.Dive.{Export, Replay}
  alias Neptunus.Vehicle.Recorder

  @typedoc """
  Where a node keeps its recordings: `{module, function, args}`, applied on that node; it
  returns the directory, or nil when recording is off there.
  """
  @type dir :: {module(), atom(), [term()]}

  @typedoc """
  Why a request is refused: `:invalid` (a malformed request), `:not_found` (no such dive,
  or recording off), `:conflict` (the dive is being recorded, or cannot do what is asked),
  `:unreachable` (its vehicle's node is cut off), `:failed` (the file system refused).
  """
  @type error ::
          {:error, :invalid | :not_found | :conflict | :unreachable | :failed, String.t()}

  @typedoc "Dives, as listed (`Neptunus.Dive.info/3`), each with its node's name."
  @type listing :: %{recording: boolean(), recordings: [map()]}

  @list_timeout_ms 5_000
  @call_timeout_ms 30_000
  @pull_timeout_ms 60_000
  @batch 256
  @batch_bytes 1_048_576

  @doc """
  Every node's dives, newest first, or only those of `vehicle` (from its node; none when
  that node is cut off). `recording` is whether any node records. The dive being recorded
  has `recording: true`.
  """
  @spec list(String.t() | nil, dir()) :: {:ok, listing()} | error()
  def list(vehicle, dir) do
    if vehicle != nil and not Dive.valid_vehicle?(vehicle) do
      {:error, :invalid, "vehicle must be a vehicle id"}
    else
      nodes = Fleet.nodes_of(vehicle)

      results = on_nodes(nodes, :list_here, [vehicle, dir])
      list = Enum.flat_map(results, & &1.recordings)

      list =
        if length(results) > 1,
          do: Enum.sort_by(list, &{&1.started_at || 0, &1.vehicle, &1.name}, :desc),
          else: list

      {:ok, %{recording: Enum.any?(results, & &1.recording), recordings: list}}
    end
  end

  @doc """
  This node's dives (of one vehicle, or all), each with this node's name and whether it is
  being recorded (`list/2` on each node).
  """
  @spec list_here(String.t() | nil, dir()) :: listing()
  def list_here(vehicle, dir) do
    case dir_here(dir) do
      nil ->
        %{recording: false, recordings: []}

      path ->
        here = Atom.to_string(node())
        writing = writing_folders(path, vehicle)

        %{
          recording: true,
          recordings:
            path
            |> Dive.list(vehicle)
            |> Enum.map(fn info ->
              info
              |> Map.put(:node, here)
              |> Map.put(:recording, Dive.path(path, info.vehicle, info.name) in writing)
            end)
        }
    end
  end

  # the dive folders this node's recorders write now (of one vehicle, or all)
  defp writing_folders(dir, vehicle) do
    vehicles = if vehicle, do: [vehicle], else: Dive.vehicles(dir)

    for v <- vehicles, folder = recording_folder(v), folder != nil, do: folder
  end

  defp recording_folder(vehicle) do
    Recorder.status(vehicle).folder
  catch
    :exit, _ -> nil
  end

  @doc """
  Dive `name` of `vehicle`, read on its node: as listed, with `video` the segments and their
  keyframes (`Neptunus.Dive.Replay.video/1`) and the video's problems added to `problems`.
  """
  @spec details(String.t(), String.t(), dir()) :: {:ok, map()} | error()
  def details(vehicle, name, dir) do
    case on_vehicle_node(vehicle, :details_here, [vehicle, name, dir]) do
      {:ok, _node, result} -> result
      {:error, _, _} = error -> error
    end
  end

  @doc false
  # On the dive's node.
  @spec details_here(String.t(), String.t(), dir()) :: {:ok, map()} | error()
  def details_here(vehicle, name, dir) do
    with {:ok, path} <- dive_here(vehicle, name, dir),
         %{} = info <- Dive.info(Path.dirname(Path.dirname(path)), vehicle, name) do
      Recorder.sync(vehicle)
      video = Replay.video(path)

      {:ok,
       info
       |> Map.put(:node, Atom.to_string(node()))
       |> Map.put(:recording, recording_folder(vehicle) == path)
       |> Map.put(:segments, video.segments)
       |> Map.update!(:problems, &Enum.uniq(&1 ++ video.problems))}
    else
      nil -> {:error, :not_found, "no such dive: #{vehicle}/#{name}"}
      error -> error
    end
  end

  @doc """
  Exports dive `name` of `vehicle` from its node: the plan (`plan/4`) and the export, a
  lazy enumerable of iodata read on that node as it is enumerated (in batches pulled from
  there, when it is another node). `options` are as a query string gives them (`"format"`,
  `"every"`, `"max"`), and `"schemas"` from the edge (see `Neptunus.Dive.Export.plan/3`).
  """
  @spec export(String.t(), String.t(), map(), dir()) ::
          {:ok, Export.plan(), Enumerable.t()} | error()
  def export(vehicle, name, options, dir) do
    case on_vehicle_node(vehicle, :plan, [vehicle, name, options, dir]) do
      {:ok, node, {:ok, plan}} when node == node() -> {:ok, plan, Export.stream(plan)}
      {:ok, node, {:ok, plan}} -> {:ok, plan, pull(node, {Export, :stream, [plan]})}
      {:ok, _node, {:error, _, _} = error} -> error
      {:error, _, _} = error -> error
    end
  end

  @doc """
  Plans an export of this node's dive `name` of `vehicle` (`export/4` on its node): the dive
  must exist; then `options` are checked (`Neptunus.Dive.Export.plan/3`). What the vehicle's
  recorder still buffers goes to disk first.
  """
  @spec plan(String.t(), String.t(), map(), dir()) :: {:ok, Export.plan()} | error()
  def plan(vehicle, name, options, dir) do
    with {:ok, path} <- dive_here(vehicle, name, dir) do
      Recorder.sync(vehicle)
      Export.plan(path, "#{vehicle}-#{Path.rootname(name)}", options)
    end
  end

  @doc """
  The frames of dive `name`'s video from `from` to `to` (ms since the epoch, as text), read
  on its node (`Neptunus.Dive.Replay.frames/3`), lazily.
  """
  @spec video(String.t(), String.t(), term(), term(), dir()) :: {:ok, Enumerable.t()} | error()
  def video(vehicle, name, from, to, dir) do
    with {:ok, from, to} <- Replay.window(from, to) do
      case on_vehicle_node(vehicle, :video_here, [vehicle, name, dir]) do
        {:ok, node, {:ok, path}} when node == node() ->
          {:ok, Replay.frames(path, from, to)}

        {:ok, node, {:ok, path}} ->
          {:ok, pull(node, {Replay, :frames, [path, from, to]})}

        {:ok, _node, {:error, _, _} = error} ->
          error

        {:error, _, _} = error ->
          error
      end
    end
  end

  @doc false
  # On the dive's node: its path, once the recorder wrote what it buffers.
  @spec video_here(String.t(), String.t(), dir()) :: {:ok, Path.t()} | error()
  def video_here(vehicle, name, dir) do
    with {:ok, path} <- dive_here(vehicle, name, dir) do
      {:ok, path}
    end
  end

  @doc """
  The export's pieces, read on `node` by a process there (`serve/2`) from the enumerable
  `{module, function, args}` gives, pulled a batch at a time as they are enumerated. Raises
  `ErlangError` with `{:recording_node, reason}` when that process ends before the last
  batch or does not answer within 60 s; the process ends when the enumeration does.
  """
  @spec pull(node(), {module(), atom(), [term()]}) :: Enumerable.t()
  def pull(node, mfa) do
    Stream.resource(
      fn ->
        pid = Node.spawn(node, __MODULE__, :serve, [self(), mfa])
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
  On the dive's node (`pull/2`): sends `to` the pieces of the enumerable
  `{module, function, args}` gives, a batch of up to #{@batch} (or about 1 MB) for each
  `{:more, to}` as `{:lines, self(), batch}`, then `{:done, self()}`; ends when `to` does.
  """
  @spec serve(pid(), {module(), atom(), [term()]}) :: :ok
  def serve(to, {module, fun, args}) do
    ref = Process.monitor(to)

    module
    |> apply(fun, args)
    |> Stream.chunk_while(
      {[], 0, 0},
      fn piece, {acc, n, bytes} ->
        bytes = bytes + IO.iodata_length(piece)

        if n + 1 >= @batch or bytes >= @batch_bytes,
          do: {:cont, Enum.reverse([piece | acc]), {[], 0, 0}},
          else: {:cont, {[piece | acc], n + 1, bytes}}
      end,
      fn
        {[], _, _} -> {:cont, {[], 0, 0}}
        {acc, _, _} -> {:cont, Enum.reverse(acc), {[], 0, 0}}
      end
    )
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
  Gives dive `name` of `vehicle` a title and notes on its node (`Neptunus.Dive.put_notes/4`):
  the notes as saved, or why not.
  """
  @spec put_notes(String.t(), String.t(), map(), String.t() | nil, dir()) ::
          {:ok, map()} | error()
  def put_notes(vehicle, name, changes, by, dir) do
    case on_vehicle_node(vehicle, :put_notes_here, [vehicle, name, changes, by, dir]) do
      {:ok, _node, result} -> result
      {:error, _, _} = error -> error
    end
  end

  @doc false
  @spec put_notes_here(String.t(), String.t(), map(), String.t() | nil, dir()) ::
          {:ok, map()} | error()
  def put_notes_here(vehicle, name, changes, by, dir) do
    with {:ok, path} <- dive_here(vehicle, name, dir) do
      Dive.put_notes(path, changes, by, Neptunus.Clock.wall_ms())
    end
  end

  @doc """
  Deletes dive `name` of `vehicle` on its node (`delete_here/3` there): `:ok`, or why not.
  """
  @spec delete(String.t(), String.t(), dir()) :: :ok | error()
  def delete(vehicle, name, dir) do
    case on_vehicle_node(vehicle, :delete_here, [vehicle, name, dir]) do
      {:ok, _node, result} -> result
      {:error, _, _} = error -> error
    end
  end

  @doc """
  Deletes this node's dive `name` of `vehicle` (its folder: entries, video, snapshots), never
  the one being recorded (`:conflict`), and logs it.
  """
  @spec delete_here(String.t(), String.t(), dir()) :: :ok | error()
  def delete_here(vehicle, name, dir) do
    with {:ok, path} <- dive_here(vehicle, name, dir),
         :ok <- not_writing(vehicle, name, path) do
      case Dive.delete(path) do
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

  # The path of this node's dive, if there is one.
  defp dive_here(vehicle, name, dir) do
    dir = dir_here(dir)

    with true <- dir != nil || {:error, :not_found, "recording is off on this server"},
         true <- Dive.valid?(vehicle, name) || {:error, :not_found, "no such recording"},
         path = Dive.path(dir, vehicle, name),
         true <-
           if(Dive.legacy?(name), do: File.regular?(path), else: File.dir?(path)) ||
             {:error, :not_found, "no such recording: #{vehicle}/#{name}"} do
      {:ok, path}
    end
  end

  defp dir_here({module, fun, args}), do: apply(module, fun, args)

  defp not_writing(vehicle, name, path) do
    if recording_folder(vehicle) == path,
      do: {:error, :conflict, "#{name} is being recorded now"},
      else: :ok
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
end
