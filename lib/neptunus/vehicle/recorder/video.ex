defmodule Neptunus.Vehicle.Recorder.Video do
  @moduledoc """
  Writes a vehicle's camera frames into the dive being recorded (`Neptunus.Dive.Video` for
  the format), as received: H.264 access units or JPEG images, never re-encoded. Started
  and linked by the vehicle's recorder (`Neptunus.Vehicle.Recorder`), which tells it where
  to write (`record/2`: a dive's video folder, or nil to stop).

  Frames come as messages: it subscribes to the camera's recording topic
  (`Neptunus.Vehicle.Camera.record_topic/1`, the same shared binary every viewer gets; again
  after a PubSub restart, `Neptunus.PubSub.Follow`), so
  the camera never waits for it and a slow disk holds up only this process. The recording
  topic is not the viewers' topic, so recording does not count as watching: a simulated
  camera renders (and is recorded) while someone watches it.

  Segments begin at keyframes (`decide/3`): frames before the first keyframe, and a new
  stream's frames before its first keyframe, are not written (no decoder could start
  there). Durability: both files are synced (`datasync`, the frames then the index) every
  `sync_ms` (500) while anything is unsynced, so a node killed outright or a power cut loses
  at most the last half second plus one sync's time of video, and every segment before is
  whole and playable.

  A write that fails (disk full, removed) stops the writing and is told to the recorder as
  `{:video_failed, reason}`, which stops recording and says why; what was written stays.

  Options: `:id`, `:recorder` (the pid told of failures), `:sync_ms` (500), `:segment_us`
  (60 s), `:segment_bytes` (64 MiB), `:stream_info` (a function of the vehicle id giving the
  camera's current stream info, default `Neptunus.Vehicle.Camera.status/1`'s `stream`).
  """
  use GenServer

  alias Neptunus.Camera.Frame
  alias Neptunus.Dive.Video
  alias Neptunus.PubSub.Follow
  alias Neptunus.Vehicle.Camera

  @default_sync_ms 500
  @default_segment_us 60_000_000
  @default_segment_bytes 64 * 1024 * 1024

  defmodule Segment do
    @moduledoc false
    @type t :: %__MODULE__{
            n: pos_integer(),
            codec: String.t(),
            generation: non_neg_integer(),
            data: term(),
            index: term(),
            offset: non_neg_integer(),
            started_us: non_neg_integer(),
            frames: non_neg_integer()
          }
    @enforce_keys [:n, :codec, :generation, :data, :index, :started_us]
    defstruct [:n, :codec, :generation, :data, :index, :started_us, offset: 0, frames: 0]
  end

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            recorder: pid(),
            follow: Neptunus.PubSub.Follow.t(),
            folder: Path.t() | nil,
            segment: Neptunus.Vehicle.Recorder.Video.Segment.t() | nil,
            info: map() | nil,
            stream_info: (String.t() -> map() | nil),
            sync_ms: pos_integer(),
            segment_us: pos_integer(),
            segment_bytes: pos_integer(),
            tick: reference() | nil,
            unsynced: boolean(),
            frames: non_neg_integer(),
            bytes: non_neg_integer(),
            segments: non_neg_integer(),
            codec: String.t() | nil,
            error: String.t() | nil
          }
    @enforce_keys [:id, :recorder, :follow, :stream_info, :sync_ms, :segment_us, :segment_bytes]
    defstruct [
      :id,
      :recorder,
      :follow,
      :folder,
      :segment,
      :info,
      :stream_info,
      :sync_ms,
      :segment_us,
      :segment_bytes,
      :tick,
      :codec,
      :error,
      unsynced: false,
      frames: 0,
      bytes: 0,
      segments: 0
    ]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts), do: GenServer.start_link(__MODULE__, opts)

  @doc """
  Writes the camera's frames into `folder` (a dive's video folder, created when the first
  segment begins) from the next keyframe on, or stops writing (nil). The segment being
  written is synced and closed first.
  """
  @spec record(pid(), Path.t() | nil) :: :ok
  def record(pid, folder), do: GenServer.call(pid, {:record, folder}, 30_000)

  @doc """
  What has been written into the current folder: `frames`, `bytes`, `segments`, `codec`
  (nil before the first frame), `error` (why writing stopped, or nil).
  """
  @spec status(pid()) :: map()
  def status(pid), do: GenServer.call(pid, :status, 30_000)

  @doc """
  What to do with a frame (pure): `:write` it into the open segment, begin a `:new_segment`
  with it (a keyframe when there is no segment, the stream changed, or the segment is
  `segment_us` long or `segment_bytes` big), or `:drop` it (no keyframe to start from yet).
  `segment` is `%{generation, started_us, offset}` or nil; `frame` `%{keyframe, generation,
  at_us}`.

      iex> alias Neptunus.Vehicle.Recorder.Video
      iex> limits = %{segment_us: 60_000_000, segment_bytes: 1_000_000}
      iex> Video.decide(nil, %{keyframe: false, generation: 1, at_us: 0}, limits)
      :drop
      iex> Video.decide(nil, %{keyframe: true, generation: 1, at_us: 0}, limits)
      :new_segment
      iex> seg = %{generation: 1, started_us: 0, offset: 500}
      iex> Video.decide(seg, %{keyframe: false, generation: 1, at_us: 70_000_000}, limits)
      :write
      iex> Video.decide(seg, %{keyframe: true, generation: 1, at_us: 70_000_000}, limits)
      :new_segment
      iex> Video.decide(seg, %{keyframe: false, generation: 2, at_us: 10}, limits)
      :drop
  """
  @spec decide(map() | nil, map(), map()) :: :write | :new_segment | :drop
  def decide(nil, %{keyframe: true}, _limits), do: :new_segment
  def decide(nil, _frame, _limits), do: :drop

  def decide(%{generation: g} = seg, %{keyframe: key, generation: g, at_us: at}, limits) do
    if key and (at - seg.started_us >= limits.segment_us or seg.offset >= limits.segment_bytes),
      do: :new_segment,
      else: :write
  end

  def decide(_seg, %{keyframe: true}, _limits), do: :new_segment
  def decide(_seg, _frame, _limits), do: :drop

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)

    state = %State{
      id: id,
      recorder: Keyword.fetch!(opts, :recorder),
      follow: Follow.new([Camera.record_topic(id)]),
      stream_info: Keyword.get(opts, :stream_info, &camera_stream/1),
      sync_ms: Keyword.get(opts, :sync_ms, @default_sync_ms),
      segment_us: Keyword.get(opts, :segment_us, @default_segment_us),
      segment_bytes: Keyword.get(opts, :segment_bytes, @default_segment_bytes)
    }

    {:ok, state, {:continue, :subscribe}}
  end

  @impl true
  def handle_continue(:subscribe, state) do
    # a PubSub that is not running: the recorder is told by its own subscription (the
    # frames meanwhile are lost with the vehicle's events)
    {_subscribed_or_waiting, follow} = Follow.subscribe(state.follow)
    {:noreply, %{state | follow: follow}}
  end

  @impl true
  def handle_call({:record, folder}, _from, state) do
    state = close_segment(state)

    state = %{
      state
      | folder: folder,
        error: nil,
        frames: 0,
        bytes: 0,
        segments: 0,
        codec: nil
    }

    {:reply, :ok, state}
  end

  def handle_call(:status, _from, state) do
    {:reply,
     %{
       frames: state.frames,
       bytes: state.bytes,
       segments: state.segments,
       codec: state.codec,
       error: state.error
     }, state}
  end

  @impl true
  def handle_info({:pubsub, _topic, "stream", info}, state) when is_map(info),
    do: {:noreply, %{state | info: info}}

  def handle_info({:pubsub, _topic, "frame", _}, %State{folder: nil} = state),
    do: {:noreply, state}

  def handle_info({:pubsub, _topic, "frame", %{frame: %Frame{} = frame}}, state) do
    {:ok, header} = Frame.parse(frame.data)
    f = %{keyframe: frame.keyframe, generation: frame.generation, at_us: header.arrival_us}
    limits = %{segment_us: state.segment_us, segment_bytes: state.segment_bytes}

    state =
      case decide(state.segment, f, limits) do
        :drop -> state
        :write -> write(state, header)
        :new_segment -> state |> close_segment() |> open_segment(header, frame) |> write(header)
      end

    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}
  def handle_info(:sync_tick, state), do: {:noreply, sync(%{state | tick: nil})}

  # the PubSub scope restarted: subscribe again (Follow)
  def handle_info({:DOWN, _, :process, _, _} = msg, state), do: follow(state, msg)
  def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)
  def handle_info(_other, state), do: {:noreply, state}

  defp follow(state, msg) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  @impl true
  def terminate(_reason, state) do
    _ = close_segment(state)
    :ok
  end

  # Segments

  defp open_segment(%State{folder: nil} = state, _header, _frame), do: state

  defp open_segment(state, header, frame) do
    codec = if header.kind == :h264, do: "h264", else: "mjpeg"
    info = info_for(state, frame.generation, codec)
    n = next_number(state.folder)
    {data_name, index_name} = Video.names(n, codec)

    with :ok <- mkdir(state.folder),
         {:ok, data} <- :file.open(Path.join(state.folder, data_name), [:append, :raw, :binary]),
         {:ok, index} <- open_index(Path.join(state.folder, index_name), info, frame.seq) do
      segment = %Segment{
        n: n,
        codec: codec,
        generation: frame.generation,
        data: data,
        index: index,
        started_us: header.arrival_us
      }

      %{state | segment: segment, segments: state.segments + 1, codec: codec, info: info}
    else
      {:error, reason} ->
        failed(state, "cannot write video in #{state.folder}: #{reason(reason)}")
    end
  end

  defp mkdir(folder) do
    case File.mkdir_p(folder) do
      :ok -> :ok
      {:error, reason} -> {:error, reason}
    end
  end

  defp open_index(path, info, first_seq) do
    header = Video.header(Map.put(info, :first_seq, first_seq))

    with {:ok, fd} <- :file.open(path, [:append, :raw, :binary]),
         :ok <- :file.write(fd, header) do
      {:ok, fd}
    end
  end

  # the stream's description for a new segment: the last `stream` message, else the camera's
  defp info_for(state, generation, codec) do
    info =
      case state.info do
        %{generation: ^generation} = info -> info
        _ -> state.stream_info.(state.id)
      end

    case info do
      %{generation: ^generation, codec: ^codec} ->
        Map.take(info, [:codec, :width, :height, :fps, :avc, :generation, :source])

      _ ->
        %{codec: codec, generation: generation}
    end
  end

  defp camera_stream(id) do
    Camera.status(id).stream
  catch
    :exit, _ -> nil
  end

  defp next_number(folder) do
    case File.ls(folder) do
      {:ok, names} ->
        names
        |> Enum.flat_map(fn name ->
          case Integer.parse(name) do
            {n, "." <> _} -> [n]
            _ -> []
          end
        end)
        |> Enum.max(fn -> 0 end)
        |> Kernel.+(1)

      {:error, _} ->
        1
    end
  end

  defp write(%State{segment: nil} = state, _header), do: state

  defp write(%State{segment: seg} = state, header) do
    payload = header.payload
    size = byte_size(payload)

    record =
      Video.record(%{
        at_us: header.arrival_us,
        capture_us: header.capture_us,
        offset: seg.offset,
        size: size,
        keyframe: header.keyframe
      })

    with :ok <- :file.write(seg.data, payload),
         :ok <- :file.write(seg.index, record) do
      seg = %{seg | offset: seg.offset + size, frames: seg.frames + 1}

      %{state | segment: seg, frames: state.frames + 1, bytes: state.bytes + size, unsynced: true}
      |> arm_sync()
    else
      {:error, reason} -> failed(state, "writing video failed: #{reason(reason)}")
    end
  end

  defp arm_sync(%State{tick: nil} = state),
    do: %{state | tick: Process.send_after(self(), :sync_tick, state.sync_ms)}

  defp arm_sync(state), do: state

  # the frames first, then the index that points into them
  defp sync(%State{segment: %Segment{} = seg, unsynced: true} = state) do
    with :ok <- :file.datasync(seg.data),
         :ok <- :file.datasync(seg.index) do
      %{state | unsynced: false}
    else
      {:error, reason} -> failed(state, "writing video failed: #{reason(reason)}")
    end
  end

  defp sync(state), do: state

  defp close_segment(%State{segment: nil} = state), do: state

  defp close_segment(%State{segment: seg} = state) do
    state = sync(state)
    _ = :file.close(seg.data)
    _ = :file.close(seg.index)
    %{state | segment: nil, unsynced: false}
  end

  defp failed(state, message) do
    if state.segment do
      _ = :file.close(state.segment.data)
      _ = :file.close(state.segment.index)
    end

    send(state.recorder, {:video_failed, message})
    %{state | segment: nil, folder: nil, unsynced: false, error: message}
  end

  defp reason(reason), do: reason |> :file.format_error() |> to_string()
end
