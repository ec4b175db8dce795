defmodule Neptunus.Vehicle.Board.ReadingsTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Vehicle.Board.Backoff

  alias Neptunus.Vehicle.Board.Readings

  @nav "hdgd:90;deap:1.5;pitc:0;roll:0;yaw:90;fthr:0;\r\n"
  @status "vout:12.1;iout:0.5;time:1000;pres:1100;temp:10;\r\n"

  test "no sample until all six measurements are known; then one per navigation line" do
    r = Readings.new()
    {r, []} = Readings.feed(r, @nav, 0.1)
    {r, [s1]} = Readings.feed(r, @status, 0.2)
    {r, [s2, s3]} = Readings.feed(r, @nav <> @nav, 0.3)

    assert %{t: 0.2, sim: nil, measurement: m, board: board} = s1
    assert m.depth == 1.5 and m.voltage == 12.1 and m.current == 0.5
    assert_in_delta m.heading, :math.pi() / 2, 1.0e-12
    assert Map.keys(m) |> Enum.sort() == ~w(current depth heading pitch roll voltage)a
    assert board.temperature == 10.0 and board.board_time == 1.0 and board.pressure == 110_000.0
    assert s2.t == 0.3 and s3.t == 0.3
    assert r.counters.lines == 4 and r.counters.samples == 3
  end

  test "a line with only other fields does not make a sample" do
    {r, [_]} = Readings.feed(Readings.new(), @nav <> @status, 0.0)
    assert {_, []} = Readings.feed(r, "temp:11;fmem:1000;\n", 0.1)
  end

  test "wild points and garbage are counted and never reach a sample" do
    {r, [good]} = Readings.feed(Readings.new(), @nav <> @status, 0.0)

    {r, samples} =
      Readings.feed(r, "deap:150.0;vout:121;hdgd:pitc;iout:nan;junk;\n" <> <<0, 255, 10>>, 0.1)

    # deap 150 m is in range (the sensor could), so one sample, with the wild values left out
    assert [%{measurement: m}] = samples
    assert m.depth == 150.0
    assert m.voltage == good.measurement.voltage
    assert m.heading == good.measurement.heading
    assert m.current == good.measurement.current

    assert %{out_of_range: 1, key_as_value: 1, not_a_number: 1, malformed: 2} = r.counters
    assert Readings.wild_points(r) == 3
  end

  test "overlong lines are counted; unknown keys kept raw, bounded" do
    {r, []} =
      Readings.feed(Readings.new(16), String.duplicate("x", 40) <> "\nfmem:12;pong:3\n", 0.0)

    assert r.counters.overlong == 1
    assert r.raw == %{"fmem" => "12", "pong" => "3"}

    noise = Enum.map_join(1..100, fn i -> "k#{i}:v;\n" end)
    {r, []} = Readings.feed(Readings.new(), noise, 0.0)
    assert map_size(r.raw) == 64
  end

  test "reset starts a new session: partial line and values forgotten, counters kept" do
    {r, [_]} = Readings.feed(Readings.new(), @nav <> @status <> "deap:", 0.0)
    r = Readings.reset(r)
    assert r.measurement == %{} and r.lines.rest == ""
    assert {_, []} = Readings.feed(r, "2.0;\n" <> @nav, 0.1)
    assert r.counters.samples == 1
  end
end
