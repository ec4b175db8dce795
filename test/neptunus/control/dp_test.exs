defmodule Neptunus.Control.DPTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.{DP, Mission, PositionHold, VelocityLoop}

  doctest Neptunus.Control.Demand
  doctest Neptunus.Control.Guidance
  doctest Neptunus.Control.Survey
  doctest Neptunus.Control.Mission

  @pi :math.pi()

  defp pos(n, e, opts \\ []) do
    Map.merge(
      %{
        valid: true,
        reason: nil,
        north: n * 1.0,
        east: e * 1.0,
        velocity_north: 0.0,
        velocity_east: 0.0,
        velocity_measured: true,
        frame: :usbl,
        epoch: 1,
        shift: nil
      },
      Map.new(opts)
    )
  end

  defp invalid(reason),
    do: %{valid: false, reason: reason, north: nil, east: nil, epoch: 1, shift: nil}

  describe "velocity loop" do
    test "pushes towards the desired velocity; the integral learns a steady force" do
      loop = VelocityLoop.new()
      loop = VelocityLoop.step(loop, {0.1, 0.0}, {0.0, 0.0}, 0.02)
      {fn_, fe} = loop.output
      assert fn_ > 0 and fe == 0.0
      # a steady error: the integral grows, in its direction
      loop =
        Enum.reduce(1..500, loop, fn _, l ->
          VelocityLoop.step(l, {0.0, 0.0}, {0.0, -0.05}, 0.02)
        end)

      {_, ie} = loop.integral
      assert ie > 0.05
      # soft gains push less for the same error
      hard = VelocityLoop.step(VelocityLoop.new(), {0.1, 0.0}, {0.0, 0.0}, 0.02, true).output
      soft = VelocityLoop.step(VelocityLoop.new(), {0.1, 0.0}, {0.0, 0.0}, 0.02, false).output
      assert elem(soft, 0) < elem(hard, 0)
    end

    test "the output is limited as a vector; the integral does not wind up while saturated" do
      loop =
        Enum.reduce(1..1000, VelocityLoop.new(), fn _, l ->
          VelocityLoop.step(l, {3.0, 3.0}, {0.0, 0.0}, 0.02)
        end)

      {a, b} = loop.output
      assert_in_delta :math.sqrt(a * a + b * b), 1.0, 1.0e-9
      assert_in_delta a, b, 1.0e-9
      {ia, _} = loop.integral
      assert ia < 0.2
    end
  end

  describe "position hold, fully actuated" do
    test "pushes towards the target in the body frame and keeps the pilot's heading" do
      # facing east, the target is north: that is to port (negative sway)
      ph = PositionHold.new({1.0, 0.0}, @pi / 2, actuation: :full)
      ph = PositionHold.step(ph, {0.0, 0.0}, {0.0, 0.0}, @pi / 2, 0.02)
      assert ph.demand.sway < 0
      assert_in_delta ph.demand.surge, 0.0, 1.0e-12
      assert ph.heading_setpoint == @pi / 2
      assert_in_delta ph.distance, 1.0, 1.0e-12
    end

    test "a far target is approached at the limited speed: a jump makes no jump of thrust" do
      near =
        PositionHold.step(
          PositionHold.new({2.0, 0.0}, 0.0, actuation: :full),
          {0.0, 0.0},
          {0.0, 0.0},
          0.0,
          0.02
        )

      far =
        PositionHold.step(
          PositionHold.new({200.0, 0.0}, 0.0, actuation: :full),
          {0.0, 0.0},
          {0.0, 0.0},
          0.0,
          0.02
        )

      assert_in_delta near.demand.surge, far.demand.surge, 1.0e-12
    end
  end

  describe "position hold, three thrusters" do
    test "inside the radius: surge along the heading only; no sway" do
      ph = PositionHold.new({0.0, 0.0}, 0.0, actuation: :surge)
      ph = PositionHold.step(ph, {-0.5, 0.0}, {0.0, 0.0}, 0.0, 0.02)
      assert ph.phase == :hold and ph.demand.surge > 0 and ph.demand.sway == 0.0
      assert ph.heading_setpoint == 0.0
      # sideways offset: nothing along the heading to do (in still water)
      ph =
        PositionHold.step(
          PositionHold.new({0.0, 0.0}, 0.0, actuation: :surge),
          {0.0, 0.5},
          {0.0, 0.0},
          0.0,
          0.02
        )

      assert_in_delta ph.demand.surge, 0.0, 1.0e-12
    end

    test "beyond the radius it turns to the target and does not drive off while turning" do
      ph = PositionHold.new({0.0, 0.0}, 0.0, actuation: :surge, radius: 1.0)
      # 2 m east of the target, facing north: bearing back is west
      ph = PositionHold.step(ph, {0.0, 2.0}, {0.0, 0.0}, 0.0, 0.02)
      assert ph.phase == :return
      assert_in_delta ph.heading_setpoint, -@pi / 2, 1.0e-12
      assert_in_delta ph.demand.surge, 0.0, 1.0e-12
      # facing the target: it surges
      ph = PositionHold.step(ph, {0.0, 2.0}, {0.0, 0.0}, -@pi / 2, 0.02)
      assert ph.demand.surge > 0
      # back within half the radius: hold again
      ph = PositionHold.step(ph, {0.0, 0.3}, {0.0, 0.0}, -@pi / 2, 0.02)
      assert ph.phase == :hold
    end

    test "holding in a current it turns its bow into it" do
      # a steady push to the east (a current): the integral learns a westward force
      ph = PositionHold.new({0.0, 0.0}, 0.0, actuation: :surge)

      ph =
        Enum.reduce(1..600, ph, fn _, ph ->
          PositionHold.step(ph, {0.0, 0.3}, {0.0, 0.02}, 0.0, 0.02)
        end)

      assert ph.phase == :hold
      assert_in_delta ph.heading_setpoint, -@pi / 2, 0.2
    end
  end

  describe "DP" do
    test "engaged with a valid position it holds it; without one, depth and heading only" do
      dp = DP.new(pos(1, 2), 0.5, actuation: :surge)
      assert DP.target(dp) == {1.0, 2.0}
      assert DP.holds(dp) == ["depth", "heading", "position"]

      dp = DP.new(invalid("dvl: no bottom lock"), 0.5)
      assert DP.target(dp) == nil
      assert DP.holds(dp) == ["depth", "heading"]
      assert dp.waiting == "dvl: no bottom lock"
      assert DP.new(nil, 0.5).waiting == "no position source"
    end

    test "losing the position: no demand at once, the heading setpoint kept; back: holding again" do
      dp = DP.new(pos(0, 0), 0.0, actuation: :surge)
      {dp, []} = DP.step(dp, pos(3, 0), 0.0, 0.02)
      assert dp.hold.phase == :return
      heading = dp.heading_setpoint
      assert dp.demand.surge < 0 or dp.demand.surge == 0.0

      {dp, [{:notice, text}]} = DP.step(dp, invalid("dvl: disconnected"), 0.0, 0.02)
      assert text =~ "no valid position (dvl: disconnected)"
      assert dp.demand == %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
      assert dp.heading_setpoint == heading
      assert DP.holds(dp) == ["depth", "heading"]

      {dp, [{:notice, "dp: position valid again: holding position"}]} =
        DP.step(dp, pos(2.9, 0), 0.0, 0.02)

      assert DP.target(dp) == {0.0, 0.0}
    end

    test "a frame change with a shift moves the target; one without drops it" do
      dp = DP.new(pos(1, 1), 0.0)
      {dp, [{:notice, text}]} = DP.step(dp, pos(11, 1, epoch: 2, shift: {10.0, 0.0}), 0.0, 0.02)
      assert text =~ "targets moved with it (10.0 m north, 0.0 m east)"
      assert DP.target(dp) == {11.0, 1.0}

      {dp, [{:notice, text} | _]} = DP.step(dp, pos(0, 0, epoch: 5), 0.0, 0.02)
      assert text =~ "started again"
      # the next step holds where the vehicle is now
      assert DP.target(dp) == {0.0, 0.0}
    end

    test "a mission steers its legs, then holds at the last waypoint" do
      wps = [
        %{north: 5.0, east: 0.0, depth: 2.0, heading: nil, speed: 0.3, radius: 0.5},
        %{north: 5.0, east: 5.0, depth: 3.0, heading: nil, speed: 0.3, radius: 0.5}
      ]

      {:ok, dp} = DP.start_mission(DP.new(pos(0, 0), 0.0), wps, pos(0, 0))
      assert DP.mission_running?(dp) and DP.target(dp) == nil
      {dp, []} = DP.step(dp, pos(1, 0.2), 0.0, 0.02)
      assert dp.depth_setpoint == 2.0
      assert %{phase: "mission", mission: %{leg: 1, cross_track: ct}} = DP.public(dp)
      assert_in_delta ct, 0.2, 1.0e-9
      # steer back towards the line (to port)
      assert Neptunus.Control.Guidance.wrap_pi(dp.heading_setpoint) < 0

      {dp, events} = DP.step(dp, pos(4.8, 0.1), 0.0, 0.02)
      assert {:notice, "mission: waypoint 1 reached"} in events and :mission in events
      assert dp.mission.leg == 1 and dp.depth_setpoint == 3.0

      {dp, events} = DP.step(dp, pos(5.0, 4.9), @pi / 2, 0.02)
      assert {:notice, "mission: done, holding position at the last waypoint"} in events
      assert dp.mission.state == :done
      assert DP.target(dp) == {5.0, 5.0}
    end

    test "a mission needs a valid position; pause holds, resume goes on, abort holds here" do
      wp = [%{north: 5.0, east: 0.0, depth: 2.0, heading: nil, speed: 0.3, radius: 0.5}]

      assert {:error, "a mission needs a valid position: dvl: no bottom lock"} =
               DP.start_mission(DP.new(nil, 0.0), wp, invalid("dvl: no bottom lock"))

      {:ok, dp} = DP.start_mission(DP.new(pos(0, 0), 0.0), wp, pos(0, 0))
      {:ok, dp} = DP.pause_mission(dp, pos(1, 0))
      assert DP.target(dp) == {1.0, 0.0} and dp.mission.state == :paused
      assert {:error, "the mission is paused: nothing to pause"} = DP.pause_mission(dp, pos(1, 0))
      {:ok, dp} = DP.resume_mission(dp, pos(1, 0))
      assert DP.mission_running?(dp)
      {:ok, dp} = DP.abort_mission(dp, pos(2, 0))
      assert dp.mission == nil and DP.target(dp) == {2.0, 0.0}
      assert {:error, "no mission to abort"} = DP.abort_mission(dp, pos(2, 0))
      # without a position, abort holds depth and heading only
      {:ok, dp} = DP.start_mission(DP.new(pos(0, 0), 0.0), wp, pos(0, 0))
      {:ok, dp} = DP.abort_mission(dp, invalid("lost"))
      assert DP.target(dp) == nil
    end

    test "on the fully actuated vehicle a mission holds the waypoint's heading and sways" do
      wp = [%{north: 10.0, east: 0.0, depth: 2.0, heading: @pi / 2, speed: 0.3, radius: 0.5}]
      {:ok, dp} = DP.start_mission(DP.new(pos(0, 0), 0.0, actuation: :full), wp, pos(0, 0))
      {dp, []} = DP.step(dp, pos(2, 0), @pi / 2, 0.02)
      assert dp.heading_setpoint == @pi / 2
      # facing east, moving north is to port
      assert dp.demand.sway < 0
    end
  end

  describe "missions" do
    test "reachability: range, depth, repeated points" do
      wp = fn n, e, d ->
        %{north: n * 1.0, east: e * 1.0, depth: d * 1.0, heading: nil, speed: 0.3, radius: 0.5}
      end

      assert {:ok, _} = Mission.reachable([wp.(10, 0, 2)], {0.0, 0.0})

      assert Mission.reachable([wp.(10, 0, 150)], {0.0, 0.0}) ==
               {:error, "waypoint 1 is 150.0 m deep: beyond this vehicle's 100 m"}

      assert Mission.reachable([wp.(10, 0, 2), wp.(10, 0, 2)], {0.0, 0.0}) ==
               {:error, "waypoints 1 and 2 are the same point"}

      assert {:error, "waypoint 1 is 30.0 m away: beyond the 20 m a mission may reach"} =
               Mission.reachable([wp.(30, 0, 2)], {0.0, 0.0}, max_range: 20)
    end

    test "a waypoint passed is reached even when the vehicle was pushed off the line" do
      wps = [
        %{north: 5.0, east: 0.0, depth: 2.0, heading: nil, speed: 0.3, radius: 0.5},
        %{north: 5.0, east: 5.0, depth: 2.0, heading: nil, speed: 0.3, radius: 0.5}
      ]

      m = Mission.start(1, wps, {0.0, 0.0})
      {m, events} = Mission.step(m, {5.5, 2.0})
      assert events == [{:reached, 1}] and m.leg == 1
    end

    test "the final waypoint is approached slowing down" do
      m =
        Mission.start(
          1,
          [%{north: 10.0, east: 0.0, depth: 2.0, heading: nil, speed: 0.5, radius: 0.5}],
          {0.0, 0.0}
        )

      {far, _} = Mission.step(m, {0.0, 0.0})
      {near, _} = Mission.step(m, {9.0, 0.0})
      assert far.guidance.speed == 0.5
      assert near.guidance.speed < 0.5
    end

    test "shifting a mission moves its waypoints and its leg's start" do
      m =
        Mission.start(
          1,
          [%{north: 10.0, east: 0.0, depth: 2.0, heading: nil, speed: 0.5, radius: 0.5}],
          {0.0, 0.0}
        )

      m = Mission.shift(m, {1.0, -2.0})
      assert m.from == {1.0, -2.0}
      assert [%{north: 11.0, east: -2.0}] = m.waypoints
    end
  end
end
