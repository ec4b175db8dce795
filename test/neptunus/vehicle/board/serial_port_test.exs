defmodule Neptunus.Vehicle.Board.SerialPortTest do
  use ExUnit.Case, async: true

  alias Neptunus.Test.{Patience, Properties}
  alias Neptunus.Vehicle.Board.SerialPort

  doctest SerialPort

  describe "decode/1" do
    test "every frame the program sends, as a plain term" do
      for {frame, event} <- [
            {"o/dev/ttyUSB0", {:open, "/dev/ttyUSB0"}},
            {"o", {:open, ""}},
            {"O", :peer_opened},
            {"r", {:read, ""}},
            {<<?r, 0, 255, ?;>>, {:read, <<0, 255, ?;>>}},
            {"t123456789012", {:read_at_ns, 123_456_789_012}},
            {"d0", {:dropped, 0}},
            {"d4096", {:dropped, 4096}},
            {"srx=1 tx=22 dropped=0 queued=3",
             {:counters, %{"rx" => 1, "tx" => 22, "dropped" => 0, "queued" => 3}}},
            {"ecannot open /dev/x: No such file or directory",
             {:error, "cannot open /dev/x: No such file or directory"}},
            {"e", {:error, ""}}
          ] do
        assert SerialPort.decode({:data, frame}) == event, inspect(frame)
      end
    end

    test "the exit status" do
      assert SerialPort.decode({:exit_status, 0}) == {:exit, 0}
      assert SerialPort.decode({:exit_status, 66}) == {:exit, 66}
    end

    test "what is not the protocol is unknown, never a wrong event" do
      for frame <- ["", "x", "OO", "t", "t12a", "d", "d-3", "d1.5", "s", "srx=a", "sjunk"] do
        assert SerialPort.decode({:data, frame}) == {:unknown, frame}, inspect(frame)
      end
    end

    test "any frame decodes to an event of the documented shapes" do
      Properties.check(:proper_types.binary(), fn frame ->
        case SerialPort.decode({:data, frame}) do
          {:open, path} -> frame == "o" <> path
          :peer_opened -> frame == "O"
          {:read, bytes} -> frame == "r" <> bytes
          {:read_at_ns, ns} -> frame == "t#{ns}"
          {:dropped, n} -> frame == "d#{n}" and n >= 0
          {:counters, map} -> binary_part(frame, 0, 1) == "s" and map_size(map) > 0
          {:error, text} -> frame == "e" <> text
          {:unknown, ^frame} -> true
        end
      end)
    end
  end

  describe "the program" do
    @describetag :tmp_dir

    defp next_event(port) do
      receive do
        {^port, message} -> SerialPort.decode(message)
      after
        Patience.ms() -> flunk("nothing from the port program")
      end
    end

    defp read_until(port, wanted, acc \\ "") do
      case next_event(port) do
        {:read, bytes} when acc <> bytes == wanted -> wanted
        {:read, bytes} -> read_until(port, wanted, acc <> bytes)
        _other -> read_until(port, wanted, acc)
      end
    end

    test "a pty and a tty on its slave end: bytes both ways; closed, no more writes",
         %{tmp_dir: dir} do
      link = Path.join(dir, "tty")
      {:ok, master} = SerialPort.open_pty(link)
      assert {:ok, pty} = SerialPort.await_open(master, Patience.ms())
      assert File.read_link!(link) == pty

      {:ok, slave} = SerialPort.open_tty(link, 115_200)
      assert {:ok, ^link} = SerialPort.await_open(slave, Patience.ms())
      assert :ok = SerialPort.write(master, "ping(1);")
      assert read_until(slave, "ping(1);") == "ping(1);"
      assert :ok = SerialPort.write(slave, <<0, 255>>)
      assert read_until(master, <<0, 255>>) == <<0, 255>>

      assert :ok = SerialPort.close(slave)
      assert SerialPort.write(slave, "x") == {:error, :closed}
      assert :ok = SerialPort.close(slave)
    end

    test "a program whose line hangs up tells its exit", %{tmp_dir: dir} do
      link = Path.join(dir, "tty")
      {:ok, master} = SerialPort.open_pty(link)
      {:ok, _pty} = SerialPort.await_open(master, Patience.ms())
      {:ok, slave} = SerialPort.open_tty(link, 115_200)
      {:ok, _} = SerialPort.await_open(slave, Patience.ms())
      :ok = SerialPort.close(master)
      assert exit_of(slave) == 67
    end

    defp exit_of(port) do
      case next_event(port) do
        {:exit, status} -> status
        _other -> exit_of(port)
      end
    end

    test "a device that cannot be opened: its reason, then its exit" do
      {:ok, port} = SerialPort.open_tty("/nonexistent/tty", 115_200)
      assert {:error, "open /nonexistent/tty: " <> _} = SerialPort.await_open(port, Patience.ms())
      assert next_event(port) == {:exit, 66}
    end

    test "a program that cannot be started is an error, not a crash" do
      assert {:error, why} = SerialPort.open_tty("/dev/null", 115_200, program: "/nonexistent/x")
      assert is_binary(why)
    end
  end
end
