defmodule Neptunus.Vehicle.Recorder do
  @moduledoc """
  Records everything a vehicle publishes on `"vehicle:<id>"` — telemetry at its full rate,
  stops, helm and control events — and its developer log entries on `"log:<id>"` (event
  `log`: safety, link, errors, autopilot notices, so a recording's logger is complete) to disk (`Neptunus.Recording` for the format, the
  listing and the exports).

  One file per run of this process (`<dir>/<id>/<UTC start>-<n>.log`, a `disk_log` of
  `{at, event, payload}` terms, written asynchronously so a slow disk never holds up the
  vehicle). When a file reaches `max_bytes` (counted as the entries' external term size) it
  is closed and the next one opened, so a long dive is never cut short and no entry is
  refused. Recording also stops before the disk fills — less than `min_free_bytes` (default
  512 MiB) free, checked at start and every minute — and starts a new file when there is
  room again. Nothing is dropped silently: when the disk refuses to write (full, removed,
  read-only) or is nearly full, recording stops and says so — a `log` entry (category `errors`) on
  `"log:<id>"`, a `recording` event on the vehicle's topic and the server log — and `status/1`
  tells why.

  Retention is opt-in (`keep_ms`, from `NEPTUNUS_RECORDING_KEEP_DAYS`; nil keeps everything):
  at start and every minute, the recorder deletes its vehicle's recordings last written more
  than `keep_ms` ago, never the file it is writing. Each deletion is said — an `info` entry
  (category `recording`) on `"log:<id>"` and the server log; a file that cannot be deleted is
  an `errors` entry.

  Durability: `disk_log` keeps what it is given in memory (up to 64 KiB or 2 s) before it
  writes, so a node killed outright (`kill -9`, the kernel's OOM killer, a crash of the VM)
  would lose up to 2 s of the dive. So the recorder has its log written and synced
  (`disk_log:sync/1`: written to the file, then `fsync`) every `sync_ms` (default 100) while
  anything waits, and at once after every entry that is not `telemetry` (stops, helm and
  control events, `recording`, presence: `Neptunus.Recording.sync_at_once?/1`). A killed node
  loses at most the telemetry of the last `sync_ms` plus the time one sync takes (≈ 0.2 ms,
  tens of ms on a busy disk: `bench/recorder_sync`), within the 0.25 s the recorder promises,
  and no other event once the recorder has handled it (it is on disk before the recorder
  takes its next message); with the `fsync`, the same holds when the vehicle computer loses
  power. On a disk slower than that (10 or more messages waiting for the recorder), events
  too wait for the periodic sync, and one sync follows the other: the recorder never falls
  ever further behind, it only writes in larger batches. The writing happens in the `disk_log` process and
  the recorder, both off the control path: the vehicle only sends them its broadcasts, and
  no broadcaster waits for the disk. A file left by a killed node is read as far as it is
  whole (`Neptunus.Recording.entries/1`) and repaired when opened for writing.

  PubSub restarts: the recorder watches the PubSub scope it subscribed with (see
  `Neptunus.PubSub`). When the scope stops, the subscription is gone and nothing reaches the
  recorder: from then until it has subscribed again (it retries every 20 ms), `status/1` and
  the telemetry say it is not recording, and why; the gap is then said — a `log` entry
  (category `errors`) on `"log:<id>"` and the server log.

  Its state is in every telemetry payload as `recording: %{on, error}`. It comes after the
  helm in the vehicle's tree: its failures never restart the board,
  control or helm. Options: `:id`; `:recording` — `dir` (nil or absent: recording is off; the
  node's vehicles get `config :neptunus, :recording` here, from `Neptunus.Application`),
  `max_bytes` and `min_free_bytes` (`defaults/0`), `keep_ms`, `sync_ms` and, for tests, `free_bytes` (a function of the
  directory), `sync` (syncs a log, like `disk_log:sync/1`),
  `wall_ms` (the wall clock in ms, a function) and `rm` (deletes a file, like `File.rm/1`).
  """
  use GenServer

  require Logger

  alias Neptunus.{Fleet, PubSub, Recording}
  alias Neptunus.Vehicle.Telemetry

  @default_max_bytes 256 * 1024 * 1024
  @default_min_free_bytes 512 * 1024 * 1024
  @disk_check %{every_ms: 60_000}
  @default_sync_ms 100
  # messages waiting beyond which the recorder is behind (see "Durability")
  @behind 10
  @resubscribe_ms 20
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
            pubsub: reference() | nil,
            unsubscribed_at_ms: integer() | nil
          }
    @enforce_keys [:id, :dir, :max_bytes, :min_free_bytes, :free_bytes, :wall_ms, :rm]
    defstruct [
      :id,
      :dir,
      :max_bytes,
      :log,
      :file,
      :error,
      :min_free_bytes,
      :free_bytes,
      :keep_ms,
      :wall_ms,
      :rm,
      :sync_ms,
      :sync,
      :tick,
      :pubsub,
      :unsubscribed_at_ms,
      files: [],
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
  What the recorder is doing: `recording` (bool), the `file` being written and the `files` of
  this run, the `entries` written, the `error` that stopped it (nil).
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(Fleet.via(__MODULE__, id), :status)

  @doc "Writes what is buffered to disk (before an export of the file being written)."
  @spec sync(String.t()) :: :ok
  def sync(id) do
    GenServer.call(Fleet.via(__MODULE__, id), :sync)
  catch
    :exit, _ -> :ok
  end

  @doc """
  The file size and free disk limits when `:recording` does not say (the one place of
  these defaults; `Neptunus.Config.Recording` gives them to the environment variables).
  """
  @spec defaults() :: %{max_bytes: pos_integer(), min_free_bytes: non_neg_integer()}
  def defaults, do: %{max_bytes: @default_max_bytes, min_free_bytes: @default_min_free_bytes}

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    config = Keyword.get(opts, :recording, [])
    config = Map.new(config)

    state = %State{
      id: id,
      dir: Map.get(config, :dir),
      max_bytes: Map.get(config, :max_bytes, @default_max_bytes),
      min_free_bytes: Map.get(config, :min_free_bytes, @default_min_free_bytes),
      free_bytes: Map.get(config, :free_bytes, &Recording.free_bytes/1),
      keep_ms: Map.get(config, :keep_ms),
      wall_ms: Map.get(config, :wall_ms, &Neptunus.Clock.wall_ms/0),
      rm: Map.get(config, :rm, &File.rm/1),
      sync_ms: Map.get(config, :sync_ms, @default_sync_ms),
      sync: Map.get(config, :sync, &:disk_log.sync/1)
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
    state = subscribe(state)
    :timer.send_interval(Map.get(@disk_check, :every_ms), :check_disk)
    {:noreply, state |> check_disk() |> expire()}
  end

  @impl true
  def handle_info({:pubsub, _topic, _event, _payload}, %State{log: nil} = state),
    do: {:noreply, state}

  def handle_info({:pubsub, _topic, event, payload}, state) when is_map(payload) do
    entry = {Neptunus.Clock.wall_ms(), event, payload}
    _ = :disk_log.alog(state.log, entry)
    bytes = state.bytes + :erlang.external_size(entry)
    state = %{state | entries: state.entries + 1, bytes: bytes, unsynced: true}

    # events on disk at once, telemetry with the periodic sync (see "Durability")
    state =
      if Recording.sync_at_once?(event) and not behind?(),
        do: sync_log(state),
        else: arm_sync(state)

    # the next file before this one passes max_bytes: no entry is ever refused as "full"
    state = if bytes >= state.max_bytes, do: state |> close() |> open_next(), else: state
    {:noreply, state}
  end

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  def handle_info(:sync_tick, state), do: {:noreply, sync_log(%{state | tick: nil})}

  # The PubSub scope stopped: the subscription is gone (see "PubSub restarts").
  def handle_info({:DOWN, ref, :process, _pid, _reason}, %State{pubsub: ref} = state) do
    Logger.warning("vehicle #{state.id}: recording paused: #{@not_subscribed}")
    state = %{state | pubsub: nil, unsubscribed_at_ms: Neptunus.Clock.monotonic_ms()}
    report(state)
    {:noreply, subscribe(state)}
  end

  # a scope watched before the one the recorder subscribed with
  def handle_info({:DOWN, _ref, :process, _pid, _reason}, state), do: {:noreply, state}

  def handle_info(:subscribe, %State{pubsub: nil} = state), do: {:noreply, subscribe(state)}
  def handle_info(:subscribe, state), do: {:noreply, state}

  # disk_log's notifications (notify: true)

  def handle_info(
        {:disk_log, _node, log, {:error_status, {:error, reason}}},
        %State{log: log} = state
      ) do
    {:noreply, state |> close() |> failed("writing #{state.file} failed: #{inspect(reason)}")}
  end

  def handle_info({:disk_log, _node, _log, _info}, state), do: {:noreply, state}
  def handle_info(:check_disk, state), do: {:noreply, state |> check_disk() |> expire()}
  def handle_info({:EXIT, _pid, _reason}, state), do: {:noreply, state}

  @impl true
  def handle_call(:status, _from, state) do
    %{on: on, error: error} = recording_state(state)

    reply = %{
      recording: on,
      dir: state.dir,
      file: state.file,
      files: Enum.reverse(state.files),
      entries: state.entries,
      error: error
    }

    {:reply, reply, state}
  end

  def handle_call(:sync, _from, state), do: {:reply, :ok, sync_log(%{state | unsynced: true})}

  @impl true
  def terminate(_reason, state) do
    _ = close(state)
    :ok
  end

  # Subscribes to the vehicle's topic, watching the scope first; retries while it restarts.
  defp subscribe(state) do
    with {:ok, ref} <- PubSub.monitor(),
         :ok <- subscribe_or_demonitor(state.id, ref) do
      state = %{state | pubsub: ref}
      if state.unsubscribed_at_ms, do: resubscribed(state), else: state
    else
      {:error, :not_running} ->
        Process.send_after(self(), :subscribe, @resubscribe_ms)
        %{state | unsubscribed_at_ms: state.unsubscribed_at_ms || Neptunus.Clock.monotonic_ms()}
    end
  end

  # the vehicle's topic and its log topic (safety, link, errors, autopilot notices: the
  # recording's logger is complete)
  defp subscribe_or_demonitor(id, ref) do
    with :ok <- PubSub.subscribe(Telemetry.topic(id)),
         :ok <- PubSub.subscribe(Telemetry.log_topic(id)) do
      :ok
    else
      {:error, :not_running} = error ->
        Process.demonitor(ref, [:flush])
        error
    end
  end

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
  defp recording_state(%State{pubsub: nil}), do: %{on: false, error: @not_subscribed}
  defp recording_state(%State{log: nil}), do: %{on: false, error: nil}
  defp recording_state(_state), do: %{on: true, error: nil}

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

  # Retention (opt-in): the vehicle's recordings last written more than keep_ms ago go, each
  # one said on the log topic; never the file being written.
  defp expire(%State{keep_ms: nil} = state), do: state

  defp expire(%State{dir: dir, id: id} = state) do
    dir
    |> Recording.list(id)
    |> Recording.expired(dir, state.wall_ms.(), state.keep_ms, state.file)
    |> Enum.each(fn %{name: name, modified_at: at} ->
      days = div(state.keep_ms, 86_400_000)

      case state.rm.(Recording.path(dir, id, name)) do
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
  # than recording) and resumes in a new file once there is room again.
  defp check_disk(%State{dir: dir} = state) do
    free = state.free_bytes.(dir) || state.free_bytes.(Path.dirname(Path.expand(dir)))
    low? = free != nil and free < state.min_free_bytes

    cond do
      low? and not state.low_disk ->
        mb = div(free, 1_048_576)
        limit = div(state.min_free_bytes, 1_048_576)
        state = close(state)
        %{failed(state, "disk nearly full: #{mb} MB free (below #{limit} MB)") | low_disk: true}

      not low? and state.low_disk ->
        open_next(%{state | low_disk: false})

      not low? and state.log == nil and state.error == nil ->
        # the first check, at start
        open_next(state)

      true ->
        state
    end
  end

  defp open_next(state) do
    dir = Path.join(state.dir, state.id)

    with :ok <- File.mkdir_p(dir),
         name = free_name(dir),
         path = Path.join(dir, name),
         {:ok, log} <- open_log(state.id, path) do
      state = %{state | log: log, file: path, files: [path | state.files], bytes: 0, error: nil}
      report(state)
      state
    else
      {:error, reason} ->
        failed(state, "cannot record to #{dir}: #{inspect(reason)}")
    end
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

  # the next free `<UTC now>-<n>.log` in dir
  defp free_name(dir) do
    now = DateTime.utc_now()

    Stream.iterate(1, &(&1 + 1))
    |> Stream.map(&Recording.file_name(now, &1))
    |> Enum.find(&(not File.exists?(Path.join(dir, &1))))
  end

  defp close(%State{log: nil} = state), do: state

  defp close(state) do
    _ = :disk_log.close(state.log)
    %{state | log: nil, unsynced: false}
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
