defmodule Neptunus.Vehicle.BoardSpecTest do
  # How NEPTUNUS_VEHICLES names a board: the type alone or `type:SPEC`, the spec parsed by
  # the board itself (Board.parse/1 → the board's parse_spec/1).
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Vehicle.Board
  alias Neptunus.Vehicle.Board.SerialPort

  doctest Neptunus.Vehicle.Board.OpenROV.UART, only: [parse_spec: 1]
  doctest Neptunus.Vehicle.Board.MAVLink, only: [parse_spec: 1]

  # pieces of boards' specs, good and bad, so generated text reaches every branch
  @tokens ~w(uart: mavlink: sitl simulated udp: udpout: tcp: serial: /dev/ttyO1 ttyO1 @ : [ ] ::1
             0.0.0.0 localhost 14550 57600 115200 1234 0 65536 x) ++ [" ", ""]

  defp spec_text do
    :proper_types.oneof([
      :proper_unicode.utf8(),
      bind(:proper_types.list(:proper_types.elements(@tokens)), &Enum.join/1)
    ])
  end

  test "a board named by its type alone has no spec; one with a spec parses it itself" do
    for type <- Board.types() do
      module = Board.module(type)
      assert Code.ensure_loaded?(module)
      named? = match?({:ok, ^type}, Board.named(Atom.to_string(type)))

      assert named? != function_exported?(module, :parse_spec, 1),
             "#{inspect(module)}: parse_spec/1 exactly when NEPTUNUS_VEHICLES names it type:SPEC"
    end
  end

  test "the per-vehicle settings each board takes, as it declares them" do
    assert Board.taking(:wiring) == [:sitl, :uart]
    assert Board.taking(:firmware) == [:sitl, :uart]
    assert Board.taking(:bootloader) == [:sitl]
    assert Board.taking(:mavlink_ids) == [:mavlink]
    assert Board.taking(:disarm_delay) == [:mavlink]
    assert Board.taking(:sim_sources) == [:simulated, :sitl]
    # a board implemented outside the registry (tests) takes none
    refute Board.takes?(Neptunus.Vehicle.Board.Test, :wiring)
  end

  test "every board's spec as the boards parse it" do
    assert {:ok, %{board: :simulated}} == Board.parse("simulated")

    assert {:ok, %{board: :uart, device: "/dev/ttyUSB0", baud: 115_200}} ==
             Board.parse("uart:/dev/ttyUSB0")

    assert {:ok, %{board: :mavlink, link: {:serial, "/dev/ttyACM0", 57_600}}} ==
             Board.parse("mavlink:serial:/dev/ttyACM0@57600")

    assert {:ok, %{board: :mavlink, link: {:tcp, "localhost", 5760}}} ==
             Board.parse("mavlink:tcp:localhost:5760")

    assert {:error, "a known board", _} = Board.parse("uart")
    assert {:error, "a known board", _} = Board.parse("sitl:/dev/tty")
    assert {:error, "a known board", _} = Board.parse("UART:/dev/ttyO1")

    assert {:error, "mavlink:udp:ADDRESS:PORT" <> _, "expected HOST:PORT" <> _} =
             Board.parse("mavlink:udp:0.0.0.0")
  end

  test "any text is a board with its options or what was expected and why, never a crash" do
    check(spec_text(), fn text ->
      case Board.parse(text) do
        {:ok, %{board: type}} -> type in Board.types()
        {:error, expected, why} -> is_binary(expected) and is_binary(why) and why != ""
      end
    end)
  end

  test "a serial line: an absolute device at a rate the program sets, or why not" do
    check(spec_text(), fn text ->
      case SerialPort.parse_line(text) do
        {:ok, "/" <> _ = device, baud} -> String.starts_with?(text, device) and baud > 0
        {:error, why} -> is_binary(why)
      end
    end)
  end

  test "a serial line round trip" do
    rates = [1200, 9600, 57_600, 115_200, 921_600]

    lines =
      :proper_types.tuple([
        bind(:proper_types.list(:proper_types.elements(~w(dev tty ttyO1 serial by-id a_b))), fn
          parts -> "/" <> Enum.join(parts, "/")
        end),
        :proper_types.elements(rates)
      ])

    check(lines, fn {device, baud} ->
      SerialPort.parse_line("#{device}@#{baud}") == {:ok, device, baud}
    end)
  end

  test "HOST:PORT: a host and a port in 1..65535, or why not" do
    check(spec_text(), fn text ->
      case Neptunus.Config.host_port(text) do
        {:ok, host, port} -> host != "" and port in 1..65_535
        {:error, why} -> is_binary(why)
      end
    end)
  end
end
