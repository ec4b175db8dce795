defmodule Neptunus.Vehicle.Board.SITL.FirmwareTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.SITL.Firmware

  alias Neptunus.{Sim, Wiring}
  alias Neptunus.Protocol.OpenROV
  alias Neptunus.Vehicle.Board.SITL.Firmware

  test "commands split across chunks are applied when their ';' arrives" do
    fw = Firmware.new(0)
    {fw, ""} = Firmware.receive(fw, "go(2000,15", 1)
    assert fw.thrusters == %{port: 0.0, vertical: 0.0, starboard: 0.0}
    {fw, ""} = Firmware.receive(fw, "00,2000,1);ligt(9);claser(8);tilt(1100);", 2)
    # default wiring: port reversed
    assert fw.thrusters == %{port: -1.0, vertical: 0.0, starboard: 1.0}
    assert {fw.lights, fw.laser, fw.tilt, fw.commands} == {9, 8, 1100, 4}
  end

  test "corrupt commands are ignored and counted; stop goes neutral" do
    {fw, _} = Firmware.receive(Firmware.new(0), "go(1600,1600,1600,1);", 0)
    {fw, ""} = Firmware.receive(fw, "go(900,1500,1500,1);warp();go(1500;", 1)
    assert fw.bad_commands == 3
    assert fw.thrusters.vertical == 0.2
    {fw, ""} = Firmware.receive(fw, "stop();", 2)
    assert fw.thrusters == %{port: 0.0, vertical: 0.0, starboard: 0.0}
  end

  test "endless bytes without ';' do not grow the buffer" do
    {fw, ""} = Firmware.receive(Firmware.new(0), :binary.copy("x", 10_000), 0)
    assert fw.pending == ""
  end

  test "deadman: trips without pings, ignores go until the next ping, then recovers" do
    fw = Firmware.new(0, deadman_ms: 1000)
    {fw, "pong:1;\n"} = Firmware.receive(fw, "ping(1);", 500)
    {fw, ""} = Firmware.tick(fw, 1500)
    {fw, "deadman:1;\n"} = Firmware.tick(fw, 1501)
    {fw, ""} = Firmware.tick(fw, 1600)
    {fw, ""} = Firmware.receive(fw, "go(2000,2000,2000,1);", 1601)
    assert fw.tripped and fw.thrusters == %{port: 0.0, vertical: 0.0, starboard: 0.0}
    {fw, "deadman:0;\npong:2;\n"} = Firmware.receive(fw, "ping(2);", 1700)
    {fw, ""} = Firmware.receive(fw, "go(2000,2000,2000,1);", 1701)
    assert fw.thrusters.vertical == 1.0 and not fw.tripped
  end

  test "the firmware honours the vehicle's wiring" do
    w = %Wiring{order: [:starboard, :vertical, :port], reversed: [], direct: true}

    {fw, _} =
      Firmware.receive(
        Firmware.new(0, wiring: w),
        Wiring.go_command(w, %{port: 0.5, vertical: 0.0, starboard: -0.5}),
        0
      )

    assert fw.thrusters == %{port: 0.5, vertical: 0.0, starboard: -0.5}
  end

  test "telemetry lines parse back to the simulator's measurements" do
    sim =
      Sim.new(initial: [z: 2.0])
      |> Sim.command(%{port: 0.5, vertical: 0.2, starboard: 0.5})
      |> Sim.step(50)

    sample = Sim.sample(sim)
    fw = Firmware.new(0)
    nav = Firmware.navdata(sample, fw)
    status = Firmware.shared_data(sample, fw)
    assert String.ends_with?(nav, ";\n") and String.ends_with?(status, ";\n")

    {fields, []} =
      OpenROV.parse_line(String.trim_trailing((nav <> status) |> String.replace("\n", ""), "\n"))

    for key <- [:depth, :heading, :roll, :pitch, :voltage, :current] do
      assert_in_delta fields[key], sample.measurement[key], 1.0e-3, "#{key}"
    end

    assert_in_delta fields.board_time, sample.t, 1.0e-3
    assert_in_delta fields.pressure, (1013.25 + 100.55 * sample.measurement.depth) * 100, 1.0
  end

  describe "go()'s flag: 1 at once, 0 ramped like the OpenROV firmware" do
    # a wiring without reversal, so pulse widths read directly
    defp fw,
      do:
        Firmware.new(0,
          wiring: %Wiring{order: [:port, :vertical, :starboard], reversed: [], direct: true}
        )

    defp ramp_trace(fw, times) do
      Enum.map_reduce(times, fw, fn t, fw ->
        {fw, ""} = Firmware.tick(fw, t)
        {fw.out_us, fw}
      end)
    end

    test "flag 1: the motors take the values at once" do
      {fw, _} = Firmware.receive(fw(), "ping(1);go(2000,1000,1600,1);", 0)
      assert fw.out_us == {2000, 1000, 1600}
      assert fw.thrusters == %{port: 1.0, vertical: -1.0, starboard: 0.2}
    end

    test "flag 0: 40 µs further from neutral every 50 ms, until the target" do
      {fw, _} = Firmware.receive(fw(), "ping(1);go(2000,1000,1520,0);", 0)
      assert fw.out_us == {1500, 1500, 1500}
      {trace, fw} = ramp_trace(fw, [0, 10, 50, 100, 150])

      assert trace == [
               {1540, 1460, 1520},
               {1540, 1460, 1520},
               {1580, 1420, 1520},
               {1620, 1380, 1520},
               {1660, 1340, 1520}
             ]

      # 13 steps from 1500 to 2000: there at 600 ms, and no further steps
      {fw, ""} = Firmware.tick(fw, 600)
      assert fw.out_us == {2000, 1000, 1520}
      assert fw.ramp_at == nil
      assert fw.thrusters == %{port: 1.0, vertical: -1.0, starboard: 0.04}
    end

    test "flag 0: less power at once; a reversal goes through neutral first" do
      {fw, _} = Firmware.receive(fw(), "ping(1);go(2000,2000,2000,1);", 0)
      {fw, _} = Firmware.receive(fw, "go(1700,1000,2000,0);", 100)
      {[first, second], _} = ramp_trace(fw, [100, 150])
      assert first == {1700, 1500, 2000}
      assert second == {1700, 1460, 2000}
    end

    test "stop and the deadman are immediate whatever the flag" do
      {fw, _} = Firmware.receive(fw(), "ping(1);go(2000,2000,2000,0);", 0)
      {fw, _} = Firmware.tick(fw, 0)
      {stopped, _} = Firmware.receive(fw, "stop();", 10)
      assert stopped.out_us == {1500, 1500, 1500} and stopped.ramp_at == nil
      {tripped, "deadman:1;\n"} = Firmware.tick(fw, 3_001)
      assert tripped.out_us == {1500, 1500, 1500} and tripped.ramp_at == nil
    end
  end
end
