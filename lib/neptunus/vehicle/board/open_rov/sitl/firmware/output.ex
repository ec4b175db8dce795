defmodule Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Output do
  @moduledoc """
  The lines the SITL firmware prints on its own (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware`; the
  firmware's main loop, `OpenROV.ino`): its boot lines, the navigation line and the shared
  data, and how it prints a number. Each device's own replies are its own
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices`).

  **Telemetry** (2 decimals, `\\r\\n` line ends, fields glued as printed):

    * every 101 ms `hdgd:…;deap:…;pitc:…;roll:…;yaw:…;fthr:…;\\r\\n` — `fthr` is the mean
      of the raw port and starboard targets mapped to ±100 (integer `map`); `deap` is `0.00`
      until the depth sensor's first reading, `hdgd` until the IMU's;
    * every 1001 ms (after the controller board's line, when both are due) the shared data:
      `motorAttached:1;`, `servo:…;starg:…;`,
      `fmem:…;vout:…;iout:…;atmp:…;ver:…;cmpd:<date>, <time>, <gcc>` (every 1001 ms from
      boot) whose newline comes before its `;` (the next line begins `;time:`),
      `pres:…;temp:…;` (`0.00` until the depth sensor's first reading, the first shared data
      at 1001 ms included), `dlms:…;`, `alps:…;`. `iout` is the controller board's own
      supply current (`BRDI`); `vout`, `iout` and `time` are sampled every 101 ms. 30.0.2
      also prints `BNO055.status:…;` once a second.

  **Boot.** At boot the board prints its setup lines (2.5.2's depth sensor's; 30.0.2's
  calibration constants as `Depth.C0:…;` … `Depth.C7:…;`, keys with a dot) and, when its
  setup is done (`setup_ms`), `boot:1;\r\n` — 2.5.x and 30.x alike (`OpenROV.ino`'s
  `setup()` ends with it).
  """

  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.Devices

  @compiled "Dec 10 2014, 10:42:17, 4.3.2"
  # the devices as the firmware registers them (their loop times print in `dlms:`)
  @devices [:controller, :lights, :laser, :thrusters, :deadman, :camera, :imu, :depth]
  @depth_index 7
  @calibration [0, 46372, 43981, 29059, 27842, 31553, 28165, 0]

  @doc "The main loop's outputs due at millis `m`: the shared data, then the navigation line."
  @spec outputs(Firmware.t(), integer()) :: {Firmware.t(), iodata()}
  def outputs(fw, m) do
    {second, fw} = Devices.elapsed(fw, :second, 1000, m)

    {fw, shared} =
      if second do
        fw = %{fw | alps: fw.drains, drains: 0}
        {fw, shared_data(fw)}
      else
        {fw, []}
      end

    {nav, fw} = Devices.elapsed(fw, :nav, 100, m)
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
    fthr = Devices.map(div(p + s, 2), 1000, 2000, -100, 100)
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

  @doc "What the board prints while it sets up, `boot:1;` last."
  @spec boot_lines(Firmware.profile()) :: iodata()
  def boot_lines(:openrov_25) do
    [
      "Depth Sensor setup.\r\nDepth Sensor: initialized I2C\r\nDepth Sensor is reset\r\n",
      "Depth: Calibration constants are:\r\n",
      "log:init on primary addresses;\r\n",
      "boot:1;\r\n"
    ]
  end

  def boot_lines(:openrov_30) do
    constants =
      @calibration
      |> Enum.with_index()
      |> Enum.map(fn {c, i} ->
        ["Depth.C", Integer.to_string(i), ?:, Integer.to_string(c), ";\r\n"]
      end)

    [constants, "log:init on primary addresses;\r\n", "boot:1;\r\n"]
  end

  @doc "Three pulses as the firmware prints them: `1500,1500,1500`."
  @spec join3(Firmware.us3()) :: String.t()
  def join3({a, b, c}), do: Enum.map_join([a, b, c], ",", &Integer.to_string/1)

  @doc """
  A number as the Arduino prints a float: `Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.float2/1`.
  """
  @spec float2(number()) :: binary()
  def float2(x) when x == 0, do: "0.00"
  def float2(x), do: :erlang.float_to_binary(x * 1.0, decimals: 2)
end
