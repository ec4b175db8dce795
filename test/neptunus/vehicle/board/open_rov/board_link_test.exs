defmodule Neptunus.Vehicle.Board.OpenROV.BoardLinkTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties, only: [check: 3]

  alias Neptunus.Vehicle.Board.OpenROV.BoardLink

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
    {l, [{:board_reset, reason}, :neutral]} = BoardLink.event(l, {:board_time, 300}, 2_000)
    assert reason =~ "201.0 s to 0.3 s"
    assert {_, []} = BoardLink.event(l, pong(1_300), 3_000)
    assert l.resets == 1

    # from a pong too
    {_, [{:board_reset, _}, :neutral]} = BoardLink.event(l, pong(100), 2_100)
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
    {l, [{:board_reset, reason}, :neutral]} = BoardLink.event(l, pong(400), 2_500)
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
    {l, [{:deadman_recovery, reason}, :neutral]} = BoardLink.event(l, pong(191_000), 1_000)
    assert reason =~ "icmd:stop"
    assert {_, []} = BoardLink.event(l, pong(192_000), 2_000)
    assert l.deadman_recoveries == 1
  end

  test "deadman recovery from the board's clock: pongs > 2 s apart while armed; not before 180 s" do
    l = BoardLink.new(:openrov_25)
    {l, []} = BoardLink.event(l, pong(185_000), 0)
    assert {_, [{:deadman_recovery, reason}, :neutral]} = BoardLink.event(l, pong(187_500), 2_500)
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
    {l, []} = BoardLink.event(l, {:echo, "ping", ["7"], true}, 0)
    assert BoardLink.status(l, 0).firmware_mismatch == false
    {l, [{:firmware_mismatch, :openrov_25}]} = BoardLink.event(l, {:echo, "ping", [], false}, 0)
    assert BoardLink.status(l, 0).detected_firmware == "openrov-2.5"

    # a 2.5 board echoing our CRC byte as part of the name
    l = BoardLink.new(:openrov_30)

    assert {l, [{:firmware_mismatch, :openrov_25}]} =
             BoardLink.event(l, {:echo_prefixed, "go"}, 0)

    assert BoardLink.status(l, 0).commands_confirmed == 0
  end

  test "echoes count confirmed commands against sent ones" do
    l = BoardLink.new(:openrov_25) |> BoardLink.sent() |> BoardLink.sent()
    {l, []} = BoardLink.event(l, {:echo, "go", ["1500", "1500", "1500", "1"], false}, 0)
    assert %{commands_sent: 2, commands_confirmed: 1} = BoardLink.status(l, 0)
  end

  test "a reopened link forgets the board's clock and pings, keeps counters" do
    l = BoardLink.new(:openrov_25) |> BoardLink.ping_sent(1, 0) |> BoardLink.sent()
    {l, []} = BoardLink.event(l, pong(500_000), 10)
    {l, [:neutral]} = BoardLink.opened(l, 15)
    assert BoardLink.status(l, 20).board_uptime_ms == nil
    # a board that reset while the port was closed is not a "reset" on the new link
    assert {_, []} = BoardLink.event(l, pong(1_000), 30)
    assert l.sent == 1
  end

  describe "the board's settings, confirmed" do
    @mods [mtrmod1: "mtrmod1(100,100,100);", mtrmod2: "mtrmod2(100,100,100);"]

    defp link(opts \\ []), do: BoardLink.new(:openrov_25, [settings: @mods] ++ opts)

    defp echo(command, crc? \\ false) do
      {name, args} = Neptunus.Vehicle.Board.OpenROV.Protocol.call(command)
      {:echo, name, args, crc?}
    end

    defp confirm_all(l, now) do
      Enum.reduce(@mods, l, fn {_k, c}, l -> elem(BoardLink.event(l, echo(c), now), 0) end)
    end

    defp sends(actions), do: for({:send, key, _} <- actions, do: key)

    test "opening the link: neutral, then the motor modifiers, then the devices, in that order" do
      l = link()
      # set while the link is down: kept, not written
      {l, []} = BoardLink.set(l, :tilt, "tilt(1600);", 0)
      {l, []} = BoardLink.set(l, :lights, "ligt(80);", 0)
      {l, actions} = BoardLink.opened(l, 10)

      assert actions == [
               :neutral,
               {:send, :mtrmod1, "mtrmod1(100,100,100);"},
               {:send, :mtrmod2, "mtrmod2(100,100,100);"},
               {:send, :lights, "ligt(80);"},
               {:send, :tilt, "tilt(1600);"}
             ]

      assert %{
               board_settings: "pending",
               board_settings_pending: ["mtrmod1", "mtrmod2", "lights", "tilt"],
               board_settings_reason: nil,
               thrust_held: false
             } = BoardLink.status(l, 10)
    end

    test "a setting is confirmed by the echo of that very command; the last one confirms all" do
      {l, _} = BoardLink.opened(link(), 0)
      {l, _} = BoardLink.set(l, :lights, "ligt(80);", 0)
      # an echo of another value, another command, or without arguments confirms nothing
      {l, []} = BoardLink.event(l, echo("ligt(79);"), 5)
      {l, []} = BoardLink.event(l, echo("mtrmod2(100,100,200);"), 5)
      {l, []} = BoardLink.event(l, {:echo, "mtrmod1", nil, false}, 5)
      {l, []} = BoardLink.event(l, echo("go(1500,1500,1500,1);"), 5)
      assert BoardLink.settings(l).pending == [:mtrmod1, :mtrmod2, :lights]

      # the 30.x echo carries the arguments as we wrote them, even with the ';'-avoiding space
      {l, [{:firmware_mismatch, :openrov_30}, {:settings, %{pending: [:mtrmod2, :lights]}}]} =
        BoardLink.event(l, echo("mtrmod1( 100,100,100);", true), 6)

      # (what is pending changed: the page is told)

      {l, [{:settings, %{state: :pending, pending: [:mtrmod2]}}]} =
        BoardLink.event(l, echo("ligt(80);", true), 7)

      assert BoardLink.settings(l).pending == [:mtrmod2]
      refute BoardLink.motors_confirmed?(l)

      {l, [{:settings, %{state: :confirmed, pending: [], reason: nil}}]} =
        BoardLink.event(l, echo("mtrmod2(100,100,100);"), 8)

      assert BoardLink.motors_confirmed?(l)
      assert BoardLink.next_tick_at(l) == nil
      # a repeated echo changes nothing
      assert {^l, []} = BoardLink.event(l, echo("mtrmod2(100,100,100);"), 9) |> bump_back()
    end

    # the echo counter goes up; everything else stays
    defp bump_back({l, actions}), do: {%{l | confirmed: l.confirmed - 1}, actions}

    test "a new value is pending again; the same confirmed value is written and stays confirmed" do
      {l, _} = BoardLink.opened(link(), 0)
      l = confirm_all(l, 1)

      {l, [{:send, :lights, "ligt(80);"}, {:settings, %{pending: [:lights]}}]} =
        BoardLink.set(l, :lights, "ligt(80);", 2)

      {l, [{:settings, %{state: :confirmed}}]} = BoardLink.event(l, echo("ligt(80);"), 3)
      assert {_, [{:send, :lights, "ligt(80);"}]} = BoardLink.set(l, :lights, "ligt(80);", 4)

      # a value changed before the echo of the last: only the new one's echo confirms
      {l, _} = BoardLink.set(l, :lights, "ligt(90);", 5)
      {l, []} = BoardLink.event(l, echo("ligt(80);"), 6)
      assert BoardLink.settings(l).pending == [:lights]
      {l, [{:settings, %{state: :confirmed}}]} = BoardLink.event(l, echo("ligt(90);"), 7)
      # a setting the board never echoes does not hold thrust: only the motor modifiers do
      {l, _} = BoardLink.set(l, :laser, "claser(3);", 8)
      assert {_, :send, []} = BoardLink.demand(l, false)
    end

    test "unconfirmed settings are written again every retry_ms, then fail with a reason, then slower" do
      {l, _} = BoardLink.opened(link(retry_ms: 100, attempts: 3, slow_retry_ms: 500), 1_000)
      assert BoardLink.next_tick_at(l) == 1_100
      assert {_, []} = BoardLink.tick(l, 1_099)

      {l, a2} = BoardLink.tick(l, 1_100)
      assert sends(a2) == [:mtrmod1, :mtrmod2]
      # one confirmed meanwhile: only the other is written again
      {l, [{:settings, _}]} = BoardLink.event(l, echo("mtrmod1(100,100,100);"), 1_150)
      {l, a3} = BoardLink.tick(l, 1_200)
      assert a3 == [{:send, :mtrmod2, "mtrmod2(100,100,100);"}]

      # the third write was the last of the bound: at the next retry it fails, is written again
      {l, a4} = BoardLink.tick(l, 1_300)

      assert [
               {:send, :mtrmod2, _},
               {:settings, %{state: :failed, pending: [:mtrmod2], reason: r}}
             ] = a4

      assert r =~ "has not confirmed mtrmod2(100,100,100);"
      assert r =~ "3 writes in 0.3 s"
      assert %{board_settings: "failed", board_settings_reason: ^r} = BoardLink.status(l, 1_300)

      # then every slow_retry_ms, for as long as it takes
      assert BoardLink.next_tick_at(l) == 1_800
      assert {_, []} = BoardLink.tick(l, 1_799)
      {l, [{:send, :mtrmod2, _}]} = BoardLink.tick(l, 1_800)
      {l, [{:send, :mtrmod2, _}]} = BoardLink.tick(l, 2_300)
      # a late echo confirms it
      {l, [{:settings, %{state: :confirmed}}]} =
        BoardLink.event(l, echo("mtrmod2(100,100,100);"), 2_350)

      assert BoardLink.next_tick_at(l) == nil
    end

    test "nothing is written while the link is down" do
      {l, _} = BoardLink.opened(link(), 0)
      l = BoardLink.closed(l)
      assert BoardLink.next_tick_at(l) == nil
      assert BoardLink.tick(l, 10_000) == {l, []}
    end

    test "thrust is held until both motor modifiers are confirmed, then released" do
      {l, _} = BoardLink.opened(link(), 0)
      # neutral is never held
      assert {l, :send, []} = BoardLink.demand(l, true)
      {l, :hold, [{:hold, reason}]} = BoardLink.demand(l, false)
      assert reason =~ "board settings not confirmed (mtrmod1, mtrmod2)"
      assert reason =~ "thrust held at neutral"
      assert BoardLink.status(l, 0).thrust_held
      # one hold, one message
      {l, :hold, []} = BoardLink.demand(l, false)

      {l, [{:settings, %{pending: [:mtrmod2]}}]} =
        BoardLink.event(l, echo("mtrmod1(100,100,100);"), 10)

      assert BoardLink.status(l, 10).thrust_held

      {l, [{:settings, %{state: :confirmed}}, :release]} =
        BoardLink.event(l, echo("mtrmod2(100,100,100);"), 20)

      refute BoardLink.status(l, 20).thrust_held
      assert {_, :send, []} = BoardLink.demand(l, false)
    end

    test "a neutral demand ends a hold: nothing is released later" do
      {l, _} = BoardLink.opened(link(), 0)
      {l, :hold, [{:hold, _}]} = BoardLink.demand(l, false)
      {l, :send, []} = BoardLink.demand(l, true)
      refute l.held
      l = confirm_all(l, 5)
      {l, :send, []} = BoardLink.demand(l, false)
      assert l.demanding
    end

    test "a new link starts neutral: a demand from before the open is not resumed, the next one is held" do
      l = link()
      {l, :hold, []} = BoardLink.demand(l, false)
      {l, actions} = BoardLink.opened(l, 100)
      assert [:neutral, {:send, :mtrmod1, _}, {:send, :mtrmod2, _}] = actions
      refute l.held
      {l, :hold, [{:hold, _}]} = BoardLink.demand(l, false)
      {l, [{:settings, _}]} = BoardLink.event(l, echo("mtrmod2(100,100,100);"), 110)
      assert l.held

      {_l, [{:settings, %{state: :confirmed}}, :release]} =
        BoardLink.event(l, echo("mtrmod1(100,100,100);"), 120)
    end

    test "the firmware's start-up line is a board reset: neutral, every setting again, a standing demand held" do
      {l, _} = BoardLink.opened(link(), 0)
      {l, _} = BoardLink.set(l, :lights, "ligt(80);", 0)
      l = confirm_all(l, 5)
      {l, [{:settings, %{state: :confirmed}}]} = BoardLink.event(l, echo("ligt(80);"), 6)
      {l, :send, []} = BoardLink.demand(l, false)
      {l, []} = BoardLink.event(l, pong(42_000), 50)

      {l, actions} = BoardLink.event(l, :boot, 1_000)

      assert [
               {:board_reset, reason},
               :neutral,
               {:send, :mtrmod1, _},
               {:send, :mtrmod2, _},
               {:send, :lights, _},
               {:settings, %{state: :pending, pending: [:mtrmod1, :mtrmod2, :lights]}},
               {:hold, _}
             ] = actions

      assert reason =~ "boot:1"

      assert %{board_resets: 1, board_uptime_ms: 500, thrust_held: true} =
               BoardLink.status(l, 1_500)

      # its first pong is of the new life: no second reset
      assert {l, []} = BoardLink.event(l, pong(600), 1_600)
      {l, [{:settings, _}]} = BoardLink.event(l, echo("mtrmod1(100,100,100);"), 1_700)
      {l, [{:settings, _}, :release]} = BoardLink.event(l, echo("mtrmod2(100,100,100);"), 1_710)
      assert l.resets == 1
    end

    test "a board reset mid-dive stops the vehicle until they are confirmed again; a deadman recovery starts neutral" do
      {l, _} = BoardLink.opened(link(), 0)
      l = confirm_all(l, 5)
      {l, :send, []} = BoardLink.demand(l, false)
      {l, []} = BoardLink.event(l, pong(200_000), 100)
      {l, actions} = BoardLink.event(l, pong(900), 1_000)

      assert [
               {:board_reset, _},
               :neutral,
               {:send, :mtrmod1, _},
               {:send, :mtrmod2, _},
               {:settings, _},
               {:hold, _}
             ] = actions

      {l, :hold, []} = BoardLink.demand(l, false)
      {l, [{:settings, _}]} = BoardLink.event(l, echo("mtrmod1(100,100,100);"), 1_050)
      {l, [{:settings, _}, :release]} = BoardLink.event(l, echo("mtrmod2(100,100,100);"), 1_060)

      # the deadman (another board, up for 190 s): a pong more than 2 s after the last on its
      # clock
      {l, _} = BoardLink.opened(l, 2_000)
      l = confirm_all(l, 2_010)
      {l, :send, []} = BoardLink.demand(l, false)
      {l, []} = BoardLink.event(l, pong(190_000), 2_100)
      {l, actions} = BoardLink.event(l, pong(193_000), 5_100)

      # the board stopped on its own: it starts neutral, the standing demand is not resumed
      assert [
               {:deadman_recovery, _},
               :neutral,
               {:send, _, _},
               {:send, _, _},
               {:settings, _}
             ] = actions

      refute BoardLink.status(l, 5_100).thrust_held
      {l, :hold, [{:hold, _}]} = BoardLink.demand(l, false)
      assert BoardLink.status(l, 5_100).thrust_held
    end

    test "property: thrust other than neutral is sent only with both modifiers confirmed" do
      check(
        :proper_types.list(
          :proper_types.oneof([
            :proper_types.exactly(:open),
            :proper_types.exactly(:close),
            :proper_types.exactly(:boot),
            :proper_types.exactly(:tick),
            {:demand, :proper_types.boolean()},
            {:echo, :proper_types.oneof([:mtrmod1, :mtrmod2, :other])}
          ])
        ),
        fn steps ->
          {_l, _now, ok} =
            Enum.reduce(steps, {link(retry_ms: 50, attempts: 2), 0, true}, fn step,
                                                                              {l, now, ok} ->
              now = now + 30

              {l, verdict_ok} =
                case step do
                  :open ->
                    {elem(BoardLink.opened(l, now), 0), true}

                  :close ->
                    {BoardLink.closed(l), true}

                  :boot when l.up ->
                    {elem(BoardLink.event(l, :boot, now), 0), true}

                  :boot ->
                    {l, true}

                  :tick ->
                    {elem(BoardLink.tick(l, now), 0), true}

                  {:demand, neutral?} ->
                    {l, verdict, _} = BoardLink.demand(l, neutral?)
                    {l, neutral? or verdict == :hold or BoardLink.motors_confirmed?(l)}

                  {:echo, key} ->
                    command = Keyword.get(@mods, key, "ligt(1);")
                    {l, actions} = BoardLink.event(l, echo(command), now)
                    # a release comes only with both confirmed, and only for a held demand
                    released = :release in actions
                    {l, not released or (BoardLink.motors_confirmed?(l) and l.demanding)}
                end

              # a hold is never left standing once the modifiers are confirmed
              {l, now, ok and verdict_ok and not (l.held and BoardLink.motors_confirmed?(l))}
            end)

          ok
        end,
        500
      )
    end
  end
end
