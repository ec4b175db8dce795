defmodule Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices do
  @moduledoc """
  The SITL firmware's devices and their timers (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware`; the
  firmware's device files): the commands each device takes (`handle/5`) and what it does on
  its timers (`timers/2`) — motors, deadman, lights, laser, camera servo, IMU, depth sensor
  and the controller board. A timer fires when *more than* its period has passed since it
  last fired (`elapsed/4`).

  **Motors** (`Motor::goms`). `go(p,v,s[,flag])` (each 1000..2000, else ignored) sets the
  targets; the 4th argument only sets a bypass flag nothing reads (the smoothing ramp was
  removed before 2.5.2). Every 50 ms tick (`controltime`, 51 ms) changed targets are applied:
  the ESC pulse is `1500 + (us - 1500) * modifier` within 1000..2000, with the forward
  modifier (default 1) above 1500 and the reverse one (default 2) below, then mapped around
  a ±50 µs dead zone: 1500..2000 → 1550..2000, 1000..1500 → 1000..1450 (integer arithmetic).
  `go(1300,1500,1700)` gives 1090/1500/1730 µs; 1000..1250 give 1000. `mtrmod1(p,v,s)` /
  `mtrmod2(p,v,s)` set the forward / reverse modifiers in percent, integer-divided by 100
  (`150` → 1). The ESC pulses drive the simulated thrusters through the vehicle's
  `Neptunus.Vehicle.Board.OpenROV.Wiring` (a reversed motor turns the other way). `stop()` sets the
  targets to 1500 and does not detach the motors. A change prints `motors:p,v,s;\\r\\n` (the ESC
  pulses); once a second `mtarg:p,v,s;\\r\\n` and `mtrmod:` with the six modifiers.

  **Deadman** (`DeadManSwitch.cpp`). `ping(...)` answers `pong:<argument count>,<millis>;`
  without newline. The switch arms when millis passes `arm_ms` (default 180 000, an option so
  tests can shorten it). Its 2000 ms timer (`:deadman_ms`) restarts at each ping and whenever
  it fires; when it fires armed it pushes `deptloff`, `headloff`, `stop` and starts blinking:
  every 501 ms it pushes `ligt(50)` / `ligt(0)` in turn. It prints no deadman line and
  `go()` is still obeyed. A ping ends it, pushing `start`; the lights stay where the blink
  left them.

  `ligt(n)` prints `LIGT:n;LIGP:<n/255>;\r\n`, `claser(n)` prints `claser:n;` without
  newline, `tilt(us)` (1000..2000) moves the camera servo (taken at once here; the firmware
  moves it 1 µs a loop) and shows in `servo:`/`starg:`.

  **Sensors.** The depth sensor reads once a second (first at `setup_ms` + 1001 ms; until then
  depth, pressure and temperature are `0.00`); depth is `(pres - 1015) * 1.019716 / 100`
  (fresh water). The simulated lake has 1015 mbar at its surface and fresh water, so the
  depth is the simulator's, updated once a second. 2.5.2's driver prints two plain-text
  temperature lines at each reading. The IMU updates heading, pitch, roll and yaw every
  51 ms (first at `setup_ms` + 51 ms, before the first navigation line).

  **The controller board** samples `vout`, `iout` (its own supply current) and `time` every
  101 ms and prints every 1001 ms (from the end of the setup)
  `BRDT:…;SC1I:…;SC2I:…;SC3I:…;BRDI:…;BT1I:…;BT2I:…;BRDV:…;AVCC:5000;\r\n` (ESC currents
  on a 0..10 A ADC, battery currents likewise, the board's own supply current on 0..2 A).
  """

  alias Neptunus.Vehicle.Board.OpenROV.Wiring
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.{Commands, Output}

  @neutral 1500
  @esc_log 32
  @atmos_mbar 1015.0
  @fresh 1.019716
  @water_temp 10.0
  @board_current 0.25
  @lights_current 0.6

  @doc """
  Command `name` (from the serial line or the internal ring) with `count` arguments, `args`
  as integers, at millis `m`: the device whose word starts the name takes it. Returns what it
  printed.
  """
  @spec handle(Firmware.t(), binary(), non_neg_integer(), [integer()], integer()) ::
          {Firmware.t(), iodata()}
  def handle(fw, name, count, args, m) do
    arg = fn i -> Enum.at(args, i - 1, 0) end
    is = &String.starts_with?(name, &1)

    cond do
      name == "" ->
        {fw, []}

      is.("ligt") ->
        v = arg.(1)
        ligp = Output.float2(v / 255)
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

    {fw, out} =
      if fw.tripped, do: Commands.push(%{fw | tripped: false}, {"start", []}), else: {fw, []}

    {fw, [out, "pong:", Integer.to_string(count), ?,, Integer.to_string(m), ?;]}
  end

  # Timers -------------------------------------------------------------------------------------

  @doc "The devices' timers due at millis `m`, in the firmware's order; returns what they printed."
  @spec timers(Firmware.t(), integer()) :: {Firmware.t(), iodata()}
  def timers(fw, m) do
    [&deadman/2, &thrusters/2, &imu/2, &depth/2, &controller/2]
    |> Enum.reduce({fw, []}, fn step, {fw, out} ->
      {fw, more} = step.(fw, m)
      {fw, [out, more]}
    end)
  end

  @doc """
  Whether timer `timer` fires at millis `m`: more than `period` ms since it last fired (then
  it restarts at `m`).
  """
  @spec elapsed(Firmware.t(), atom(), non_neg_integer(), integer()) :: {boolean(), Firmware.t()}
  def elapsed(fw, timer, period, m) do
    if m - Map.fetch!(fw.timers, timer) > period,
      do: {true, %{fw | timers: Map.put(fw.timers, timer, m)}},
      else: {false, fw}
  end

  defp deadman(fw, m) do
    fw = if not fw.armed and m > fw.arm_ms, do: %{fw | armed: true}, else: fw
    {fired, fw} = elapsed(fw, :deadman, fw.deadman_ms, m)

    {fw, out} =
      if fired and fw.armed do
        {fw, a} = Commands.push(fw, {"deptloff", []})
        {fw, b} = Commands.push(fw, {"headloff", []})
        {fw, c} = Commands.push(fw, {"stop", []})
        {%{fw | tripped: true}, [a, b, c]}
      else
        {fw, []}
      end

    {blink, fw} = if fw.tripped, do: elapsed(fw, :blink, 500, m), else: {false, fw}

    if blink do
      {fw, d} = Commands.push(fw, {"ligt", [if(fw.blink, do: 0, else: 50)]})
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
         }, ["motors:", Output.join3(esc), ";\r\n"]}
      else
        {fw, []}
      end

    {second, fw} = elapsed(fw, :thruster_out, 1000, m)

    if second do
      {p1, v1, s1} = fw.positive_mod
      {p2, v2, s2} = fw.negative_mod
      mods = Enum.map_join([p1, v1, s1, p2, v2, s2], ",", &Output.float2/1)
      {fw, [out, "mtarg:", Output.join3(fw.target_us), ";\r\nmtrmod:", mods, ";\r\n"]}
    else
      {fw, out}
    end
  end

  defp esc_us(%{target_us: {p, v, s}, positive_mod: {pp, pv, ps}, negative_mod: {np, nv, ns}}),
    do: {goms(p, pp, np), goms(v, pv, nv), goms(s, ps, ns)}

  @doc """
  `Motor::goms`, the ESC pulse for a target pulse:
  `Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.goms/3`.
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

  @doc "Arduino's `map()`: integer arithmetic, truncating."
  @spec map(integer(), integer(), integer(), integer(), integer()) :: integer()
  def map(x, in_min, in_max, out_min, out_max),
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
          t = Output.float2(@water_temp)

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
      Output.float2(25.0),
      ";SC1I:",
      Output.float2(sc1),
      ";SC2I:",
      Output.float2(sc2),
      ";SC3I:",
      Output.float2(sc3),
      ";BRDI:",
      Output.float2(board_current(fw)),
      ";BT1I:",
      Output.float2(half),
      ";BT2I:",
      Output.float2(half),
      ";BRDV:",
      Output.float2(voltage(fw)),
      ";AVCC:5000;\r\n"
    ]
  end
end
