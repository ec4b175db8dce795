defmodule Neptunus.Fleet.OverviewTest do
  use ExUnit.Case, async: true

  alias Neptunus.Fleet.Overview

  defp entry(overrides) do
    Map.merge(
      %{
        id: "rov",
        board: :simulated,
        node: "v@10.0.0.2",
        status: "up",
        helm: "free",
        pilot: nil,
        link: %{up: true, reason: "ok"},
        depth: 1.23456,
        heading: 0.5004,
        recording: false
      },
      Map.new(overrides)
    )
  end

  describe "summarize/1" do
    test "rounds depth to cm and heading to mrad, keeps the rest" do
      assert [%{depth: 1.23, heading: 0.5, pilot: nil, node: "v@10.0.0.2", link: %{up: true}}] =
               Overview.summarize([entry([])])
    end

    test "an unreachable vehicle's nil depth and heading stay nil" do
      assert [%{depth: nil, heading: nil, status: "unreachable"}] =
               Overview.summarize([entry(status: "unreachable", depth: nil, heading: nil)])
    end

    test "noise below what a page shows gives the same summary" do
      assert Overview.summarize([entry(depth: 2.0001)]) ==
               Overview.summarize([entry(depth: 1.9999)])
    end
  end

  describe "decide/2" do
    test "the first summary is sent, a repeat is kept, a change is sent" do
      a = Overview.summarize([entry([])])
      b = Overview.summarize([entry(pilot: "ada", helm: "held")])
      assert {:send, ^a} = Overview.decide(nil, a)
      assert :keep = Overview.decide(a, a)
      assert {:send, ^b} = Overview.decide(a, b)
      assert {:send, []} = Overview.decide(a, [])
    end
  end
end
