defmodule Neptunus.Vehicle.Board.SITL.Firmware do
  @moduledoc """
  The SITL board's firmware as a pure value: what the published OpenROV Arduino firmware does
  with the bytes it receives and what it writes back, byte for byte, in two profiles —
  `:openrov_25` (2.5.2, plain commands) and `:openrov_30` (30.0.2, each command prefixed with a
  CRC byte). `Neptunus.Vehicle.Board.SITL.Device` runs it next to a `Neptunus.Sim`: it feeds
  the simulator's readings in with `sense/2`, the received bytes with `receive/3`, and calls
  `tick/2`; both return the bytes the board writes. Times are ms of one monotonic clock; the
  board's own `millis()` is that clock minus the time of the last (re)boot (`reset/2`).

  ## The loop

  The firmware is one loop; its timers fire when *more than* their period has passed since
  they last fired (`now - last > period`), so at a loop of about a millisecond the 100 ms
  navigation output comes every 101 ms and the 1 s outputs every 1001 ms. This module steps
  from one due timer to the next, which is what a 1 ms loop does, and runs each loop
  iteration in the firmware's order: serial commands, then internal commands, then the
  devices' timers, then the shared-data and navigation outputs. The main loop's output timers
  start at millis 0, before the devices' setup; the devices' own timers, and the loop itself,
  start when that setup ends (`:setup_ms`, default 20: the depth sensor's two 10 ms waits).

  **Receive buffer** (`:loop_ms`, `:stall_ms`). Bytes land in the serial receive buffer
  (64 bytes); what arrives while it is full is lost and counted in `rx_dropped`. The loop
  empties it every `loop_ms` (default 10), except that the depth sensor's conversion once a
  second (two 10 ms waits) stalls it for `stall_ms` (default 20). So a burst of more than
  64 bytes loses bytes, and a link that writes at most 60 bytes in any 30 ms loses none.

  **Commands** are read into an 80-byte command buffer up to their `;` (a command that grows
  past 80 bytes is cut and its next byte lost, as the firmware does). 2.5.2 parses the text;
  30.0.2 first checks the leading byte against the Dallas/Maxim CRC-8 of the rest (`;`
  included), prints `rawcmd:` with every byte in hex and `,` then `;\\r\\n`, then
  `crc:pass;` or `crc:fail,COMPUTED/RECEIVED;` (hex, no newline) and drops a failed command.
  A CRC byte equal to `;` ends the command at once (it then fails, and the rest is read as
  another command). An accepted command is split at spaces, commas, parentheses and `;`,
  echoed as `cmd:name(arg,arg);\\r\\n` (the arguments as received) and its arguments read as
  16-bit integers (`atoi`). A device takes a command whose name *starts with* its own word
  (the firmware's `cmp`). Internal commands (the deadman's) go through a three-slot ring that
  holds two (the oldest is overwritten; 30.0.2 prints `log: CommandBufferOverrun;\\r\\n`) and
  are announced `icmd:name(args);\\r\\n`; 2.5.2 reads the slot before advancing, 30.0.2 after,
  so they lose different commands when it overflows.

  **Motors** (`Motor::goms`). `go(p,v,s[,flag])` (each 1000..2000, else ignored) sets the
  targets; the 4th argument only sets a bypass flag nothing reads (the smoothing ramp was
  removed before 2.5.2). Every 50 ms tick (`controltime`, 51 ms) changed targets are applied:
  the ESC pulse is `1500 + (us - 1500) * modifier` within 1000..2000, with the forward
  modifier (default 1) above 1500 and the reverse one (default 2) below, then mapped around
  a ±50 µs dead zone: 1500..2000 → 1550..2000, 1000..1500 → 1000..1450 (integer arithmetic).
  `go(1300,1500,1700)` gives 1090/1500/1730 µs; 1000..1250 give 1000. `mtrmod1(p,v,s)` /
  `mtrmod2(p,v,s)` set the forward / reverse modifiers in percent, integer-divided by 100
  (`150` → 1). The ESC pulses drive the simulated thrusters through the vehicle's
  `Neptunus.Wiring` (a reversed motor turns the other way). `stop()` sets the targets to
  1500 and does not detach the motors. A change prints `motors:p,v,s;\\r\\n` (the ESC
  pulses); once a second `mtarg:p,v,s;\\r\\n` and `mtrmod:` with the six modifiers.

  **Deadman** (`DeadManSwitch.cpp`). `ping(...)` answers `pong:<argument count>,<millis>;`
  without newline. The switch arms when millis passes `arm_ms` (default 180 000, an option so
  tests can shorten it). Its 2000 ms timer (`:deadman_ms`) restarts at each ping and whenever
  it fires; when it fires armed it pushes `deptloff`, `headloff`, `stop` and starts blinking:
  every 501 ms it pushes `ligt(50)` / `ligt(0)` in turn. It prints no deadman line and
  `go()` is still obeyed. A ping ends it, pushing `start`; the lights stay where the blink
  left them.

  **Telemetry** (2 decimals, `\\r\\n` line ends, fields glued as printed):

    * every 101 ms `hdgd:…;deap:…;pitc:…;roll:…;yaw:…;fthr:…;\\r\\n` — `fthr` is the mean
      of the raw port and starboard targets mapped to ±100 (integer `map`);
    * every 1001 ms (from the end of the setup) the controller board's
      `BRDT:…;SC1I:…;SC2I:…;SC3I:…;BRDI:…;BT1I:…;BT2I:…;BRDV:…;AVCC:5000;\\r\\n` (ESC
      currents on a 0..10 A ADC, battery currents likewise, the board's own supply current
      on 0..2 A), then the shared data: `motorAttached:1;`, `servo:…;starg:…;`,
      `fmem:…;vout:…;iout:…;atmp:…;ver:…;cmpd:<date>, <time>, <gcc>` (every 1001 ms from
      boot) whose newline comes
      before its `;` (the next line begins `;time:`), `pres:…;temp:…;`, `dlms:…;`,
      `alps:…;`. `iout` is the controller board's own supply current (`BRDI`), `vout`,
      `iout` and `time` are sampled every 101 ms;
    * the depth sensor reads once a second (first at `setup_ms` + 1001 ms; until then `deap`,
      `pres` and `temp` print `0.00`, the first shared data at 1001 ms included); depth is `(pres - 1015) * 1.019716 / 100` (fresh water). The
      simulated lake has 1015 mbar at its surface and fresh water, so `deap` is the
      simulator's depth, updated once a second. 2.5.2's driver prints two plain-text
      temperature lines at each reading; 30.0.2 prints its calibration constants at boot as
      `Depth.C0:…;` … `Depth.C7:…;` (keys with a dot) and `BNO055.status:…;` once a second;
    * the IMU updates heading, pitch, roll and yaw every 51 ms (first at `setup_ms` + 51 ms,
      before the first navigation line, so heading has no visible placeholder with a working
      IMU; `hdgd` is `0.00` until then).

  `ligt(n)` prints `LIGT:n;LIGP:<n/255>;\r\n`, `claser(n)` prints `claser:n;` without
  newline, `tilt(us)` (1000..2000) moves the camera servo (taken at once here; the firmware
  moves it 1 µs a loop) and shows in `servo:`/`starg:`.

  **Boot.** At boot the board prints its setup lines (the depth sensor's, the IMU's) and, when
  its setup is done (`setup_ms`), `boot:1;\r\n` — 2.5.x and 30.x alike (`OpenROV.ino`'s
  `setup()` ends with it). `reset/2` reboots it: millis back to 0 and every state lost
  (targets, modifiers, lights, laser, tilt, deadman, buffers).

  **Bootloader** (`:bootloader_ms`, default 0). An Arduino that resets runs its bootloader
  first (a USB Arduino resets whenever its port is opened: DTR), for a few hundred ms to a
  second: what arrives meanwhile is lost (counted in `boot_lost`), nothing is written, the
  motors get no pulses (neutral) and the firmware's millis start when it ends. So a board
  link that writes its settings as it opens the line loses them all, unless it writes them
  again.

  `esc_log` records the ESC pulses the motors got (what `motors:` prints), newest first, the
  last #{32} changes of this board life, with the millis of each: what a test needs to say that
  thrust was never unbalanced.
  """

  import Bitwise, only: [&&&: 2]

  alias Neptunus.{Allocation, Wiring}
  alias Neptunus.Protocol.OpenROV

  @rx_size 64
  @cmd_size 80
  @max_args 9
  @ring 3
  @neutral 1500
  @atmos_mbar 1015.0
  @fresh 1.019716
  @water_temp 10.0
  @board_current 0.25
  @lights_current 0.6
  @compiled "Dec 10 2014, 10:42:17, 4.3.2"
  # the devices as the firmware registers them (their loop times print in `dlms:`)
  @devices [:controller, :lights, :laser, :thrusters, :deadman, :camera, :imu, :depth]
  @depth_index 7
  @calibration [0, 46372, 43981, 29059, 27842, 31553, 28165, 0]

  @typedoc "A firmware profile: `:openrov_25` (2.5.2) or `:openrov_30` (30.0.2)."
  @type profile :: :openrov_25 | :openrov_30
  @type us3 :: {integer(), integer(), integer()}
  @type internal :: {String.t(), [integer()]}
  @type reading :: %{
          heading: float(),
          depth: float(),
          pitch: float(),
          roll: float(),
          voltage: float(),
          current: float()
        }

  @enforce_keys [:profile, :wiring, :boot_at_ms, :options]
  defstruct [
    :profile,
    :wiring,
    :boot_at_ms,
    :options,
    :reading,
    at: 0,
    deadman_ms: 2_000,
    arm_ms: 180_000,
    loop_ms: 10,
    stall_ms: 20,
    outbox: [],
    setup_ms: 20,
    boot_lost: 0,
    esc_log: [],
    rx: "",
    rx_dropped: 0,
    rx_bytes: 0,
    cmdbuf: "",
    next_drain: 10,
    drains: 0,
    alps: 0,
    timers: %{},
    ring: {{{"", []}, {"", []}, {"", []}}, 0, 0},
    target_us: {@neutral, @neutral, @neutral},
    applied_us: {@neutral, @neutral, @neutral},
    esc_us: {@neutral, @neutral, @neutral},
    positive_mod: {1, 1, 1},
    negative_mod: {2, 2, 2},
    bypass: false,
    thrusters: %{port: 0.0, vertical: 0.0, starboard: 0.0},
    lights: 0,
    laser: 0,
    tilt: @neutral,
    armed: false,
    tripped: false,
    blink: false,
    depth: 0.0,
    pressure: 0.0,
    temperature: 0.0,
    attitude: %{heading: 0.0, pitch: 0.0, roll: 0.0, yaw: 0.0},
    status: %{vout: 0.0, iout: 0.0, utim: 0.0},
    depth_ms: 0,
    last_ping: nil,
    commands: 0,
    bad_commands: 0,
    neutral_commands: 0
  ]

  @typedoc """
  * `profile`, `wiring`, `boot_at_ms` (clock ms of the last boot), `options` (kept over resets)
  * `deadman_ms`, `arm_ms`, `loop_ms`, `stall_ms` — see the moduledoc
  * `reading` — the simulator's latest measurement (`sense/2`), nil before the first
  * `at` — millis of the last loop iteration
  * `outbox` — bytes written at boot, sent with the first `tick/2` or `receive/3` at or after
    the end of the setup (`setup_ms`, millis)
  * `boot_lost` — bytes that arrived during the bootloader (before millis 0), lost
  * `esc_log` — `{millis, esc_us}` of the last changes of the ESC pulses, newest first
  * `rx` — the serial receive buffer (at most #{@rx_size} bytes); `rx_dropped` — bytes lost
    because it was full; `rx_bytes` — every byte that reached the board's serial port (kept,
    dropped, or lost in the bootloader); `cmdbuf` — the command being read (at most #{@cmd_size} bytes)
  * `next_drain` — millis when the loop next empties `rx` (first at `setup_ms`); `drains`, `alps` — loops counted
    this second and in the last
  * `timers` — millis each firmware timer last fired
  * `ring` — the internal command ring `{slots, head, tail}`
  * `target_us` — the last `go()`; `applied_us` — the targets applied at the last 50 ms tick;
    `esc_us` — the ESC pulses; `thrusters` — the physical thruster values from them
  * `positive_mod`, `negative_mod` — the motors' modifiers (port, vertical, starboard)
  * `armed`, `tripped`, `blink` — the deadman; `last_ping` — millis of the last ping
  * `depth`, `pressure`, `temperature` — the depth sensor's last reading (0.0 before the
    first); `attitude` — the IMU's; `status` — `vout`, `iout`, `time` as last sampled
  * `commands` — commands accepted; `bad_commands` — commands dropped (CRC);
    `neutral_commands` — neutral `go()`s and `stop`s among them (a neutral followed at once
    by another `go()` may never show in `target_us`: this says it arrived)
  """
  @type t :: %__MODULE__{
          profile: profile(),
          wiring: Wiring.t(),
          boot_at_ms: integer(),
          options: keyword(),
          reading: reading() | nil,
          at: integer(),
          deadman_ms: pos_integer(),
          arm_ms: non_neg_integer(),
          loop_ms: pos_integer(),
          stall_ms: non_neg_integer(),
          outbox: iodata(),
          setup_ms: non_neg_integer(),
          boot_lost: non_neg_integer(),
          esc_log: [{integer(), us3()}],
          rx: binary(),
          rx_dropped: non_neg_integer(),
          rx_bytes: non_neg_integer(),
          cmdbuf: binary(),
          next_drain: integer(),
          drains: non_neg_integer(),
          alps: non_neg_integer(),
          timers: %{atom() => integer()},
          ring: {tuple(), 0..2, 0..2},
          target_us: us3(),
          applied_us: us3(),
          esc_us: us3(),
          positive_mod: us3(),
          negative_mod: us3(),
          bypass: boolean(),
          thrusters: Allocation.thrusters(),
          lights: integer(),
          laser: integer(),
          tilt: integer(),
          armed: boolean(),
          tripped: boolean(),
          blink: boolean(),
          depth: float(),
          pressure: float(),
          temperature: float(),
          attitude: %{atom() => float()},
          status: %{atom() => float()},
          depth_ms: non_neg_integer(),
          last_ping: integer() | nil,
          commands: non_neg_integer(),
          bad_commands: non_neg_integer(),
          neutral_commands: non_neg_integer()
        }

  @profiles [:openrov_25, :openrov_30]
  @option_keys [:firmware, :wiring, :deadman_ms, :arm_ms, :loop_ms, :stall_ms, :setup_ms] ++
                 [:bootloader_ms]
  @esc_log 32
  @reading_keys [:heading, :depth, :pitch, :roll, :voltage, :current]
  @device_timers [:control, :thruster_out, :imu, :depth, :board, :status, :deadman, :blink]

  @doc """
  The firmware booted at `now` (ms). Options: `:firmware` (`:openrov_25`, the default, or
  `:openrov_30`), `:wiring` (default the thesis'), `:deadman_ms` (2000), `:arm_ms`
  (180 000), `:loop_ms` (10), `:stall_ms` (20), `:setup_ms` (20: how long the devices' setup
  takes after the main loop's timers started), `:bootloader_ms` (0: how long the bootloader
  runs before the firmware starts, its millis 0 at `now + bootloader_ms`). A bad option raises
  `ArgumentError`.
  """
  @spec new(integer(), keyword()) :: t()
  def new(now, opts \\ []) when is_integer(now) do
    opts = Keyword.take(opts, @option_keys)
    profile = Keyword.get(opts, :firmware, :openrov_25)

    unless profile in @profiles,
      do: raise(ArgumentError, "firmware must be one of #{inspect(@profiles)}")

    wiring = Keyword.get(opts, :wiring) || Wiring.default()

    unless is_struct(wiring, Wiring),
      do: raise(ArgumentError, "wiring must be a Neptunus.Wiring, got #{inspect(wiring)}")

    loop_ms = positive!(opts, :loop_ms, 10)
    setup_ms = non_negative!(opts, :setup_ms, 20)
    bootloader_ms = non_negative!(opts, :bootloader_ms, 0)

    fw = %__MODULE__{
      profile: profile,
      wiring: wiring,
      boot_at_ms: now + bootloader_ms,
      options: opts,
      setup_ms: setup_ms,
      deadman_ms: positive!(opts, :deadman_ms, 2_000),
      arm_ms: non_negative!(opts, :arm_ms, 180_000),
      loop_ms: loop_ms,
      stall_ms: non_negative!(opts, :stall_ms, 20),
      at: setup_ms,
      next_drain: setup_ms,
      # the main loop's output timers start before the devices' setups, the devices' own
      # timers at the end of them
      timers:
        Map.merge(
          %{nav: 0, second: 0},
          Map.new(@device_timers, &{&1, setup_ms})
        )
    }

    %{fw | outbox: boot_lines(profile)}
  end

  defp positive!(opts, key, default) do
    case Keyword.get(opts, key, default) do
      n when is_integer(n) and n > 0 -> n
      other -> raise ArgumentError, "#{key} must be a positive integer, got #{inspect(other)}"
    end
  end

  defp non_negative!(opts, key, default) do
    case Keyword.get(opts, key, default) do
      n when is_integer(n) and n >= 0 -> n
      other -> raise ArgumentError, "#{key} must be a non-negative integer, got #{inspect(other)}"
    end
  end

  @doc """
  The board reboots at `now` (a USB Arduino resets when its port opens): its bootloader runs
  (`:bootloader_ms`), then millis start from 0 and every firmware state is lost; the options
  (profile, wiring, timings) stay, and the byte counts (received, dropped, lost) carry on.
  """
  @spec reset(t(), integer()) :: t()
  def reset(%__MODULE__{} = fw, now) do
    %{
      new(now, fw.options)
      | rx_dropped: fw.rx_dropped,
        rx_bytes: fw.rx_bytes,
        boot_lost: fw.boot_lost,
        reading: fw.reading
    }
  end

  @doc """
  The board as it is at `now` when it was powered long enough before to have started: booted
  (`reset/2`) its bootloader and setup before `now`, its boot output written (returned) and its
  loop about to run.
  """
  @spec started(t(), integer()) :: {t(), binary()}
  def started(%__MODULE__{} = fw, now) do
    bootloader_ms = Keyword.get(fw.options, :bootloader_ms, 0)
    fw |> reset(now - bootloader_ms - fw.setup_ms) |> tick(now)
  end

  @doc "The board's `millis()` at clock time `now`."
  @spec millis(t(), integer()) :: integer()
  def millis(%__MODULE__{boot_at_ms: boot_at_ms}, now), do: now - boot_at_ms

  @doc """
  The simulator's current measurement (a `Neptunus.Vehicle.Board.sample/0`'s or its
  `measurement`): what the board's sensors read when their timers next fire.
  """
  @spec sense(t(), map()) :: t()
  def sense(%__MODULE__{} = fw, %{measurement: m}), do: sense(fw, m)

  def sense(%__MODULE__{} = fw, m) when is_map(m) do
    reading = Map.take(m, @reading_keys)

    unless map_size(reading) == length(@reading_keys) and
             Enum.all?(Map.values(reading), &is_number/1),
           do: raise(ArgumentError, "a reading needs numbers for #{inspect(@reading_keys)}")

    %{fw | reading: reading}
  end

  @doc """
  Bytes from the server arriving at `now` (ms): the loop first catches up to `now` (see
  `tick/2`), then the bytes go into the receive buffer, the overflow is dropped. Returns the
  firmware and the bytes the board wrote meanwhile. Commands take effect when the loop next
  empties the buffer (at most `loop_ms` later, or `loop_ms + stall_ms` once a second).

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {fw, _boot} = Firmware.tick(Firmware.new(0), 20)
      iex> {fw, ""} = Firmware.receive(fw, "ping(7);", 23)
      iex> Firmware.tick(fw, 30) |> elem(1)
      "cmd:ping(7);\\r\\npong:1,30;"
  """
  @spec receive(t(), binary(), integer()) :: {t(), binary()}
  def receive(%__MODULE__{} = fw, bytes, now) when is_binary(bytes) do
    {fw, out} = tick(fw, now)
    fw = %{fw | rx_bytes: fw.rx_bytes + byte_size(bytes)}

    if millis(fw, now) < 0,
      do: {%{fw | boot_lost: fw.boot_lost + byte_size(bytes)}, out},
      else: buffer(fw, bytes, out)
  end

  # the serial receive buffer keeps what fits
  defp buffer(fw, bytes, out) do
    room = @rx_size - byte_size(fw.rx)
    kept = binary_part(bytes, 0, min(room, byte_size(bytes)))

    {%{fw | rx: fw.rx <> kept, rx_dropped: fw.rx_dropped + byte_size(bytes) - byte_size(kept)},
     out}
  end

  @doc """
  Runs the loop up to `now` (ms): every timer and buffer read due by then, in order. Returns
  the firmware and the bytes the board wrote.

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {_fw, out} = Firmware.tick(Firmware.new(0), 101)
      iex> out |> String.split("\\r\\n") |> Enum.at(-2)
      "hdgd:0.00;deap:0.00;pitc:0.00;roll:0.00;yaw:0.00;fthr:0.00;"
  """
  @spec tick(t(), integer()) :: {t(), binary()}
  def tick(%__MODULE__{} = fw, now) when is_integer(now) do
    m = millis(fw, now)
    # the setup's lines, boot:1 last, once the setup is done
    {boot, fw} = if m >= fw.setup_ms, do: {fw.outbox, %{fw | outbox: []}}, else: {[], fw}
    {fw, out} = run(fw, m, [boot])
    {fw, IO.iodata_to_binary(out)}
  end

  defp run(fw, m, out) do
    case next_event(fw) do
      t when t <= m ->
        {fw, more} = iteration(fw, t)
        run(fw, m, [out | more])

      _later ->
        {fw, out}
    end
  end

  # the millis of the next loop iteration that does something
  defp next_event(fw) do
    t = fw.timers

    [
      fw.next_drain,
      t.control + 51,
      t.imu + 51,
      t.status + 101,
      t.nav + 101,
      t.second + 1001,
      t.depth + 1001,
      t.board + 1001,
      t.thruster_out + 1001,
      t.deadman + fw.deadman_ms + 1,
      if(fw.tripped, do: t.blink + 501),
      if(not fw.armed, do: fw.arm_ms + 1)
    ]
    |> Enum.reject(&is_nil/1)
    |> Enum.min()
    |> max(fw.at)
  end

  # One pass of the firmware's loop at millis `m`; the internal commands the devices push are
  # taken by the loops that follow at once (a loop takes about a millisecond).
  defp iteration(fw, m) do
    fw = %{fw | at: m}
    {fw, serial} = if m >= fw.next_drain, do: drain(fw, m), else: {fw, []}
    {fw, internal} = internal_commands(fw, m)
    {fw, timers} = timers(fw, m)
    {fw, pushed} = internal_commands(fw, m)
    {fw, [serial, internal, timers, pushed]}
  end

  # Receive buffer → command buffer → commands -----------------------------------------------

  defp drain(fw, m) do
    {commands, cmdbuf} = read_commands(fw.rx, fw.cmdbuf, [])
    fw = %{fw | rx: "", cmdbuf: cmdbuf, drains: fw.drains + 1}
    fw = %{fw | next_drain: next_drain(fw, m)}

    Enum.reduce(commands, {fw, []}, fn raw, {fw, out} ->
      {fw, more} = serial_command(fw, raw, m)
      {fw, [out, more]}
    end)
  end

  # the next read: a loop later, or after the depth sensor's stall if it falls in between
  defp next_drain(fw, m) do
    next = m + fw.loop_ms
    conversion = fw.timers.depth + 1001
    if conversion <= next, do: max(next, conversion + fw.stall_ms), else: next
  end

  # getSerialString: bytes up to and including ';' (2.5.2 drops the ';', 30.0.2 keeps it); a
  # command that reaches the buffer size is discarded with the byte that overflows it
  defp read_commands(<<>>, buf, acc), do: {Enum.reverse(acc), buf}

  defp read_commands(<<_byte, rest::binary>>, buf, acc) when byte_size(buf) == @cmd_size,
    do: read_commands(rest, "", acc)

  defp read_commands(<<?;, rest::binary>>, buf, acc),
    do: read_commands(rest, "", [buf <> ";" | acc])

  defp read_commands(<<byte, rest::binary>>, buf, acc),
    do: read_commands(rest, <<buf::binary, byte>>, acc)

  defp serial_command(%{profile: :openrov_25} = fw, raw, m) do
    text = binary_part(raw, 0, byte_size(raw) - 1)
    accept(fw, text, [], m)
  end

  defp serial_command(%{profile: :openrov_30} = fw, raw, m) do
    rawcmd = ["rawcmd:", for(<<b <- raw>>, do: [hex(b), ?,]), ";\r\n"]

    case OpenROV.unframe(raw) do
      {:ok, text} ->
        accept(fw, text, [rawcmd, "crc:pass;"], m)

      {:error, {computed, received}} ->
        fail = ["crc:fail,", hex(computed), ?/, hex(received), ?;]
        {%{fw | bad_commands: fw.bad_commands + 1}, [rawcmd, fail]}
    end
  end

  defp accept(fw, text, prefix, m) do
    {name, tokens} = tokens(text)
    # without a name the firmware prints only the closing ");"
    echo = if name == "", do: ");\r\n", else: ["cmd:", name, ?(, Enum.join(tokens, ","), ");\r\n"]
    args = tokens |> Enum.take(@max_args) |> Enum.map(&atoi/1)
    {fw, out} = handle(%{fw | commands: fw.commands + 1}, name, length(tokens), args, m)
    {fw, [prefix, echo, out]}
  end

  @doc """
  The firmware's split of a command (`strtok` at spaces, commas, parentheses and `;`): the
  name and the argument tokens as received (`Neptunus.Protocol.OpenROV.call/1`, which the
  board link uses to know the echo a command gets). The SITL board's own parser (the server's
  `Neptunus.Protocol.OpenROV.parse_command/1` knows only the commands the server sends).

      iex> Neptunus.Vehicle.Board.SITL.Firmware.tokens("mtrmod1(100, 100,150);")
      {"mtrmod1", ["100", "100", "150"]}
      iex> Neptunus.Vehicle.Board.SITL.Firmware.tokens(";;")
      {"", []}
  """
  @spec tokens(binary()) :: {binary(), [binary()]}
  def tokens(text) when is_binary(text), do: OpenROV.call(text)

  @doc """
  C's `atoi` into the AVR's 16-bit `int`: leading spaces, a sign, digits; anything else
  ends it (no digits: 0); the result wraps to -32768..32767.

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {Firmware.atoi("1500"), Firmware.atoi("-20x"), Firmware.atoi("abc"), Firmware.atoi("40000")}
      {1500, -20, 0, -25536}
  """
  @spec atoi(binary()) :: integer()
  def atoi(text) when is_binary(text) do
    n =
      case Regex.run(~r/\A\s*([+-]?)(\d+)/, text) do
        [_, sign, digits] -> if(sign == "-", do: -1, else: 1) * String.to_integer(digits)
        nil -> 0
      end

    wrap16(n)
  end

  defp wrap16(n) do
    n = n &&& 0xFFFF
    if n >= 0x8000, do: n - 0x10000, else: n
  end

  defp hex(byte), do: Integer.to_string(byte, 16)

  # Internal commands ------------------------------------------------------------------------

  defp ring_empty?({_slots, head, tail}), do: head == tail

  defp push(fw, command) do
    {slots, head, tail} = fw.ring
    head = rem(head + 1, @ring)

    {tail, out} =
      cond do
        head != tail -> {tail, []}
        fw.profile == :openrov_30 -> {rem(tail + 1, @ring), "log: CommandBufferOverrun;\r\n"}
        true -> {rem(tail + 1, @ring), []}
      end

    {%{fw | ring: {put_elem(slots, head, command), head, tail}}, out}
  end

  defp pop(%{ring: {slots, head, tail}, profile: :openrov_25} = fw),
    do: {%{fw | ring: {slots, head, rem(tail + 1, @ring)}}, elem(slots, tail)}

  defp pop(%{ring: {slots, head, tail}} = fw) do
    tail = rem(tail + 1, @ring)
    {%{fw | ring: {slots, head, tail}}, elem(slots, tail)}
  end

  defp internal_commands(fw, m) do
    if ring_empty?(fw.ring) do
      {fw, []}
    else
      {fw, {name, args}} = pop(fw)
      echo = ["icmd:", name, ?(, Enum.map_join(args, ",", &Integer.to_string/1), ");\r\n"]
      {fw, out} = handle(fw, name, length(args), args, m)
      {fw, more} = internal_commands(fw, m)
      {fw, [echo, out, more]}
    end
  end

  # The devices' command handling ------------------------------------------------------------

  defp handle(fw, name, count, args, m) do
    arg = fn i -> Enum.at(args, i - 1, 0) end
    is = &String.starts_with?(name, &1)

    cond do
      name == "" ->
        {fw, []}

      is.("ligt") ->
        v = arg.(1)
        ligp = float2(v / 255)
        {%{fw | lights: v}, ["LIGT:", Integer.to_string(v), ";LIGP:", ligp, ";\r\n"]}

      is.("claser") ->
        v = arg.(1)
        {%{fw | laser: v}, ["claser:", Integer.to_string(v), ?;]}

      is.("tilt") ->
        v = arg.(1)
        {if(v > 999 and v < 2001, do: %{fw | tilt: v}, else: fw), []}

      is.("ping") ->
        ping(fw, count, m)

      is.("dms") ->
        {%{fw | armed: arg.(1) != 0}, []}

      is.("mtrmod1") ->
        {%{fw | positive_mod: {cdiv(arg.(1)), cdiv(arg.(2)), cdiv(arg.(3))}}, []}

      is.("mtrmod2") ->
        {%{fw | negative_mod: {cdiv(arg.(1)), cdiv(arg.(2)), cdiv(arg.(3))}}, []}

      is.("go") ->
        {go(fw, arg.(1), arg.(2), arg.(3), arg.(4)), []}

      is.("stop") ->
        {%{
           fw
           | target_us: {@neutral, @neutral, @neutral},
             neutral_commands: fw.neutral_commands + 1
         }, []}

      true ->
        {fw, []}
    end
  end

  # the modifier as the firmware stores it: args / 100 in integer arithmetic
  defp cdiv(n), do: div(n, 100)

  defp go(fw, p, v, s, flag) do
    if Enum.all?([p, v, s], &(&1 > 999 and &1 < 2001)) do
      neutral = if {p, v, s} == {@neutral, @neutral, @neutral}, do: 1, else: 0

      %{
        fw
        | target_us: {p, v, s},
          bypass: fw.bypass or flag == 1,
          neutral_commands: fw.neutral_commands + neutral
      }
    else
      fw
    end
  end

  defp ping(fw, count, m) do
    fw = %{fw | timers: %{fw.timers | deadman: m}, last_ping: m}

    {fw, out} = if fw.tripped, do: push(%{fw | tripped: false}, {"start", []}), else: {fw, []}

    {fw, [out, "pong:", Integer.to_string(count), ?,, Integer.to_string(m), ?;]}
  end

  # Timers -------------------------------------------------------------------------------------

  defp timers(fw, m) do
    [&deadman/2, &thrusters/2, &imu/2, &depth/2, &controller/2, &outputs/2]
    |> Enum.reduce({fw, []}, fn step, {fw, out} ->
      {fw, more} = step.(fw, m)
      {fw, [out, more]}
    end)
  end

  defp elapsed(fw, timer, period, m) do
    if m - Map.fetch!(fw.timers, timer) > period,
      do: {true, %{fw | timers: Map.put(fw.timers, timer, m)}},
      else: {false, fw}
  end

  defp deadman(fw, m) do
    fw = if not fw.armed and m > fw.arm_ms, do: %{fw | armed: true}, else: fw
    {fired, fw} = elapsed(fw, :deadman, fw.deadman_ms, m)

    {fw, out} =
      if fired and fw.armed do
        {fw, a} = push(fw, {"deptloff", []})
        {fw, b} = push(fw, {"headloff", []})
        {fw, c} = push(fw, {"stop", []})
        {%{fw | tripped: true}, [a, b, c]}
      else
        {fw, []}
      end

    {blink, fw} = if fw.tripped, do: elapsed(fw, :blink, 500, m), else: {false, fw}

    if blink do
      {fw, d} = push(fw, {"ligt", [if(fw.blink, do: 0, else: 50)]})
      {%{fw | blink: not fw.blink}, [out, d]}
    else
      {fw, out}
    end
  end

  defp thrusters(fw, m) do
    {tick, fw} = elapsed(fw, :control, 50, m)

    {fw, out} =
      if tick and fw.target_us != fw.applied_us do
        esc = esc_us(fw)

        {%{
           fw
           | applied_us: fw.target_us,
             esc_us: esc,
             esc_log: Enum.take([{m, esc} | fw.esc_log], @esc_log),
             bypass: false,
             thrusters: Wiring.from_us(fw.wiring, esc)
         }, ["motors:", join3(esc), ";\r\n"]}
      else
        {fw, []}
      end

    {second, fw} = elapsed(fw, :thruster_out, 1000, m)

    if second do
      {p1, v1, s1} = fw.positive_mod
      {p2, v2, s2} = fw.negative_mod
      mods = Enum.map_join([p1, v1, s1, p2, v2, s2], ",", &float2/1)
      {fw, [out, "mtarg:", join3(fw.target_us), ";\r\nmtrmod:", mods, ";\r\n"]}
    else
      {fw, out}
    end
  end

  defp esc_us(%{target_us: {p, v, s}, positive_mod: {pp, pv, ps}, negative_mod: {np, nv, ns}}),
    do: {goms(p, pp, np), goms(v, pv, nv), goms(s, ps, ns)}

  @doc """
  `Motor::goms`: the ESC pulse for a target pulse `us` with the forward and reverse
  modifiers (integers), around the ±50 µs dead zone.

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> Enum.map([1300, 1500, 1700, 1250, 1000, 2000, 1501], &Firmware.goms(&1, 1, 2))
      [1090, 1500, 1730, 1000, 1000, 2000, 1550]
      iex> {Firmware.goms(1300, 1, 1), Firmware.goms(1700, 1, 1)}
      {1270, 1730}
  """
  @spec goms(integer(), integer(), integer()) :: integer()
  def goms(us, positive, negative) do
    modifier =
      cond do
        us > @neutral -> positive
        us < @neutral -> negative
        true -> 1
      end

    pre = clamp(@neutral + (us - @neutral) * modifier, 1000, 2000)

    final =
      cond do
        pre < @neutral -> map(pre, 1000, @neutral, 1000, @neutral - 50)
        pre > @neutral -> map(pre, @neutral, 2000, @neutral + 50, 2000)
        true -> @neutral
      end

    clamp(final, 1000, 2000)
  end

  # Arduino's map(): integer arithmetic, truncating
  defp map(x, in_min, in_max, out_min, out_max),
    do: div((x - in_min) * (out_max - out_min), in_max - in_min) + out_min

  defp clamp(x, lo, hi), do: x |> max(lo) |> min(hi)

  defp imu(fw, m) do
    case elapsed(fw, :imu, 50, m) do
      {true, %{reading: %{} = r} = fw} ->
        heading = r.heading * 180 / :math.pi()
        yaw = if heading > 180, do: heading - 360, else: heading

        attitude = %{
          heading: heading,
          pitch: r.pitch * 180 / :math.pi(),
          roll: r.roll * 180 / :math.pi(),
          yaw: yaw
        }

        {%{fw | attitude: attitude}, []}

      {_, fw} ->
        {fw, []}
    end
  end

  defp depth(fw, m) do
    {read, fw} = elapsed(fw, :depth, 1000, m)

    if read and fw.reading != nil do
      pressure = @atmos_mbar + fw.reading.depth / @fresh * 100
      depth = (pressure - @atmos_mbar) * @fresh / 100

      fw = %{
        fw
        | pressure: pressure,
          depth: depth,
          temperature: @water_temp,
          depth_ms: fw.depth_ms + fw.stall_ms
      }

      case fw.profile do
        :openrov_25 ->
          t = float2(@water_temp)

          {fw,
           [
             "First-Order Temperature in Degrees C is ",
             t,
             "\r\nSecond-Order Temperature in Degrees C is ",
             t,
             "\r\n"
           ]}

        :openrov_30 ->
          {fw, []}
      end
    else
      {fw, []}
    end
  end

  # the controller board: vout/iout/time every 101 ms, its current line once a second
  defp controller(fw, m) do
    {sample, fw} = elapsed(fw, :status, 100, m)

    fw =
      if sample do
        %{fw | status: %{vout: voltage(fw), iout: board_current(fw), utim: m * 1.0}}
      else
        fw
      end

    case elapsed(fw, :board, 1000, m) do
      {true, fw} -> {fw, controller_line(fw)}
      {false, fw} -> {fw, []}
    end
  end

  defp voltage(%{reading: %{voltage: v}}), do: adc(v, 20)
  defp voltage(_fw), do: 0.0

  defp board_current(fw), do: adc(@board_current + @lights_current * fw.lights / 255, 2)

  # an analogRead on a 0..full scale, 10 bits
  defp adc(x, full), do: clamp(round(x / full * 1023), 0, 1023) * full / 1023

  defp controller_line(fw) do
    battery = if fw.reading, do: max(fw.reading.current, 0.0), else: 0.0
    {p, v, s} = fw.esc_us
    offsets = Enum.map([p, v, s], &abs(&1 - @neutral))
    total = Enum.sum(offsets)
    esc = Enum.map(offsets, &if(total == 0, do: 0.0, else: battery * &1 / total))
    [sc1, sc2, sc3] = Enum.map(esc, &adc(&1, 10))
    half = adc(battery / 2, 10)

    [
      "BRDT:",
      float2(25.0),
      ";SC1I:",
      float2(sc1),
      ";SC2I:",
      float2(sc2),
      ";SC3I:",
      float2(sc3),
      ";BRDI:",
      float2(board_current(fw)),
      ";BT1I:",
      float2(half),
      ";BT2I:",
      float2(half),
      ";BRDV:",
      float2(voltage(fw)),
      ";AVCC:5000;\r\n"
    ]
  end

  defp outputs(fw, m) do
    {second, fw} = elapsed(fw, :second, 1000, m)

    {fw, shared} =
      if second do
        fw = %{fw | alps: fw.drains, drains: 0}
        {fw, shared_data(fw)}
      else
        {fw, []}
      end

    {nav, fw} = elapsed(fw, :nav, 100, m)
    {fw, [shared, if(nav, do: navdata(fw), else: [])]}
  end

  defp shared_data(fw) do
    dlms =
      @devices
      |> Enum.with_index()
      |> Enum.map(fn {_device, i} ->
        [
          Integer.to_string(i),
          ?|,
          Integer.to_string(if i == @depth_index, do: fw.depth_ms, else: 0)
        ]
      end)

    [
      "motorAttached:1;\r\n",
      "servo:",
      Integer.to_string(fw.tilt),
      ";starg:",
      Integer.to_string(fw.tilt),
      ";\r\n",
      "fmem:",
      float2(1843.0),
      ";vout:",
      float2(fw.status.vout),
      ";iout:",
      float2(fw.status.iout),
      ";atmp:",
      float2(0.0),
      ";ver:CUSTOM_BUILD;cmpd:",
      @compiled,
      "\r\n;time:",
      float2(fw.status.utim),
      ";\r\n",
      "pres:",
      float2(fw.pressure),
      ";temp:",
      float2(fw.temperature),
      ";\r\n",
      "dlms:",
      dlms,
      ";\r\n",
      if(fw.profile == :openrov_30, do: "BNO055.status:5;\r\n", else: []),
      "alps:",
      Integer.to_string(fw.alps),
      ";\r\n"
    ]
  end

  defp navdata(fw) do
    {p, _v, s} = fw.applied_us
    fthr = map(div(p + s, 2), 1000, 2000, -100, 100)
    a = fw.attitude

    [
      "hdgd:",
      float2(a.heading),
      ";deap:",
      float2(fw.depth),
      ";pitc:",
      float2(a.pitch),
      ";roll:",
      float2(a.roll),
      ";yaw:",
      float2(a.yaw),
      ";fthr:",
      float2(fthr),
      ";\r\n"
    ]
  end

  defp boot_lines(:openrov_25) do
    [
      "Depth Sensor setup.\r\nDepth Sensor: initialized I2C\r\nDepth Sensor is reset\r\n",
      "Depth: Calibration constants are:\r\n",
      "log:init on primary addresses;\r\n",
      "boot:1;\r\n"
    ]
  end

  defp boot_lines(:openrov_30) do
    constants =
      @calibration
      |> Enum.with_index()
      |> Enum.map(fn {c, i} ->
        ["Depth.C", Integer.to_string(i), ?:, Integer.to_string(c), ";\r\n"]
      end)

    [constants, "log:init on primary addresses;\r\n", "boot:1;\r\n"]
  end

  defp join3({a, b, c}), do: Enum.map_join([a, b, c], ",", &Integer.to_string/1)

  @doc """
  A number as the Arduino prints a float: 2 decimals (no `-` on zero).

      iex> alias Neptunus.Vehicle.Board.SITL.Firmware
      iex> {Firmware.float2(1.005), Firmware.float2(-0.0), Firmware.float2(12), Firmware.float2(-3.14159)}
      {"1.00", "0.00", "12.00", "-3.14"}
  """
  @spec float2(number()) :: binary()
  def float2(x) when x == 0, do: "0.00"
  def float2(x), do: :erlang.float_to_binary(x * 1.0, decimals: 2)
end
