defmodule Neptunus.Vehicle.Board.OpenROV.UARTProgramTest do
  # The C port program (c_src/neptunus_uart.c) over socat pseudo-terminal pairs.
  use ExUnit.Case, async: true

  @moduletag :uart

  import Neptunus.Test.Pty

  alias Neptunus.Test.Patience
  alias Neptunus.Vehicle.Board.OpenROV.UART

  defp spawn_program(args, env \\ []) do
    Port.open({:spawn_executable, UART.program()}, [
      :binary,
      {:packet, 2},
      :exit_status,
      {:env, env},
      args: args
    ])
  end

  defp pty_link do
    dir = Path.join(System.tmp_dir!(), "neptunus-test-#{System.unique_integer([:positive])}")
    File.mkdir_p!(dir)
    on_exit(fn -> File.rm_rf(dir) end)
    Path.join(dir, "tty")
  end

  defp os_pid(port), do: port |> Port.info(:os_pid) |> elem(1)

  defp os_monotonic_ns do
    :erlang.system_info(:os_monotonic_time_source)
    |> Keyword.fetch!(:time)
    |> System.convert_time_unit(:native, :nanosecond)
  end

  defp exit_status(port) do
    receive do
      {^port, {:exit_status, status}} -> status
    after
      Patience.ms() -> flunk("the program did not exit")
    end
  end

  defp error_text(port) do
    receive do
      {^port, {:data, "e" <> text}} -> text
    after
      Patience.ms() -> flunk("no error message")
    end
  end

  test "bytes go both ways, unchanged, all 256 values (raw mode)" do
    pair = socat_pair!()
    a = open!(pair.a)
    b = open!(pair.b)
    all = for(byte <- 0..255, into: "", do: <<byte>>)

    write(a, "go(1500,1500,1500,1);")
    assert recv_until(b, &(&1 == "go(1500,1500,1500,1);")) == "go(1500,1500,1500,1);"

    write(b, all)
    assert recv_until(a, &(byte_size(&1) >= 256)) == all
  end

  test "writes bigger than the pty buffer are queued and all arrive, in order" do
    pair = socat_pair!()
    a = open!(pair.a)
    b = open!(pair.b)
    chunks = for i <- 1..20, do: :binary.copy(<<rem(i, 256)>>, 2_000)
    Enum.each(chunks, &write(a, &1))
    assert recv_until(b, &(byte_size(&1) >= 40_000), 10_000) == IO.iodata_to_binary(chunks)
  end

  test "counters on request" do
    pair = socat_pair!()
    a = open!(pair.a)
    b = open!(pair.b)
    write(a, "hello")
    recv_until(b, &(&1 == "hello"))
    Port.command(a, "s")
    assert_receive {^a, {:data, "s" <> stats}}
    assert stats =~ ~r/^rx=0 tx=5 dropped=0 queued=0$/
  end

  test "hangup (socat dies): the program says why and exits 67" do
    pair = socat_pair!()
    a = open!(pair.a)
    hang_up!(pair)
    assert error_text(a) =~ "hangup"
    assert exit_status(a) == 67
  end

  test "a device that does not exist: exit 66 with the reason" do
    port = spawn_program(["tty", "/nonexistent/ttyX", "115200"])
    assert error_text(port) == "open /nonexistent/ttyX: No such file or directory"
    assert exit_status(port) == 66
  end

  test "not a terminal: exit 66" do
    port = spawn_program(["tty", "/dev/null", "115200"])
    assert error_text(port) == "/dev/null is not a terminal device"
    assert exit_status(port) == 66
  end

  test "unsupported baud rate: exit 65; usage: exit 64" do
    port = spawn_program(["tty", "/dev/null", "115201"])
    assert error_text(port) =~ "unsupported baud rate 115201"
    assert exit_status(port) == 65

    port = spawn_program(["bogus"])
    assert error_text(port) =~ "usage"
    assert exit_status(port) == 64
  end

  test "an unknown tag from the VM: exit 69" do
    pair = socat_pair!()
    a = open!(pair.a)
    Port.command(a, "?")
    assert error_text(a) =~ "unknown tag 0x3f"
    assert exit_status(a) == 69
  end

  test "the program knows only the tags the VM sends: 'x' (discard) is gone" do
    pair = socat_pair!()
    a = open!(pair.a)
    Port.command(a, "x")
    assert error_text(a) =~ "unknown tag 0x78"
    assert exit_status(a) == 69
  end

  test "the program exits when the VM closes the port (stdin EOF)" do
    pair = socat_pair!()
    a = open!(pair.a)
    {:os_pid, os_pid} = Port.info(a, :os_pid)
    Port.close(a)
    wait_until(fn -> not File.exists?("/proc/#{os_pid}") end, "program exit")
  end

  test "pty mode: a pair whose slave is linked at the path, removed on exit" do
    link = pty_link()

    master = spawn_program(["pty", link])
    assert_receive {^master, {:data, "o/dev/pts/" <> _}}
    assert {:ok, "/dev/pts/" <> _} = File.read_link(link)

    slave = open!(link)
    Port.command(master, ["w", "from master\n"])
    assert recv_until(slave, &(&1 == "from master\n")) == "from master\n"
    write(slave, "ping(1);")
    # every open of the slave end is told ('O': the SITL board resets on it), before the bytes
    assert next_frame(master) == "O"
    assert next_frame(master) == "rping(1);"

    # the board side closes and reopens its end: no hangup on the master side
    Port.close(slave)
    slave = open!(link)
    write(slave, "again")
    assert next_frame(master) == "O"
    assert next_frame(master) == "ragain"

    # the master side goes: the slave hangs up, the link is removed
    Port.close(master)
    assert error_text(slave) =~ "hangup"
    assert exit_status(slave) == 67
    wait_until(fn -> not File.exists?(link) end, "link removed")
  end

  test "NEPTUNUS_SLICE_NS: the program asks for that time slice; a bad value is ignored" do
    {:ok, vm} = Neptunus.OS.thread_slices(0)
    kernel_reports_slices? = Enum.any?(vm, fn {_tid, ns} -> ns > 0 end)

    sliced = spawn_program(["pty", pty_link()], [{~c"NEPTUNUS_SLICE_NS", ~c"250000"}])
    assert_receive {^sliced, {:data, "o" <> _}}
    plain = spawn_program(["pty", pty_link()], [{~c"NEPTUNUS_SLICE_NS", ~c"fast"}])
    assert_receive {^plain, {:data, "o" <> _}}

    {:ok, [{_, sliced_ns}]} = Neptunus.OS.thread_slices(os_pid(sliced))
    {:ok, [{_, plain_ns}]} = Neptunus.OS.thread_slices(os_pid(plain))

    if kernel_reports_slices? do
      assert sliced_ns == 250_000
      assert plain_ns not in [0, 250_000]
    else
      assert sliced_ns == 0 and plain_ns == 0
    end
  end

  test "NEPTUNUS_UART_RX_STAMPS=1: each read comes after a frame with its CLOCK_MONOTONIC time" do
    link = pty_link()
    master = spawn_program(["pty", link], [{~c"NEPTUNUS_UART_RX_STAMPS", ~c"1"}])
    assert_receive {^master, {:data, "o" <> _}}
    slave = open!(link)
    assert_receive {^master, {:data, "O"}}

    before = os_monotonic_ns()
    write(slave, "hdgd:90;")
    assert_receive {^master, {:data, "t" <> stamp}}
    assert_receive {^master, {:data, "rhdgd:90;"}}
    stamp = String.to_integer(stamp)
    assert before <= stamp and stamp <= os_monotonic_ns()

    # without the variable (the VM's board link): 'r' frames only
    plain_link = pty_link()
    plain = spawn_program(["pty", plain_link])
    assert_receive {^plain, {:data, "o" <> _}}
    write(open!(plain_link), "x")
    assert next_frame(plain) == "O"
    assert next_frame(plain) == "rx"
  end

  defp next_frame(port) do
    receive do
      {^port, {:data, frame}} -> frame
    after
      Patience.ms() -> flunk("no frame from the program")
    end
  end
end
