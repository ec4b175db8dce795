defmodule Neptunus.Vehicle.Board.UARTFirmwareTest do
  # Board.UART against a fake board scripted to answer like the OpenROV 2.5.x / 30.x firmware
  # (CRLF lines, glued pong, echoes, crc lines), on the other end of a socat pty pair. The test
  # process is the fake board and stands in for the vehicle's navigation and telemetry.
  use ExUnit.Case, async: true

  @moduletag :uart
  @moduletag :capture_log

  import Neptunus.Test.Pty

  alias Neptunus.Protocol.OpenROV
  alias Neptunus.Vehicle.Board
  alias Neptunus.Vehicle.Board.UART

  # the test process stands in for the vehicle's navigation and telemetry
  setup do
    {:ok, board_rig!("uartfw")}
  end

  defp start_uart(ctx, opts) do
    defaults = [
      id: ctx.id,
      device: ctx.pair.b,
      ping_interval: 100,
      keepalive_timeout: 60_000,
      reopen_min: 20,
      reopen_max: 200
    ]

    start_supervised!({UART, Keyword.merge(defaults, opts)})
  end

  # 30.x commands: one CRC byte, then the text up to ';'. Returns the commands read so far
  # (each {crc_ok?, text}) once `count` have arrived.
  defp recv_framed(board, count) do
    bytes = recv_until(board, &(length(split_framed(&1)) >= count))
    split_framed(bytes)
  end

  defp split_framed(bytes) do
    # not OpenROV.split_commands/1: it trims whitespace, and a CRC byte may be one
    {commands, [_rest]} = bytes |> :binary.split(";", [:global]) |> Enum.split(-1)

    Enum.map(commands, fn framed ->
      case OpenROV.unframe(framed <> ";") do
        {:ok, text} -> {true, text}
        {:error, _} -> {false, framed}
      end
    end)
  end

  test "openrov-30: every command written carries a valid CRC byte", ctx do
    start_uart(ctx, firmware: :openrov_30)
    opening = recv_framed(ctx.board, 3)

    assert Enum.take(opening, 3) == [
             {true, "go(1500,1500,1500,1);"},
             {true, "mtrmod1(100,100,100);"},
             {true, "mtrmod2(100,100,100);"}
           ]

    Board.go(ctx.id, %{port: 0.5, vertical: 0.0, starboard: 0.5})
    UART.lights(ctx.id, 50)
    UART.keepalive(ctx.id)
    commands = recv_framed(ctx.board, 6)
    assert Enum.all?(commands, &elem(&1, 0)), inspect(commands)
    texts = Enum.map(commands, &elem(&1, 1))
    assert "go(1250,1500,1750,1);" in texts and "ligt(50);" in texts
    assert Enum.any?(texts, &String.starts_with?(&1, "ping("))
  end

  test "openrov-2.5: plain commands; a board answering with crc lines is reported, not switched",
       ctx do
    start_uart(ctx, firmware: :openrov_25)
    assert recv_until(ctx.board, &String.contains?(&1, "mtrmod2")) =~ "go(1500,1500,1500,1);"
    # a 30.x board refuses the plain commands
    write(ctx.board, "rawcmd:67,6F,28,;\r\ncrc:fail,5A/67;")
    write(ctx.board, "hdgd:1.00;\r\n")

    assert_receive {:pubsub, _, "firmware", %{configured: "openrov-2.5", detected: "openrov-30"}}

    assert %{firmware: "openrov-2.5", detected_firmware: "openrov-30", firmware_mismatch: true} =
             UART.link_status(ctx.id)

    # still plain
    Board.neutral(ctx.id)
    assert recv_until(ctx.board, &String.ends_with?(&1, ";")) == "go(1500,1500,1500,1);"
  end

  test "openrov-30 configured, a 2.5 board echoing the CRC byte as part of the name: reported",
       ctx do
    start_uart(ctx, firmware: :openrov_30)
    [{true, _} | _] = recv_framed(ctx.board, 3)
    write(ctx.board, <<"cmd:", 0x9C, "go(1500,1500,1500,1);\r\n">>)

    assert_receive {:pubsub, _, "firmware", %{configured: "openrov-30", detected: "openrov-2.5"}}

    assert %{firmware_mismatch: true, commands_confirmed: 0} = UART.link_status(ctx.id)
  end

  test "pong → round-trip time and pong age in the link status; echoes counted as confirmed",
       ctx do
    start_uart(ctx, firmware: :openrov_25)
    recv_until(ctx.board, &String.contains?(&1, "mtrmod2"))
    UART.keepalive(ctx.id)
    assert recv_until(ctx.board, &String.contains?(&1, "ping(")) =~ "ping(0);"
    # the 2.5 firmware: echo on its own line, the pong glued to the next line
    write(ctx.board, "cmd:ping(0);\r\npong:1,183422;hdgd:1.00;\r\n")

    status = wait_until(fn -> (s = UART.link_status(ctx.id)).rtt_ms && s end, "a round trip")
    assert is_integer(status.rtt_ms) and status.rtt_ms >= 0
    assert status.pong_age_ms >= 0
    assert status.board_deadman_armed == true
    assert status.board_uptime_ms >= 183_422
    assert status.commands_confirmed == 1
    assert status.commands_sent >= 4
    assert status.detected_firmware == "openrov-2.5" and status.firmware_mismatch == false
    # the page gets the liveness fields with the link state
    assert_receive {:"$gen_cast", {:link, %{up: true, rtt_ms: rtt}}} when is_integer(rtt)
  end

  test "the board's uptime going backwards: its whole state is sent again", ctx do
    start_uart(ctx, firmware: :openrov_30)
    recv_framed(ctx.board, 3)
    UART.lights(ctx.id, 80)
    UART.tilt(ctx.id, 0.0)
    UART.laser(ctx.id, 1)
    recv_framed(ctx.board, 3)

    write(ctx.board, "vout:12.00;iout:0.40;time:250000;pres:1100.00;temp:9.00;\r\n")
    Process.sleep(50)
    refute_receive {:pubsub, _, "board", _}, 100
    # the board reset: millis from 250 s back to 0.4 s
    write(ctx.board, "vout:12.00;iout:0.40;time:400;pres:0.00;temp:0.00;\r\n")

    assert_receive {:pubsub, _, "board", %{event: "reset", reason: reason}}
    assert reason =~ "250.0 s to 0.4 s"

    texts = ctx.board |> recv_framed(6) |> Enum.map(fn {true, text} -> text end)

    assert Enum.take(texts, 3) == [
             "go(1500,1500,1500,1);",
             "mtrmod1(100,100,100);",
             "mtrmod2(100,100,100);"
           ]

    assert Enum.sort(Enum.drop(texts, 3)) == ["claser(1);", "ligt(80);", "tilt(1500);"]
    assert %{board_resets: 1, board_deadman_armed: false} = UART.link_status(ctx.id)
  end

  test "deadman recovery: icmd:stop seen, the next pong clears it and the state is sent again",
       ctx do
    start_uart(ctx, firmware: :openrov_30)
    recv_framed(ctx.board, 3)
    UART.lights(ctx.id, 120)
    recv_framed(ctx.board, 1)

    write(
      ctx.board,
      "icmd:deptloff();\r\nicmd:headloff();\r\nicmd:stop();\r\nicmd:ligt(50);\r\n"
    )

    wait_until(fn -> UART.link_status(ctx.id).board_deadman_tripped end, "trip seen")
    write(ctx.board, "pong:1,200000;\r\n")
    assert_receive {:pubsub, _, "board", %{event: "deadman_recovery"}}

    texts = ctx.board |> recv_framed(4) |> Enum.map(&elem(&1, 1))
    assert "ligt(120);" in texts and "go(1500,1500,1500,1);" in texts
    assert %{deadman_recoveries: 1, board_deadman_tripped: false} = UART.link_status(ctx.id)
  end
end
