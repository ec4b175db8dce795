defmodule NeptunusWeb.VideoSocket.FlowTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias NeptunusWeb.VideoSocket.Flow

  doctest Flow

  test "a new viewer, a new stream, a keyframe request: nothing before the next keyframe" do
    flow = Flow.new(backlog: 3)
    assert {flow, :drop} = Flow.frame(flow, false, 0)
    assert {flow, :send} = Flow.frame(flow, true, 0)
    assert {flow, :send} = Flow.frame(flow, false, 0)
    flow = Flow.await_keyframe(flow)
    assert {flow, :drop} = Flow.frame(flow, false, 0)
    assert {flow, :send} = Flow.frame(flow, true, 0)
    # waiting for a keyframe is not being behind: not counted, not reported
    assert flow.dropped == 0 and flow.sent == 3
  end

  test "behind: whole groups dropped until a keyframe finds the viewer caught up" do
    flow = Flow.new(backlog: 3)
    {flow, :send} = Flow.frame(flow, true, 0)
    {flow, :drop} = Flow.frame(flow, false, 3)
    # frames after it are dropped even once the backlog is gone: they need the dropped ones
    {flow, :drop} = Flow.frame(flow, false, 0)
    {flow, :drop} = Flow.frame(flow, true, 5)
    {flow, :drop} = Flow.frame(flow, false, 0)
    assert {flow, {:skipped, 4}} = Flow.frame(flow, true, 2)
    assert {_flow, :send} = Flow.frame(flow, false, 0)
  end

  test "every frame is sent or dropped; a decoder always starts at a keyframe; drops are told" do
    frames = :proper_types.list({:proper_types.boolean(), :proper_types.choose(0, 20)})

    check(frames, fn frames ->
      {flow, verdicts} =
        Enum.map_reduce(frames, Flow.new(backlog: 8), fn {key?, waiting}, flow ->
          {flow, verdict} = Flow.frame(flow, key?, waiting)
          {{key?, verdict}, flow}
        end)
        |> then(fn {verdicts, flow} -> {flow, verdicts} end)

      sent = Enum.reject(verdicts, &match?({_, :drop}, &1))
      told = for {_, {:skipped, n}} <- verdicts, do: n

      # a viewer (re)starts at a keyframe: the first frame sent, and every one after a skip
      starts_at_keyframes = match?([{true, _} | _], sent) or sent == []

      skips_at_keyframes =
        Enum.all?(verdicts, fn {key?, v} -> key? or not match?({:skipped, _}, v) end)

      flow.sent == length(sent) and Enum.sum(told) <= flow.dropped and starts_at_keyframes and
        skips_at_keyframes
    end)
  end
end
