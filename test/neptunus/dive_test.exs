defmodule Neptunus.DiveTest do
  use ExUnit.Case, async: true

  alias Neptunus.Dive
  alias Neptunus.Dive.{Boundary, Summary, Video}

  doctest Neptunus.Dive
  doctest Neptunus.Dive.Summary
  doctest Neptunus.Dive.Boundary
  doctest Neptunus.Dive.Video
  doctest Neptunus.Dive.ASS
  doctest Neptunus.Dive.Matroska
  doctest Neptunus.Dive.Export
  doctest Neptunus.Vehicle.Recorder.Video
  doctest NeptunusWeb.WireSchema.JSONSchema

  @moduletag :tmp_dir

  describe "names" do
    test "only dive folders and recordings from before dives, never a path" do
      for {vehicle, name} <- [
            {"rov", "20261122-130509Z-1/x"},
            {"rov", ".."},
            {"rov", "20261122-130509Z-1\n"},
            {"../rov", "20261122-130509Z-1"},
            {"rov", "summary.json"},
            {"rov", "snapshots"},
            {nil, "20261122-130509Z-1"}
          ] do
        refute Dive.valid?(vehicle, name), "#{inspect({vehicle, name})} accepted"
      end

      assert Dive.legacy?("20261122-130509Z-3.log")
      refute Dive.legacy?("20261122-130509Z-3")
    end
  end

  describe "Summary" do
    test "a handover counts each pilot once, in order; nothing else changes the pilots" do
      s =
        [
          {1, "helm", %{"state" => "piloted", "pilot" => %{"name" => "bo"}}},
          {2, "helm", %{state: "piloted", pilot: %{name: "ada"}}},
          {3, "helm", %{state: "free", pilot: nil}},
          {4, "helm", %{state: "piloted", pilot: %{name: "bo"}}},
          {5, "log", %{message: "x"}}
        ]
        |> Enum.reduce(Summary.new(0), &Summary.add(&2, &1))

      assert s.pilots == ["bo", "ada"]
      assert %{duration_ms: 5, closed: false, max_depth: nil} = Summary.to_map(s, false)
    end

    test "an entry that is not one changes nothing" do
      s = Summary.new(10)
      assert Summary.add(s, {:unreadable, "p", 3}) == s
      assert Summary.add(s, {1, "telemetry", :not_a_map}) == s
    end
  end

  describe "Boundary" do
    test "no gap (0) or nil: one dive per recorder run" do
      b = Boundary.new(0, 0)
      piloted = %{state: "piloted", pilot: %{name: "a"}}

      {:same, b} = Boundary.event(b, {1, "helm", piloted})
      {:same, b} = Boundary.event(b, {2, "helm", %{state: "free", pilot: nil}})
      assert {:same, _} = Boundary.event(b, {100_000_000, "helm", piloted})
    end

    test "the time before a dive's first pilot stays in that dive" do
      b = Boundary.new(1_000, 0)

      assert {:same, %{piloted: true}} =
               Boundary.event(b, {1_000_000, "helm", %{state: "piloted", pilot: %{name: "a"}}})
    end

    test "a request while piloted is still piloted; a takeover too" do
      b = Boundary.new(1_000, 0)
      {:same, b} = Boundary.event(b, {1, "helm", %{state: "piloted", pilot: %{name: "a"}}})
      {:same, b} = Boundary.event(b, {2, "helm", %{state: "requested", pilot: %{name: "a"}}})
      {:same, b} = Boundary.event(b, {5_000, "helm", %{state: "takeover", pilot: %{name: "a"}}})
      assert b.free_since == nil
    end
  end

  describe "video index" do
    test "records whose frames are not in the data file, or out of order, are left out", %{
      tmp_dir: dir
    } do
      {data, index} = Video.names(1, "h264")
      File.write!(Path.join(dir, data), :binary.copy(<<1>>, 100))

      records =
        [
          %{at_us: 10, capture_us: 0, offset: 0, size: 40, keyframe: true},
          %{at_us: 20, capture_us: 0, offset: 40, size: 40, keyframe: false},
          %{at_us: 15, capture_us: 0, offset: 80, size: 10, keyframe: false},
          %{at_us: 30, capture_us: 0, offset: 80, size: 40, keyframe: false}
        ]
        |> Enum.map(&Video.record/1)

      File.write!(Path.join(dir, index), [Video.header(%{codec: "h264"}) | records])
      assert %{frames: [%{at_us: 10}, %{at_us: 20}], problems: [problem]} = Video.read(dir, 1)
      assert problem == "segment 1: 2 frames not (all) in 000001.h264"
    end

    test "an index that is not one, or missing: said, no frames", %{tmp_dir: dir} do
      File.write!(Path.join(dir, "000001.idx"), "garbage")
      File.write!(Path.join(dir, "000002.h264"), "x")

      assert [
               %{
                 n: 1,
                 frames: [],
                 problems: ["segment 1: not a video index (no NEPVIDX1 header)"]
               },
               %{n: 2, frames: [], problems: ["segment 2: no index (000002.idx is missing)"]}
             ] = Video.segments(dir)
    end
  end
end
