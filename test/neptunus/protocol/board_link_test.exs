defmodule Neptunus.Protocol.BoardLinkTest do
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.BoardLink

  doctest BoardLink

  defp feed(l, events) do
    Enum.reduce(events, {l, []}, fn {event, now}, {l, actions} ->
      {l, new} = BoardLink.event(l, event, now)
      {l, actions ++ new}
    end)
  end

  defp pong(ms), do: {:pong, %{args: 1, millis: ms}}

  test "pongs are matched to pings in order: round-trip time and pong age" do
    l =
      BoardLink.new(:openrov_25) |> BoardLink.ping_sent(1, 1_000) |> BoardLink.ping_sent(2, 2_000)

    {l, []} = BoardLink.event(l, pong(50_000), 1_040)
    assert l.rtt_ms == 40
    {l, []} = BoardLink.event(l, pong(51_000), 2_015)
    assert l.rtt_ms == 15
    status = BoardLink.status(l, 2_515)
    assert %{rtt_ms: 15, pong_age_ms: 500, board_uptime_ms: 51_500} = status
    assert status.board_deadman_armed == false
  end

  test "the board's millis going backwards (pong or time) is a board reset, once" do
    l = BoardLink.new(:openrov_25)
    {l, []} = feed(l, [{{:board_time, 200_000}, 0}, {pong(201_000), 1_000}])
    {l, [{:board_reset, reason}]} = BoardLink.event(l, {:board_time, 300}, 2_000)
    assert reason =~ "201.0 s to 0.3 s"
    assert {_, []} = BoardLink.event(l, pong(1_300), 3_000)
    assert l.resets == 1

    # from a pong too
    {_, [{:board_reset, _}]} = BoardLink.event(l, pong(100), 2_100)
  end

  test "a time field behind the last pong is the firmware's sampling, not a reset" do
    # the firmware samples `time` at its 101 ms navigation tick and prints it later: just after
    # a pong it can be behind it while the board runs on (seen under load: 315.3 s, then 315.2 s)
    l = BoardLink.new(:openrov_25)
    {l, []} = feed(l, [{{:board_time, 314_300}, 0}, {pong(315_300), 990}])
    {l, []} = BoardLink.event(l, {:board_time, 315_200}, 1_000)
    {l, []} = BoardLink.event(l, pong(316_300), 2_000)
    assert l.resets == 0

    # a real reset is still seen, once, whichever source shows it first
    {l, [{:board_reset, reason}]} = BoardLink.event(l, pong(400), 2_500)
    assert reason =~ "316.3 s to 0.4 s"
    {l, []} = BoardLink.event(l, {:board_time, 1_001}, 3_100)
    {l, []} = BoardLink.event(l, pong(1_400), 3_500)
    assert l.resets == 1
  end

  test "a 32-bit millis wrap is not a reset" do
    l = BoardLink.new(:openrov_25)
    {l, []} = BoardLink.event(l, {:board_time, 4_294_967_000}, 0)
    assert {_, []} = BoardLink.event(l, {:board_time, 500}, 1_000)
  end

  test "deadman recovery: icmd:stop seen, cleared by the next pong" do
    l = BoardLink.new(:openrov_30)
    {l, []} = feed(l, [{pong(190_000), 0}, {{:icmd, "deptloff"}, 10}, {{:icmd, "stop"}, 20}])
    assert BoardLink.status(l, 20).board_deadman_tripped
    {l, [{:deadman_recovery, reason}]} = BoardLink.event(l, pong(191_000), 1_000)
    assert reason =~ "icmd:stop"
    assert {_, []} = BoardLink.event(l, pong(192_000), 2_000)
    assert l.deadman_recoveries == 1
  end

  test "deadman recovery from the board's clock: pongs > 2 s apart while armed; not before 180 s" do
    l = BoardLink.new(:openrov_25)
    {l, []} = BoardLink.event(l, pong(185_000), 0)
    assert {_, [{:deadman_recovery, reason}]} = BoardLink.event(l, pong(187_500), 2_500)
    assert reason =~ "2.5 s"

    # not armed yet: the board's deadman could not trip
    {l, []} = BoardLink.event(BoardLink.new(:openrov_25), pong(100_000), 0)
    assert {_, []} = BoardLink.event(l, pong(105_000), 5_000)
    # 2 s exactly is no trip
    {l, []} = BoardLink.event(BoardLink.new(:openrov_25), pong(200_000), 0)
    assert {_, []} = BoardLink.event(l, pong(202_000), 2_000)
  end

  test "firmware detection: crc/rawcmd lines are 30.x, a lone echo is 2.5; a mismatch reported once" do
    l = BoardLink.new(:openrov_25)
    {l, [{:firmware_mismatch, :openrov_30}]} = BoardLink.event(l, {:crc, {:fail, 1, 2}}, 0)
    {l, []} = feed(l, [{:rawcmd, 1}, {{:crc, :pass}, 2}])
    status = BoardLink.status(l, 3)
    assert %{detected_firmware: "openrov-30", firmware_mismatch: true, crc_failures: 1} = status

    l = BoardLink.new(:openrov_30)
    {l, []} = BoardLink.event(l, {:echo, "ping", true}, 0)
    assert BoardLink.status(l, 0).firmware_mismatch == false
    {l, [{:firmware_mismatch, :openrov_25}]} = BoardLink.event(l, {:echo, "ping", false}, 0)
    assert BoardLink.status(l, 0).detected_firmware == "openrov-2.5"

    # a 2.5 board echoing our CRC byte as part of the name
    l = BoardLink.new(:openrov_30)

    assert {l, [{:firmware_mismatch, :openrov_25}]} =
             BoardLink.event(l, {:echo_prefixed, "go"}, 0)

    assert BoardLink.status(l, 0).commands_confirmed == 0
  end

  test "echoes count confirmed commands against sent ones" do
    l = BoardLink.new(:openrov_25) |> BoardLink.sent() |> BoardLink.sent()
    {l, []} = BoardLink.event(l, {:echo, "go", false}, 0)
    assert %{commands_sent: 2, commands_confirmed: 1} = BoardLink.status(l, 0)
  end

  test "a reopened link forgets the board's clock and pings, keeps counters" do
    l = BoardLink.new(:openrov_25) |> BoardLink.ping_sent(1, 0) |> BoardLink.sent()
    {l, []} = BoardLink.event(l, pong(500_000), 10)
    l = BoardLink.opened(l)
    assert BoardLink.status(l, 20).board_uptime_ms == nil
    # a board that reset while the port was closed is not a "reset" on the new link
    assert {_, []} = BoardLink.event(l, pong(1_000), 30)
    assert l.sent == 1
  end
end
