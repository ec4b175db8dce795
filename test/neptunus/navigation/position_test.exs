defmodule Neptunus.Navigation.PositionTest do
  use ExUnit.Case, async: true

  alias Neptunus.Navigation.Position

  defp velocity(t, vx, vy \\ 0.0, extra \\ %{}) do
    {:velocity,
     Map.merge(
       %{
         t: t,
         vx: vx,
         vy: vy,
         fom: 0.005,
         covariance: nil,
         altitude: 10.0,
         valid: true,
         tracking: :bottom
       },
       extra
     )}
  end

  defp fix(t, n, e, std \\ 0.3, extra \\ %{}),
    do: {:fix, Map.merge(%{t: t, north: n, east: e, std: std, valid: true, frame: :usbl}, extra)}

  # heading `psi` known from 0 to `until` every 50 ms
  defp headed(pos, psi, from, until) do
    Enum.reduce(0..round((until - from) / 0.05), pos, fn k, pos ->
      Position.heading(pos, from + k * 0.05, psi, 0.01)
    end)
  end

  defp dvl_run(pos, from, until, vx, vy \\ 0.0) do
    Enum.reduce(0..round((until - from) / 0.125), pos, fn k, pos ->
      t = from + k * 0.125

      pos
      |> Position.heading(t, 0.0, 0.01)
      |> Position.report(:dvl, velocity(t, vx, vy), t + 0.03)
    end)
  end

  test "no source, no position — and it says so" do
    e = Position.estimate(Position.new(), 1.0)
    assert %{valid: false, reason: "no position source", north: nil, frame: nil} = e

    e = Position.estimate(Position.new(sources: [:dvl, :usbl]), 1.0)
    assert e.reason == "no position yet: dvl: no report yet; usbl: no report yet"
  end

  test "a DVL alone starts a local frame at the origin and dead-reckons" do
    pos = dvl_run(Position.new(sources: [:dvl]), 0.0, 10.0, 0.2)
    e = Position.estimate(pos, 10.0)
    assert e.valid and e.frame == :local and e.epoch == 1
    assert_in_delta e.north, 2.0, 0.05
    assert_in_delta e.velocity_north, 0.2, 0.01
    assert e.std_north < 0.1
  end

  test "DVL reports navigation cannot use are rejected and counted by reason" do
    pos = Position.new(sources: [:dvl]) |> headed(0.0, 0.0, 2.0)

    pos =
      Position.report(pos, :dvl, velocity(0.1, 0.1, 0.0, %{valid: false, altitude: 52.3}), 0.2)

    assert [%{state: "invalid", reason: "no bottom lock (altitude 52.3 m)"}] =
             Position.status(pos, 0.2).sources

    pos = Position.report(pos, :dvl, velocity(0.2, 5.0), 0.3)
    pos = Position.report(pos, :dvl, velocity(0.3, 0.1, 0.0, %{tracking: :water}), 0.4)
    [source] = Position.status(pos, 0.4).sources
    assert source.rejected == %{"no_lock" => 1, "out_of_range" => 1, "water_track" => 1}
    assert source.reason =~ "water-tracking"
    refute Position.estimate(pos, 0.4).valid

    # without a heading the velocity cannot be turned into north and east
    pos = Position.new() |> Position.report(:dvl, velocity(0.1, 0.1), 0.2)
    assert [%{rejected: %{"no_heading" => 1}}] = Position.status(pos, 0.2).sources
  end

  test "a DVL velocity jump is gated; a jump that persists is re-acquired" do
    pos = dvl_run(Position.new(), 0.0, 5.0, 0.0)
    # one wild velocity: rejected, counted, the estimate keeps still
    pos =
      pos |> Position.heading(5.1, 0.0, 0.01) |> Position.report(:dvl, velocity(5.1, 0.8), 5.1)

    assert [%{rejected: %{"innovation" => 1}}] = Position.status(pos, 5.1).sources
    assert_in_delta Position.estimate(pos, 5.1).velocity_north, 0.0, 0.01
    # the vehicle really was pushed: 0.8 m/s goes on, and is taken after five agreeing readings
    pos = dvl_run(pos, 5.225, 6.0, 0.8)
    [source] = Position.status(pos, 6.0).sources
    assert source.reacquired == 1
    assert_in_delta Position.estimate(pos, 6.0).velocity_north, 0.8, 0.02
  end

  test "USBL: an outlier is rejected; the frame starts on fixes and needs a second one" do
    pos = Position.new(sources: [:usbl]) |> Position.report(:usbl, fix(1.0, 5.0, 5.0), 1.5)
    e = Position.estimate(pos, 1.5)
    refute e.valid
    assert e.reason == "waiting for a second fix to agree with the first"
    pos = Position.report(pos, :usbl, fix(1.5, 5.1, 4.9), 2.0)
    assert %{valid: true, frame: :usbl} = Position.estimate(pos, 2.0)
    pos = Position.report(pos, :usbl, fix(2.0, 12.0, 5.0), 2.5)
    assert [%{rejected: %{"innovation" => 1}, reason: nil}] = Position.status(pos, 2.5).sources
    assert_in_delta Position.estimate(pos, 2.5).north, 5.05, 0.2
  end

  test "fixes that persist away from the estimate are re-acquired" do
    pos =
      Enum.reduce(0..9, Position.new(), fn k, pos ->
        Position.report(pos, :usbl, fix(k * 0.5, 0.0, 0.0, 0.2), k * 0.5 + 0.5)
      end)

    pos =
      Enum.reduce(10..12, pos, fn k, pos ->
        Position.report(pos, :usbl, fix(k * 0.5, 8.0, 0.0, 0.2), k * 0.5 + 0.5)
      end)

    [source] = Position.status(pos, 7.0).sources
    assert source.reacquired == 1
    assert source.rejected == %{"innovation" => 2}
    assert_in_delta Position.estimate(pos, 6.5).north, 8.0, 0.5
  end

  test "USBL fixes re-anchor a DVL's local frame: a new epoch with the shift between them" do
    pos = dvl_run(Position.new(), 0.0, 4.0, 0.5)
    before = Position.estimate(pos, 4.0)
    assert before.frame == :local
    # the topside says the vehicle is 10 m east of where dead reckoning put it
    pos =
      Enum.reduce([4.0, 4.5, 5.0], pos, fn t, pos ->
        pos
        |> dvl_run(t, t + 0.5, 0.5)
        |> Position.report(:usbl, fix(t, 0.5 * t, 10.0, 0.2), t + 0.5)
      end)

    e = Position.estimate(pos, 5.5)
    assert e.frame == :usbl and e.epoch == 2
    {dn, de} = e.shift
    assert_in_delta dn, 0.0, 0.3
    assert_in_delta de, 10.0, 0.3
    assert_in_delta e.east, 10.0, 0.3
  end

  test "a fix from another frame than the filter's is refused" do
    pos =
      Position.new()
      |> Position.report(:usbl, fix(1.0, 0.0, 0.0), 1.1)
      |> Position.report(:ardusub, fix(1.1, 3.0, 3.0, 0.5, %{frame: :ardusub}), 1.2)

    assert %{"frame" => 1} =
             Enum.find(Position.status(pos, 1.2).sources, &(&1.name == "ardusub")).rejected
  end

  test "links, garbage and silence are told as reasons; the estimate is lost after 30 s" do
    pos = dvl_run(Position.new(), 0.0, 2.0, 0.0)
    pos = Position.report(pos, :dvl, {:link, :up}, 2.0)
    pos = Position.report(pos, :dvl, {:link, {:down, "connection refused"}}, 2.1)
    [source] = Position.status(pos, 2.2).sources

    assert %{state: "invalid", reason: "disconnected (connection refused)", disconnects: 1} =
             source

    # still valid within the DVL's 2 s: position hold keeps going through a short gap
    assert Position.estimate(pos, 3.0).valid
    e = Position.estimate(pos, 4.2)
    refute e.valid
    assert e.reason =~ "dvl: disconnected (connection refused)"

    pos = Position.report(pos, :dvl, {:garbage, "invalid JSON at byte 3"}, 4.3)
    assert [%{garbage: 1}] = Position.status(pos, 4.3).sources
    assert Position.tick(pos, 20.0).filter.x != nil
    assert Position.tick(pos, 40.0).filter.x == nil
  end

  test "the status carries the ellipse, the depth and the last innovation" do
    pos = dvl_run(Position.new(), 0.0, 2.0, 0.1) |> Position.depth(3.5)
    status = Position.status(pos, 2.0)
    assert status.depth == 3.5
    assert %{major: a, minor: b} = status.ellipse
    assert a >= b
    assert [%{innovation: [_, _], dead_reckoning: nil, state: "valid"}] = status.sources
  end
end
