defmodule Neptunus.Navigation.WildPointsTest do
  use ExUnit.Case, async: true

  alias Neptunus.Navigation.WildPoints
  alias Neptunus.Vehicle.Board.OpenROV

  doctest WildPoints

  @limits WildPoints.limits()

  test "the ranges are the OpenROV parser's (a simulated board meets the same limits)" do
    for field <- [:depth, :voltage, :current] do
      assert {@limits[field].min, @limits[field].max} == OpenROV.Protocol.si_range(field)
    end

    assert {@limits.heading.min, @limits.heading.max} == OpenROV.Protocol.si_range(:heading)
    assert {@limits.pitch.min, @limits.pitch.max} == OpenROV.Protocol.si_range(:pitch)
    assert {@limits.roll.min, @limits.roll.max} == OpenROV.Protocol.si_range(:roll)
  end

  test "range: bounds included, a heading of 2π is 0, integers are floats, non-numbers refused" do
    assert WildPoints.range(@limits.depth, -10) == {:ok, -10.0}
    assert WildPoints.range(@limits.depth, 200.0) == {:ok, 200.0}
    assert WildPoints.range(@limits.depth, 200.0001) == {:error, :out_of_range}
    assert WildPoints.range(@limits.heading, 2 * :math.pi()) == {:ok, 0.0}
    assert WildPoints.range(@limits.heading, -0.01) == {:error, :out_of_range}
    assert WildPoints.range(@limits.voltage, 4.9) == {:error, :out_of_range}
    assert WildPoints.range(@limits.current, -0.1) == {:error, :out_of_range}
    assert WildPoints.range(@limits.pitch, 1.6) == {:error, :out_of_range}

    for bad <- [nil, "1.0", :pitc, [1.0], %{}] do
      assert WildPoints.range(@limits.depth, bad) == {:error, :not_a_number}
    end

    assert WildPoints.range(@limits.depth, 10 ** 400) == {:error, :out_of_range}
  end

  test "plausible: rate × elapsed time + tolerance, angles the short way round" do
    # 2 m/s × 0.05 s + 0.1 m
    assert WildPoints.plausible?(@limits.depth, {0.0, 1.0}, {0.05, 1.2})
    refute WildPoints.plausible?(@limits.depth, {0.0, 1.0}, {0.05, 1.21})
    refute WildPoints.plausible?(@limits.depth, {0.0, 1.0}, {0.05, 0.1})
    # after a long gap anything in range is plausible
    assert WildPoints.plausible?(@limits.depth, {0.0, 1.0}, {60.0, 50.0})
    # a clock that went back counts as no time
    refute WildPoints.plausible?(@limits.depth, {1.0, 1.0}, {0.0, 1.15})

    # 359° → 1° is 2°; 90° → 100° in 0.05 s is 0.17 rad ≤ 3 rad/s × 0.05 s + 0.1 rad
    assert WildPoints.plausible?(@limits.heading, {0.0, 6.27}, {0.05, 0.02})
    refute WildPoints.plausible?(@limits.heading, {0.0, 6.27}, {0.05, 0.3})
    assert WildPoints.plausible?(@limits.heading, {0.0, 1.57}, {0.05, 1.745})

    # the battery sags 1.5 V at once when the thrusters start: plausible
    assert WildPoints.plausible?(@limits.voltage, {0.0, 12.5}, {0.01, 11.0})
    refute WildPoints.plausible?(@limits.voltage, {0.0, 12.5}, {0.01, 5.5})
  end

  test "counts by field and reason, and re-acquisitions" do
    counts =
      WildPoints.new_counts()
      |> WildPoints.count(:depth, :rate_of_change)
      |> WildPoints.count(:depth, :out_of_range)
      |> WildPoints.count(:heading, :innovation)
      |> WildPoints.reacquired()

    assert counts.total == 3
    assert counts.by_field == %{depth: 2, heading: 1, roll: 0, pitch: 0, voltage: 0, current: 0}

    assert counts.by_reason == %{
             rate_of_change: 1,
             out_of_range: 1,
             innovation: 1,
             not_a_number: 0
           }

    assert counts.reacquired == 1
  end
end
