defmodule Neptunus.Vehicle.Board.OpenROV.SITL.Firmware do
  @moduledoc """
  The SITL board's firmware as a pure value: what the published OpenROV Arduino firmware does
  with the bytes it receives and what it writes back, byte for byte, in two profiles —
  `:openrov_25` (2.5.2, plain commands) and `:openrov_30` (30.0.2, each command prefixed with a
  CRC byte). `Neptunus.Vehicle.Board.OpenROV.SITL.Device` runs it next to a `Neptunus.Sim`: it feeds
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

  The firmware's parts, as its own files are: the serial input
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Commands`: the receive buffer, commands, their CRC
  and echo, the internal command ring), the devices and their timers
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices`: motors, deadman, lights, laser, camera
  servo, IMU, depth sensor, controller board) and the lines it prints
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Output`: boot, navigation, shared data). This
  module is the firmware's state and its loop.

  **Boot.** `reset/2` reboots the board: millis back to 0 and every state lost (targets,
  modifiers, lights, laser, tilt, deadman, buffers).

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

  alias Neptunus.Allocation
  alias Neptunus.Vehicle.Board.OpenROV.Wiring
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.{Commands, Devices, Output}

  @neutral 1500

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
  * `rx` — the serial receive buffer (at most 64 bytes); `rx_dropped` — bytes lost
    because it was full; `rx_bytes` — every byte that reached the board's serial port (kept,
    dropped, or lost in the bootloader); `cmdbuf` — the command being read (at most 80 bytes)
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
      do:
        raise(
          ArgumentError,
          "wiring must be a Neptunus.Vehicle.Board.OpenROV.Wiring, got #{inspect(wiring)}"
        )

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

    %{fw | outbox: Output.boot_lines(profile)}
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

      iex> alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
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
      else: {Commands.buffer(fw, bytes), out}
  end

  @doc """
  Runs the loop up to `now` (ms): every timer and buffer read due by then, in order. Returns
  the firmware and the bytes the board wrote.

      iex> alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
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
    {fw, serial} = if m >= fw.next_drain, do: Commands.drain(fw, m), else: {fw, []}
    {fw, internal} = Commands.internal_commands(fw, m)
    {fw, timers} = Devices.timers(fw, m)
    {fw, lines} = Output.outputs(fw, m)
    {fw, pushed} = Commands.internal_commands(fw, m)
    {fw, [serial, internal, timers, lines, pushed]}
  end

  # Helpers of the parts, with the firmware's own behaviour ------------------------------------

  @doc """
  The firmware's split of a command (`strtok` at spaces, commas, parentheses and `;`): the
  name and the argument tokens as received (`Neptunus.Vehicle.Board.OpenROV.Protocol.call/1`, which
  the board link uses to know the echo a command gets). The SITL board's own parser (the server's
  `Neptunus.Vehicle.Board.OpenROV.Protocol.parse_command/1` knows only the commands the server
  sends).

      iex> Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.tokens("mtrmod1(100, 100,150);")
      {"mtrmod1", ["100", "100", "150"]}
      iex> Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.tokens(";;")
      {"", []}
  """
  @spec tokens(binary()) :: {binary(), [binary()]}
  defdelegate tokens(text), to: Commands

  @doc """
  C's `atoi` into the AVR's 16-bit `int`: leading spaces, a sign, digits; anything else
  ends it (no digits: 0); the result wraps to -32768..32767.

      iex> alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
      iex> {Firmware.atoi("1500"), Firmware.atoi("-20x"), Firmware.atoi("abc"), Firmware.atoi("40000")}
      {1500, -20, 0, -25536}
  """
  @spec atoi(binary()) :: integer()
  defdelegate atoi(text), to: Commands

  @doc """
  `Motor::goms`: the ESC pulse for a target pulse `us` with the forward and reverse
  modifiers (integers), around the ±50 µs dead zone.

      iex> alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
      iex> Enum.map([1300, 1500, 1700, 1250, 1000, 2000, 1501], &Firmware.goms(&1, 1, 2))
      [1090, 1500, 1730, 1000, 1000, 2000, 1550]
      iex> {Firmware.goms(1300, 1, 1), Firmware.goms(1700, 1, 1)}
      {1270, 1730}
  """
  @spec goms(integer(), integer(), integer()) :: integer()
  defdelegate goms(us, positive, negative), to: Devices

  @doc """
  A number as the Arduino prints a float: 2 decimals (no `-` on zero).

      iex> alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
      iex> {Firmware.float2(1.005), Firmware.float2(-0.0), Firmware.float2(12), Firmware.float2(-3.14159)}
      {"1.00", "0.00", "12.00", "-3.14"}
  """
  @spec float2(number()) :: binary()
  defdelegate float2(x), to: Output
end
