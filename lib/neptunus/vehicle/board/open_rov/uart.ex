defmodule Neptunus.Vehicle.Board.OpenROV.UART do
  @moduledoc """
  A real board on a serial port, speaking the OpenROV protocol
  (`Neptunus.Vehicle.Board.OpenROV.Protocol`) through our port program `priv/neptunus_uart`
  (`Neptunus.Vehicle.Board.SerialPort`): the program owns the file descriptor and its `poll()`
  loop, so nothing in the VM ever blocks on the tty.

  ## What it does

    * **Link.** Opens the device at the configured baud (raw 8N1). The link is *up* once the
      program reports the device open; it is *down* when opening fails, the device hangs up
      or is unplugged, or the program exits for any reason (its exit status, or the port's
      exit alone when a write found the program gone).
      A link that was up for at least 100 ms is reopened at once (the board keeps the
      last `go()` until a link writes neutral: every open does first); after that, or when
      it flapped faster, it reopens after a backoff (`Neptunus.Vehicle.Board.Backoff`:
      `reopen_min` doubling to `reopen_max`). Every change of `{up, reason}` is broadcast as event `link`
      `%{up: boolean, reason: String.t()}` on `"vehicle:<id>"` and logged; `link_status/1`
      returns it with the counters.
    * **Firmware profile** (`:firmware`, `:openrov_25` default or `:openrov_30`): every
      command is written in the profile's wire form
      (`Neptunus.Vehicle.Board.OpenROV.Protocol.frame/2`: 30.x wants a CRC byte before each
      command). What the board's output says about its firmware line is in the link status; a
      mismatch is logged once and broadcast (event `firmware` `%{configured, detected}`), never
      acted on (`Neptunus.Vehicle.Board.OpenROV.BoardLink`).
    * **The board's state on every (re)open, board reset and deadman recovery**: a neutral
      `go()` first, then the motor modifiers (`mtrmod1`/`mtrmod2` from the wiring, see
      `Neptunus.Vehicle.Board.OpenROV.Wiring`), lights, laser and tilt. A board reset (its
      uptime going backwards, or its start-up line `boot:1;`) and every (re)open are also told
      to navigation (`Navigation.board_reset/2`): its measurements start afresh.
    * **Settings confirmed, thrust held until they are**
      (`Neptunus.Vehicle.Board.OpenROV.BoardLink` decides): every setting is written again until
      the board echoes it, with a bound after which it is shown as failed with a reason (and
      still written, slower); a thrust demand other than neutral is held — a neutral `go()`
      written instead — until the board has confirmed the motor modifiers, then written. A hold
      is logged, broadcast as event `board` `%{event: "thrust_held", reason}` and put in the
      developer logger; the link status and telemetry show `board_settings` (`confirmed`,
      `pending`, `failed`), what is pending, why one failed, and `thrust_held`. A timer runs
      only while a setting is not confirmed.
    * **Commands.** `go` casts become `go(...)` with the vehicle's
      `Neptunus.Vehicle.Board.OpenROV.Wiring` (order, reversed motors, flag). Commands while the
      link is down are dropped (counted), never queued: the next link starts neutral. Writes are
      paced (`Neptunus.Vehicle.Board.OpenROV.Pacer`: at most 60 bytes in any 30 ms, commands
      ≥ 3 ms apart, so the board's 64-byte receive buffer never overflows), a newer `go()` or
      device value replacing a queued one (never a queued neutral `go()`: a newer `go()` waits
      behind it); a timer runs only while something is queued. Writes never block: when the
      program's input is busy the command is dropped and counted.
    * **Deadman.** Every `ping_interval` (1 s) it sends `ping(n);` — but only while the link is
      up *and* the vehicle's control was heard (`go` or `keepalive/1`, which
      `Neptunus.Vehicle.Control` calls every second) within `keepalive_timeout` (2 s). If
      control dies or hangs, pings stop and the board's own deadman stops the motors (once
      armed: 180 s after the board's boot; before that only the server's deadman protects,
      shown as `board_deadman_armed: false`). Pongs give the round-trip time and the link's
      liveness (`rtt_ms`, `pong_age_ms`).
    * **Telemetry.** Lines are framed, parsed and checked in
      `Neptunus.Vehicle.Board.OpenROV.Readings`; samples (`sim: nil`, plus the board's other
      fields under `board`) go to navigation (`Neptunus.Vehicle.Board.sample/3`). Garbage and
      wild points are counted, never passed on. The board's echoes (`cmd:…;`) count the
      commands it confirmed. The link's state (`up`, `reason` and the liveness fields) goes to
      `Telemetry.link/2` on every change and every ping tick.
    * **Shutdown.** It traps exits; on an orderly shutdown it writes a neutral `go()` before the
      port closes (the program flushes it before exiting). After a brutal kill the port
      program sees stdin close and exits; the board's deadman covers the rest.

  `t` of a sample is the time since this process started (s, monotonic).
  """
  use GenServer

  # a link up at least this long (ms) before it went down is reopened without waiting
  @reopen_at_once_after_ms 100

  require Logger

  alias Neptunus.{Allocation, PubSub}
  alias Neptunus.Vehicle.{Board, Navigation, Telemetry}
  alias Neptunus.Vehicle.Board.{Backoff, OpenROV, SerialPort}
  alias Neptunus.Vehicle.Board.OpenROV.{BoardLink, Pacer, Readings, Wiring}

  @behaviour Board

  @default_baud 115_200

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            device: String.t(),
            baud: pos_integer(),
            wiring: Neptunus.Vehicle.Board.OpenROV.Wiring.t(),
            profile: Neptunus.Vehicle.Board.OpenROV.Protocol.profile(),
            pacer: Neptunus.Vehicle.Board.OpenROV.Pacer.t(),
            pace_timer: reference() | nil,
            board_link: Neptunus.Vehicle.Board.OpenROV.BoardLink.t(),
            program: String.t(),
            port_env: [{charlist(), charlist()}],
            port: port() | nil,
            link: :down | :opening | :up,
            reason: String.t(),
            announced: {boolean(), String.t()} | nil,
            since_ms: integer(),
            program_error: String.t() | nil,
            backoff: Neptunus.Vehicle.Board.Backoff.t(),
            readings: Neptunus.Vehicle.Board.OpenROV.Readings.t(),
            started_at_ms: integer(),
            heard_at_ms: integer() | nil,
            ping_interval_ms: pos_integer(),
            keepalive_timeout_ms: pos_integer(),
            ping_n: non_neg_integer(),
            demand: Neptunus.Allocation.thrusters(),
            confirm_timer: {reference(), integer()} | nil,
            counters: %{atom() => non_neg_integer()}
          }
    @enforce_keys [
      :id,
      :topic,
      :device,
      :baud,
      :wiring,
      :profile,
      :pacer,
      :board_link,
      :program,
      :backoff,
      :readings
    ]
    defstruct [
      :id,
      :topic,
      :device,
      :baud,
      :wiring,
      :profile,
      :pacer,
      :pace_timer,
      :board_link,
      :program,
      :backoff,
      :readings,
      :port,
      :announced,
      :program_error,
      :heard_at_ms,
      :confirm_timer,
      port_env: [],
      link: :down,
      reason: "not opened yet",
      since_ms: 0,
      started_at_ms: 0,
      ping_interval_ms: 1_000,
      keepalive_timeout_ms: 2_000,
      ping_n: 0,
      demand: %{port: 0.0, vertical: 0.0, starboard: 0.0},
      counters: %{
        opens: 0,
        downs: 0,
        commands: 0,
        dropped_commands: 0,
        dropped_bytes: 0,
        pings: 0,
        pings_withheld: 0
      }
    ]
  end

  @doc """
  Starts the board link of vehicle `opts[:id]`, registered as `Board.via(id)`.

  Options:
    * `:id` (required)
    * `:device` (required) — e.g. `"/dev/ttyO1"`
    * `:baud` — #{@default_baud} (1200 … 921600, standard rates)
    * `:wiring` — a `Neptunus.Vehicle.Board.OpenROV.Wiring`, default
      `Neptunus.Vehicle.Board.OpenROV.Wiring.default/0`
    * `:firmware` — `:openrov_25` (default) or `:openrov_30`
    * `:ping_interval` — ms between deadman pings, default 1000
    * `:keepalive_timeout` — ms since control was last heard after which pings stop, default 2000
    * `:confirm_retry`, `:confirm_attempts` — a setting the board has not echoed is written
      again every `confirm_retry` ms (250), and shown as failed after `confirm_attempts` (8)
      writes (`Neptunus.Vehicle.Board.OpenROV.BoardLink`)
    * `:reopen_min`, `:reopen_max` — reopen backoff in ms, default 100 and 5000
    * `:max_line` — longest telemetry line kept, bytes, default 512
    * `:program` — path of the port program, default `priv/neptunus_uart`
    * `:os_time_slice_ns` — the OS time slice the port program asks for (`Neptunus.OS`),
      default none
  """
  @impl Board
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Board.via(id))
  end

  @doc "An OpenROV board: the three-thruster vehicle, our allocation (thesis eq. 9.3)."
  @impl Board
  @spec capabilities(keyword()) :: Board.capabilities()
  def capabilities(_opts), do: Board.thesis_capabilities()

  @doc """
  The serial line from the spec of `uart:DEVICE[@BAUD]` (`Board.SerialPort.parse_line/1`).

      iex> Neptunus.Vehicle.Board.OpenROV.UART.parse_spec("/dev/ttyO1@57600")
      {:ok, %{device: "/dev/ttyO1", baud: 57600}}
  """
  @impl Board
  @spec parse_spec(String.t()) ::
          {:ok, %{device: String.t(), baud: pos_integer()}} | {:error, String.t(), String.t()}
  def parse_spec(spec) do
    case SerialPort.parse_line(spec) do
      {:ok, device, baud} -> {:ok, %{device: device, baud: baud}}
      {:error, why} -> {:error, "uart:DEVICE[@BAUD]", why}
    end
  end

  @doc "Its motor wiring and firmware profile (`NEPTUNUS_WIRING`, `NEPTUNUS_FIRMWARE`)."
  @impl Board
  @spec settings() :: [Board.setting()]
  def settings, do: [:wiring, :firmware]

  @impl Board
  @spec go(String.t(), Neptunus.Allocation.thrusters()) :: :ok
  def go(id, thrusters), do: GenServer.cast(Board.via(id), {:go, thrusters})

  @doc "Control is alive: keeps the deadman pings going (see the moduledoc)."
  @impl Board
  @spec keepalive(String.t()) :: :ok
  def keepalive(id), do: GenServer.cast(Board.via(id), :keepalive)

  @doc """
  The link's state: `%{up, reason, device, baud, since_ms, queued, counters}` and the fields
  of `Neptunus.Vehicle.Board.OpenROV.BoardLink.status/2` (`firmware detected_firmware
  firmware_mismatch rtt_ms pong_age_ms board_uptime_ms board_deadman_armed
  board_deadman_tripped commands_sent commands_confirmed crc_failures board_resets
  deadman_recoveries board_settings board_settings_pending board_settings_reason
  thrust_held`), where `since_ms` is how long the link has been in its current state,
  `queued` the commands waiting for the pacer and `counters` merges the link's counters
  (`opens downs commands dropped_commands dropped_bytes pings pings_withheld`) with the
  readings' (`lines samples overlong text debug placeholder malformed out_of_range
  not_a_number key_as_value`).
  """
  @impl Board
  @spec link_status(String.t()) :: map()
  def link_status(id), do: GenServer.call(Board.via(id), :link_status)

  @doc "Sets the lights (0..255): `ligt(n);`. Kept and re-sent after every (re)open."
  @impl Board
  @spec lights(String.t(), 0..255) :: :ok
  def lights(id, n), do: GenServer.cast(Board.via(id), {:device, :lights, n})

  @doc "Sets the laser (0..255): `claser(n);`. Kept and re-sent after every (re)open."
  @impl Board
  @spec laser(String.t(), 0..255) :: :ok
  def laser(id, n), do: GenServer.cast(Board.via(id), {:device, :laser, n})

  @doc "Tilts the camera to `rad` (see `Board.tilt_us/1`): `tilt(µs);`. Re-sent after (re)open."
  @impl Board
  @spec tilt(String.t(), number()) :: :ok
  def tilt(id, rad), do: GenServer.cast(Board.via(id), {:device, :tilt, rad})

  @doc "Path of the port program (`Neptunus.Vehicle.Board.SerialPort.program/0`)."
  @spec program() :: String.t()
  defdelegate program, to: SerialPort

  # Callbacks

  @impl true
  def init(opts) do
    # the control path runs before the web fan-out (see Neptunus.Vehicle.Helm)
    Process.flag(:priority, :high)
    Process.flag(:trap_exit, true)
    id = Keyword.fetch!(opts, :id)
    now = now_ms()
    profile = Keyword.get(opts, :firmware) || :openrov_25
    wiring = Keyword.get(opts, :wiring) || Wiring.default()
    [mtrmod1, mtrmod2] = Wiring.modifier_commands(wiring)

    state = %State{
      id: id,
      topic: Telemetry.topic(id),
      device: Keyword.fetch!(opts, :device),
      baud: Keyword.get(opts, :baud, @default_baud),
      wiring: wiring,
      profile: profile,
      pacer: Pacer.new(),
      board_link:
        BoardLink.new(profile,
          settings: [mtrmod1: mtrmod1, mtrmod2: mtrmod2],
          retry_ms: Keyword.get(opts, :confirm_retry, 250),
          attempts: Keyword.get(opts, :confirm_attempts, 8)
        ),
      program: Keyword.get(opts, :program, program()),
      port_env: Neptunus.OS.port_env(Keyword.get(opts, :os_time_slice_ns)),
      backoff:
        Backoff.new(Keyword.get(opts, :reopen_min, 100), Keyword.get(opts, :reopen_max, 5_000)),
      readings: Readings.new(Keyword.get(opts, :max_line, 512)),
      ping_interval_ms: Keyword.get(opts, :ping_interval, 1_000),
      keepalive_timeout_ms: Keyword.get(opts, :keepalive_timeout, 2_000),
      started_at_ms: now,
      since_ms: now
    }

    Process.send_after(self(), :ping, state.ping_interval_ms)
    {:ok, state, {:continue, :open}}
  end

  @impl true
  def handle_continue(:open, state), do: {:noreply, open(state)}

  @impl true
  # The control path: a held demand (the board has not confirmed its motor modifiers) goes
  # out as neutral, and as itself once they are (BoardLink's :release).
  def handle_cast({:go, thrusters}, state) do
    us = Wiring.to_us(state.wiring, thrusters)

    {board_link, verdict, actions} = BoardLink.demand(state.board_link, us == {1500, 1500, 1500})

    state = %{state | heard_at_ms: now_ms(), demand: thrusters, board_link: board_link}

    case state.link do
      :up ->
        state = bump(state, :commands)

        state =
          case verdict do
            :send ->
              go_us(state, us)

            :hold ->
              Navigation.command(state.id, Allocation.neutral())
              write_go(state, Allocation.neutral())
          end

        {:noreply, perform(state, actions)}

      _ ->
        {:noreply, bump(state, :dropped_commands)}
    end
  end

  def handle_cast(:keepalive, state), do: {:noreply, %{state | heard_at_ms: now_ms()}}

  # Lights, laser and tilt are sent at once, independent of thrust (thesis §13.1), and kept
  # (BoardLink) so a reopened link gets them back; while the link is down they are only kept.
  def handle_cast({:device, device, value}, state) do
    {board_link, actions} =
      BoardLink.set(state.board_link, device, device_command(device, value), now_ms())

    state = %{state | board_link: board_link}

    case state.link do
      :up -> {:noreply, state |> bump(:commands) |> perform(actions)}
      _ -> {:noreply, bump(state, :dropped_commands)}
    end
  end

  @impl true
  def handle_call(:link_status, _from, state) do
    now = now_ms()

    status =
      %{
        up: state.link == :up,
        reason: state.reason,
        device: state.device,
        baud: state.baud,
        since_ms: now - state.since_ms,
        queued: Pacer.queued(state.pacer),
        counters: Map.merge(state.counters, state.readings.counters)
      }
      |> Map.merge(BoardLink.status(state.board_link, now))

    {:reply, status, state}
  end

  @impl true
  def handle_info({port, {kind, _} = message}, %State{port: port} = state)
      when kind in [:data, :exit_status],
      do: {:noreply, program_event(SerialPort.decode(message), state)}

  def handle_info(:reopen, %State{port: nil} = state), do: {:noreply, open(state)}
  def handle_info(:reopen, state), do: {:noreply, state}

  def handle_info(:ping, state) do
    Process.send_after(self(), :ping, state.ping_interval_ms)
    state = ping(state)
    report_link(state)
    {:noreply, state}
  end

  def handle_info(:pace, state), do: {:noreply, drain(%{state | pace_timer: nil})}

  def handle_info(:confirm, state) do
    {board_link, actions} = BoardLink.tick(state.board_link, now_ms())
    state = %{state | board_link: board_link, confirm_timer: nil}
    {:noreply, state |> perform(actions) |> confirm_timer()}
  end

  # The port is linked to us (we trap exits). When its program exits, the exit_status message
  # (above) comes first and does the work. A port closed before the program's exit status
  # reached the VM (a write to a program that had just ended: `epipe`) sends only this exit:
  # the link is down all the same (else it would stay "up" on a dead port, every command
  # dropped, never reopened).
  def handle_info({:EXIT, port, reason}, %State{port: port} = state) do
    reason = state.program_error || "port program gone (#{inspect(reason)})"
    {:noreply, down(%{state | port: nil}, reason)}
  end

  def handle_info({:EXIT, port, _reason}, state) when is_port(port), do: {:noreply, state}
  def handle_info({:EXIT, _pid, reason}, state), do: {:stop, reason, state}

  # Messages from a port we already gave up on.
  def handle_info({port, _}, state) when is_port(port), do: {:noreply, state}

  @impl true
  def terminate(_reason, %State{link: :up} = state) do
    # Orderly shutdown: neutral first; the program writes it before it exits on stdin close.
    write(
      state,
      OpenROV.Protocol.frame(Wiring.go_command(state.wiring, Allocation.neutral()), state.profile)
    )

    SerialPort.close(state.port)
  catch
    _, _ -> :ok
  end

  def terminate(_reason, _state), do: :ok

  # Link ----------------------------------------------------------------------------------

  defp device_command(:lights, n), do: OpenROV.Protocol.lights(n)
  defp device_command(:laser, n), do: OpenROV.Protocol.laser(n)
  defp device_command(:tilt, rad), do: OpenROV.Protocol.tilt(Board.tilt_us(rad))

  defp open(state) do
    case SerialPort.open_tty(state.device, state.baud,
           program: state.program,
           env: state.port_env
         ) do
      {:ok, port} -> %{state | port: port, link: :opening, program_error: nil}
      {:error, why} -> down(state, "cannot start #{state.program}: #{why}")
    end
  end

  defp program_event({:open, _path}, state) do
    now = now_ms()
    {board_link, actions} = BoardLink.opened(state.board_link, now)

    state =
      %{
        state
        | link: :up,
          since_ms: now,
          readings: Readings.reset(state.readings),
          pacer: Pacer.clear(state.pacer),
          board_link: board_link
      }
      |> bump(:opens)
      |> announce(true, "open")

    board_reset(state, "board link opened")
    perform(state, actions)
  end

  defp program_event({:read, bytes}, state) do
    now = now_ms()
    t = (now - state.started_at_ms) / 1000
    {readings, samples} = Readings.feed(state.readings, bytes, t)
    {events, readings} = Readings.take_events(readings)
    Enum.each(samples, &Board.sample(state.id, &1))
    Enum.reduce(events, %{state | readings: readings}, &board_event(&1, &2, now))
  end

  defp program_event({:error, text}, state), do: %{state | program_error: text}
  defp program_event({:dropped, n}, state), do: bump(state, :dropped_bytes, n)

  defp program_event({:exit, status}, state) do
    reason = state.program_error || "port program exited with status #{status}"
    down(%{state | port: nil}, reason)
  end

  defp program_event(_other, state), do: state

  defp down(state, reason) do
    now = now_ms()
    was_up = state.link == :up

    backoff =
      if was_up, do: Backoff.up_for(state.backoff, now - state.since_ms), else: state.backoff

    # A link that was up for a while is tried again at once: the board keeps the last go()
    # until a new link writes neutral (its own deadman is seconds away, and not armed for
    # minutes after boot). Failures after that back off; a link that was up for less than
    # 100 ms (one that flaps) backs off at once.
    {delay, backoff} =
      if was_up and now - state.since_ms >= @reopen_at_once_after_ms,
        do: {0, backoff},
        else: Backoff.next(backoff)

    Process.send_after(self(), :reopen, delay)

    state = %{
      state
      | link: :down,
        board_link: BoardLink.closed(state.board_link),
        pacer: Pacer.clear(state.pacer),
        backoff: backoff,
        since_ms: if(was_up, do: now, else: state.since_ms)
    }

    state = if was_up, do: bump(state, :downs), else: state
    announce(state, false, reason)
  end

  # Broadcasts and logs a change of {up, reason}; repeated failures for the same reason are
  # announced once.
  defp announce(state, up, reason) do
    state = %{state | reason: reason}

    if state.announced == {up, reason} do
      state
    else
      if up,
        do: Logger.info("vehicle #{state.id}: board link up on #{state.device} @ #{state.baud}"),
        else: Logger.warning("vehicle #{state.id}: board link down on #{state.device}: #{reason}")

      PubSub.broadcast(state.topic, "link", %{up: up, reason: reason})
      state = %{state | announced: {up, reason}}
      report_link(state)
      state
    end
  end

  # Deadman ---------------------------------------------------------------------------------

  defp ping(%State{link: :up} = state) do
    if state.heard_at_ms != nil and now_ms() - state.heard_at_ms <= state.keepalive_timeout_ms do
      n = state.ping_n
      state = %{state | ping_n: rem(n + 1, 2_147_483_647)}
      state |> bump(:pings) |> queue({:ping, n}, OpenROV.Protocol.ping(n))
    else
      bump(state, :pings_withheld)
    end
  end

  defp ping(state), do: state

  # The board's state -------------------------------------------------------------------------

  defp board_event(event, state, now) do
    {board_link, actions} = BoardLink.event(state.board_link, event, now)
    perform(%{state | board_link: board_link}, actions)
  end

  # Carries out what the board link's core decided, in order; while a setting is not
  # confirmed, a timer asks it again.
  defp perform(state, []), do: state

  defp perform(state, actions),
    do: actions |> Enum.reduce(state, &board_action/2) |> confirm_timer()

  # one timer, for the earliest time the core has something to do (a stale one is harmless:
  # the core does nothing before its time)
  defp confirm_timer(state) do
    case {BoardLink.next_tick_at(state.board_link), state.confirm_timer} do
      {nil, _} ->
        state

      {at, {_ref, armed_at}} when armed_at <= at ->
        state

      {at, timer} ->
        if timer, do: Process.cancel_timer(elem(timer, 0))
        ref = Process.send_after(self(), :confirm, max(at - now_ms(), 0))
        %{state | confirm_timer: {ref, at}}
    end
  end

  # navigation's model follows what the motors get (Board.go/2 told it the demand)
  defp board_action(:neutral, state) do
    Navigation.command(state.id, Allocation.neutral())
    write_go(state, Allocation.neutral())
  end

  defp board_action({:send, key, command}, state), do: queue(state, key, command)

  defp board_action({:board_reset, reason}, state) do
    Logger.warning("vehicle #{state.id}: #{reason}: sending its state again")
    PubSub.broadcast(state.topic, "board", %{event: "reset", reason: reason})
    board_reset(state, reason)
    %{state | readings: Readings.board_reset(state.readings)}
  end

  defp board_action({:deadman_recovery, reason}, state) do
    Logger.warning("vehicle #{state.id}: #{reason}; it was cleared: sending its state again")
    PubSub.broadcast(state.topic, "board", %{event: "deadman_recovery", reason: reason})
    state
  end

  defp board_action({:firmware_mismatch, detected}, state) do
    configured = BoardLink.profile_name(state.profile)
    detected = BoardLink.profile_name(detected)

    Logger.error(
      "vehicle #{state.id}: the board on #{state.device} talks like #{detected} firmware, " <>
        "configured #{configured} (NEPTUNUS_FIRMWARE): its commands may be refused"
    )

    PubSub.broadcast(state.topic, "firmware", %{configured: configured, detected: detected})
    report_link(state)
    state
  end

  defp board_action({:hold, reason}, state) do
    Logger.warning("vehicle #{state.id}: #{reason}")
    PubSub.broadcast(state.topic, "board", %{event: "thrust_held", reason: reason})
    log_entry(state, "warning", reason)
    report_link(state)
    state
  end

  defp board_action(:release, state) do
    log_entry(state, "info", "board settings confirmed: the held thrust goes to the board")
    report_link(state)
    Navigation.command(state.id, state.demand)
    write_go(state, state.demand)
  end

  defp board_action({:settings, summary}, state) do
    case summary.state do
      :confirmed ->
        Logger.info("vehicle #{state.id}: board settings confirmed")
        log_entry(state, "info", "board settings confirmed")

      :failed ->
        message = "board settings not confirmed: #{summary.reason}"
        Logger.error("vehicle #{state.id}: #{message}")
        log_entry(state, "error", message)

      :pending ->
        :ok
    end

    report_link(state)
    state
  end

  # an entry for the developer page's logger (category link) and the recording
  defp log_entry(state, level, message), do: Telemetry.log(state.id, "link", level, message)

  # Navigation starts its measurements afresh: nothing read before is trusted.
  defp board_reset(state, reason), do: Navigation.board_reset(state.id, reason)

  @link_report [
    :rtt_ms,
    :pong_age_ms,
    :board_uptime_ms,
    :board_deadman_armed,
    :firmware,
    :detected_firmware,
    :firmware_mismatch,
    :commands_sent,
    :commands_confirmed,
    :board_settings,
    :board_settings_pending,
    :board_settings_reason,
    :thrust_held
  ]

  @doc "The details `link_status/1` reports (telemetry's `link`): the board link's liveness."
  @impl Board
  @spec link_details() :: [atom()]
  def link_details, do: @link_report

  defp report_link(state) do
    {up, reason} = state.announced || {state.link == :up, state.reason}

    details =
      if up, do: Map.take(BoardLink.status(state.board_link, now_ms()), @link_report), else: %{}

    Telemetry.link(state.id, Map.merge(details, %{up: up, reason: reason}))
  end

  # I/O ------------------------------------------------------------------------------------

  # A neutral go() is sticky: never replaced by a later go() while it waits (Pacer).
  defp write_go(state, thrusters), do: go_us(state, Wiring.to_us(state.wiring, thrusters))

  defp go_us(state, us),
    do:
      queue(state, :go, OpenROV.Protocol.go(us, state.wiring.direct),
        sticky: us == {1500, 1500, 1500}
      )

  # Queues a command (framed for the firmware) and writes what the pacer allows now.
  defp queue(state, key, text, opts \\ [])

  defp queue(%State{link: :up} = state, key, text, opts) do
    case Pacer.push(state.pacer, key, OpenROV.Protocol.frame(text, state.profile), opts) do
      {:ok, pacer} -> drain(%{state | pacer: pacer})
      {:error, _} -> bump(state, :dropped_commands)
    end
  end

  defp queue(state, _key, _text, _opts), do: bump(state, :dropped_commands)

  defp drain(state) do
    now = now_ms()
    {out, pacer} = Pacer.take(state.pacer, now)

    state =
      Enum.reduce(out, %{state | pacer: pacer}, fn {key, bytes}, state ->
        dropped = state.counters.dropped_commands
        state = write(state, bytes)

        cond do
          state.counters.dropped_commands != dropped -> state
          match?({:ping, _}, key) -> sent(state, &BoardLink.ping_sent(&1, elem(key, 1), now))
          true -> sent(state, & &1)
        end
      end)

    case {Pacer.next_at(state.pacer, now), state.pace_timer} do
      {nil, _} ->
        state

      {at, nil} ->
        %{state | pace_timer: Process.send_after(self(), :pace, max(at - now, 0))}

      {_at, _timer} ->
        state
    end
  end

  # Never blocks: a busy port program means the command is dropped (and counted).
  defp write(%State{port: port} = state, bytes) when is_port(port) do
    case SerialPort.write(port, bytes) do
      :ok -> state
      {:error, _busy_or_closed} -> bump(state, :dropped_commands)
    end
  end

  defp write(state, _bytes), do: bump(state, :dropped_commands)

  defp sent(state, also),
    do: %{state | board_link: state.board_link |> BoardLink.sent() |> also.()}

  defp bump(state, key, n \\ 1),
    do: %{state | counters: Map.update!(state.counters, key, &(&1 + n))}

  defp now_ms, do: Neptunus.Clock.monotonic_ms()
end
