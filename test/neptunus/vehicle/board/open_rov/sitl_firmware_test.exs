defmodule Neptunus.Vehicle.Board.OpenROV.SITL.FirmwareTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.OpenROV.SITL.Firmware

  import Neptunus.Test.Properties, only: [check: 3, bind: 2]

  alias Neptunus.Sim
  alias Neptunus.Vehicle.Board.OpenROV.Wiring
  alias Neptunus.Vehicle.Board.OpenROV
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware

  @reading %{heading: 2.0, depth: 1.2, pitch: 0.01, roll: -0.02, voltage: 12.1, current: 3.0}
  @profiles [:openrov_25, :openrov_30]
  # a wiring without reversal, so ESC pulses read directly as thruster values
  @plain %Wiring{order: [:port, :vertical, :starboard], reversed: [], direct: true}

  # most tests: the loop runs from millis 0 (no setup time), so the times read simply
  defp boot(opts \\ []) do
    opts = Keyword.put_new(opts, :setup_ms, 0)
    {fw, _boot} = Firmware.new(0, opts) |> Firmware.sense(@reading) |> Firmware.tick(0)
    fw
  end

  defp wire(command, :openrov_25), do: command

  defp wire(commands, :openrov_30) do
    {commands, ""} = OpenROV.Protocol.split_commands(commands)
    Enum.map_join(commands, &OpenROV.Protocol.frame(&1 <> ";", :openrov_30))
  end

  # sends `commands` (framed for the profile) at `at`, runs the loop to `until`
  defp send_cmd(fw, commands, at, until) do
    {fw, _} = Firmware.receive(fw, wire(commands, fw.profile), at)
    Firmware.tick(fw, until)
  end

  defp lines(out), do: String.split(out, "\r\n", trim: true)
  defp navlines(out), do: out |> lines() |> Enum.filter(&String.starts_with?(&1, "hdgd:"))

  describe "boot" do
    for profile <- @profiles do
      test "#{profile}: depth, pressure and temperature print 0.00 until the first reading" do
        # default setup time: the devices start 20 ms after the main loop's output timers
        fw = boot(firmware: unquote(profile), setup_ms: 20)
        {_fw, out} = Firmware.tick(fw, 2_100)
        [first | _] = nav = navlines(out)
        assert first == "hdgd:114.59;deap:0.00;pitc:0.57;roll:-1.15;yaw:114.59;fthr:0.00;"
        # navigation at 101, 202, … 1010 before the reading at 1021; 1111, 1212, … after
        assert Enum.take(nav, 12) |> Enum.map(&(&1 =~ "deap:0.00;")) ==
                 List.duplicate(true, 10) ++ [false, false]

        assert Enum.at(nav, 10) =~ ";deap:1.20;"
        # the first shared data (1001 ms) comes before the reading, the second after it
        [first_status, second_status] = Regex.scan(~r/pres:[\d.]+;temp:[\d.]+;\r\n/, out)
        assert first_status == ["pres:0.00;temp:0.00;\r\n"]
        assert second_status == ["pres:1132.68;temp:10.00;\r\n"]
      end
    end

    test "depth changes once a second but is printed every 101 ms" do
      fw = boot()
      {fw, _} = Firmware.tick(fw, 1_050)
      fw = Firmware.sense(fw, %{@reading | depth: 2.0})
      {fw, out} = Firmware.tick(fw, 1_950)
      assert out |> navlines() |> Enum.all?(&(&1 =~ ";deap:1.20;"))
      {_fw, out} = Firmware.tick(fw, 2_100)
      assert List.last(navlines(out)) =~ ";deap:2.00;"
    end

    test "navigation data every 101 ms, the shared data every 1001 ms" do
      {_fw, out} = Firmware.tick(boot(), 3_100)
      assert length(navlines(out)) == 30
      assert length(Regex.scan(~r/;time:/, out)) == 3
      assert length(Regex.scan(~r/vout:12\.10;iout:0\.25;/, out)) == 3
    end

    test "heading comes from the IMU 51 ms after the setup, before the first navigation line" do
      fw = Firmware.new(0)
      {fw, _} = Firmware.tick(fw, 60)
      assert fw.attitude.heading == 0.0
      # the IMU's first read is 51 ms after its setup ended (20 ms)
      {fw, _} = fw |> Firmware.sense(@reading) |> Firmware.tick(71)
      assert_in_delta fw.attitude.heading, 114.59, 0.01
    end

    test "the millis start at 0 at boot and again at a reset; every state is lost" do
      fw = boot(firmware: :openrov_25)

      {fw, _} = send_cmd(fw, "mtrmod1(100,100,100);ligt(200);claser(9);", 5_000, 5_010)
      {fw, _} = send_cmd(fw, "tilt(1200);go(1700,1600,1700);", 5_011, 5_200)

      assert {fw.lights, fw.laser, fw.tilt, fw.esc_us} == {200, 9, 1200, {1730, 1640, 1730}}
      fw = Firmware.reset(fw, 6_000)
      assert Firmware.millis(fw, 6_000) == 0
      assert {fw.lights, fw.laser, fw.tilt, fw.esc_us} == {0, 0, 1500, {1500, 1500, 1500}}

      assert {fw.positive_mod, fw.negative_mod, fw.armed, fw.depth} ==
               {{1, 1, 1}, {2, 2, 2}, false, 0.0}

      {_fw, out} = Firmware.tick(fw, 6_101)
      assert out =~ "Depth Sensor setup.\r\n"
      assert List.last(navlines(out)) =~ "deap:0.00;"
      {fw, out} = send_cmd(fw, "ping(1);", 6_102, 6_120)
      assert out =~ "pong:1,110;"
      assert fw.last_ping == 110
    end

    for profile <- @profiles do
      test "#{profile}: boot:1 ends the setup's lines, when the setup is done" do
        fw = Firmware.new(0, firmware: unquote(profile), setup_ms: 20)
        assert {fw, ""} = Firmware.tick(fw, 19)
        {_fw, out} = Firmware.tick(fw, 20)
        assert [_ | _] = setup = lines(out)
        assert List.last(setup) == "boot:1;"
        assert Enum.count(setup, &(&1 == "boot:1;")) == 1
      end

      test "#{profile}: the bootloader loses what arrives, writes nothing, then the firmware starts" do
        profile = unquote(profile)
        fw = Firmware.new(1_000, firmware: profile, bootloader_ms: 500, setup_ms: 20)
        assert Firmware.millis(fw, 1_500) == 0
        {fw, ""} = Firmware.receive(fw, wire("mtrmod1(100,100,100);", profile), 1_010)
        {fw, ""} = Firmware.receive(fw, wire("go(1300,1500,1700,1);", profile), 1_499)
        assert {fw, ""} = Firmware.tick(fw, 1_519)
        assert fw.boot_lost > 0 and fw.rx == "" and fw.commands == 0
        # its setup done, boot:1; then what arrives is read
        {fw, out} = Firmware.tick(fw, 1_520)
        assert out =~ ~r/boot:1;\r\n\z/
        {fw, out} = send_cmd(fw, "ping(3);", 1_530, 1_545)
        assert out =~ "pong:1,"
        # the reset of a running board starts another bootloader
        fw = Firmware.reset(fw, 5_000)
        {fw, ""} = Firmware.receive(fw, wire("ligt(9);", profile), 5_100)
        {fw, _} = Firmware.tick(fw, 5_600)
        assert fw.lights == 0 and fw.commands == 0
      end
    end

    test "the ESC pulses the motors got are logged, newest first" do
      fw = boot(wiring: @plain)
      {fw, _} = send_cmd(fw, "go(1600,1500,1500);", 1, 60)
      {fw, _} = send_cmd(fw, "go(1400,1500,1500);", 61, 120)
      # the firmware's default modifiers: forward ×1, reverse ×2
      assert [{m2, {1270, 1500, 1500}}, {m1, {1640, 1500, 1500}}] = fw.esc_log
      assert m2 > m1
      assert Firmware.reset(fw, 200).esc_log == []
    end

    test "bad options are refused" do
      assert_raise ArgumentError, ~r/firmware/, fn -> Firmware.new(0, firmware: :v1) end
      assert_raise ArgumentError, ~r/loop_ms/, fn -> Firmware.new(0, loop_ms: 0) end
      assert_raise ArgumentError, ~r/arm_ms/, fn -> Firmware.new(0, arm_ms: -1) end
      assert_raise ArgumentError, ~r/wiring/, fn -> Firmware.new(0, wiring: "-port") end
      fw = boot()
      assert_raise ArgumentError, ~r/reading/, fn -> Firmware.sense(fw, %{depth: 1.0}) end

      assert_raise ArgumentError, ~r/reading/, fn ->
        Firmware.sense(fw, %{@reading | depth: nil})
      end
    end
  end

  describe "30.x CRC" do
    test "a command passes with its CRC byte: rawcmd, crc:pass, then the echo" do
      fw = boot(firmware: :openrov_30)
      framed = OpenROV.Protocol.frame("ping(1);", :openrov_30)
      {_fw, out} = send_cmd(fw, "ping(1);", 1, 10)
      hex = for <<b <- framed>>, into: "", do: Integer.to_string(b, 16) <> ","
      assert out == "rawcmd:" <> hex <> ";\r\ncrc:pass;cmd:ping(1);\r\npong:1,10;"
    end

    test "a wrong CRC prints crc:fail,COMPUTED/RECEIVED; and drops the command" do
      fw = boot(firmware: :openrov_30, wiring: @plain)
      {fw, _} = Firmware.receive(fw, <<0, "go(2000,2000,2000);">>, 1)
      {fw, out} = Firmware.tick(fw, 200)
      computed = Integer.to_string(OpenROV.Protocol.crc8("go(2000,2000,2000);"), 16)
      assert out =~ "\r\ncrc:fail," <> computed <> "/0;hdgd:"
      refute out =~ ~r/(?<!raw)cmd:/
      assert fw.target_us == {1500, 1500, 1500} and fw.bad_commands == 1
    end

    test "a plain 2.5 command is refused by 30.x; a framed one by 2.5 only echoes garbage" do
      {fw30, _} = Firmware.receive(boot(firmware: :openrov_30), "ping(1);", 1)
      {fw30, out} = Firmware.tick(fw30, 10)
      # framed for 2.5: the first byte is the CRC, here the 'p'
      refute out =~ "pong"
      assert fw30.bad_commands == 1

      {_fw, out} =
        Firmware.tick(
          boot(firmware: :openrov_25) |> then(&elem(Firmware.receive(&1, "ping(1);", 1), 0)),
          10
        )

      assert out == "cmd:ping(1);\r\npong:1,10;"
    end

    test "a CRC byte equal to ';' ends the command early" do
      fw = boot(firmware: :openrov_30)
      {_fw, out} = Firmware.tick(elem(Firmware.receive(fw, ";ping(1);", 1), 0), 10)
      assert out =~ "rawcmd:3B,;\r\ncrc:fail,0/3B;"
      refute out =~ "pong"
    end

    test "2.5 takes plain commands, without rawcmd or crc lines" do
      {_fw, out} = send_cmd(boot(firmware: :openrov_25), "ligt(9);", 1, 10)
      assert out == "cmd:ligt(9);\r\nLIGT:9;LIGP:0.04;\r\n"
    end
  end

  describe "echo" do
    for profile <- @profiles do
      test "#{profile}: every accepted command is echoed as the parser splits it" do
        {fw, out} =
          send_cmd(boot(firmware: unquote(profile)), "go(1500, 1600,1400,1);stop();", 1, 10)

        assert out =~ "cmd:go(1500,1600,1400,1);\r\n"
        assert out =~ "cmd:stop();\r\n"
        assert fw.commands == 2
      end
    end
  end

  describe "motors" do
    test "a neutral go() or stop is counted though a later go() in the same loop hides it" do
      {fw, _} = send_cmd(boot(), "go(1500,1500,1500,1);go(1700,1500,1300,1);", 1, 10)
      assert fw.target_us == {1700, 1500, 1300}
      assert fw.neutral_commands == 1

      {fw, _} = send_cmd(fw, "stop();go(1600,1500,1400,1);go(1500,1500,1499,1);", 11, 20)
      assert fw.target_us == {1500, 1500, 1499}
      assert fw.neutral_commands == 2

      # refused (out of range) neutral-looking commands are not counted
      {fw, _} = send_cmd(fw, "go(1500,1500,2500,1);", 21, 30)
      assert fw.neutral_commands == 2
    end

    test "Motor::goms with the default modifiers: go(1300,1500,1700) → 1090/1500/1730" do
      {fw, out} = send_cmd(boot(), "go(1300,1500,1700,1);", 1, 100)
      assert fw.esc_us == {1090, 1500, 1730}
      assert out =~ "motors:1090,1500,1730;\r\n"
      for us <- 1000..1250, do: assert(Firmware.goms(us, 1, 2) == 1000)
    end

    for profile <- @profiles do
      test "#{profile}: with the thesis wiring straight surge yaws; after mtrmod 100 it is even" do
        fw = boot(firmware: unquote(profile))
        {fw, _} = send_cmd(fw, "go(1300,1500,1700,1);", 1, 100)
        assert fw.thrusters == %{port: 0.82, vertical: 0.0, starboard: 0.46}
        {fw, _} = send_cmd(fw, "mtrmod1(100,100,100);mtrmod2(100,100,100);stop();", 101, 200)
        {fw, _} = send_cmd(fw, "go(1300,1500,1700,1);", 201, 300)
        assert fw.esc_us == {1270, 1500, 1730}
        assert fw.thrusters == %{port: 0.46, vertical: 0.0, starboard: 0.46}
      end
    end

    test "modifiers are integer percent: 150 → 1, 250 → 2, 50 → 0" do
      {fw, _} = send_cmd(boot(), "mtrmod1(150,250,50);mtrmod2(100,300,99);", 1, 20)
      assert {fw.positive_mod, fw.negative_mod} == {{1, 2, 0}, {1, 3, 0}}
    end

    test "fthr is the mean of the raw port/starboard targets mapped to ±100" do
      {_fw, out} = send_cmd(boot(), "go(1300,1500,1700,1);", 1, 110)
      assert List.last(navlines(out)) =~ "fthr:0.00;"
      {_fw, out} = send_cmd(boot(), "go(1750,1500,1750,1);", 1, 110)
      assert List.last(navlines(out)) =~ "fthr:50.00;"
    end

    test "the simulated thrust comes from the ESC pulses through the wiring" do
      # thesis wiring, port reversed: go 1300 on port is forward thrust
      {fw, _} = send_cmd(boot(), "go(1250,1500,1750,1);", 1, 100)
      assert fw.thrusters == Wiring.from_us(Wiring.default(), {1000, 1500, 1775})
    end
  end

  describe "go() timing" do
    test "new values take effect at the next 50 ms tick, whatever the 4th argument" do
      fw = boot(wiring: @plain)
      # received at 10; control ticks at 51, 102, …
      {fw, _} = send_cmd(fw, "go(2000,1000,1600,0);", 1, 50)
      assert fw.esc_us == {1500, 1500, 1500}
      {fw, _} = Firmware.tick(fw, 51)
      assert fw.esc_us == {2000, 1000, 1640}
      {fw, _} = send_cmd(fw, "go(1600,1500,1500,1);", 52, 101)
      assert fw.esc_us == {2000, 1000, 1640}
      {fw, _} = Firmware.tick(fw, 102)
      assert fw.esc_us == {1640, 1500, 1500}
    end

    test "stop sets neutral at the next tick and does not detach" do
      {fw, _} = send_cmd(boot(wiring: @plain), "go(2000,2000,2000,1);", 1, 60)
      {fw, out} = send_cmd(fw, "stop();", 61, 110)
      assert fw.esc_us == {1500, 1500, 1500}
      assert out =~ "motors:1500,1500,1500;"
      {_fw, out} = Firmware.tick(fw, 1_100)
      assert out =~ "motorAttached:1;"
    end
  end

  describe "deadman" do
    test "ping answers pong:<argument count>,<millis>; without newline" do
      {_fw, out} = send_cmd(boot(), "ping(42);ping();ping(1,2);", 1, 10)

      assert out ==
               "cmd:ping(42);\r\npong:1,10;cmd:ping();\r\npong:0,10;cmd:ping(1,2);\r\npong:2,10;"
    end

    test "it arms only after arm_ms (default 180 s)" do
      fw = boot(wiring: @plain)
      {fw, _} = send_cmd(fw, "go(2000,2000,2000,1);", 1, 60_000)
      refute fw.tripped
      assert fw.esc_us == {2000, 2000, 2000}
      {fw, _} = Firmware.tick(fw, 180_000)
      refute fw.armed or fw.tripped
      {fw, _} = Firmware.tick(fw, 182_002)
      assert fw.armed and fw.tripped
      assert fw.esc_us == {1500, 1500, 1500}
    end

    test "30.x: a trip runs deptloff/headloff/stop, blinks, still obeys go, a ping clears it" do
      fw = boot(firmware: :openrov_30, arm_ms: 0, wiring: @plain)
      {fw, _} = send_cmd(fw, "go(2000,2000,2000,1);ping(1);", 1, 2_010)
      refute fw.tripped
      {fw, out} = Firmware.tick(fw, 2_012)
      assert fw.tripped
      # the ring holds two: the overflow is logged and the oldest lost
      assert out =~
               "log: CommandBufferOverrun;\r\nlog: CommandBufferOverrun;\r\n" <>
                 "icmd:stop();\r\nicmd:ligt(50);\r\nLIGT:50;LIGP:0.20;\r\n"

      refute out =~ "deadman"
      {fw, _} = Firmware.tick(fw, 2_100)
      assert fw.esc_us == {1500, 1500, 1500} and fw.lights == 50
      {fw, out} = Firmware.tick(fw, 2_513)
      assert out =~ "icmd:ligt(0);\r\nLIGT:0;"
      # go() is still obeyed while tripped
      {fw, _} = send_cmd(fw, "go(1600,1600,1600,1);", 2_520, 2_600)
      assert fw.esc_us == {1640, 1640, 1640} and fw.tripped
      {fw, out} = Firmware.tick(fw, 3_015)
      assert out =~ "icmd:ligt(50);"
      {fw, out} = send_cmd(fw, "ping(2);", 3_016, 3_030)
      assert out =~ "icmd:start();\r\n"
      refute fw.tripped
      {fw, out} = Firmware.tick(fw, 5_000)
      refute out =~ "icmd:"
      # the lights stay at the blink level
      assert fw.lights == 50
    end

    test "2.5: the same trip, its ring read before advancing (the blink lags by one)" do
      fw = boot(firmware: :openrov_25, arm_ms: 0, wiring: @plain)
      {fw, _} = send_cmd(fw, "go(2000,2000,2000,1);ping(1);", 1, 2_010)
      {fw, out} = Firmware.tick(fw, 2_012)
      assert fw.tripped
      assert out =~ "icmd:headloff();\r\nicmd:stop();\r\n"
      refute out =~ "CommandBufferOverrun"
      refute out =~ "LIGT"
      {fw, out} = Firmware.tick(fw, 2_513)
      assert out =~ "icmd:ligt(50);\r\nLIGT:50;"
      assert fw.esc_us == {1500, 1500, 1500}
    end

    test "the trip repeats every 2001 ms without pings" do
      fw = boot(arm_ms: 0, wiring: @plain)
      {fw, _} = Firmware.tick(fw, 2_500)
      assert fw.tripped
      {fw, _} = send_cmd(fw, "go(2000,2000,2000,1);", 2_501, 2_600)
      assert fw.esc_us == {2000, 2000, 2000}
      {fw, _} = Firmware.tick(fw, 4_100)
      assert fw.esc_us == {1500, 1500, 1500}
    end
  end

  describe "telemetry bytes" do
    test "2.5: CRLF lines, glued fields, cmpd's newline before its ';', plain-text depth lines" do
      {_fw, out} = send_cmd(boot(), "claser(3);ping(1);", 1, 1_001)
      assert out =~ "cmd:claser(3);\r\nclaser:3;cmd:ping(1);\r\npong:1,10;"
      assert out =~ ~r/cmpd:[^;\r\n]+\r\n;time:\d+\.00;\r\n/
      assert out =~ "First-Order Temperature in Degrees C is 10.00\r\n"

      assert out =~
               ~r/BRDT:[\d.]+;SC1I:[\d.]+;SC2I:[\d.]+;SC3I:[\d.]+;BRDI:0\.25;BT1I:1\.50;BT2I:1\.50;BRDV:12\.10;AVCC:5000;\r\n/

      refute out =~ "\n\n"
      refute out =~ ~r/[^\r]\n/
    end

    test "30.x: dotted keys, no plain-text depth lines" do
      {_fw, out} =
        Firmware.new(0, firmware: :openrov_30) |> Firmware.sense(@reading) |> Firmware.tick(1_001)

      assert out =~ "Depth.C0:0;\r\n"
      assert out =~ "BNO055.status:5;\r\n"
      refute out =~ "Temperature in Degrees"
    end

    test "every number has 2 decimals; depth comes from pressure with 1015 mbar, fresh water" do
      {_fw, out} = Firmware.tick(boot(), 1_010)
      [_, pres] = Regex.run(~r/pres:([\d.]+);/, out)
      [_, deap] = Regex.run(~r/deap:(-?[\d.]+);/, List.last(navlines(out)))
      assert_in_delta (String.to_float(pres) - 1015) * 1.019716 / 100, String.to_float(deap), 0.01

      for [_, v] <-
            Regex.scan(~r/(?:hdgd|deap|pitc|roll|yaw|fthr|vout|iout|pres|temp):(-?[\d.]+);/, out),
          do: assert(v =~ ~r/\A-?\d+\.\d\d\z/)
    end

    test "the server's parser reads the navigation and shared lines back to the reading" do
      {_fw, out} = Firmware.tick(boot(), 1_111)
      nav = List.last(navlines(out))
      {fields, []} = OpenROV.Protocol.parse_line(nav)
      assert_in_delta fields.depth, 1.2, 0.01
      assert_in_delta fields.heading, 2.0, 0.001
      assert_in_delta fields.pitch, 0.01, 0.001
    end
  end

  describe "receive buffer" do
    test "a 100-byte burst loses what does not fit in 64 bytes" do
      burst = String.duplicate("ligt(5);", 12) <> "ping(1);go(1500,1500,1500);"
      assert byte_size(burst) > 100
      {fw, _} = Firmware.receive(boot(), burst, 1)
      assert fw.rx_dropped == byte_size(burst) - 64
      {_fw, out} = Firmware.tick(fw, 10)
      assert length(Regex.scan(~r/cmd:ligt/, out)) == 8
      refute out =~ "pong"
    end

    test "paced writes (60 bytes per 30 ms, commands 3 ms apart) lose nothing, stall included" do
      command = "go(1500,1500,1500,1);"
      # 3 commands of 21 bytes = 63 bytes... two per 30 ms window, 3 ms apart, over 5 s
      times = for window <- 0..166, k <- 0..1, do: window * 30 + k * 3 + 1

      {fw, out} =
        Enum.reduce(times, {boot(), ""}, fn t, {fw, out} ->
          {fw, more} = Firmware.receive(fw, command, t)
          {fw, out <> more}
        end)

      {fw, more} = Firmware.tick(fw, 5_100)
      assert fw.rx_dropped == 0
      assert length(Regex.scan(~r/cmd:go/, out <> more)) == length(times)
    end

    test "the buffer is emptied every loop_ms, and not during the depth sensor's stall" do
      fw = boot(loop_ms: 10, stall_ms: 20)
      {fw, _} = Firmware.tick(fw, 995)
      # the conversion at 1001 holds the loop until 1021: 3 × 21 bytes arrive, the 4th overflows
      {fw, _} = Firmware.receive(fw, "go(1500,1500,1500,1);", 1_002)
      {fw, _} = Firmware.receive(fw, "go(1500,1500,1500,1);", 1_008)
      {fw, _} = Firmware.receive(fw, "go(1500,1500,1500,1);", 1_014)
      {fw, _} = Firmware.receive(fw, "go(1500,1500,1500,1);", 1_019)
      assert fw.rx_dropped == 4 * 21 - 64
      {fw, out} = Firmware.tick(fw, 1_021)
      assert length(Regex.scan(~r/cmd:go/, out)) == 3
      assert fw.rx == ""
    end

    test "a command longer than the 80-byte command buffer is cut" do
      long = "ligt(" <> String.duplicate("1", 90) <> ");"
      {fw, _} = Firmware.receive(boot(loop_ms: 1), binary_part(long, 0, 60), 1)
      {fw, _} = Firmware.tick(fw, 2)
      {fw, out} = send_cmd(fw, binary_part(long, 60, byte_size(long) - 60) <> "ping(1);", 3, 5)
      refute out =~ "cmd:ligt"
      assert out =~ "pong:1,"
      assert fw.lights == 0
    end
  end

  test "the firmware drives a simulator: forward surge yaws with the defaults, not with mtrmod" do
    yaw_rate = fn commands ->
      fw = boot()
      {fw, _} = send_cmd(fw, commands, 1, 300)
      sim = Sim.new(initial: [z: 2.0]) |> Sim.command(fw.thrusters) |> Sim.step(300)
      sim.dyn.r
    end

    # thesis wiring, port reversed: straight surge is go(1300,1500,1700)
    skewed = yaw_rate.("go(1300,1500,1700,1);")
    straight = yaw_rate.("mtrmod1(100,100,100);mtrmod2(100,100,100);go(1300,1500,1700,1);")
    assert abs(skewed) > 0.05
    assert abs(straight) < 1.0e-6
  end

  describe "properties" do
    test "atoi reads back every 16-bit integer and never crashes on random bytes" do
      check(
        :proper_types.integer(-32_768, 32_767),
        &(Firmware.atoi(Integer.to_string(&1)) == &1),
        1_000
      )

      check(
        :proper_types.binary(),
        fn bytes ->
          n = Firmware.atoi(bytes)
          is_integer(n) and n >= -32_768 and n <= 32_767
        end,
        1_000
      )
    end

    test "tokens splits name(args) back into the name and the arguments" do
      word =
        bind(
          :proper_types.non_empty(:proper_types.list(:proper_types.integer(?a, ?z))),
          &List.to_string/1
        )

      arg = bind(:proper_types.integer(-40_000, 40_000), &Integer.to_string/1)
      sep = :proper_types.elements([",", ", ", " ,", " "])

      check(
        {word, :proper_types.list(arg), sep},
        fn {name, args, sep} ->
          Firmware.tokens(name <> "(" <> Enum.join(args, sep) <> ");") == {name, args}
        end,
        1_000
      )
    end

    test "random bytes: no crash, the buffers stay bounded, every byte is kept or counted dropped" do
      chunks = :proper_types.list({:proper_types.binary(), :proper_types.integer(0, 40)})

      for profile <- @profiles do
        check(
          chunks,
          fn chunks ->
            {fw, _t} =
              Enum.reduce(chunks, {boot(firmware: profile), 0}, fn {bytes, dt}, {fw, t} ->
                {fw, _} = Firmware.receive(fw, bytes, t + dt)
                true = byte_size(fw.rx) <= 64 and byte_size(fw.cmdbuf) <= 80
                {fw, t + dt}
              end)

            sent = chunks |> Enum.map(fn {b, _} -> byte_size(b) end) |> Enum.sum()
            fw.rx_dropped <= sent and fw.rx_dropped >= 0
          end,
          300
        )
      end
    end

    test "goms stays within 1000..2000, keeps the direction and is monotonic" do
      us = :proper_types.integer(1000, 2000)
      mod = :proper_types.integer(0, 3)

      check(
        {us, us, mod, mod},
        fn {a, b, pos, neg} ->
          {lo, hi} = {min(a, b), max(a, b)}
          out = Firmware.goms(a, pos, neg)

          out in 1000..2000 and Firmware.goms(lo, pos, neg) <= Firmware.goms(hi, pos, neg) and
            (out - 1500) * (a - 1500) >= 0
        end,
        2_000
      )
    end
  end
end
