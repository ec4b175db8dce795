defmodule NeptunusWeb.Socket.FlowControlTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.Socket.FlowControl

  doctest FlowControl

  defp new(limit \\ 3, backlog \\ 8),
    do: FlowControl.new(pilot_frames_per_s: limit, backlog: backlog)

  defp pilot(limit), do: new(limit) |> FlowControl.piloting("vehicle:a", true)

  defp run(flow, times), do: Enum.map_reduce(times, flow, &swap(FlowControl.frame(&2, &1)))
  defp swap({flow, verdict}), do: {verdict, flow}

  describe "frame budget" do
    test "up to the limit within one second, over after, fresh in the next second" do
      {verdicts, flow} = run(pilot(3), [100, 200, 300, 400, 1_099])
      assert verdicts == [:within, :within, :within, :over_budget, :over]
      assert FlowControl.priority(flow) == :normal
      {verdicts, flow} = run(flow, [1_100, 1_101, 1_102, 1_103])
      assert verdicts == [:within, :within, :within, :over_budget]
      assert FlowControl.priority(flow) == :normal
    end

    test "a steady client at the limit always stays within, at :high" do
      {verdicts, flow} = run(pilot(50), Enum.map(0..499, &(&1 * 20)))
      assert Enum.all?(verdicts, &(&1 == :within))
      assert FlowControl.priority(flow) == :high
    end

    test "a clock that goes back starts a new window instead of counting on" do
      {verdicts, _} = run(pilot(1), [5_000, 5_001, 10, 11])
      assert verdicts == [:within, :over_budget, :within, :over_budget]
    end

    test "frames of a connection that pilots nothing are not counted" do
      {verdicts, flow} = run(new(1), [0, 1, 2, 3])
      assert verdicts == [:within, :within, :within, :within]
      assert flow == new(1)
      assert FlowControl.priority(flow) == :low
    end

    test "the limits must be positive integers" do
      for bad <- [0, -1, 1.5, nil, "200"] do
        assert_raise ArgumentError, ~r/pilot_frames_per_s must be a positive integer/, fn ->
          FlowControl.new(pilot_frames_per_s: bad, backlog: 8)
        end

        assert_raise ArgumentError, ~r/backlog must be a positive integer/, fn ->
          FlowControl.new(pilot_frames_per_s: 200, backlog: bad)
        end
      end

      assert_raise ArgumentError, ~r/backlog is required/, fn ->
        FlowControl.new(pilot_frames_per_s: 200)
      end
    end
  end

  describe "priority" do
    test ":low while piloting nothing, :high while piloting any topic" do
      flow = new()
      assert FlowControl.priority(flow) == :low
      flow = FlowControl.piloting(flow, "vehicle:a", true)
      assert FlowControl.priority(flow) == :high
      flow = FlowControl.piloting(flow, "vehicle:b", true)
      flow = FlowControl.piloting(flow, "vehicle:a", false)
      assert FlowControl.priority(flow) == :high
      flow = FlowControl.piloting(flow, "vehicle:b", false)
      assert FlowControl.priority(flow) == :low
      # losing a topic not piloted changes nothing
      assert FlowControl.piloting(flow, "vehicle:c", false) == flow
    end

    test "a pilot over budget that loses control is :low, and :high on its next grant" do
      {_, flow} = run(pilot(1), [0, 1])
      assert FlowControl.priority(flow) == :normal
      flow = FlowControl.piloting(flow, "vehicle:a", false)
      assert FlowControl.priority(flow) == :low
      assert FlowControl.priority(FlowControl.piloting(flow, "vehicle:a", true)) == :high
    end

    test "over budget on one topic stays over when a second topic is granted" do
      {_, flow} = run(pilot(1), [0, 1])
      flow = FlowControl.piloting(flow, "vehicle:b", true)
      assert FlowControl.priority(flow) == :normal
    end
  end

  describe "shedding" do
    test "telemetry goes out below the backlog and is dropped from it on" do
      flow = new(3, 8)
      assert FlowControl.deliver?(flow, "telemetry", 0)
      assert FlowControl.deliver?(flow, "telemetry", 7)
      refute FlowControl.deliver?(flow, "telemetry", 8)
      refute FlowControl.deliver?(flow, "telemetry", 1_000)
    end

    test "every other event always goes out" do
      flow = new(3, 8)

      for event <- ~w(helm stopped presence_diff presence_state log control_granted),
          do: assert(FlowControl.deliver?(flow, event, 1_000))
    end

    test "drops are reported at the first, then at most once a minute with the count" do
      flow = new()
      {flow, report} = FlowControl.dropped(flow, 1_000)
      assert report == {:report, 1, nil}

      {flow, reports} =
        Enum.reduce(Enum.map(1..9, &(1_000 + &1 * 1_000)), {flow, []}, fn t, {flow, acc} ->
          {flow, report} = FlowControl.dropped(flow, t)
          {flow, [report | acc]}
        end)

      assert Enum.all?(reports, &is_nil/1)
      # the drop that reports counts itself: 9 silent ones since the last report, then it
      assert {flow, {:report, 10, 60_000}} = FlowControl.dropped(flow, 61_000)
      assert {_, nil} = FlowControl.dropped(flow, 61_001)
      assert {_, {:report, 1, 120_000}} = FlowControl.dropped(flow, 181_000)
    end

    test "a bad waiting count is refused" do
      assert_raise FunctionClauseError, fn -> FlowControl.deliver?(new(), "telemetry", -1) end
    end
  end

  describe "effects for the connection to carry out" do
    test "frames: nothing within budget, the warning and :normal over it, :high again after" do
      flow = pilot(2)
      {flow, []} = FlowControl.frame_received(flow, 0, "ada")
      {flow, []} = FlowControl.frame_received(flow, 10, "ada")

      {flow, [{:log, :warning, line}, {:priority, :normal}]} =
        FlowControl.frame_received(flow, 20, "ada")

      assert line =~ ~s(pilot "ada" sends more than 2 frames/s)
      # later frames of the same second: already said, already :normal
      {flow, []} = FlowControl.frame_received(flow, 30, "ada")
      assert {_flow, [{:priority, :high}]} = FlowControl.frame_received(flow, 1_000, "ada")
    end

    test "frames of an observer change nothing" do
      flow = new(1)
      assert FlowControl.frame_received(flow, 0, "olga") == {flow, []}
      assert FlowControl.frame_received(flow, 1, "olga") == {flow, []}
    end

    test "control: telemetry first on each granted topic, the priority only when it changes" do
      {flow, [{:prioritize, "vehicle:a", true}, {:priority, :high}]} =
        FlowControl.control_changed(new(), "vehicle:a", true)

      {flow, [{:prioritize, "vehicle:b", true}]} =
        FlowControl.control_changed(flow, "vehicle:b", true)

      {flow, [{:prioritize, "vehicle:a", false}]} =
        FlowControl.control_changed(flow, "vehicle:a", false)

      assert {_flow, [{:prioritize, "vehicle:b", false}, {:priority, :low}]} =
               FlowControl.control_changed(flow, "vehicle:b", false)
    end

    test "drops: a line at the first, then at most once a minute with the count" do
      {flow, [{:log, :info, first}]} = FlowControl.telemetry_dropped(new(), 0, "olga")
      assert first =~ "dropped 1 stale telemetry frame(s)"
      refute first =~ "in the last"

      flow =
        Enum.reduce(1..5, flow, fn t, flow ->
          assert {flow, []} = FlowControl.telemetry_dropped(flow, t * 1_000, "olga")
          flow
        end)

      assert {_flow, [{:log, :info, line}]} = FlowControl.telemetry_dropped(flow, 60_000, "olga")
      assert line =~ "dropped 6 stale telemetry frame(s) in the last 60 s"
    end
  end
end
