defmodule Neptunus.Vehicle.Camera do
  @moduledoc """
  A vehicle's camera: runs its source program (`Neptunus.Camera.Source`, e.g. ffmpeg on
  `/dev/video0`) as a port, cuts its output into JPEG frames (`Neptunus.Camera.MJPEG`),
  keeps the newest and hands each to the viewers — the `/camera/<id>.mjpg` streams
  (`NeptunusWeb.CameraStream`), subscribed to `"camera:<id>"`. A frame is one binary shared by
  every viewer, never copied or re-encoded per viewer.

  When the program exits or cannot start, the camera says why (`status/1`, a `log` entry on
  `"log:<id>"`) and starts it again after 1, 2, 4 … 30 s. Telemetry carries its state as
  `camera: %{running, fps, error}`, updated every second. It is the last process of the
  vehicle's tree: a camera problem never restarts the board, control or helm.

  On shutdown (the vehicle stops, the node stops) the camera ends its program with `SIGTERM`,
  whatever the program is doing: closing the port alone stops only a program that writes (it
  gets `SIGPIPE`) or reads its input. After a brutal kill of this process the program is left
  with a closed pipe and ends at its next write, as a streaming camera does within a frame.

  Options: `:id`, `:camera` — a source string or parsed source (none: no camera; this
  process then idles).
  """
  use GenServer

  require Logger

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Camera.{MJPEG, Source}
  alias Neptunus.Vehicle.Telemetry

  @max_backoff_ms 30_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            source: Neptunus.Camera.Source.t() | nil,
            port: port() | nil,
            buffer: binary(),
            frame: binary() | nil,
            frames: non_neg_integer(),
            skipped: non_neg_integer(),
            window: [integer()],
            error: String.t() | nil,
            backoff_ms: pos_integer(),
            restarts: non_neg_integer()
          }
    @enforce_keys [:id, :source]
    defstruct [
      :id,
      :source,
      :port,
      :frame,
      :error,
      buffer: <<>>,
      frames: 0,
      skipped: 0,
      window: [],
      backoff_ms: 1_000,
      restarts: 0
    ]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts),
    do:
      GenServer.start_link(__MODULE__, opts,
        name: Fleet.via(__MODULE__, Keyword.fetch!(opts, :id))
      )

  @doc "The `\"camera:<id>\"` topic viewers subscribe to (term messages `{:pubsub, topic, \"frame\", %{jpeg: binary}}`)."
  @spec topic(String.t()) :: String.t()
  def topic(id), do: "camera:" <> id

  @doc "Where browsers watch the camera (nil: the vehicle has none)."
  @spec url(String.t()) :: String.t() | nil
  def url(id) do
    if configured?(id), do: "/camera/#{URI.encode(id)}.mjpg", else: nil
  end

  @doc "Whether vehicle `id` has a camera (false when it has no camera process)."
  @spec configured?(String.t()) :: boolean()
  def configured?(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :configured?)
  catch
    :exit, _ -> false
  end

  @doc """
  The camera's state: `configured`, `running` (the program is up), `frames` received,
  `skipped` bytes, `fps` over the last second, `error` (why it is not running), `restarts`.
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(Fleet.via(__MODULE__, id), :status)

  @doc "The newest frame (nil before the first)."
  @spec latest(String.t()) :: binary() | nil
  def latest(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :latest)
  catch
    :exit, _ -> nil
  end

  @impl true
  def init(opts) do
    # so that terminate/2 runs on shutdown and ends the program
    Process.flag(:trap_exit, true)
    id = Keyword.fetch!(opts, :id)

    state =
      case Keyword.get(opts, :camera) do
        nil ->
          %State{id: id, source: nil}

        %{kind: _} = source ->
          %State{id: id, source: source}

        text when is_binary(text) ->
          case Source.parse(text) do
            {:ok, source} -> %State{id: id, source: source}
            {:error, reason} -> %State{id: id, source: nil, error: reason}
          end
      end

    if state.source, do: {:ok, state, {:continue, :start}}, else: {:ok, state}
  end

  @impl true
  def handle_continue(:start, state) do
    :timer.send_interval(1_000, :report)
    {:noreply, state |> start() |> report()}
  end

  @impl true
  def handle_info({port, {:data, data}}, %State{port: port} = state) do
    {frames, rest, skipped} = MJPEG.split(state.buffer <> data)
    now = Neptunus.Clock.monotonic_ms()

    Enum.each(frames, fn frame ->
      PubSub.broadcast(topic(state.id), "frame", %{jpeg: frame})
    end)

    state =
      case frames do
        [] ->
          state

        _ ->
          window = Enum.take_while([now | state.window], &(&1 > now - 1_000))
          window = List.duplicate(now, length(frames) - 1) ++ window

          %{
            state
            | frame: List.last(frames),
              frames: state.frames + length(frames),
              window: window,
              backoff_ms: 1_000,
              error: nil
          }
      end

    {:noreply, %{state | buffer: rest, skipped: state.skipped + skipped}}
  end

  def handle_info({port, {:exit_status, code}}, %State{port: port} = state) do
    state = state |> Map.put(:port, nil) |> stopped("the camera program exited (status #{code})")
    {:noreply, report(state)}
  end

  def handle_info(:restart, %State{port: nil} = state),
    do: {:noreply, report(start(%{state | restarts: state.restarts + 1}))}

  # the camera's state in telemetry, once a second
  def handle_info(:report, state), do: {:noreply, report(state)}

  # the port is linked to us; its exit_status message does the work
  def handle_info({:EXIT, port, _reason}, state) when is_port(port), do: {:noreply, state}
  def handle_info({:EXIT, _pid, reason}, state), do: {:stop, reason, state}

  def handle_info(_other, state), do: {:noreply, state}

  @impl true
  def handle_call(:configured?, _from, state), do: {:reply, state.source != nil, state}
  def handle_call(:latest, _from, state), do: {:reply, state.frame, state}

  def handle_call(:status, _from, state) do
    reply = %{
      configured: state.source != nil,
      running: state.port != nil,
      frames: state.frames,
      skipped: state.skipped,
      fps: fps(state),
      error: state.error,
      restarts: state.restarts
    }

    {:reply, reply, state}
  end

  @impl true
  def terminate(_reason, %State{port: port}) when is_port(port) do
    os_pid =
      case Port.info(port, :os_pid) do
        {:os_pid, pid} -> pid
        nil -> nil
      end

    Port.close(port)

    if os_pid,
      do: System.cmd("kill", ["-TERM", Integer.to_string(os_pid)], stderr_to_stdout: true)

    :ok
  catch
    _, _ -> :ok
  end

  def terminate(_reason, _state), do: :ok

  defp fps(state) do
    now = Neptunus.Clock.monotonic_ms()
    Enum.count(state.window, &(&1 > now - 1_000))
  end

  defp report(state) do
    Telemetry.report(state.id, :camera, %{
      running: state.port != nil,
      fps: fps(state),
      error: state.error
    })

    state
  end

  defp start(state) do
    case Source.command(state.source) do
      {:ok, program, args} ->
        port =
          Port.open({:spawn_executable, program}, [
            :binary,
            :stream,
            :exit_status,
            :use_stdio,
            args: args
          ])

        %{state | port: port, buffer: <<>>}

      {:error, reason} ->
        stopped(state, reason)
    end
  end

  defp stopped(state, reason) do
    Logger.warning("vehicle #{state.id} camera: #{reason}; retrying in #{state.backoff_ms} ms")

    if state.error != reason do
      PubSub.broadcast(Telemetry.log_topic(state.id), "log", %{
        category: "errors",
        level: "warning",
        message: "camera: #{reason}",
        at: Neptunus.Clock.wall_ms()
      })
    end

    Process.send_after(self(), :restart, state.backoff_ms)
    %{state | error: reason, backoff_ms: min(state.backoff_ms * 2, @max_backoff_ms), buffer: <<>>}
  end
end
