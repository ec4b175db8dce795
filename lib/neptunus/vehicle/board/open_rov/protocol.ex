defmodule Neptunus.Vehicle.Board.OpenROV.Protocol do
  @moduledoc """
  The OpenROV serial protocol between the server and the vehicle's board (115200 8N1), as the
  OpenROV Arduino firmware 2.5.x and 30.x speak it (docs/OPENROV.md). Pure: no I/O, never
  raises on input from the line.

  ## Commands (server → board)

  `;`-terminated, no newline: `go(port,vertical,starboard,flag);` with each motor in
  1000..2000 µs (1500 neutral) in the order the motors are wired (see
  `Neptunus.Vehicle.Board.OpenROV.Wiring`), `ligt(0..255);`, `claser(0..255);`, `tilt(µs);`,
  `ping(n);`, `stop();`, and the motor modifiers `mtrmod1(a,b,c);` (forward) / `mtrmod2(a,b,c);`
  (reverse) in percent. The encoders take values already in range and raise `FunctionClauseError`
  otherwise: validating a pilot's input is the caller's job, a bad value here is a bug. `frame/2`
  puts a command in the wire form of a firmware line (30.x: a CRC byte first). `parse_command/1`,
  `unframe/1` and `goms/3` are the board's side (used by the SITL board and the tests).

  ## Telemetry (board → server)

  Lines end `\r\n` (`Neptunus.Protocol.Lines` removes the `\r`) and carry `key:value;`
  fields, e.g. `hdgd:123.40;deap:0.52;pitc:1.20;roll:-0.30;yaw:12.00;fthr:0.00;` and
  `vout:12.10;iout:0.50;time:12345;pres:1065.30;temp:11.20;`. Some fields are printed without
  a newline and glue onto the next line (`pong:1,183422;hdgd:…`, `claser:255;`, 30.x
  `crc:pass;cmd:…;`), and `cmpd:` prints its newline before its `;`, so a line may start
  with `;`: fields are split on `;` whatever the line, so all of these parse. `parse_line/1`
  returns the fields it accepts and the ones it rejects:

  | key    | field             | board unit        | accepted raw range | SI value           |
  |--------|-------------------|-------------------|--------------------|--------------------|
  | `hdgd` | `:heading`        | degree            | 0 .. 360           | rad in [0, 2π)     |
  | `deap` | `:depth`          | m                 | -10 .. 200         | m                  |
  | `pitc` | `:pitch`          | degree            | -90 .. 90          | rad                |
  | `roll` | `:roll`           | degree            | -180 .. 180        | rad                |
  | `yaw`  | `:yaw`            | degree            | -180 .. 360        | rad                |
  | `fthr` | `:forward_thrust` | % of full thrust  | -100 .. 100        | fraction in [-1, 1]|
  | `vout` | `:voltage`        | V                 | 5 .. 20            | V                  |
  | `iout` | `:current`        | A                 | 0 .. 10            | A                  |
  | `temp` | `:temperature`    | °C                | -40 .. 85          | °C                 |
  | `pres` | `:pressure`       | mbar              | 0 .. 25 000        | Pa                 |
  | `time` | `:board_time`     | ms since boot     | 0 .. 2³² − 1       | s                  |
  | `BT1I` | `:battery1_current` | A               | 0 .. 10            | A                  |
  | `BT2I` | `:battery2_current` | A               | 0 .. 10            | A                  |
  | `SC1I`..`SC3I` | `:esc1_current`..`:esc3_current` | A | 0 .. 30       | A                  |

  What the fields mean (which `iout` is the vehicle's current, `fthr`, the depth's reference)
  differs between the boards: `Neptunus.Vehicle.Board.OpenROV.Readings` maps them. The ranges are
  what the sensors can physically report (the IMU's Euler angles, the depth sensor's 0..14 bar plus
  margin down to the thesis' 200 m, the 20 V ADC scale, the cape's 0..5.4 A and the controller
  board's 0..2 A `iout` with margin, the controller board's battery and ESC current channels; a
  board that reports its own supply below 5 V would not be running). The rate-of-change check
  belongs to navigation.

  Unknown keys (`cmd`, `icmd`, `rawcmd`, `crc`, `log`, `pong`, `fmem`, 30.x dotted keys such as
  `BNO055.status` or `Depth.C0`, …) are kept with their raw string value under the key as a
  string; `parse_pong/1`, `parse_echo/1` and `parse_crc/1` read the ones the link uses. Known
  keys become atoms with numbers in SI units. Plain-text lines the firmware prints (the 2.5.2
  depth driver's) are recognised by `text_line?/1` and not parsed.

  Rejected fields, each `{reason, key, raw}` (`key` nil when there is none, `raw` at most
  #{32} bytes):

    * `:malformed` — not `key:value` (no colon, empty or invalid key: a key is a letter
      followed by up to 31 letters, digits, `_` or `.`);
    * `:not_a_number` — a known key whose value is not a plain decimal number
      (`nan`, `ovf`, `12.3.4`, …);
    * `:out_of_range` — a known key whose value is outside its range above;
    * `:key_as_value` — a field whose value is the name of a known key (the thesis saw
      `hdgd:pitc`, ch. 8.3): the line is misaligned and the field cannot be trusted.

  The last three are **wild points** (`wild_point?/1`); they are counted by the board and
  never passed on. Empty fields (`;;`) and surrounding spaces are ignored. When a key repeats
  on a line, the last accepted value wins.
  """

  import Bitwise, only: [<<<: 2, >>>: 2, &&&: 2, bxor: 2]

  @typedoc "Motor pulse widths in µs, in `go()` order."
  @type us :: 1000..2000
  @type field_key :: atom() | String.t()
  @type fields :: %{optional(field_key()) => number() | String.t()}
  @type reject_reason :: :malformed | :not_a_number | :out_of_range | :key_as_value
  @type reject :: {reject_reason(), String.t() | nil, binary()}
  @type command ::
          {:go, us(), us(), us(), 0 | 1}
          | {:ligt, 0..255}
          | {:claser, 0..255}
          | {:tilt, us()}
          | {:ping, non_neg_integer()}
          | {:mtrmod1, integer(), integer(), integer()}
          | {:mtrmod2, integer(), integer(), integer()}
          | :stop

  @max_raw 32
  @max_key 32
  @int16 -32_768..32_767
  @max_number 24
  @max_ping (1 <<< 31) - 1
  @deg :math.pi() / 180

  # key => {field, min, max, conversion}
  @known %{
    "hdgd" => {:heading, 0, 360, :heading},
    "deap" => {:depth, -10, 200, :identity},
    "pitc" => {:pitch, -90, 90, :deg},
    "roll" => {:roll, -180, 180, :deg},
    "yaw" => {:yaw, -180, 360, :deg},
    "fthr" => {:forward_thrust, -100, 100, :percent},
    "vout" => {:voltage, 5, 20, :identity},
    "iout" => {:current, 0, 10, :identity},
    "temp" => {:temperature, -40, 85, :identity},
    "pres" => {:pressure, 0, 25_000, :mbar},
    "time" => {:board_time, 0, 4_294_967_295, :ms},
    # the 2.5 controller board's battery and ESC currents (controllerboard25.cpp)
    "BT1I" => {:battery1_current, 0, 10, :identity},
    "BT2I" => {:battery2_current, 0, 10, :identity},
    "SC1I" => {:esc1_current, 0, 30, :identity},
    "SC2I" => {:esc2_current, 0, 30, :identity},
    "SC3I" => {:esc3_current, 0, 30, :identity}
  }

  # the raw ranges above in SI units (the same conversions as convert/2 below)
  @si_ranges Map.new(@known, fn {_key, {field, min, max, conversion}} ->
               range =
                 case conversion do
                   # 360° is accepted and wraps to 0
                   :heading -> {0.0, 2 * :math.pi()}
                   :identity -> {min * 1.0, max * 1.0}
                   :deg -> {min * @deg, max * @deg}
                   :percent -> {min / 100, max / 100}
                   :mbar -> {min * 100.0, max * 100.0}
                   :ms -> {min / 1000, max / 1000}
                 end

               {field, range}
             end)

  @doc "The known telemetry keys and their field name, raw range and conversion (see the table above)."
  @spec known() :: %{String.t() => {atom(), number(), number(), atom()}}
  def known, do: @known

  @doc """
  The SI range of each known field: what `parse_line/1` can return for it.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.si_range(:depth)
      {-10.0, 200.0}
  """
  @spec si_range(atom()) :: {float(), float()}
  def si_range(field), do: Map.fetch!(@si_ranges, field)

  # Commands ------------------------------------------------------------------------------

  @doc """
  `go(port,vertical,starboard,flag);` with the motors' pulse widths in `go()` order; the
  flag is 1 for `direct`, 0 for `ramp` (the 2.5.x and 30.x firmware store it and never read
  it: the values take effect at its next 50 ms tick either way; see
  `Neptunus.Vehicle.Board.OpenROV.Wiring`).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.go({1500, 1750, 1000}, true)
      "go(1500,1750,1000,1);"
  """
  @spec go({us(), us(), us()}, boolean()) :: binary()
  def go({a, b, c}, direct)
      when a in 1000..2000 and b in 1000..2000 and c in 1000..2000 and is_boolean(direct) do
    "go(#{a},#{b},#{c},#{if direct, do: 1, else: 0});"
  end

  @doc """
  Lights, 0..255.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.lights(255)
      "ligt(255);"
  """
  @spec lights(0..255) :: binary()
  def lights(n) when n in 0..255, do: "ligt(#{n});"

  @doc """
  Laser, 0..255.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.laser(0)
      "claser(0);"
  """
  @spec laser(0..255) :: binary()
  def laser(n) when n in 0..255, do: "claser(#{n});"

  @doc """
  Camera tilt servo pulse width, 1000..2000 µs.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.tilt(1500)
      "tilt(1500);"
  """
  @spec tilt(us()) :: binary()
  def tilt(us) when us in 1000..2000, do: "tilt(#{us});"

  @doc """
  Deadman ping number `n` (0..2³¹ − 1; the board answers `pong:n;`).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.ping(7)
      "ping(7);"
  """
  @spec ping(non_neg_integer()) :: binary()
  def ping(n) when is_integer(n) and n >= 0 and n <= @max_ping, do: "ping(#{n});"

  @doc """
  Stops the motors: the 2.5.x/30.x firmware drives them to neutral (it does not detach them).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.stop()
      "stop();"
  """
  @spec stop() :: binary()
  def stop, do: "stop();"

  @typedoc "A motor modifier in percent, as `mtrmod1/2` send it (see `motor_modifiers/2`)."
  @type modifier :: 0..1000

  @doc """
  The motors' forward modifiers, in percent, in `go()` order: `mtrmod1(a,b,c);`. The firmware
  (`Motor::goms`) multiplies a motor's offset from neutral by `modifier div 100` (an integer
  division: only multiples of 100 change anything; 100 is ×1), for commands above neutral.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.mtrmod1({100, 100, 100})
      "mtrmod1(100,100,100);"
  """
  @spec mtrmod1({modifier(), modifier(), modifier()}) :: binary()
  def mtrmod1({a, b, c}) when a in 0..1000 and b in 0..1000 and c in 0..1000,
    do: "mtrmod1(#{a},#{b},#{c});"

  @doc """
  The motors' reverse modifiers (commands below neutral), in percent, in `go()` order:
  `mtrmod2(a,b,c);`. The firmware's default is 200 (reverse doubled).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.mtrmod2({100, 100, 100})
      "mtrmod2(100,100,100);"
  """
  @spec mtrmod2({modifier(), modifier(), modifier()}) :: binary()
  def mtrmod2({a, b, c}) when a in 0..1000 and b in 0..1000 and c in 0..1000,
    do: "mtrmod2(#{a},#{b},#{c});"

  @doc """
  The ESC pulse width the OpenROV 2.5.2+ firmware writes for a `go()` value (`Motor::goms`):
  the offset from neutral is multiplied by the integer modifier (`forward div 100` above
  neutral, `reverse div 100` below; the firmware's defaults are 100 and 200), clamped to
  1000..2000, then mapped out of the ESCs' dead zone: 1000..1500 onto 1000..1450 and
  1500..2000 onto 1550..2000 (integer arithmetic, truncating like the Arduino's `map()`).
  A model of the board, for tests and the SITL board.

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> Enum.map([1300, 1500, 1700], &OpenROV.Protocol.goms(&1, 100, 200))
      [1090, 1500, 1730]
  """
  @spec goms(integer(), integer(), integer()) :: integer()
  def goms(us, forward, reverse)
      when is_integer(us) and is_integer(forward) and is_integer(reverse) do
    modifier =
      cond do
        us > 1500 -> div(forward, 100)
        us < 1500 -> div(reverse, 100)
        true -> 1
      end

    pre = (1500 + (us - 1500) * modifier) |> max(1000) |> min(2000)

    final =
      cond do
        pre < 1500 -> arduino_map(pre, 1000, 1500, 1000, 1450)
        pre > 1500 -> arduino_map(pre, 1500, 2000, 1550, 2000)
        true -> 1500
      end

    final |> max(1000) |> min(2000)
  end

  defp arduino_map(x, in_min, in_max, out_min, out_max),
    do: div((x - in_min) * (out_max - out_min), in_max - in_min) + out_min

  # Framing (firmware profiles) -------------------------------------------------------------

  @typedoc """
  How a board's firmware wants its commands: `:openrov_25` (OpenROV 2.5.x, plain
  `;`-terminated text) or `:openrov_30` (OpenROV 30.x: each command prefixed with one CRC byte,
  see `frame/2`).
  """
  @type profile :: :openrov_25 | :openrov_30

  @doc """
  The Dallas/Maxim CRC-8 (reflected polynomial 0x8C, initial value 0) of `bytes`: what the
  OpenROV 30.x firmware computes over a received command, `;` included.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.crc8("123456789")
      0xA1
  """
  @spec crc8(binary()) :: byte()
  def crc8(bytes) when is_binary(bytes), do: crc8(bytes, 0)

  defp crc8(<<byte, rest::binary>>, crc), do: crc8(rest, crc8_bits(crc, byte, 8))
  defp crc8(<<>>, crc), do: crc

  defp crc8_bits(crc, _byte, 0), do: crc

  defp crc8_bits(crc, byte, n) do
    shifted = crc >>> 1
    crc = if (bxor(crc, byte) &&& 1) == 1, do: bxor(shifted, 0x8C), else: shifted
    crc8_bits(crc, byte >>> 1, n - 1)
  end

  @doc """
  A command (as the encoders above return it, `;`-terminated) in the wire form of a firmware
  profile. `:openrov_25` sends it as it is. `:openrov_30` prefixes the CRC-8 of the command,
  `;` included. The 30.x firmware ends a command at the first `;` it reads, so a CRC byte
  equal to `;` (1 command in 256) would cut the command short: such a command is sent with a
  space after its `(` instead (the firmware splits arguments on spaces as on commas, so the
  meaning is the same), as many as needed for a CRC that is not `;`.

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> OpenROV.Protocol.frame("ping(0);", :openrov_25)
      "ping(0);"
      iex> <<crc, "ping(0);">> = OpenROV.Protocol.frame("ping(0);", :openrov_30)
      iex> crc == OpenROV.Protocol.crc8("ping(0);")
      true
  """
  @spec frame(binary(), profile()) :: binary()
  def frame(command, :openrov_25) when is_binary(command), do: command

  def frame(command, :openrov_30) when is_binary(command) do
    case crc8(command) do
      ?; -> command |> String.replace("(", "( ", global: false) |> frame(:openrov_30)
      crc -> <<crc, command::binary>>
    end
  end

  @doc """
  The board's side of `frame/2` for `:openrov_30`: checks the CRC byte of one received
  command (`;` included) as the firmware does. Returns the command text after the CRC byte,
  or the CRC the firmware computed and the one it received (it prints them as
  `crc:fail,COMPUTED/RECEIVED;` and drops the command).

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> OpenROV.Protocol.unframe(OpenROV.Protocol.frame("stop();", :openrov_30))
      {:ok, "stop();"}
      iex> OpenROV.Protocol.unframe(<<0, "stop();">>)
      {:error, {OpenROV.Protocol.crc8("stop();"), 0}}
  """
  @spec unframe(binary()) :: {:ok, binary()} | {:error, {byte(), byte()} | :empty}
  def unframe(<<received, command::binary>>) do
    case crc8(command) do
      ^received -> {:ok, command}
      computed -> {:error, {computed, received}}
    end
  end

  def unframe(<<>>), do: {:error, :empty}

  @doc """
  The board's side: parses one command (with or without its `;`) into a term, checking every
  argument's range like the firmware does ("ignore corrupt data").

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_command("go(1500,1600,1400,1);")
      {:ok, {:go, 1500, 1600, 1400, 1}}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_command("go(900,1500,1500,0)")
      {:error, "go: motor values must be 1000..2000 and the flag 0 or 1"}
  """
  @spec parse_command(binary()) :: {:ok, command()} | {:error, String.t()}
  def parse_command(text) when is_binary(text) do
    text = text |> String.trim() |> String.trim_trailing(";")

    with {:ok, name, args} <- split_call(text),
         {:ok, ints} <- int_args(args) do
      command(name, ints)
    end
  end

  @doc """
  Splits a stream of command bytes into complete `;`-terminated commands and the incomplete
  rest (to prepend to the next chunk). Whitespace (a stray newline) around commands is removed.

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> OpenROV.Protocol.split_commands("ping(1);go(1500,1500,1500,1);sto")
      {["ping(1)", "go(1500,1500,1500,1)"], "sto"}
  """
  @spec split_commands(binary()) :: {[binary()], binary()}
  def split_commands(bytes) do
    {commands, [rest]} = bytes |> :binary.split(";", [:global]) |> Enum.split(-1)
    {commands |> Enum.map(&String.trim/1) |> Enum.reject(&(&1 == "")), rest}
  end

  defp split_call(text) do
    case Regex.run(~r/\A([a-z]+[0-9]?)\(([^()]*)\)\z/, text) do
      [_, name, args] -> {:ok, name, args}
      nil -> {:error, "not a command: #{inspect(truncate(text))}"}
    end
  end

  defp int_args(""), do: {:ok, []}

  defp int_args(args) do
    args
    |> String.split(",")
    |> Enum.reduce_while({:ok, []}, fn arg, {:ok, acc} ->
      case Integer.parse(String.trim(arg)) do
        {n, ""} -> {:cont, {:ok, [n | acc]}}
        _ -> {:halt, {:error, "bad argument #{inspect(truncate(arg))}"}}
      end
    end)
    |> case do
      {:ok, ints} -> {:ok, Enum.reverse(ints)}
      error -> error
    end
  end

  defp command("go", [a, b, c, s])
       when a in 1000..2000 and b in 1000..2000 and c in 1000..2000 and s in [0, 1],
       do: {:ok, {:go, a, b, c, s}}

  defp command("go", _), do: {:error, "go: motor values must be 1000..2000 and the flag 0 or 1"}
  defp command("ligt", [n]) when n in 0..255, do: {:ok, {:ligt, n}}
  defp command("claser", [n]) when n in 0..255, do: {:ok, {:claser, n}}
  defp command("tilt", [n]) when n in 1000..2000, do: {:ok, {:tilt, n}}
  defp command("ping", [n]) when n >= 0 and n <= @max_ping, do: {:ok, {:ping, n}}

  # the firmware keeps the arguments as 16-bit ints; a negative modifier reverses the motor
  defp command("mtrmod1", [a, b, c]) when a in @int16 and b in @int16 and c in @int16,
    do: {:ok, {:mtrmod1, a, b, c}}

  defp command("mtrmod2", [a, b, c]) when a in @int16 and b in @int16 and c in @int16,
    do: {:ok, {:mtrmod2, a, b, c}}

  defp command("stop", []), do: {:ok, :stop}
  defp command(name, _), do: {:error, "#{name}: unknown command or bad arguments"}

  # Telemetry -----------------------------------------------------------------------------

  @doc """
  Parses one telemetry line (without its newline) into `{fields, rejects}`; never raises.

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> OpenROV.Protocol.parse_line("deap:1.5;vout:12.1;hdgd:pitc;fmem:1234;x")
      {%{:depth => 1.5, :voltage => 12.1, "fmem" => "1234"},
       [{:key_as_value, "hdgd", "pitc"}, {:malformed, nil, "x"}]}

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_line("iout:40;temp:nan")
      {%{}, [{:out_of_range, "iout", "40"}, {:not_a_number, "temp", "nan"}]}
  """
  @spec parse_line(binary()) :: {fields(), [reject()]}
  def parse_line(line) when is_binary(line) do
    {fields, rejects} =
      line
      |> :binary.split(";", [:global])
      |> Enum.reduce({%{}, []}, &parse_field/2)

    {fields, Enum.reverse(rejects)}
  end

  # Plain-text lines the 2.5.2 depth driver (MS5803_14BA.cpp) prints at setup and every second.
  @text_lines [
    ~r/\ADepth Sensor setup\.\z/,
    ~r/\ADepth Sensor: initialized I2C\z/,
    ~r/\ADepth Sensor is reset\z/,
    ~r/\ADepth: Calibration constants are:\z/,
    ~r/\A(First|Second)-Order Temperature in Degrees C is -?[0-9]+(\.[0-9]+)?\z/
  ]

  @doc """
  Whether a line is one of the plain-text lines the firmware prints besides its `key:value;`
  fields (the 2.5.2 depth driver's setup lines and its temperature lines every second): such
  a line is counted as `text`, not parsed, and never counted as malformed.

      iex> alias Neptunus.Vehicle.Board.OpenROV
      iex> OpenROV.Protocol.text_line?("First-Order Temperature in Degrees C is 11.52")
      true
      iex> OpenROV.Protocol.text_line?("deap:1.00;")
      false
  """
  @spec text_line?(binary()) :: boolean()
  def text_line?(line) when is_binary(line) do
    byte_size(line) <= 80 and :binary.match(line, ";") == :nomatch and
      Enum.any?(@text_lines, &Regex.match?(&1, line))
  end

  @typedoc """
  The board's reply to `ping()`: `pong:<argument count>,<millis>;` (`args`, and `millis` the
  board's uptime in ms); an older or simulated board answering `pong:n;` gives neither.
  """
  @type pong :: %{args: non_neg_integer() | nil, millis: non_neg_integer() | nil}

  @doc """
  Parses the value of a `pong` field.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_pong("1,183422")
      {:ok, %{args: 1, millis: 183422}}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_pong("7")
      {:ok, %{args: nil, millis: nil}}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_pong("x")
      :error
  """
  @spec parse_pong(binary()) :: {:ok, pong()} | :error
  def parse_pong(value) when is_binary(value) do
    case :binary.split(value, ",") do
      [args, millis] ->
        with {:ok, a} <- non_neg(args),
             {:ok, ms} <- non_neg(millis),
             do: {:ok, %{args: a, millis: ms}}

      [n] ->
        with {:ok, _} <- non_neg(n), do: {:ok, %{args: nil, millis: nil}}
    end
  end

  defp non_neg(text) do
    case Integer.parse(trim(text)) do
      {n, ""} when n >= 0 and n <= 4_294_967_295 -> {:ok, n}
      _ -> :error
    end
  end

  @doc """
  Parses a command echo (the value of a `cmd` or `icmd` field, `name(args)`) into the
  command's name.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_echo("go(1500,1500,1500,0)")
      {:ok, "go"}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_echo("1500")
      :error
  """
  @spec parse_echo(binary()) :: {:ok, String.t()} | :error
  def parse_echo(value) when is_binary(value) do
    case Regex.run(~r/\A([A-Za-z][A-Za-z0-9_]*)\(/, value) do
      [_, name] -> {:ok, name}
      nil -> :error
    end
  end

  @doc """
  Parses a command echo (`name(arg,arg)`, the value of a `cmd` field) into its name and its
  arguments as the board printed them: the firmware splits a command at spaces, commas and
  parentheses and echoes the pieces joined by commas, so `call/1` of what we sent gives
  the same pair (see `call/1`). A piece of an argument after a stray `(` or a missing `)`
  makes it no echo.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_call("mtrmod1(100,100,100)")
      {:ok, "mtrmod1", ["100", "100", "100"]}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_call("stop()")
      {:ok, "stop", []}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_call("ligt(1")
      :error
  """
  @spec parse_call(binary()) :: {:ok, String.t(), [String.t()]} | :error
  def parse_call(value) when is_binary(value) do
    case Regex.run(~r/\A([A-Za-z][A-Za-z0-9_]*)\(([^()]*)\)\z/, value) do
      [_, name, ""] -> {:ok, name, []}
      [_, name, args] -> {:ok, name, String.split(args, ",")}
      nil -> :error
    end
  end

  @doc """
  What the board echoes for a command we write (as `parse_call/1` reads it): the name and
  the argument pieces, split as the firmware splits (spaces, commas, parentheses, `;`).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.call("mtrmod2(100,200,100);")
      {"mtrmod2", ["100", "200", "100"]}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.call("ligt( 80);")
      {"ligt", ["80"]}
  """
  @spec call(binary()) :: {String.t(), [String.t()]}
  def call(command) when is_binary(command) do
    case String.split(command, [" ", ",", "(", ")", ";"], trim: true)
         |> Enum.reject(&(&1 == "")) do
      [name | args] -> {name, args}
      [] -> {"", []}
    end
  end

  @doc """
  Parses the value of a 30.x `crc` field: `pass`, or `fail,COMPUTED/RECEIVED` (hex).

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_crc("pass")
      {:ok, :pass}
      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.parse_crc("fail,A1/3B")
      {:ok, {:fail, 0xA1, 0x3B}}
  """
  @spec parse_crc(binary()) :: {:ok, :pass | {:fail, byte(), byte()}} | :error
  def parse_crc("pass"), do: {:ok, :pass}

  def parse_crc("fail," <> pair) do
    with [c, r] <- :binary.split(pair, "/"),
         {computed, ""} when computed in 0..255 <- Integer.parse(c, 16),
         {received, ""} when received in 0..255 <- Integer.parse(r, 16) do
      {:ok, {:fail, computed, received}}
    else
      _ -> :error
    end
  end

  def parse_crc(_), do: :error

  @doc """
  Whether a rejected field is a wild point (counted as such) rather than a malformed field.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.wild_point?({:out_of_range, "deap", "2000"})
      true
  """
  @spec wild_point?(reject()) :: boolean()
  def wild_point?({reason, _key, _raw}), do: reason != :malformed

  @doc """
  Formats fields as a telemetry line (no newline) in board units: the inverse of
  `parse_line/1` for known fields, used by the SITL board. Numbers get `decimals` decimals.

      iex> Neptunus.Vehicle.Board.OpenROV.Protocol.format_line([depth: 1.5, heading: :math.pi()], 2)
      "deap:1.50;hdgd:180.00;"
  """
  @spec format_line([{atom(), number()}], non_neg_integer()) :: binary()
  def format_line(fields, decimals) do
    IO.iodata_to_binary(
      for {field, value} <- fields do
        {key, conversion} = key_of(field)
        raw = unconvert(value, conversion)
        [key, ?:, :erlang.float_to_binary(raw * 1.0, decimals: decimals), ?;]
      end
    )
  end

  for {key, {field, _min, _max, conversion}} <- @known do
    defp key_of(unquote(field)), do: {unquote(key), unquote(conversion)}
  end

  defp parse_field(segment, {fields, rejects} = acc) do
    case :binary.split(segment, ":") do
      [key, value] ->
        key = trim(key)
        value = trim(value)

        if valid_key?(key),
          do: classify(key, value, acc),
          else: {fields, [{:malformed, nil, truncate(segment)} | rejects]}

      [other] ->
        case trim(other) do
          "" -> acc
          _ -> {fields, [{:malformed, nil, truncate(segment)} | rejects]}
        end
    end
  end

  defp classify(key, value, {fields, rejects}) when is_map_key(@known, value) do
    {fields, [{:key_as_value, key, value} | rejects]}
  end

  defp classify(key, value, {fields, rejects}) do
    case Map.fetch(@known, key) do
      :error ->
        {Map.put(fields, key, value), rejects}

      {:ok, {field, min, max, conversion}} ->
        case number(value) do
          :error ->
            {fields, [{:not_a_number, key, truncate(value)} | rejects]}

          {:ok, n} when n >= min and n <= max ->
            {Map.put(fields, field, convert(n, conversion)), rejects}

          {:ok, _} ->
            {fields, [{:out_of_range, key, truncate(value)} | rejects]}
        end
    end
  end

  defp convert(n, :identity), do: n * 1.0
  defp convert(n, :deg), do: n * @deg
  defp convert(n, :percent), do: n / 100
  defp convert(n, :mbar), do: n * 100.0
  defp convert(n, :ms), do: n / 1000

  defp convert(n, :heading) do
    rad = n * @deg
    if rad >= 2 * :math.pi(), do: 0.0, else: rad
  end

  defp unconvert(v, :identity), do: v
  defp unconvert(v, :deg), do: v / @deg
  defp unconvert(v, :heading), do: v / @deg
  defp unconvert(v, :percent), do: v * 100
  defp unconvert(v, :mbar), do: v / 100
  defp unconvert(v, :ms), do: v * 1000

  # A plain decimal number as the Arduino prints it: optional sign, digits, optional
  # fraction, optional short exponent. Anything else (nan, inf, ovf, 1.2.3, 0x10) is not one.
  defp number(value) when byte_size(value) > @max_number, do: :error

  # A byte scanner (no regex: this runs for every field of every line): sign, integer digits,
  # fraction digits, exponent of at most two digits; at least one digit before the exponent.
  # Fast path for what boards print ("12.34", "-0.5", "7"); anything else goes to the scanner.
  defp number(<<c, _::binary>> = value) when c in ?0..?9 or c == ?- do
    if :binary.match(value, ["e", "E"]) == :nomatch do
      try do
        {:ok, :erlang.binary_to_float(value) + 0.0}
      rescue
        ArgumentError ->
          try do
            {:ok, :erlang.binary_to_integer(value) + 0.0}
          rescue
            ArgumentError -> scan_number(value)
          end
      end
    else
      scan_number(value)
    end
  end

  defp number(value), do: scan_number(value)

  defp scan_number(<<?-, rest::binary>>), do: digits(rest, "-", "")
  defp scan_number(<<?+, rest::binary>>), do: digits(rest, "", "")
  defp scan_number(value), do: digits(value, "", "")

  defp digits(<<d, rest::binary>>, sign, int) when d in ?0..?9,
    do: digits(rest, sign, <<int::binary, d>>)

  defp digits(<<?., rest::binary>>, sign, int), do: fraction(rest, sign, int, "")
  defp digits(rest, sign, int), do: exponent(rest, sign, int, "")

  defp fraction(<<d, rest::binary>>, sign, int, frac) when d in ?0..?9,
    do: fraction(rest, sign, int, <<frac::binary, d>>)

  defp fraction(rest, sign, int, frac), do: exponent(rest, sign, int, frac)

  defp exponent(_rest, _sign, "", ""), do: :error
  defp exponent("", sign, int, frac), do: to_float(sign, int, frac, "0")

  defp exponent(<<e, rest::binary>>, sign, int, frac) when e in [?e, ?E] do
    case rest do
      <<s, d1, d2>> when s in [?+, ?-] and d1 in ?0..?9 and d2 in ?0..?9 ->
        to_float(sign, int, frac, <<s, d1, d2>>)

      <<s, d1>> when s in [?+, ?-] and d1 in ?0..?9 ->
        to_float(sign, int, frac, <<s, d1>>)

      <<d1, d2>> when d1 in ?0..?9 and d2 in ?0..?9 ->
        to_float(sign, int, frac, <<d1, d2>>)

      <<d1>> when d1 in ?0..?9 ->
        to_float(sign, int, frac, <<d1>>)

      _ ->
        :error
    end
  end

  defp exponent(_rest, _sign, _int, _frac), do: :error

  defp to_float(sign, int, frac, exp) do
    text =
      <<sign::binary, zero_if_empty(int)::binary, ?., zero_if_empty(frac)::binary, ?e,
        exp::binary>>

    {:ok, :erlang.binary_to_float(text) + 0.0}
  rescue
    # beyond the float range (cannot happen with a two-digit exponent; kept as a guard)
    ArgumentError -> :error
  end

  defp zero_if_empty(""), do: "0"
  defp zero_if_empty(digits), do: digits

  defp valid_key?(<<first, rest::binary>>)
       when (first in ?a..?z or first in ?A..?Z) and byte_size(rest) <= @max_key - 1,
       do: key_rest?(rest)

  defp valid_key?(_), do: false

  defp key_rest?(<<c, rest::binary>>)
       when c in ?a..?z or c in ?A..?Z or c in ?0..?9 or c == ?_ or c == ?.,
       do: key_rest?(rest)

  defp key_rest?(<<>>), do: true
  defp key_rest?(_), do: false

  defp trim(s), do: s |> trim_leading() |> trim_trailing(byte_size(s))

  defp trim_leading(<<c, rest::binary>>) when c in [?\s, ?\t], do: trim_leading(rest)
  defp trim_leading(s), do: s

  defp trim_trailing(s, _) when s == "", do: s

  defp trim_trailing(s, _) do
    case :binary.last(s) do
      c when c in [?\s, ?\t] -> trim_trailing(binary_part(s, 0, byte_size(s) - 1), 0)
      _ -> s
    end
  end

  defp truncate(s) when byte_size(s) <= @max_raw, do: s
  defp truncate(s), do: binary_part(s, 0, @max_raw)
end
