defmodule Neptunus.Vehicle.Board.OpenROV.SITL.DeviceTest do
  # The simulated board alone, over its pseudo-terminal: the test writes command bytes and
  # reads the firmware's output as a board link would.
  use ExUnit.Case, async: true

  @moduletag :uart
  @moduletag :capture_log

  import Neptunus.Test.Pty, only: [open!: 1, write: 2, recv_until: 2, drain: 2, wait_until: 2]

  alias Neptunus.Vehicle.Board.OpenROV
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Device

  defp start_device(opts \\ []) do
    id = "sitl-dev-#{System.unique_integer([:positive])}"
    dir = Path.join(System.tmp_dir!(), "neptunus-sitl-dev-#{System.unique_integer([:positive])}")
    link = Path.join(dir, "board.tty")
    on_exit(fn -> File.rm_rf(dir) end)

    opts = [id: id, link: link, sim: [noise: false], initial: [z: 2.0]] ++ opts
    start_supervised!({Device, opts})
    {id, open!(link)}
  end

  defp truth(id), do: Device.state(id).sim.dyn
  defp millis_of_pong(bytes), do: Regex.run(~r/pong:\d+,(\d+);/, bytes, capture: :all_but_first)

  test "lines end in CRLF, the echo and the glued pong come back, depth is a placeholder at first" do
    {id, port} = start_device()
    write(port, "ping(5);")
    out = recv_until(port, &(&1 =~ ~r/pong:1,\d+;/))
    assert out =~ "cmd:ping(5);\r\npong:1,"
    out = recv_until(port, &(&1 =~ ~r/deap:[1-9]/))
    assert out =~ ~r/\r\n;time:\d+\.00;\r\n/
    refute out =~ ~r/[^\r]\n/
    assert Device.state(id).firmware.depth > 1.9
  end

  test "reset/1 reboots the board: millis from 0, state lost, placeholder depth; the vehicle is untouched" do
    {id, port} = start_device()
    write(port, "ligt(77);")
    write(port, "mtrmod1(100,100,100);")
    wait_until(fn -> Device.state(id).firmware.lights == 77 end, "lights")
    wait_until(fn -> Device.state(id).firmware.depth > 1.9 end, "the first depth reading")
    before = truth(id)
    reset_at = Neptunus.Clock.monotonic_ms()

    :ok = Device.reset(id)
    state = Device.state(id)
    assert state.resets == 1

    assert {state.firmware.lights, state.firmware.positive_mod, state.firmware.depth} ==
             {0, {1, 1, 1}, 0.0}

    # the simulated vehicle carried on where it was
    assert_in_delta state.sim.dyn.z, before.z, 0.05
    assert state.sim.steps > 0

    out = recv_until(port, &(&1 =~ "Depth Sensor setup.\r\n" and &1 =~ "hdgd:"))
    assert out =~ ";deap:0.00;"
    _ = drain(port, 20)
    write(port, "ping(1);")
    out = recv_until(port, &(&1 =~ ~r/pong:1,\d+;/))
    [millis] = millis_of_pong(out)
    # counted from the reset (the board had run over a second before it: its first depth)
    assert String.to_integer(millis) <= Neptunus.Clock.monotonic_ms() - reset_at
  end

  test "reset_on_open: every open of the line reboots the board into its bootloader, which loses what arrives" do
    {id, port} = start_device(reset_on_open: true, bootloader_ms: 1_000)
    # our open of the line rebooted it; what we write at once is lost (the open is told to
    # the board before the bytes that follow it)
    write(port, "ligt(77);")

    wait_until(fn -> Device.state(id).firmware.boot_lost >= 9 end, "lost in the bootloader")

    assert Device.state(id).resets == 1
    out = recv_until(port, &(&1 =~ "boot:1;\r\n"))
    assert out =~ "log:init on primary addresses;\r\nboot:1;\r\n"
    write(port, "ligt(78);")
    wait_until(fn -> Device.state(id).firmware.lights == 78 end, "after the boot")
    assert %{opens: 1, resets: 1} = Device.state(id)
    assert Device.state(id).firmware.commands == 1

    # another open (after a close: the line is opened exclusively): another reboot
    Port.close(port)
    second = open!(Device.state(id).pty)
    wait_until(fn -> Device.state(id).resets == 2 end, "the second open")
    assert Device.state(id).firmware.lights == 0
    Port.close(second)
  end

  test "without reset_on_open an open is counted, the board runs on" do
    {id, port} = start_device()
    write(port, "ligt(5);")
    wait_until(fn -> Device.state(id).firmware.lights == 5 end, "lights")
    assert %{opens: 1, resets: 0} = Device.state(id)
  end

  test "30.x: framed commands pass, plain ones fail their CRC" do
    {id, port} = start_device(firmware: :openrov_30)
    write(port, OpenROV.Protocol.frame("ping(3);", :openrov_30))
    out = recv_until(port, &(&1 =~ ~r/pong:1,\d+;/))
    assert out =~ ~r/rawcmd:[0-9A-F,]+;\r\ncrc:pass;cmd:ping\(3\);\r\npong:1,\d+;/
    write(port, "ping(4);")
    out = recv_until(port, &(&1 =~ "crc:fail,"))
    assert out =~ ~r/crc:fail,[0-9A-F]+\/70;/
    assert Device.state(id).firmware.bad_commands == 1
  end

  test "a 100-byte burst overflows the 64-byte receive buffer; paced writes lose nothing" do
    {id, port} = start_device()
    _ = recv_until(port, &(&1 =~ "hdgd:"))
    burst = String.duplicate("tilt(1500);", 9) <> "ping(1);"
    write(port, burst)
    # the whole burst has reached the board, however the pty cut it up
    # the whole burst has reached the board, however the pty cut it up, and the board has
    # read its receive buffer since (else the next command would be dropped too)
    wait_until(
      fn ->
        fw = Device.state(id).firmware
        fw.rx_bytes >= byte_size(burst) and fw.rx == ""
      end,
      "the burst at the board, read"
    )

    assert Device.state(id).rx_dropped > 0
    # the ';' first ends what is left of the burst's cut command, as it would on the board
    write(port, ";ligt(99);")

    wait_until(
      fn -> Device.state(id).firmware.lights == 99 end,
      "the command after the burst"
    )

    dropped = Device.state(id).rx_dropped
    assert dropped >= 107 - 64

    # as the board link paces them: one command at a time (each once the board has carried
    # out the one before: a stalled machine's pty would hand over several at once)
    for n <- 1..20 do
      write(port, "ligt(#{n});")
      wait_until(fn -> Device.state(id).firmware.lights == n end, "ligt(#{n})")
    end

    wait_until(fn -> Device.state(id).firmware.lights == 20 end, "the last command")
    assert Device.state(id).rx_dropped == dropped
  end

  describe "straight surge with the thesis wiring (port reversed)" do
    # the heading's change over 1.5 s of the simulation's time (it keeps pace with the clock,
    # and skips what a stalled machine could not step: its own time is what counts)
    defp heading_change(commands) do
      {id, port} = start_device()
      _ = recv_until(port, &(&1 =~ "hdgd:"))
      # one at a time, each once the board has taken the one before (together they would
      # overflow its receive buffer)
      for c <- commands do
        taken = Device.state(id).firmware.commands
        write(port, c)
        wait_until(fn -> Device.state(id).firmware.commands > taken end, c)
      end

      # measured from the moment the board has taken the last command
      wait_until(fn -> Device.state(id).firmware.target_us == {1300, 1500, 1700} end, "go()")
      %{sim: sim} = Device.state(id)
      {psi0, t0} = {sim.dyn.psi, Neptunus.Sim.time(sim)}

      wait_until(
        fn -> Neptunus.Sim.time(Device.state(id).sim) >= t0 + 1.5 end,
        "1.5 s of simulated time"
      )

      abs(truth(id).psi - psi0)
    end

    test "with the default modifiers (reverse ×2) the vehicle yaws" do
      assert heading_change(["go(1300,1500,1700,1);"]) > 0.1
    end

    test "after mtrmod1/mtrmod2 100 it drives straight" do
      turn =
        heading_change(["mtrmod1(100,100,100);", "mtrmod2(100,100,100);", "go(1300,1500,1700,1);"])

      assert turn < 0.01
    end
  end
end
