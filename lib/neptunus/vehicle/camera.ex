defmodule Neptunus.Vehicle.Camera do
  @moduledoc """
  A vehicle's camera: runs its source (`Neptunus.Camera.Source`) through the camera port
  program (`priv/neptunus_camera`: ffmpeg on a V4L2 device or an RTSP URL, ffmpeg's test
  pattern, an `exec:` program, or the simulated camera's renderer and its encoder), cuts
  the output into frames (`Neptunus.Camera.Stream`) and publishes each on `"camera:<id>"`
  as one binary shared by every viewer — the video WebSocket (`NeptunusWeb.VideoSocket`),
  the MJPEG `<img>` stream (`NeptunusWeb.CameraStream`), another node's relay
  (`NeptunusWeb.CameraRelay`) — never copied or encoded per viewer. Video never passes
  through the board, control or helm processes.

  Messages on `"camera:<id>"` (term subscribers, `{:pubsub, topic, event, payload}`):

    * `"frame"` `%{frame: Neptunus.Camera.Frame.t()}` — each frame;
    * `"stream"` `Neptunus.Camera.Stream.info()` — a new stream (generation) begins;
    * `"camera"` `%{state, reason, restarts}` — the camera's state changed (`view/1`).

  States: `"starting"` (the program runs, no picture yet), `"running"`, `"restarting"`
  (it stopped; starting again after a backoff), `"failed"` (it cannot start: the program or
  ffmpeg is missing, the device offers no usable codec; tried again after the backoff),
  `"idle"` (a `sim` camera nobody watches: it renders only while someone does, and stops
  `linger_ms` after the last viewer left), `"none"` (no camera configured).

  Faults: the program exits, sends what is not video (`Stream` refuses it), sends no
  picture for `stall_ms` (or none within `start_ms` of starting): the camera says why (a log
  line, a `log` entry on `"log:<id>"`, the `camera` event, telemetry) and starts it again
  after 1, 2, 4 … 30 s; each new program's stream is a new generation. A picture that
  changes size is a new generation too, without a restart. It is the last process of the
  vehicle's tree: a camera problem never restarts the board, control or helm.

  A V4L2 source without `@h264`/`@mjpeg` is probed (`Neptunus.Camera.V4L2`) before each
  start. The simulated camera gets the vehicle's pose from its simulator
  (`Neptunus.Camera.Pose`) while it renders (again after a PubSub restart,
  `Neptunus.PubSub.Follow`).

  Telemetry carries the state once a second as `camera: %{running, fps, error, state,
  restarts, codec, width, height}`.

  Options: `:id`, `:camera` — a source string or parsed source (none: no camera; this
  process then idles); `:ffmpeg` (the program, default found on the path), `:stall_ms`
  (default 5 000), `:start_ms` (default 20 000), `:linger_ms` (default 10 000).
  """
  use GenServer

  require Logger

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Camera.{Frame, Pose, Program, Source, Stream, V4L2}
  alias Neptunus.PubSub.Follow
  alias Neptunus.Vehicle.Telemetry

  @max_backoff_ms 30_000
  @check_ms 500
  # frames kept from the last keyframe on, for snapshots: at most this many, or bytes
  @max_gop_frames 600
  @max_gop_bytes 32_000_000
  # a camera program's error output kept for the reason it stopped
  @error_lines 5

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            source: Neptunus.Camera.Source.t() | nil,
            pose: Neptunus.PubSub.Follow.t(),
            phase: :none | :idle | :probing | :starting | :running | :restarting | :failed,
            port: port() | nil,
            exit_code: non_neg_integer() | nil,
            stream: Neptunus.Camera.Stream.t() | nil,
            info: Neptunus.Camera.Stream.info() | nil,
            generation: non_neg_integer(),
            frame: Neptunus.Camera.Frame.t() | nil,
            gop: [binary()] | :overflow,
            gop_bytes: non_neg_integer(),
            frames: non_neg_integer(),
            window: [integer()],
            error: String.t() | nil,
            reason: String.t() | nil,
            errors: [String.t()],
            backoff_ms: pos_integer(),
            restarts: non_neg_integer(),
            started_ms: integer() | nil,
            last_frame_ms: integer() | nil,
            watched_ms: integer() | nil,
            ffmpeg: String.t() | nil,
            stall_ms: pos_integer(),
            start_ms: pos_integer(),
            linger_ms: non_neg_integer(),
            timer: reference() | nil
          }
    @enforce_keys [:id, :source, :pose]
    defstruct [
      :id,
      :source,
      :pose,
      :port,
      :exit_code,
      :stream,
      :info,
      :frame,
      :error,
      :reason,
      :started_ms,
      :last_frame_ms,
      :watched_ms,
      :ffmpeg,
      :timer,
      phase: :none,
      generation: 0,
      gop: [],
      gop_bytes: 0,
      frames: 0,
      window: [],
      errors: [],
      backoff_ms: 1_000,
      restarts: 0,
      stall_ms: 5_000,
      start_ms: 20_000,
      linger_ms: 10_000
    ]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts),
    do:
      GenServer.start_link(__MODULE__, opts,
        name: Fleet.via(__MODULE__, Keyword.fetch!(opts, :id))
      )

  @doc "The `\"camera:<id>\"` topic viewers subscribe to (see the moduledoc)."
  @spec topic(String.t()) :: String.t()
  def topic(id), do: "camera:" <> id

  @doc """
  The topic the vehicle's recorder gets the frames on (`"stream"` and `"frame"` messages, as
  on `topic/1`): the same shared binaries, but recording is not watching — a simulated
  camera renders while someone watches it, whether it is recorded or not.
  """
  @spec record_topic(String.t()) :: String.t()
  def record_topic(id), do: "camera-record:" <> id

  @doc "Where browsers watch an MJPEG camera in an `<img>` (nil: no camera, or not MJPEG)."
  @spec url(String.t()) :: String.t() | nil
  def url(id) do
    case info(id) do
      %{codec: :mjpeg} -> "/camera/#{URI.encode(id)}.mjpg"
      _ -> nil
    end
  end

  @doc """
  What pages need to show vehicle `id`'s camera: `%{codec, video, url}` — the codec
  (`:h264` or `:mjpeg`; `:auto` for a V4L2 camera before its first stream), the video WebSocket's
  path and the MJPEG `<img>` stream's (nil for H.264) — or nil without a camera.
  """
  @spec info(String.t()) :: %{codec: atom(), video: String.t(), url: String.t() | nil} | nil
  def info(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :info)
  catch
    :exit, _ -> nil
  end

  @doc "Whether vehicle `id` has a camera (false when it has no camera process)."
  @spec configured?(String.t()) :: boolean()
  def configured?(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :configured?)
  catch
    :exit, _ -> false
  end

  @doc """
  The camera's state: `configured`, `state`, `running` (the program is up), `frames`
  published, `skipped` bytes that were not video, `fps` over the last second, `error` (why
  it is not running), `restarts`, `stream` (the current stream's info, nil before one).
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(Fleet.via(__MODULE__, id), :status)

  @doc """
  What a new viewer needs first: `%{camera: %{state, reason, restarts}, stream: info | nil}`
  (as the `camera` and `stream` messages). A `sim` camera starts rendering if it was idle.
  """
  @spec view(String.t()) :: %{camera: map(), stream: Stream.info() | nil}
  def view(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :view)
  catch
    :exit, _ -> %{camera: %{state: "none", reason: nil, restarts: 0}, stream: nil}
  end

  @doc "The newest frame (nil before the first)."
  @spec latest(String.t()) :: Frame.t() | nil
  def latest(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :latest)
  catch
    :exit, _ -> nil
  end

  @doc """
  The pictures a snapshot decodes: `{:ok, %{codec: :h264, frames: [annexb]}}` (the
  keyframe, with SPS and PPS, and every frame after it up to the newest), `{:ok, %{codec:
  :mjpeg, frames: [jpeg]}}` (the newest image) with the stream's `width` and `height`, or
  `{:error, reason}`; `source` describes the camera (`Neptunus.Camera.Source.describe/1`).
  """
  @spec pictures(String.t()) :: {:ok, map()} | {:error, String.t()}
  def pictures(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :pictures)
  catch
    :exit, _ -> {:error, "vehicle #{id} has no camera"}
  end

  # Callbacks

  @impl true
  def init(opts) do
    # so that terminate/2 runs on shutdown and ends the program
    Process.flag(:trap_exit, true)
    id = Keyword.fetch!(opts, :id)

    state = %State{
      id: id,
      source: nil,
      # the simulator's pose, followed while a sim camera renders
      pose: Follow.new([Pose.topic(id)]),
      ffmpeg: Keyword.get_lazy(opts, :ffmpeg, fn -> System.find_executable("ffmpeg") end),
      stall_ms: Keyword.get(opts, :stall_ms, 5_000),
      start_ms: Keyword.get(opts, :start_ms, 20_000),
      linger_ms: Keyword.get(opts, :linger_ms, 10_000),
      # generations go on across restarts of this process (seconds of the wall clock)
      generation: rem(div(Neptunus.Clock.wall_ms(), 1000), 0x1_0000_0000)
    }

    state =
      case Keyword.get(opts, :camera) do
        nil ->
          state

        %{kind: _} = source ->
          %{state | source: source}

        text when is_binary(text) ->
          case Source.parse(text) do
            {:ok, source} -> %{state | source: source}
            {:error, reason} -> %{state | error: reason}
          end
      end

    if state.source, do: {:ok, state, {:continue, :start}}, else: {:ok, state}
  end

  @impl true
  def handle_continue(:start, state) do
    :timer.send_interval(@check_ms, :check)
    :timer.send_interval(1_000, :report)
    state = if on_demand?(state), do: set_phase(state, :idle, nil), else: start(state)
    {:noreply, report(state)}
  end

  @impl true
  def handle_info({port, {:data, <<?d, bytes::binary>>}}, %State{port: port} = state) do
    # handled: the port program may send more (it holds back beyond a few MB unhandled)
    Program.ack(port, byte_size(bytes))

    case Stream.feed(state.stream, bytes, Neptunus.Clock.wall_us()) do
      {:ok, stream, outputs} ->
        {:noreply, Enum.reduce(outputs, %{state | stream: stream}, &publish/2)}

      {:error, reason} ->
        {:noreply, state |> stop_program() |> stopped(:restarting, reason)}
    end
  end

  def handle_info({port, {:data, <<?t, index::32, us::64>>}}, %State{port: port} = state),
    do: {:noreply, %{state | stream: Stream.stamp(state.stream, index, us)}}

  def handle_info({port, {:data, <<?e, line::binary>>}}, %State{port: port} = state) do
    limit = if state.phase == :probing, do: 200, else: @error_lines
    line = Source.redact(line, state.source)
    {:noreply, %{state | errors: Enum.take([line | state.errors], limit)}}
  end

  # the program ended: its exit code, said before the port program exits
  def handle_info({port, {:data, <<?x, code>>}}, %State{port: port} = state),
    do: {:noreply, %{state | exit_code: code}}

  def handle_info({port, {:data, _other}}, %State{port: port} = state), do: {:noreply, state}

  def handle_info({port, {:exit_status, code}}, %State{port: port} = state),
    do: {:noreply, ended(state, code)}

  # The port closed before the program's exit status reached the VM: a message written to it
  # as it ended (an acknowledgement, a pose) failed (epipe) and closed the port, which then
  # sends only this exit signal. The program is gone all the same; its code came first ('x').
  def handle_info({:EXIT, port, _reason}, %State{port: port} = state),
    do: {:noreply, ended(state, state.exit_code)}

  def handle_info(:restart, %State{port: nil, phase: phase} = state)
      when phase in [:restarting, :failed] do
    state = %{state | timer: nil, restarts: state.restarts + 1}

    if on_demand?(state) and not watched?(state),
      do: {:noreply, set_phase(state, :idle, nil)},
      else: {:noreply, report(start(state))}
  end

  def handle_info(:restart, state), do: {:noreply, state}

  def handle_info(:check, state), do: {:noreply, check(state)}

  # the camera's state in telemetry, once a second
  def handle_info(:report, state), do: {:noreply, report(state)}

  def handle_info({:pubsub, _topic, "pose", pose}, %State{port: port} = state)
      when is_port(port) do
    Program.tell(port, Pose.encode(pose))
    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, "pose", _pose}, state), do: {:noreply, state}

  # the PubSub scope restarted while rendering: follow the pose again
  def handle_info({:DOWN, _, :process, _, _} = msg, state), do: {:noreply, pose(state, msg)}
  def handle_info({Follow, :retry, _} = msg, state), do: {:noreply, pose(state, msg)}

  # the port is linked to us; its exit_status message (or, for the current port, its exit
  # signal: above) does the work
  def handle_info({:EXIT, port, _reason}, state) when is_port(port), do: {:noreply, state}
  def handle_info({:EXIT, _pid, reason}, state), do: {:stop, reason, state}

  def handle_info(_other, state), do: {:noreply, state}

  @impl true
  def handle_call(:configured?, _from, state), do: {:reply, state.source != nil, state}
  def handle_call(:latest, _from, state), do: {:reply, state.frame, state}

  def handle_call(:info, _from, %State{source: nil} = state), do: {:reply, nil, state}

  def handle_call(:info, _from, state) do
    # a probed V4L2 camera's codec once its stream is known
    codec =
      case state.info do
        %{codec: codec} -> String.to_existing_atom(codec)
        nil -> Source.codec(state.source)
      end

    url = if codec == :mjpeg, do: "/camera/#{URI.encode(state.id)}.mjpg", else: nil
    {:reply, %{codec: codec, video: "/video/#{URI.encode(state.id)}/websocket", url: url}, state}
  end

  def handle_call(:view, _from, state) do
    state = wake(state)
    {:reply, %{camera: camera_state(state), stream: state.stream && state.stream.info}, state}
  end

  def handle_call(:pictures, _from, state), do: {:reply, pictures_of(state), state}

  def handle_call(:status, _from, state) do
    reply = %{
      configured: state.source != nil,
      state: phase_name(state.phase),
      running: state.port != nil and state.phase != :probing,
      frames: state.frames,
      skipped: if(state.stream, do: state.stream.skipped_bytes, else: 0),
      fps: fps(state),
      error: state.error,
      restarts: state.restarts,
      stream: state.stream && state.stream.info
    }

    {:reply, reply, state}
  end

  @impl true
  def terminate(_reason, state) do
    # the port program ends its own program when its input closes
    stop_program(state)
    :ok
  end

  # Starting and stopping

  defp start(%State{source: %{kind: :v4l2, codec: :auto} = source} = state) do
    case Source.probe_command(source, tools(state)) do
      {:ok, command} ->
        state |> open(command) |> set_phase(:probing, nil)

      {:error, reason} ->
        stopped(state, :failed, reason)
    end
  end

  defp start(state), do: launch(state, state.source)

  # Starts the program of `source` (a V4L2 source with its codec decided).
  defp launch(state, source) do
    case Source.command(source, tools(state)) do
      {:ok, command} ->
        stream =
          Stream.new(
            format: command.format,
            source: Atom.to_string(source.kind),
            fps: Source.fps(source),
            generation: next_generation(state)
          )

        state = if source.kind == :sim, do: follow_pose(state), else: state

        %{state | stream: stream, info: nil, started_ms: now(), last_frame_ms: nil}
        |> open(command)
        |> set_phase(:starting, nil)

      {:error, reason} ->
        stopped(state, :failed, reason)
    end
  end

  # the next program's stream: a generation after the last one
  defp next_generation(%State{stream: nil} = state), do: state.generation
  defp next_generation(%State{stream: stream}), do: Stream.restart(stream).generation

  defp tools(state) do
    %{ffmpeg: state.ffmpeg, camera: Program.executable()}
  end

  defp open(state, %{executable: executable, args: args}) do
    %{state | port: Program.open(executable, args), errors: [], exit_code: nil}
  end

  # The program ended with `code` (nil: not known). A probe's end decides the codec; a
  # camera's is a fault: it starts again.
  defp ended(%State{phase: :probing} = state, _code) do
    state = %{state | port: nil}

    case V4L2.decide(Enum.reverse(state.errors), state.source) do
      {:ok, codec} ->
        Logger.info("vehicle #{state.id} camera: #{state.source.device} sends #{codec}")
        state |> launch(%{state.source | codec: codec}) |> report()

      {:error, reason} ->
        state |> stopped(:failed, reason) |> report()
    end
  end

  defp ended(state, code) do
    exited =
      if code, do: "the camera program exited (status #{code})", else: "the camera program ended"

    reason =
      case state.errors do
        [last | _] -> "#{exited}: #{last}"
        [] -> exited
      end

    %{state | port: nil} |> stopped(:restarting, reason) |> report()
  end

  defp stop_program(%State{port: port} = state) when is_port(port) do
    Program.close(port)
    %{state | port: nil}
  end

  defp stop_program(state), do: state

  # The program stopped or could not start: say why, start again after the backoff.
  defp stopped(state, phase, reason) do
    Logger.warning(
      "vehicle #{state.id} camera (#{Source.describe(state.source)}): #{reason}; " <>
        "retrying in #{state.backoff_ms} ms"
    )

    if state.error != reason do
      PubSub.broadcast(Telemetry.log_topic(state.id), "log", %{
        category: "errors",
        level: "warning",
        message: "camera: #{reason}",
        at: Neptunus.Clock.wall_ms()
      })
    end

    state = %{state | pose: Follow.unsubscribe(state.pose)}
    if state.timer, do: Process.cancel_timer(state.timer)
    timer = Process.send_after(self(), :restart, state.backoff_ms)

    %{
      state
      | error: reason,
        timer: timer,
        backoff_ms: min(state.backoff_ms * 2, @max_backoff_ms),
        gop: [],
        gop_bytes: 0
    }
    |> set_phase(phase, reason)
  end

  # (again: a stream started while one was followed)
  defp follow_pose(state) do
    {_subscribed_or_waiting, pose} = state.pose |> Follow.unsubscribe() |> Follow.subscribe()
    %{state | pose: pose}
  end

  defp pose(state, msg) do
    {_event, pose} = Follow.handle(state.pose, msg)
    %{state | pose: pose}
  end

  # A `sim` camera renders only while watched.
  defp on_demand?(%State{source: %{kind: :sim}}), do: true
  defp on_demand?(_state), do: false

  defp watched?(state), do: PubSub.subscriber_count(topic(state.id)) > 0

  defp wake(%State{phase: :idle} = state) do
    %{state | watched_ms: now()} |> start() |> report()
  end

  defp wake(state), do: %{state | watched_ms: now()}

  # Stalls, the first picture's deadline, an unwatched sim camera.
  defp check(%State{port: port, phase: phase} = state)
       when is_port(port) and phase in [:starting, :running] do
    now = now()
    state = if watched?(state), do: %{state | watched_ms: now}, else: state

    cond do
      on_demand?(state) and now - (state.watched_ms || state.started_ms) > state.linger_ms ->
        %{state | pose: Follow.unsubscribe(state.pose)}
        |> stop_program()
        |> set_phase(:idle, nil)
        |> report()

      phase == :running and now - state.last_frame_ms > state.stall_ms ->
        state
        |> stop_program()
        |> stopped(:restarting, "no picture for #{seconds(state.stall_ms)}")

      phase == :starting and now - state.started_ms > state.start_ms ->
        state
        |> stop_program()
        |> stopped(:restarting, "no picture within #{seconds(state.start_ms)} of starting")

      true ->
        state
    end
  end

  defp check(state), do: state

  defp seconds(ms), do: "#{Float.round(ms / 1000, 1)} s" |> String.replace(".0 s", " s")

  # Publishing

  defp publish({:stream, info}, state) do
    PubSub.broadcast(topic(state.id), "stream", info)
    PubSub.broadcast(record_topic(state.id), "stream", info)

    case state.info do
      %{width: w, height: h} = old when old.codec == info.codec ->
        # the same program, another picture: a new generation without a restart
        change = "the picture changed from #{w}x#{h} to #{info.width}x#{info.height}"
        Logger.info("vehicle #{state.id} camera: #{change}")
        %{state | info: info} |> set_phase(:running, change)

      _ ->
        %{state | info: info}
    end
  end

  defp publish({:frame, %Frame{} = frame}, state) do
    message = %{frame: frame}
    PubSub.broadcast(topic(state.id), "frame", message)
    PubSub.broadcast(record_topic(state.id), "frame", message)
    now = now()

    state =
      if state.phase != :running do
        %{state | backoff_ms: 1_000, error: nil} |> set_phase(:running, nil)
      else
        state
      end

    %{
      state
      | frame: frame,
        frames: state.frames + 1,
        last_frame_ms: now,
        window: [now | Enum.take_while(state.window, &(&1 > now - 1_000))]
    }
    |> keep_for_snapshot(frame)
  end

  defp keep_for_snapshot(state, %Frame{keyframe: true} = frame),
    do: %{state | gop: [Frame.payload(frame)], gop_bytes: byte_size(frame.data)}

  defp keep_for_snapshot(%State{gop: :overflow} = state, _frame), do: state

  defp keep_for_snapshot(state, frame) do
    bytes = state.gop_bytes + byte_size(frame.data)

    if length(state.gop) >= @max_gop_frames or bytes > @max_gop_bytes,
      do: %{state | gop: :overflow, gop_bytes: 0},
      else: %{state | gop: [Frame.payload(frame) | state.gop], gop_bytes: bytes}
  end

  defp pictures_of(%State{source: nil}), do: {:error, "the vehicle has no camera"}

  defp pictures_of(%State{stream: %Stream{info: %{} = info}, gop: [_ | _] = gop} = state) do
    if state.phase == :running do
      frames = if info.codec == "mjpeg", do: [hd(gop)], else: Enum.reverse(gop)

      {:ok,
       %{
         codec: String.to_existing_atom(info.codec),
         frames: frames,
         width: info.width,
         height: info.height,
         source: Source.describe(state.source)
       }}
    else
      {:error, "the camera is #{phase_name(state.phase)}: no picture now"}
    end
  end

  defp pictures_of(%State{gop: :overflow}),
    do: {:error, "no keyframe in the camera's last #{@max_gop_frames} frames: try again"}

  defp pictures_of(state),
    do: {:error, "the camera is #{phase_name(state.phase)}: no picture yet"}

  # The camera's state, told to viewers when it changes.
  defp set_phase(%State{phase: phase, reason: reason} = state, phase, reason), do: state

  defp set_phase(state, phase, reason) do
    state = %{state | phase: phase, reason: reason}
    PubSub.broadcast(topic(state.id), "camera", camera_state(state))
    state
  end

  defp camera_state(state),
    do: %{state: phase_name(state.phase), reason: state.reason, restarts: state.restarts}

  defp phase_name(:probing), do: "starting"
  defp phase_name(phase), do: Atom.to_string(phase)

  defp fps(state) do
    now = now()
    Enum.count(state.window, &(&1 > now - 1_000))
  end

  defp report(%State{source: nil} = state), do: state

  defp report(state) do
    info = state.stream && state.stream.info

    Telemetry.report(state.id, :camera, %{
      running: state.phase == :running,
      fps: fps(state),
      error: state.error,
      state: phase_name(state.phase),
      restarts: state.restarts,
      codec: info && info.codec,
      width: info && info.width,
      height: info && info.height
    })

    state
  end

  defp now, do: Neptunus.Clock.monotonic_ms()
end
