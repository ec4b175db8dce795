defmodule Neptunus.Vehicle.Board.OpenROV.UARTTest do
  # Board.OpenROV.UART against a fake board on the other end of a socat pty pair. The test process
  # is the fake board (its end opened with the port program) and stands in for the vehicle's
  # navigation process (registered under its name), so it sees exactly what the board link
  # reports. Intervals are shortened through options; nothing here measures performance.
  use ExUnit.Case, async: true

  @moduletag :uart
  @moduletag :capture_log

  import Neptunus.Test.Pty

  alias Neptunus.Vehicle.Board.OpenROV.{UART, Wiring}
  alias Neptunus.Vehicle.Board

  @neutral "go(1500,1500,1500,1);"
  @modifiers "mtrmod1(100,100,100);mtrmod2(100,100,100);"
  # what a new link writes first: neutral, then the motor modifiers
  @opening @neutral <> @modifiers
  @nav "hdgd:180;deap:2.5;pitc:1;roll:-1;yaw:180;fthr:0;\r\n"
  @status "vout:12.2;iout:0.4;time:5000;pres:1264;temp:9.5;\r\n"

  # the test process stands in for the vehicle's navigation and telemetry
  setup do
    {:ok, board_rig!("uart")}
  end

  defp start_uart(ctx, opts \\ []) do
    defaults = [
      id: ctx.id,
      device: ctx.pair.b,
      ping_interval: 50,
      keepalive_timeout: 300,
      reopen_min: 20,
      reopen_max: 200,
      # the fake board echoes when the test says so: no retries meanwhile, however slow the
      # machine (the tests of the retries say how often they want them)
      confirm_retry: 60_000
    ]

    start_supervised!({UART, Keyword.merge(defaults, opts)})
  end

  # The opening as a 2.5 board answers it: the motor modifiers echoed; returns once the link
  # has them confirmed (a go() before that would be held at neutral).
  defp opened!(ctx, board, opening \\ @opening) do
    bytes = recv_until(board, &String.starts_with?(&1, opening))
    write(board, "cmd:mtrmod1(100,100,100);\r\ncmd:mtrmod2(100,100,100);\r\n")
    wait_until(fn -> UART.link_status(ctx.id).board_settings == "confirmed" end, "settings")
    bytes
  end

  defp link_event(up) do
    assert_receive {:pubsub, _, "link", %{up: ^up, reason: reason}}
    reason
  end

  # The complete commands in `bytes`, in the order written.
  defp commands(bytes), do: ~r/[a-z0-9]+\([^)]*\);/ |> Regex.scan(bytes) |> List.flatten()

  # Reads whole commands (up to a `;`) until `done?` holds for the commands read; returns them.
  defp read_commands(board, done?) do
    board
    |> recv_until(&(String.ends_with?(&1, ";") and done?.(commands(&1))))
    |> commands()
  end

  defp ping?(command), do: String.starts_with?(command, "ping(")

  # The next go() on the line. Deadman pings run on their own timer once control is heard
  # (every go is), so they may come before it; nothing else may.
  defp next_go(board) do
    read = read_commands(board, &Enum.any?(&1, fn c -> String.starts_with?(c, "go(") end))
    {_pings, [go | rest]} = Enum.split_while(read, &ping?/1)
    assert String.starts_with?(go, "go(") and Enum.all?(rest, &ping?/1), inspect(read)
    go
  end

  test "neutral on open, then go commands with the vehicle's wiring", ctx do
    uart = start_uart(ctx)
    # the board link is on the control path: it runs before the web fan-out
    assert Process.info(uart, :priority) == {:priority, :high}
    assert link_event(true) == "open"
    assert opened!(ctx, ctx.board) =~ @neutral

    Board.go(ctx.id, %{port: 0.5, vertical: -0.2, starboard: 1.0})
    # default wiring: port reversed
    assert next_go(ctx.board) == "go(1250,1400,2000,1);"

    assert %{up: true, reason: "open", device: device, baud: 115_200, counters: c} =
             UART.link_status(ctx.id)

    assert device == ctx.pair.b
    assert c.opens == 1 and c.commands == 1
  end

  test "another wiring: order, directions and the ramp flag as configured", ctx do
    wiring = %Wiring{
      order: [:starboard, :vertical, :port],
      reversed: [:vertical],
      direct: false
    }

    start_uart(ctx, wiring: wiring)
    opening = "go(1500,1500,1500,0);" <> @modifiers
    assert String.starts_with?(opened!(ctx, ctx.board, opening), opening)
    Board.go(ctx.id, %{port: 1.0, vertical: 1.0, starboard: 0.0})
    assert next_go(ctx.board) == "go(1500,1000,2000,0);"
  end

  test "deadman pings only while control is heard from", ctx do
    start_uart(ctx, keepalive_timeout: 200)
    opened!(ctx, ctx.board)

    # control not heard yet: ping ticks pass without a ping (a lights command, written after
    # a withheld tick, shows that none went out before it)
    wait_until(fn -> UART.link_status(ctx.id).counters.pings_withheld >= 2 end, "pings withheld")
    UART.lights(ctx.id, 1)
    assert read_commands(ctx.board, &("ligt(1);" in &1)) == ["ligt(1);"]

    # keepalives (as control sends them) keep the pings coming, numbered
    pings = ctx |> keep_alive_until(&("ping(2);" in commands(&1)), "") |> commands()
    assert Enum.take(pings, 3) == ["ping(0);", "ping(1);", "ping(2);"]

    # control silent: once a tick withholds its ping, no ping follows (two lights commands,
    # each written after a withheld tick, with nothing but the pings already sent before the
    # first)
    withheld = UART.link_status(ctx.id).counters.pings_withheld
    wait_until(fn -> UART.link_status(ctx.id).counters.pings_withheld > withheld end, "silence")
    UART.lights(ctx.id, 2)
    before = read_commands(ctx.board, &("ligt(2);" in &1))
    assert List.last(before) == "ligt(2);" and Enum.all?(Enum.drop(before, -1), &ping?/1)
    withheld = UART.link_status(ctx.id).counters.pings_withheld
    wait_until(fn -> UART.link_status(ctx.id).counters.pings_withheld > withheld end, "silence")
    UART.lights(ctx.id, 3)
    assert read_commands(ctx.board, &("ligt(3);" in &1)) == ["ligt(3);"]

    # a go counts as hearing from control
    Board.neutral(ctx.id)
    assert recv_until(ctx.board, &String.contains?(&1, "ping(")) =~ @neutral
  end

  # Says keepalive, as control does, until the bytes read satisfy `done?`: returns them.
  defp keep_alive_until(ctx, done?, read) do
    UART.keepalive(ctx.id)
    read = read <> drain(ctx.board, 40)

    if done?.(read), do: read, else: keep_alive_until(ctx, done?, read)
  end

  test "telemetry lines become samples in SI units, sim: nil", ctx do
    start_uart(ctx)
    opened!(ctx, ctx.board)
    write(ctx.board, @nav <> @status <> @nav)

    assert_receive {:"$gen_cast", {:sample, s1}}
    assert_receive {:"$gen_cast", {:sample, s2}}
    assert %{sim: nil, t: t, measurement: m, board: extra} = s1
    assert is_float(t) and s2.t >= t
    assert m.depth == 2.5 and m.voltage == 12.2 and m.current == 0.4
    assert_in_delta m.heading, :math.pi(), 1.0e-12
    assert_in_delta m.pitch, :math.pi() / 180, 1.0e-12
    assert extra.temperature == 9.5 and extra.board_time == 5.0
    assert_in_delta extra.pressure, 126_400.0, 1.0e-6
    refute_receive {:"$gen_cast", {:sample, _}}, 100
  end

  test "garbage, wild points and overlong lines are counted, never crash, never reach samples",
       ctx do
    pid = start_uart(ctx, max_line: 128)
    opened!(ctx, ctx.board)
    write(ctx.board, @nav <> @status)
    assert_receive {:"$gen_cast", {:sample, _}}

    garbage = [
      "hdgd:pitc;deap:2000;vout:1.2;iout:nan;\n",
      :binary.copy("x", 1_000) <> "\n",
      <<0, 255, 254, 10, 13, 10>>,
      "no fields here\n",
      for(_ <- 1..200, into: "", do: <<:rand.uniform(256) - 1>>) <> "\n"
    ]

    Enum.each(garbage, &write(ctx.board, &1))
    write(ctx.board, "deap:3.0;\n")
    assert_receive {:"$gen_cast", {:sample, %{measurement: m}}}
    assert m.depth == 3.0 and m.voltage == 12.2 and m.heading > 3.0

    c = UART.link_status(ctx.id).counters
    assert c.key_as_value >= 1 and c.out_of_range >= 2 and c.not_a_number >= 1
    assert c.overlong >= 1 and c.malformed >= 1
    assert Process.alive?(pid)
  end

  test "hangup → link down → reopen with backoff → neutral again", ctx do
    start_uart(ctx)
    link_event(true)
    opened!(ctx, ctx.board)
    Board.go(ctx.id, %{port: 1.0, vertical: 1.0, starboard: 1.0})
    recv_until(ctx.board, &String.ends_with?(&1, "1);"))

    hang_up!(ctx.pair)
    assert link_event(false) =~ "hangup"
    assert_receive {:"$gen_cast", {:link, %{up: false, reason: "hangup" <> _}}}
    # while down: reopen attempts fail (the device is gone), commands are dropped
    wait_until(
      fn -> UART.link_status(ctx.id).reason =~ "No such file or directory" end,
      "reopen attempts"
    )

    Board.go(ctx.id, %{port: 1.0, vertical: 1.0, starboard: 1.0})

    assert %{up: false, counters: %{downs: 1, dropped_commands: dropped}} =
             UART.link_status(ctx.id)

    assert dropped >= 1

    # the board comes back: open its end first, then put the server's end in place
    pair = socat_pair!(dir: ctx.pair.dir, a: "a", b: "b-new")
    board = open!(pair.a)
    File.rename!(pair.b, ctx.pair.b)

    wait_until(fn -> UART.link_status(ctx.id).up end, "the link back up")
    assert opened!(ctx, board) =~ @neutral
    assert %{up: true, counters: %{opens: opens}} = UART.link_status(ctx.id)
    assert opens >= 2
  end

  test "lights, laser and tilt go out at once, are kept while down, and return after a reopen",
       ctx do
    start_uart(ctx)
    link_event(true)
    opened!(ctx, ctx.board)

    UART.lights(ctx.id, 200)
    assert recv_until(ctx.board, &String.ends_with?(&1, ";")) == "ligt(200);"
    UART.tilt(ctx.id, :math.pi() / 4)
    assert recv_until(ctx.board, &String.ends_with?(&1, ";")) == "tilt(2000);"

    hang_up!(ctx.pair)
    link_event(false)
    UART.laser(ctx.id, 9)
    wait_until(fn -> UART.link_status(ctx.id).counters.dropped_commands >= 1 end, "dropped")

    pair = socat_pair!(dir: ctx.pair.dir, a: "a", b: "b-new")
    board = open!(pair.a)
    File.rename!(pair.b, ctx.pair.b)
    wait_until(fn -> UART.link_status(ctx.id).up end, "the link back up")

    # neutral and the modifiers first, then the kept device settings (in whatever chunks the
    # pty delivers them)
    bytes = recv_until(board, &(&1 |> String.split(";", trim: true) |> length() >= 6))

    assert [@neutral, "mtrmod1(100,100,100);", "mtrmod2(100,100,100);" | resent] =
             bytes |> String.split(";", trim: true) |> Enum.map(&(&1 <> ";"))

    assert Enum.sort(resent) == ["claser(9);", "ligt(200);", "tilt(2000);"]
  end

  test "the port program dying is a link down too ({:exit_status, n}), then it reopens", ctx do
    start_uart(ctx)
    link_event(true)
    opened!(ctx, ctx.board)

    {:os_pid, os_pid} = Port.info(:sys.get_state(Board.via(ctx.id)).port, :os_pid)
    System.cmd("kill", ["-KILL", Integer.to_string(os_pid)])

    assert link_event(false) == "port program exited with status 137"
    assert link_event(true) == "open"
    assert opened!(ctx, ctx.board) =~ @neutral
  end

  test "its port closed without an exit status (a write that found the program gone) is a link down too, then it reopens",
       ctx do
    start_uart(ctx)
    link_event(true)
    recv_until(ctx.board, &String.starts_with?(&1, @opening))

    # the port ends with only its exit signal, as when a write fails (epipe) before the
    # program's exit status reached the VM
    Port.close(:sys.get_state(Board.via(ctx.id)).port)

    assert link_event(false) =~ "port program gone"
    assert link_event(true) == "open"
    assert %{up: true, counters: %{opens: 2}} = UART.link_status(ctx.id)
  end

  test "the port program asks for the OS time slice of its option (Neptunus.OS)", ctx do
    # the node's vehicles get the configured slice as this option (Neptunus.Application)
    start_uart(ctx, os_time_slice_ns: Application.fetch_env!(:neptunus, :os_time_slice_ns))
    link_event(true)
    {:os_pid, os_pid} = Port.info(:sys.get_state(Board.via(ctx.id)).port, :os_pid)
    {:ok, [{_, program_ns}]} = Neptunus.OS.thread_slices(os_pid)
    {:ok, vm} = Neptunus.OS.thread_slices(0)

    # the kernel reports the slices (Linux 6.12+): the program's is the node's; else none
    if Enum.any?(vm, fn {_tid, ns} -> ns > 0 end),
      do: assert(program_ns == Application.fetch_env!(:neptunus, :os_time_slice_ns)),
      else: assert(program_ns == 0)
  end

  test "a device that does not exist: down with the reason, retried with backoff", ctx do
    start_uart(ctx, device: "/nonexistent/ttyO1", reopen_min: 10, reopen_max: 40)
    assert link_event(false) == "open /nonexistent/ttyO1: No such file or directory"
    # announced once, however many times it is retried
    refute_receive {:pubsub, _, "link", _}, 200
    assert %{up: false, counters: %{opens: 0}} = UART.link_status(ctx.id)
  end

  test "a missing port program is a link down with a reason, not a crash", ctx do
    pid = start_uart(ctx, program: "/nonexistent/neptunus_uart")
    assert link_event(false) =~ "cannot start /nonexistent/neptunus_uart"
    Board.go(ctx.id, %{port: 1.0, vertical: 0.0, starboard: 0.0})
    assert %{up: false, counters: %{dropped_commands: 1}} = UART.link_status(ctx.id)
    assert Process.alive?(pid)
  end

  test "an orderly shutdown writes neutral before the port closes", ctx do
    start_uart(ctx)
    opened!(ctx, ctx.board)
    Board.go(ctx.id, %{port: 1.0, vertical: 0.0, starboard: 1.0})
    assert next_go(ctx.board) == "go(1000,1500,2000,1);"
    stop_supervised!(UART)

    # the last command written is neutral: deadman pings written before the stop may come
    # first (they run on their own timer), no other go()
    after_stop = read_commands(ctx.board, &(List.last(&1) == @neutral))
    assert Enum.all?(Enum.drop(after_stop, -1), &ping?/1), inspect(after_stop)
  end
end
