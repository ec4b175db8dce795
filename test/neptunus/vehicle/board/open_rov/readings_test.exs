defmodule Neptunus.Vehicle.Board.OpenROV.ReadingsTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.Backoff

  alias Neptunus.Vehicle.Board.OpenROV.Readings

  @nav "hdgd:90;deap:1.5;pitc:0;roll:0;yaw:90;fthr:0;\r\n"
  @status "vout:12.1;iout:0.5;time:1000;pres:1100;temp:10;\r\n"

  test "no sample until all six measurements are known; then one per navigation line" do
    r = Readings.new()
    {r, []} = Readings.feed(r, @nav, 0.1)
    {r, [s1]} = Readings.feed(r, @status, 0.2)
    {r, [s2, s3]} = Readings.feed(r, @nav <> @nav, 0.3)

    assert %{t: 0.2, sim: nil, measurement: m, board: board} = s1
    assert m.depth == 1.5 and m.voltage == 12.1 and m.current == 0.5
    assert_in_delta m.heading, :math.pi() / 2, 1.0e-12
    assert Map.keys(m) |> Enum.sort() == ~w(current depth heading pitch roll voltage)a
    assert board.temperature == 10.0 and board.board_time == 1.0 and board.pressure == 110_000.0
    assert s2.t == 0.3 and s3.t == 0.3
    assert r.counters.lines == 4 and r.counters.samples == 3
  end

  test "a line with only other fields does not make a sample" do
    {r, [_]} = Readings.feed(Readings.new(), @nav <> @status, 0.0)
    assert {_, []} = Readings.feed(r, "temp:11;fmem:1000;\n", 0.1)
  end

  test "wild points and garbage are counted and never reach a sample" do
    {r, [good]} = Readings.feed(Readings.new(), @nav <> @status, 0.0)

    {r, samples} =
      Readings.feed(r, "deap:150.0;vout:121;hdgd:pitc;iout:nan;junk;\n" <> <<0, 255, 10>>, 0.1)

    # deap 150 m is in range (the sensor could), so one sample, with the wild values left out
    assert [%{measurement: m}] = samples
    assert m.depth == 150.0
    assert m.voltage == good.measurement.voltage
    assert m.heading == good.measurement.heading
    assert m.current == good.measurement.current

    assert %{out_of_range: 1, key_as_value: 1, not_a_number: 1, malformed: 2} = r.counters
    assert Readings.wild_points(r) == 3
  end

  test "overlong lines are counted; unknown keys are parsed and left out" do
    {r, []} =
      Readings.feed(Readings.new(16), String.duplicate("x", 40) <> "\nfmem:12;pong:3\n", 0.0)

    assert r.counters.overlong == 1
    assert r.counters.malformed == 0
    assert r.measurement == %{} and r.board == %{}

    noise = Enum.map_join(1..100, fn i -> "k#{i}:v;\n" end)
    {r, []} = Readings.feed(Readings.new(), noise, 0.0)
    assert r.counters.lines == 100 and r.counters.malformed == 0
    assert r.measurement == %{} and r.board == %{}
  end

  test "reset starts a new session: partial line and values forgotten, counters kept" do
    {r, [_]} = Readings.feed(Readings.new(), @nav <> @status <> "deap:", 0.0)
    r = Readings.reset(r)
    assert r.measurement == %{} and r.lines.rest == ""
    assert {_, []} = Readings.feed(r, "2.0;\n" <> @nav, 0.1)
    assert r.counters.samples == 1
  end
end

defmodule Neptunus.Vehicle.Board.OpenROV.ReadingsFirmwareTest do
  # Telemetry exactly as the OpenROV firmware writes it (CRLF, glued fields, echoes, plain text).
  use ExUnit.Case, async: true

  alias Neptunus.Vehicle.Board.OpenROV.Readings

  @nav "hdgd:90.00;deap:1.50;pitc:0.00;roll:0.00;yaw:90.00;fthr:0.00;\r\n"
  @status "vout:12.10;iout:0.50;time:181000;pres:1165.00;temp:10.00;\r\n"

  defp feed(bytes, r \\ Readings.new()) do
    {r, samples} = Readings.feed(r, bytes, 0.0)
    {events, r} = Readings.take_events(r)
    {r, samples, events}
  end

  test "a glued pong, the 30.x echo (rawcmd, crc:pass glued to cmd), icmd lines: no malformed field" do
    bytes =
      "rawcmd:A3,70,69,6E,67,28,37,29,3B,;\r\n" <>
        "crc:pass;cmd:ping(7);\r\n" <>
        "pong:1,183422;" <> @nav <> "icmd:stop();\r\n" <> "crc:fail,A1/3B;" <> @status

    {r, [_], events} = feed(bytes)

    assert events == [
             :rawcmd,
             {:crc, :pass},
             {:echo, "ping", ["7"], true},
             {:pong, %{args: 1, millis: 183_422}},
             {:icmd, "stop"},
             {:crc, {:fail, 0xA1, 0x3B}},
             {:board_time, 181_000}
           ]

    assert r.counters.malformed == 0 and Readings.wild_points(r) == 0
  end

  test "cmpd's newline before its ';' makes the next line start ';time:'; claser glued; dotted keys parsed" do
    bytes =
      "cmpd:12.00,3.00,4.00\r\n;time:181000;claser:255;BNO055.status:1;Depth.C0:4000;\r\n" <>
        @nav <> @status

    {r, [_], events} = feed(bytes)
    assert {:board_time, 181_000} in events
    # the unknown keys, dotted or glued, are parsed and left out
    assert r.counters.malformed == 0
    refute Enum.any?(Map.keys(r.board), &is_binary/1)
  end

  test "the firmware's start-up line and an echo with its arguments are events; a cut echo counts, confirms nothing" do
    bytes =
      "log:init on primary addresses;\r\nboot:1;\r\n" <>
        "cmd:mtrmod1(100,100,100);\r\ncmd:stop();\r\ncmd:ligt(1\r\n"

    {r, [], events} = feed(bytes)

    assert events == [
             :boot,
             {:echo, "mtrmod1", ["100", "100", "100"], false},
             {:echo, "stop", [], false},
             {:echo, "ligt", nil, false}
           ]

    assert r.counters.malformed == 0
  end

  test "a 2.5 board's echo of a CRC-prefixed command: the CRC byte before the name" do
    {_r, [], events} = feed(<<"cmd:", 0xAB, "ping(7);\r\n">>)
    assert events == [{:echo_prefixed, "ping"}]
  end

  test "the 2.5.2 depth driver's plain-text lines are text, log lines debug, never malformed" do
    bytes =
      "Depth Sensor setup.\r\nDepth Sensor: initialized I2C\r\nDepth Sensor is reset\r\n" <>
        "Depth: Calibration constants are:\r\n" <>
        "First-Order Temperature in Degrees C is 11.52\r\n" <>
        "Second-Order Temperature in Degrees C is 11.50\r\n" <>
        "log:Failed to read Depth from I2C\r\nlog:MPU9150 ready;\r\n"

    {r, [], []} = feed(bytes)
    assert r.counters.text == 6 and r.counters.debug == 2 and r.counters.malformed == 0
    # a line that only looks like text is still malformed
    {r, [], []} = feed("Depth Sensor exploded\r\n")
    assert r.counters.malformed == 1
  end

  test "while the board reports pres:0.00 its deap is a boot placeholder, not a depth" do
    boot = "vout:12.10;iout:0.50;time:300;pres:0.00;temp:0.00;\r\n"

    {r, [s], _} =
      feed(boot <> "hdgd:90.00;deap:0.00;pitc:0.00;roll:0.00;yaw:90.00;fthr:0.00;\r\n")

    assert r.counters.placeholder == 1
    # the other measurements flow; depth is missing, not 0.00
    assert s.measurement.depth == nil and s.measurement.heading > 0
    {_r, samples, _} = feed(@status <> @nav, r)
    assert List.last(samples).measurement.depth == 1.5
  end

  @boot_nav "hdgd:90.00;deap:0.00;pitc:0.00;roll:0.00;yaw:90.00;fthr:0.00;\r\n"

  test "a new session: deap:0.00 is a placeholder until the board measures, even before any pres" do
    # the first second after a USB Arduino's reset: navigation lines with deap:0.00, no pres yet
    {r, [s | _], _} = feed("vout:12.10;iout:0.50;\r\n" <> @boot_nav <> @boot_nav)
    assert s.measurement.depth == nil and r.counters.placeholder == 2
    # its first reading: live from then on, a later 0.00 (at the surface) included
    {r, [s], _} = feed(String.replace(@boot_nav, "deap:0.00", "deap:1.20"), r)
    assert s.measurement.depth == 1.2
    {_r, [s], _} = feed(@boot_nav, r)
    assert s.measurement.depth == 0.0
  end

  test "a board reset the link detected: the earlier depth is never carried, 0.00 is a placeholder" do
    {r, [s], _} = feed(@status <> @nav)
    assert s.measurement.depth == 1.5
    r = Readings.board_reset(r)
    # the rebooted board still prints its old pres (once a second) but deap:0.00 every 100 ms
    {r, [s], _} = feed(@boot_nav, r)
    assert s.measurement.depth == nil

    {r, samples, _} =
      feed("vout:12.10;iout:0.50;time:1001;pres:0.00;temp:0.00;\r\n" <> @boot_nav, r)

    assert Enum.all?(samples, &(&1.measurement.depth == nil))
    {_r, [s], _} = feed(String.replace(@boot_nav, "deap:0.00", "deap:3.01"), r)
    assert s.measurement.depth == 3.01
  end

  test "the 2.5 controller board: current is BT1I + BT2I, its own iout kept as board_current" do
    bytes = "BT1I:1.20;BT2I:0.80;SC1I:0.40;SC2I:0.30;SC3I:0.20;\r\n" <> @status <> @nav
    {_r, [s | _], _} = feed(bytes)
    assert_in_delta s.measurement.current, 2.0, 1.0e-9
    assert s.board.board_current == 0.5 and s.board.esc1_current == 0.4
  end

  test "battery currents summing beyond the current's range are a wild point, not a measurement" do
    {r, [s], _} = feed("BT1I:1.00;BT2I:1.00;\r\n" <> @status <> @nav)
    {r, _, _} = feed("BT1I:9.50;BT2I:9.00;\r\n", r)
    assert r.counters.out_of_range == 1
    {_r, [s2], _} = feed(@nav, r)
    assert s2.measurement.current == s.measurement.current
  end

  test "the cape: iout is the vehicle's current" do
    {_r, [s], _} = feed(@status <> @nav)
    assert s.measurement.current == 0.5
  end
end
