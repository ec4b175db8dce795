defmodule Neptunus.Vehicle.Recorder do
  @moduledoc """
  Records a vehicle's dives: everything it publishes on `"vehicle:<id>"` — telemetry at its
  full rate, stops, helm and control events — its developer log entries on `"log:<id>"`
  (event `log`: safety, link, errors, autopilot notices, so a dive's logger is complete),
  the snapshots taken, and its camera's frames as received, into one folder per dive
  (`Neptunus.Dive` for the layout, the listing and the reading; `Neptunus.Recording` for the
  entries' format and the CSV and JSON lines exports).

  **Dives.** A dive begins when the recorder starts (with the node or the vehicle, or when
  recording resumes after the disk had no room), and when a pilot takes the helm after it
  was free for `gap_ms` (`NEPTUNUS_DIVE_GAP_MIN`, default 10 min) in a dive that had a pilot
  (`Neptunus.Dive.Boundary`): one dive per time in the water, and nothing between two dives
  left unrecorded. A dive folder `<dir>/<id>/<UTC start>-<n>/` holds the entries
  (`entries-0001.log`, a `disk_log` of `{at, event, payload}` terms written asynchronously
  so a slow disk never holds up the vehicle; when a part reaches `max_bytes`, counted as the
  entries' external term size, the next part is opened, so a long dive is never cut short and
  no entry is refused), the video (`video/`, written by `Neptunus.Vehicle.Recorder.Video`),
  the snapshots (`snapshots/`, `dive_folder/1`), and `summary.json`: the recorder folds every
  entry into a `Neptunus.Dive.Summary` and saves it when the dive begins, every 10 s, at once
  after a stop, a handover or a snapshot, and closed when the dive ends. A dive its node was
  killed in is left unclosed; the next recorder of the vehicle repairs its summary from its
  entries (`Neptunus.Dive.repair/1`, in a process of its own) and never changes the entries
  or the video.

  **Disk space.** Recording stops before the disk fills — less than `min_free_bytes`
  (`NEPTUNUS_RECORDING_MIN_FREE_MB`, default 512 MiB) free, checked at start and every 5 s —
  and a new dive begins when there is room again. Nothing is dropped silently: when the disk
  refuses to write (full, removed, read-only) or is nearly full, recording stops and says so
  — a `log` entry (category `errors`) on `"log:<id>"`, a `recording` event on the vehicle's
  topic, telemetry's `recording` (`on` false, `error` why: the operator page shows it) and the
  server log — and `status/1` tells why. What was recorded stays as it is: the dive is closed,
  never deleted; deleting is the user's (the API's `DELETE`).

  Retention is opt-in (`keep_ms`, from `NEPTUNUS_RECORDING_KEEP_DAYS`; nil keeps everything):
  at start and every minute, the recorder deletes its vehicle's dives last written more than
  `keep_ms` ago, never the dive it is writing. Each deletion is said — an `info` entry
  (category `recording`) on `"log:<id>"` and the server log; a dive that cannot be deleted is
  an `errors` entry.

  Durability: `disk_log` keeps what it is given in memory (up to 64 KiB or 2 s) before it
  writes, so a node killed outright (`kill -9`, the kernel's OOM killer, a crash of the VM)
  would lose up to 2 s of the dive. So the recorder has its log written and synced
  (`disk_log:sync/1`: written to the file, then `fsync`) every `sync_ms` (default 50) while
  anything waits, and at once after every entry that is not `telemetry` (stops, helm and
  control events, `recording`, presence: `Neptunus.Recording.sync_at_once?/1`). A killed node
  loses at most the telemetry of the last `sync_ms` plus the time one sync takes (≈ 0.2 ms,
  tens of ms on a busy disk: `bench/recorder_sync`), within the 0.1 s the recorder promises,
  and no other event once the recorder has handled it (it is on disk before the recorder
  takes its next message); with the `fsync`, the same holds when the vehicle computer loses
  power. On a disk slower than that (10 or more messages waiting for the recorder), events
  too wait for the periodic sync, and one sync follows the other: the recorder never falls
  ever further behind, it only writes in larger batches. The video writer syncs its own
  files every 0.5 s (≤ 1 s of video lost). The writing happens in the `disk_log` process,
  the recorder and the video writer, all off the control path: the vehicle and the camera
  only send them messages, and no broadcaster waits for the disk. A part left by a killed
  node is read as far as it is whole (`Neptunus.Recording.entries/1`).

  PubSub restarts: the recorder watches the PubSub scope it subscribed with (see
  `Neptunus.PubSub`). When the scope stops, the subscription is gone and nothing reaches the
  recorder: from then until it has subscribed again (it retries every 20 ms), `status/1` and
  the telemetry say it is not recording, and why; the gap is then said — a `log` entry
  (category `errors`) on `"log:<id>"` and the server log.

  Its state is in every telemetry payload as `recording: %{on, error}`. It comes after the
  helm in the vehicle's tree: its failures never restart the board, control or helm.
  Options: `:id`; `:recording` — `dir` (nil or absent: recording is off; the node's vehicles
  get `config :neptunus, :recording` here, from `Neptunus.Application`), `max_bytes` and
  `min_free_bytes` (`defaults/0`), `keep_ms`, `gap_ms`, `sync_ms`, `video` (false: no video;
  or the video writer's options) and, for tests, `free_bytes` (a function of the directory),
  `sync` (syncs a log, like `disk_log:sync/1`), `wall_ms` (the wall clock in ms, a function)
  and `rm` (deletes a dive, like `Neptunus.Dive.delete/1`).
  """
  use GenServer

  require Logger

  alias Neptunus.{Dive, Fleet, PubSub, Recording}
  alias Neptunus.Dive.{Boundary, Summary}
  alias Neptunus.PubSub.Follow
  alias Neptunus.Vehicle.Recorder.Video
  alias Neptunus.Vehicle.Telemetry

  @default_max_bytes 256 * 1024 * 1024
  @default_min_free_bytes 512 * 1024 * 1024
  @default_gap_ms 10 * 60_000
  @disk_check_ms 5_000
  @expire_ms 60_000
  @summary_ms 10_000
  @default_sync_ms 50
  # messages waiting beyond which the recorder is behind (see "Durability")
  @behind 10
  @not_subscribed "not receiving the vehicle's events: the PubSub restarted (subscribing again)"

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            dir: Path.t() | nil,
            max_bytes: pos_integer(),
            log: term() | nil,
            file: String.t() | nil,
            files: [String.t()],
            folder: Path.t() | nil,
            dives: [String.t()],
            part: non_neg_integer(),
            summary: Neptunus.Dive.Summary.t() | nil,
            summary_dirty: boolean(),
            boundary: Neptunus.Dive.Boundary.t() | nil,
            gap_ms: non_neg_integer() | nil,
            video: pid() | nil,
            video_opts: keyword() | false,
            entries: non_neg_integer(),
            bytes: non_neg_integer(),
            error: String.t() | nil,
            min_free_bytes: non_neg_integer(),
            free_bytes: (Path.t() -> non_neg_integer() | nil),
            keep_ms: pos_integer() | nil,
            wall_ms: (() -> integer()),
            rm: (Path.t() -> :ok | {:error, File.posix()}),
            low_disk: boolean(),
            sync_ms: pos_integer(),
            unsynced: boolean(),
            tick: reference() | nil,
            sync: (term() -> :ok | {:error, term()}),
            follow: Neptunus.PubSub.Follow.t(),
            unsubscribed_at_ms: integer() | nil
          }
    @enforce_keys [:id, :dir, :max_bytes, :min_free_bytes, :free_bytes, :wall_ms, :rm, :follow]
    defstruct [
      :id,
      :dir,
      :max_bytes,
      :log,
      :file,
      :folder,
      :summary,
      :boundary,
      :gap_ms,
      :video,
      :error,
      :min_free_bytes,
      :free_bytes,
      :keep_ms,
      :wall_ms,
      :rm,
      :sync_ms,
      :sync,
      :tick,
      :follow,
      :unsubscribed_at_ms,
      video_opts: [],
      files: [],
      dives: [],
      part: 0,
      summary_dirty: false,
      entries: 0,
      bytes: 0,
      low_disk: false,
      unsynced: false
    ]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: Fleet.via(__MODULE__, Keyword.fetch!(opts, :id)))
  end

  @doc """
  What the recorder is doing: `recording` (bool), the `dive` being written (its name) and
  its `folder`, the `dives` of this run, the entries part being written (`file`) and the
  `files` (parts) of this run, the `entries` written, the `error` that stopped it (nil), the
  `video` written into the current dive (`Neptunus.Vehicle.Recorder.Video.status/1`, nil
  without a video writer).
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(Fleet.via(__MODULE__, id), :status)

  @doc "Writes what is buffered to disk (before an export of the dive being written)."
  @spec sync(String.t()) :: :ok
  def sync(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :sync)
  catch
    :exit, _ -> :ok
  end

  @doc """
  The folder of the dive vehicle `id` records now (for its snapshots), nil when it does not
  record.
  """
  @spec dive_folder(String.t()) :: Path.t() | nil
  def dive_folder(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :folder)
  catch
    :exit, _ -> nil
  end

  @doc """
  Records an entry that was not broadcast — `event` and its `payload` at the wall clock now
  — into the dive being recorded (a snapshot taken: `"snapshot"`), on disk at once. Nothing
  when the vehicle does not record.
  """
  @spec note(String.t(), String.t(), map()) :: :ok
  def note(id, event, payload) when is_binary(event) and is_map(payload) do
    GenServer.call(Fleet.via(__MODULE__, id), {:note, event, payload})
  catch
    :exit, _ -> :ok
  end

  @doc """
  The part size, free disk and dive gap limits when `:recording` does not say (the one place
  of these defaults; `Neptunus.Config.Recording` gives them to the environment variables).
  """
  @spec defaults() :: %{
          max_bytes: pos_integer(),
          min_free_bytes: non_neg_integer(),
          gap_ms: non_neg_integer()
        }
  def defaults,
    do: %{
      max_bytes: @default_max_bytes,
      min_free_bytes: @default_min_free_bytes,
      gap_ms: @default_gap_ms
    }

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    config = Keyword.get(opts, :recording, [])
    config = Map.new(config)

    state = %State{
      id: id,
      # the vehicle's topic and its log topic (safety, link, errors, autopilot notices: the
      # recording's logger is complete)
      follow: Follow.new([Telemetry.topic(id), Telemetry.log_topic(id)]),
      dir: Map.get(config, :dir),
      max_bytes: Map.get(config, :max_bytes, @default_max_bytes),
      min_free_bytes: Map.get(config, :min_free_bytes, @default_min_free_bytes),
      free_bytes: Map.get(config, :free_bytes, &Recording.free_bytes/1),
      keep_ms: Map.get(config, :keep_ms),
      gap_ms: Map.get(config, :gap_ms, @default_gap_ms),
      wall_ms: Map.get(config, :wall_ms, &Neptunus.Clock.wall_ms/0),
      rm: Map.get(config, :rm, &Dive.delete/1),
      sync_ms: Map.get(config, :sync_ms, @default_sync_ms),
      sync: Map.get(config, :sync, &:disk_log.sync/1),
      video_opts: Map.get(config, :video, [])
    }

    if state.dir do
      {:ok, state, {:continue, :open}}
    else
      Telemetry.report(id, :recording, %{on: false, error: nil})
      {:ok, state}
    end
  end

  @impl true
  def handle_continue(:open, state) do
    Process.flag(:trap_exit, true)
    state = start_video(state)
    state = follow(state, Follow.subscribe(state.follow))
    :timer.send_interval(@disk_check_ms, :check_disk)
    :timer.send_interval(@expire_ms, :expire)
    :timer.send_interval(@summary_ms, :save_summary)
    state = state |> check_disk() |> expire()
    repair_unclosed(state)
    {:noreply, state}
  end

  @impl true
  def handle_info({:pubsub, _topic, _event, _payload}, %State{log: nil} = state),
    do: {:noreply, state}

  def handle_info({:pubsub, _topic, event, payload}, state) when is_map(payload),
    do: {:noreply, record(state, {Neptunus.Clock.wall_ms(), event, payload})}

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  def handle_info(:sync_tick, state), do: {:noreply, sync_log(%{state | tick: nil})}

  def handle_info(:save_summary, %State{summary_dirty: true} = state),
    do: {:noreply, save_summary(state, false)}

  def handle_info(:save_summary, state), do: {:noreply, state}

  # The PubSub scope stopped, or is back (see "PubSub restarts").
  def handle_info({:DOWN, _ref, :process, _pid, _reason} = msg, state),
    do: {:noreply, follow(state, Follow.handle(state.follow, msg))}

  def handle_info({Follow, :retry, _} = msg, state),
    do: {:noreply, follow(state, Follow.handle(state.follow, msg))}

  # disk_log's notifications (notify: true)

  def handle_info(
        {:disk_log, _node, log, {:error_status, {:error, reason}}},
        %State{log: log} = state
      ) do
    {:noreply, state |> close() |> failed("writing #{state.file} failed: #{inspect(reason)}")}
  end

  def handle_info({:disk_log, _node, _log, _info}, state), do: {:noreply, state}

  def handle_info({:video_failed, reason}, %State{log: nil} = state) do
    Logger.warning("vehicle #{state.id}: #{reason}")
    {:noreply, state}
  end

  def handle_info({:video_failed, reason}, state),
    do: {:noreply, state |> close() |> failed(reason)}

  def handle_info(:check_disk, state), do: {:noreply, check_disk(state)}
  def handle_info(:expire, state), do: {:noreply, expire(state)}

  def handle_info({:EXIT, pid, reason}, %State{video: pid} = state) when reason != :normal do
    Logger.error(
      "vehicle #{state.id}: the video writer stopped: #{inspect(reason)}; starting it again"
    )

    state = start_video(%{state | video: nil})
    if state.video && state.folder, do: Video.record(state.video, Dive.video_folder(state.folder))
    {:noreply, state}
  end

  def handle_info({:EXIT, _pid, _reason}, state), do: {:noreply, state}

  @impl true
  def handle_call(:status, _from, state) do
    %{on: on, error: error} = recording_state(state)

    reply = %{
      recording: on,
      dir: state.dir,
      dive: state.folder && Path.basename(state.folder),
      folder: state.folder,
      dives: Enum.reverse(state.dives),
      file: state.file,
      files: Enum.reverse(state.files),
      entries: state.entries,
      error: error,
      video: video_status(state)
    }

    {:reply, reply, state}
  end

  def handle_call(:sync, _from, state) do
    state = sync_log(%{state | unsynced: true})
    {:reply, :ok, if(state.summary_dirty, do: save_summary(state, false), else: state)}
  end

  def handle_call(:folder, _from, state), do: {:reply, state.log && state.folder, state}

  def handle_call({:note, _event, _payload}, _from, %State{log: nil} = state),
    do: {:reply, :ok, state}

  def handle_call({:note, event, payload}, _from, state),
    do: {:reply, :ok, record(state, {Neptunus.Clock.wall_ms(), event, payload})}

  @impl true
  def terminate(_reason, state) do
    _ = close(state)
    :ok
  end

  # One entry into the dive: a new dive first when it begins one (Dive.Boundary).
  defp record(state, {_at, event, _payload} = entry) do
    state =
      case Boundary.event(state.boundary, entry) do
        {:same, boundary} ->
          %{state | boundary: boundary}

        {:new_dive, boundary} ->
          Logger.info("vehicle #{state.id}: a new dive begins (the helm was free for a while)")
          state |> close() |> open_dive() |> Map.put(:boundary, %{boundary | piloted: true})
      end

    if state.log, do: write(state, entry, event), else: state
  end

  defp write(state, entry, event) do
    _ = :disk_log.alog(state.log, entry)
    bytes = state.bytes + :erlang.external_size(entry)
    summary = Summary.add(state.summary, entry)

    state = %{
      state
      | entries: state.entries + 1,
        bytes: bytes,
        unsynced: true,
        summary: summary,
        summary_dirty: true
    }

    # events on disk at once, telemetry with the periodic sync (see "Durability")
    state =
      if Recording.sync_at_once?(event) and not behind?(),
        do: sync_log(state),
        else: arm_sync(state)

    state = if Summary.notable?(event), do: save_summary(state, false), else: state

    # the next part before this one passes max_bytes: no entry is ever refused as "full"
    if bytes >= state.max_bytes, do: next_part(state), else: state
  end

  # What the follow of the vehicle's topics says (its retries are its own): the subscription
  # gone, the gap then said once subscribed again.
  defp follow(state, {:lost, follow}) do
    Logger.warning("vehicle #{state.id}: recording paused: #{@not_subscribed}")
    state = %{state | follow: follow, unsubscribed_at_ms: Neptunus.Clock.monotonic_ms()}
    report(state)
    state
  end

  defp follow(%State{unsubscribed_at_ms: at} = state, {:subscribed, follow}) when at != nil,
    do: resubscribed(%{state | follow: follow})

  defp follow(state, {:waiting, follow}),
    do: %{
      state
      | follow: follow,
        unsubscribed_at_ms: state.unsubscribed_at_ms || Neptunus.Clock.monotonic_ms()
    }

  defp follow(state, {_subscribed_or_other, follow}), do: %{state | follow: follow}

  defp resubscribed(state) do
    ms = Neptunus.Clock.monotonic_ms() - state.unsubscribed_at_ms

    message = "the PubSub restarted: what the vehicle published during #{ms} ms was not recorded"

    Logger.error("vehicle #{state.id}: #{message}")
    log(state, "error", message, %{gap_ms: ms})
    state = %{state | unsubscribed_at_ms: nil}
    report(state)
    state
  end

  # What the recorder is doing, as status/1 and the telemetry say it: on only while it
  # writes, that is, with a file open and the vehicle's events reaching it.
  defp recording_state(%State{dir: nil}), do: %{on: false, error: nil}
  defp recording_state(%State{error: error}) when error != nil, do: %{on: false, error: error}

  defp recording_state(state) do
    cond do
      not Follow.subscribed?(state.follow) -> %{on: false, error: @not_subscribed}
      state.log == nil -> %{on: false, error: nil}
      true -> %{on: true, error: nil}
    end
  end

  defp report(state), do: Telemetry.report(state.id, :recording, recording_state(state))

  # Writes what disk_log holds in memory and syncs it (see "Durability"); a failure arrives
  # as disk_log's error_status notification.
  defp sync_log(%State{log: log, unsynced: true} = state) when log != nil do
    _ = state.sync.(log)
    %{state | unsynced: false}
  end

  defp sync_log(state), do: state

  # One periodic sync at a time: a sync slower than sync_ms delays the next one instead of
  # piling up behind it.
  defp arm_sync(%State{tick: nil} = state),
    do: %{state | tick: Process.send_after(self(), :sync_tick, state.sync_ms)}

  defp arm_sync(state), do: state

  # A disk slower than the broadcasts: events wait for the periodic sync with the telemetry.
  defp behind? do
    {:message_queue_len, waiting} = Process.info(self(), :message_queue_len)
    waiting >= @behind
  end

  # Retention (opt-in): the vehicle's dives last written more than keep_ms ago go, each
  # one said on the log topic; never the dive being written.
  defp expire(%State{keep_ms: nil} = state), do: state

  defp expire(%State{dir: dir, id: id} = state) do
    dir
    |> Dive.list(id)
    |> Dive.expired(dir, state.wall_ms.(), state.keep_ms, state.folder)
    |> Enum.each(fn %{name: name, modified_at: at} ->
      days = div(state.keep_ms, 86_400_000)

      case state.rm.(Dive.path(dir, id, name)) do
        :ok ->
          message = "recording #{name} deleted: older than #{days} days (retention)"
          Logger.info("vehicle #{id}: #{message}")
          log(state, "info", message, %{name: name, modified_at: at})

        {:error, reason} ->
          message =
            "recording #{name} is older than #{days} days but cannot be deleted: #{reason}"

          Logger.error("vehicle #{id}: #{message}")
          log(state, "error", message, %{name: name, modified_at: at})
      end
    end)

    state
  end

  defp log(state, level, message, fields) do
    PubSub.broadcast(
      Telemetry.log_topic(state.id),
      "log",
      Map.merge(fields, %{
        category: if(level == "error", do: "errors", else: "recording"),
        level: level,
        message: message,
        at: Neptunus.Clock.wall_ms()
      })
    )
  end

  # Recording stops before the disk fills (a full disk on the vehicle's computer breaks more
  # than recording) and resumes in a new dive once there is room again.
  defp check_disk(%State{dir: dir} = state) do
    free = state.free_bytes.(dir) || state.free_bytes.(Path.dirname(Path.expand(dir)))
    low? = free != nil and free < state.min_free_bytes

    cond do
      low? and not state.low_disk ->
        mb = div(free, 1_048_576)
        limit = div(state.min_free_bytes, 1_048_576)
        state = close(state)

        %{
          failed(
            state,
            "disk nearly full: #{mb} MB free (below the #{limit} MB kept free, " <>
              "NEPTUNUS_RECORDING_MIN_FREE_MB): recording stopped; what was recorded is kept"
          )
          | low_disk: true
        }

      not low? and state.low_disk ->
        Logger.info("vehicle #{state.id}: the disk has room again: recording resumes")
        open_dive(%{state | low_disk: false})

      not low? and state.log == nil and state.error == nil ->
        # the first check, at start
        open_dive(state)

      true ->
        state
    end
  end

  # A new dive: its folder, its first entries part, its summary, the video into it.
  defp open_dive(state) do
    dir = Path.join(state.dir, state.id)
    now = state.wall_ms.()

    with :ok <- File.mkdir_p(dir),
         name = free_name(dir, now),
         folder = Path.join(dir, name),
         :ok <- File.mkdir(folder) do
      summary = Summary.new(now)

      state = %{
        state
        | folder: folder,
          dives: [name | state.dives],
          part: 0,
          summary: summary,
          boundary: Boundary.new(state.gap_ms, now),
          error: nil
      }

      state = open_part(state)

      if state.log do
        if state.video, do: Video.record(state.video, Dive.video_folder(folder))
        save_summary(state, false)
      else
        state
      end
    else
      {:error, reason} ->
        failed(state, "cannot record to #{dir}: #{inspect(reason)}")
    end
  end

  defp open_part(state) do
    part = state.part + 1
    path = Path.join(state.folder, Dive.part_name(part))

    case open_log(state.id, path) do
      {:ok, log} ->
        state = %{
          state
          | log: log,
            file: path,
            files: [path | state.files],
            part: part,
            bytes: 0,
            error: nil
        }

        report(state)
        state

      {:error, reason} ->
        failed(state, "cannot record to #{state.folder}: #{inspect(reason)}")
    end
  end

  # the dive goes on in its next entries part
  defp next_part(state) do
    _ = state.sync.(state.log)
    _ = :disk_log.close(state.log)
    open_part(%{state | log: nil, unsynced: false})
  end

  defp open_log(id, path) do
    opts = [
      name: {__MODULE__, id, path},
      file: String.to_charlist(path),
      type: :halt,
      format: :internal,
      size: :infinity,
      notify: true,
      mode: :read_write
    ]

    case :disk_log.open(opts) do
      {:ok, log} -> {:ok, log}
      {:repaired, log, _, _} -> {:ok, log}
      {:error, reason} -> {:error, reason}
    end
  end

  # the next free `<UTC now>-<n>` in dir (neither a dive nor a recording from before dives)
  defp free_name(dir, now_ms) do
    now = DateTime.from_unix!(now_ms, :millisecond)

    Stream.iterate(1, &(&1 + 1))
    |> Stream.map(&Dive.name(now, &1))
    |> Enum.find(
      &(not File.exists?(Path.join(dir, &1)) and not File.exists?(Path.join(dir, &1 <> ".log")))
    )
  end

  # Ends the dive being written: the entries synced and closed, the video stopped, the
  # summary saved closed.
  defp close(%State{log: nil} = state), do: state

  defp close(state) do
    _ = :disk_log.close(state.log)
    state = %{state | log: nil, unsynced: false}
    video = if state.video, do: stop_video(state), else: nil
    state = save_summary(state, true, video)
    %{state | folder: nil, summary: nil}
  end

  defp stop_video(state) do
    status = Video.status(state.video)
    :ok = Video.record(state.video, nil)
    status
  catch
    :exit, _ -> nil
  end

  defp save_summary(state, closed, video \\ :ask)
  defp save_summary(%State{summary: nil} = state, _closed, _video), do: state

  defp save_summary(state, closed, video) do
    video = if video == :ask, do: video_status(state), else: video

    extra =
      case video do
        %{frames: frames} = v when frames > 0 ->
          %{video: Map.take(v, [:codec, :frames, :segments, :bytes])}

        _ ->
          %{video: nil}
      end

    case Dive.write_summary(state.folder, state.summary, closed, extra) do
      :ok ->
        :ok

      {:error, reason} ->
        Logger.warning("vehicle #{state.id}: cannot save the dive's summary: #{inspect(reason)}")
    end

    %{state | summary_dirty: false}
  end

  defp video_status(%State{video: nil}), do: nil

  defp video_status(state) do
    Video.status(state.video)
  catch
    :exit, _ -> nil
  end

  defp start_video(%State{video_opts: false} = state), do: state

  defp start_video(state) do
    opts = Keyword.merge(state.video_opts, id: state.id, recorder: self())

    case Video.start_link(opts) do
      {:ok, pid} ->
        %{state | video: pid}

      {:error, reason} ->
        Logger.error("vehicle #{state.id}: cannot start the video writer: #{inspect(reason)}")
        state
    end
  end

  # Dives a killed node left unclosed get their summary from their entries, in a process of
  # its own (reading a long dive takes a while); never the dive being written.
  defp repair_unclosed(state) do
    current = state.folder
    %State{dir: dir, id: id} = state

    spawn(fn ->
      Process.flag(:priority, :low)

      for folder <- Dive.unclosed(dir, id), folder != current do
        case Dive.repair(folder) do
          :ok ->
            Logger.info(
              "vehicle #{id}: dive #{Path.basename(folder)} was interrupted: its summary is made again from what was recorded"
            )

          {:error, reason} ->
            Logger.warning(
              "vehicle #{id}: cannot repair the summary of #{folder}: #{inspect(reason)}"
            )
        end
      end
    end)
  end

  defp failed(state, message) do
    Logger.error("vehicle #{state.id}: recording stopped: #{message}")
    log(state, "error", "recording stopped: #{message}", %{})

    PubSub.broadcast(Telemetry.topic(state.id), "recording", %{recording: false, error: message})
    state = %{state | log: nil, error: message}
    report(state)
    state
  end
end
