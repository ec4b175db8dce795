defmodule Neptunus.Vehicle.Board.OpenROV.UARTFirmwareTest do
  # Board.OpenROV.UART against a fake board scripted to answer like the OpenROV 2.5.x / 30.x
  # firmware (CRLF lines, glued pong, echoes, crc lines), on the other end of a socat pty pair. The
  # test process is the fake board and stands in for the vehicle's navigation and telemetry.
  use ExUnit.Case, async: true

  @moduletag :uart
  @moduletag :capture_log

  import Neptunus.Test.Pty

  alias Neptunus.PubSub
  alias Neptunus.Vehicle.Board.OpenROV
  alias Neptunus.Vehicle.{Board, Telemetry}
  alias Neptunus.Vehicle.Board.OpenROV.UART

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
      reopen_max: 200,
      # the fake board echoes when the test says so: no retries meanwhile, however slow the
      # machine (the tests of the retries say how often they want them)
      confirm_retry: 60_000
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
    # not OpenROV.Protocol.split_commands/1: it trims whitespace, and a CRC byte may be one
    {commands, [_rest]} = bytes |> :binary.split(";", [:global]) |> Enum.split(-1)

    Enum.map(commands, fn framed ->
      case OpenROV.Protocol.unframe(framed <> ";") do
        {:ok, text} -> {true, text}
        {:error, _} -> {false, framed}
      end
    end)
  end

  # what the firmware answers to commands (30.x: crc:pass glued to the echo)
  defp echo(board, commands, profile) do
    prefix = if profile == :openrov_30, do: "crc:pass;", else: ""

    write(
      board,
      Enum.map_join(commands, &(prefix <> "cmd:" <> String.trim_trailing(&1, ";") <> ";\r\n"))
    )
  end

  @mods ["mtrmod1(100,100,100);", "mtrmod2(100,100,100);"]

  defp confirmed!(ctx) do
    wait_until(fn -> UART.link_status(ctx.id).board_settings == "confirmed" end, "confirmed")
  end

  test "openrov-30: every command written carries a valid CRC byte", ctx do
    start_uart(ctx, firmware: :openrov_30)
    opening = recv_framed(ctx.board, 3)

    assert Enum.take(opening, 3) == [
             {true, "go(1500,1500,1500,1);"},
             {true, "mtrmod1(100,100,100);"},
             {true, "mtrmod2(100,100,100);"}
           ]

    echo(ctx.board, @mods, :openrov_30)
    confirmed!(ctx)

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

  describe "settings confirmed, thrust held until the motor modifiers are" do
    for profile <- [:openrov_25, :openrov_30] do
      test "#{profile}: settings written again until echoed; thrust held at neutral meanwhile, then sent",
           ctx do
        profile = unquote(profile)
        start_uart(ctx, firmware: profile, confirm_retry: 100)
        recv_framed_or_plain(ctx.board, profile, 3)
        UART.lights(ctx.id, 80)
        recv_commands(ctx.board, profile, &("ligt(80);" in &1))

        # the pilot's surge before the board confirmed anything: the board gets neutral
        Board.go(ctx.id, %{port: 0.4, vertical: 0.0, starboard: 0.4})

        assert gos(recv_commands(ctx.board, profile, &(gos(&1) != []))) == [
                 "go(1500,1500,1500,1);"
               ]

        assert_receive {:pubsub, _, "board", %{event: "thrust_held", reason: reason}}
        assert reason =~ "board settings not confirmed (mtrmod1, mtrmod2)"
        assert %{thrust_held: true, board_settings: "pending"} = UART.link_status(ctx.id)

        # nothing echoed: each is written again (the pings are the deadman's)
        wanted = @mods ++ ["ligt(80);"]
        again = recv_commands(ctx.board, profile, &Enum.all?(wanted, fn c -> c in &1 end))
        assert Enum.sort(Enum.uniq(again)) == Enum.sort(wanted)

        # the board echoes one modifier: still held; the other: the held demand goes out
        echo(ctx.board, ["mtrmod1(100,100,100);", "ligt(80);"], profile)

        wait_until(
          fn -> UART.link_status(ctx.id).board_settings_pending == ["mtrmod2"] end,
          "one left"
        )

        assert UART.link_status(ctx.id).thrust_held
        echo(ctx.board, ["mtrmod2(100,100,100);"], profile)

        assert "go(1300,1500,1700,1);" in recv_until_command(ctx.board, profile, "go(1300")

        assert %{board_settings: "confirmed", board_settings_pending: [], thrust_held: false} =
                 UART.link_status(ctx.id)

        # the page's telemetry and the developer logger were told
        assert_receive {:"$gen_cast", {:link, %{board_settings: "confirmed", thrust_held: false}}}
      end
    end

    test "the firmware's start-up line (boot:1) is a board reset: state again, thrust held until confirmed",
         ctx do
      start_uart(ctx, firmware: :openrov_25)
      recv_framed_or_plain(ctx.board, :openrov_25, 3)
      UART.tilt(ctx.id, 0.0)
      recv_framed_or_plain(ctx.board, :openrov_25, 1)
      echo(ctx.board, @mods ++ ["tilt(1500);"], :openrov_25)
      confirmed!(ctx)
      Board.go(ctx.id, %{port: 0.0, vertical: 0.5, starboard: 0.0})

      assert gos(recv_commands(ctx.board, :openrov_25, &(gos(&1) != []))) == [
               "go(1500,1750,1500,1);"
             ]

      # the board restarts (a USB Arduino when the line opens): its setup lines, then boot:1
      write(ctx.board, "Depth Sensor setup.\r\nlog:init on primary addresses;\r\nboot:1;\r\n")
      assert_receive {:pubsub, _, "board", %{event: "reset", reason: reason}}
      assert reason =~ "boot:1"
      assert_receive {:"$gen_cast", {:board_reset, ^reason}}

      # (the pings are the deadman's)
      assert recv_commands(ctx.board, :openrov_25, &(length(&1) >= 4)) ==
               ["go(1500,1500,1500,1);" | @mods] ++ ["tilt(1500);"]

      assert %{board_resets: 1, thrust_held: true} = UART.link_status(ctx.id)
      echo(ctx.board, @mods, :openrov_25)
      assert "go(1500,1750,1500,1);" in recv_until_command(ctx.board, :openrov_25, "go(1500,1750")
    end

    test "a setting never echoed: failed after the bound, with a reason, still written slower; thrust held",
         ctx do
      PubSub.subscribe(Telemetry.log_topic(ctx.id))
      start_uart(ctx, firmware: :openrov_25, confirm_retry: 30, confirm_attempts: 3)
      # (a demand from before the link opened would not count: a new link starts neutral)
      assert_receive {:pubsub, _, "link", %{up: true}}
      Board.go(ctx.id, %{port: 0.4, vertical: 0.0, starboard: 0.4})

      assert_receive {:pubsub, _, "log", %{category: "link", level: "warning", message: held}}

      assert held =~ "thrust held at neutral"

      status =
        wait_until(
          fn -> (s = UART.link_status(ctx.id)).board_settings == "failed" && s end,
          "failed"
        )

      assert status.board_settings_reason =~ "has not confirmed mtrmod1(100,100,100);"
      assert status.thrust_held
      assert_receive {:pubsub, _, "log", %{level: "error", message: message}}
      assert message =~ "board settings not confirmed: the board has not confirmed"

      assert_receive {:"$gen_cast",
                      {:link,
                       %{board_settings: "failed", board_settings_reason: "the board" <> _}}}

      # still written (every second), and confirmed when the board answers at last
      drain(ctx.board, 0)
      recv_commands(ctx.board, :openrov_25, &(@mods -- &1 == []))
      echo(ctx.board, @mods, :openrov_25)
      confirmed!(ctx)
      refute UART.link_status(ctx.id).thrust_held
    end
  end

  # The next `count` commands the board reads, as text (30.x: unframed, CRC checked).
  defp recv_framed_or_plain(board, :openrov_30, count) do
    board |> recv_framed(count) |> Enum.map(fn {true, text} -> text end)
  end

  defp recv_framed_or_plain(board, :openrov_25, count) do
    bytes = recv_until(board, &(length(:binary.split(&1, ";", [:global])) > count))
    bytes |> :binary.split(";", [:global]) |> Enum.drop(-1) |> Enum.map(&(&1 <> ";"))
  end

  # the commands the board reads but pings, until `done?` of them (3 s at most)
  defp recv_commands(board, profile, done?) do
    commands = fn bytes ->
      case profile do
        :openrov_25 ->
          bytes |> :binary.split(";", [:global]) |> Enum.drop(-1) |> Enum.map(&(&1 <> ";"))

        :openrov_30 ->
          bytes |> split_framed() |> Enum.map(&elem(&1, 1))
      end
      |> Enum.reject(&String.starts_with?(&1, "ping("))
    end

    board |> recv_until(&done?.(commands.(&1))) |> commands.()
  end

  defp gos(commands), do: Enum.filter(commands, &String.starts_with?(&1, "go("))

  # commands until one starting with `prefix`
  defp recv_until_command(board, profile, prefix) do
    bytes = recv_until(board, &String.contains?(&1, prefix))

    case profile do
      :openrov_25 -> bytes |> :binary.split(";", [:global]) |> Enum.map(&(&1 <> ";"))
      :openrov_30 -> bytes |> split_framed() |> Enum.map(&elem(&1, 1))
    end
  end
end
