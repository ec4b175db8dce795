defmodule Neptunus.Control.DPTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.DP

  @gains [kp: 0.4, ki: 0.0, kd: 0.0]
  @pi :math.pi()

  defp dp(heading \\ 0.0), do: DP.new(%{x: 0.0, y: 0.0}, heading, gains: @gains)

  test "holds the target and heading it was engaged with" do
    dp = dp(-@pi / 2)
    assert dp.target == {0.0, 0.0} and dp.phase == :hold
    assert_in_delta dp.heading, 3 * @pi / 2, 1.0e-12
    assert DP.heading_setpoint(dp, %{x: 1.0, y: 1.0}) == dp.heading

    assert_raise ArgumentError, fn ->
      DP.new(%{x: 0, y: 0}, 0, gains: @gains, capture_radius: 3, return_radius: 2)
    end
  end

  describe "hold phase: along-track position only" do
    test "behind the target (facing it): surge forward; ahead of it: surge back" do
      # facing north (x), 1 m south of the target
      dp = DP.step(dp(), %{x: -1.0, y: 0.0}, 0.0, 0.02)
      assert_in_delta dp.output, 0.4, 1.0e-12
      assert dp.phase == :hold
      assert_in_delta dp.distance, 1.0, 1.0e-12
      dp = DP.step(dp(), %{x: 1.0, y: 0.0}, 0.0, 0.02)
      assert_in_delta dp.output, -0.4, 1.0e-12
    end

    test "a sideways offset is not corrected (no sway thruster)" do
      dp = DP.step(dp(), %{x: 0.0, y: 1.5}, 0.0, 0.02)
      assert_in_delta dp.output, 0.0, 1.0e-12
      assert dp.phase == :hold
    end

    test "the along-track error follows the vehicle's heading" do
      # facing east, the target 1 m to the east (vehicle at y = -1)
      dp = DP.step(dp(@pi / 2), %{x: 0.0, y: -1.0}, @pi / 2, 0.02)
      assert_in_delta dp.output, 0.4, 1.0e-9
    end

    test "the rate comes from successive positions (damping)" do
      dp = DP.new(%{x: 0.0, y: 0.0}, 0.0, gains: [kp: 0.0, ki: 0.0, kd: 1.0])
      dp = DP.step(dp, %{x: -1.0, y: 0.0}, 0.0, 0.02)
      # moving north (towards the target) at 0.5 m/s: braking
      dp = DP.step(dp, %{x: -0.99, y: 0.0}, 0.0, 0.02)
      assert_in_delta dp.output, -0.5, 1.0e-9
    end
  end

  describe "return phase" do
    test "beyond the return radius it steers to the target, and holds again within capture" do
      dp = DP.step(dp(), %{x: 0.0, y: 2.5}, 0.0, 0.02)
      assert dp.phase == :return
      # the target is to the west: bearing 270°
      assert_in_delta DP.heading_setpoint(dp, %{x: 0.0, y: 2.5}), 3 * @pi / 2, 1.0e-9
      # still facing north: cos(90°) = 0, no surge yet
      assert_in_delta dp.output, 0.0, 1.0e-9
      # facing the target: surge on the distance
      dp = DP.step(dp, %{x: 0.0, y: 2.4}, 3 * @pi / 2, 0.02)
      assert dp.output > 0.5
      # between the radii it keeps returning
      dp = DP.step(dp, %{x: 0.0, y: 1.0}, 3 * @pi / 2, 0.02)
      assert dp.phase == :return
      dp = DP.step(dp, %{x: 0.0, y: 0.2}, 3 * @pi / 2, 0.02)
      assert dp.phase == :hold
      assert DP.heading_setpoint(dp, %{x: 0.0, y: 0.2}) == 0.0
    end

    test "facing away it does not drive off" do
      dp = DP.step(dp(), %{x: 3.0, y: 0.0}, 0.0, 0.02)
      assert dp.phase == :return and dp.output == 0.0
    end
  end

  test "set_heading changes the held heading" do
    dp = dp() |> DP.set_heading(7.0)
    assert_in_delta dp.heading, 7.0 - 2 * @pi, 1.0e-12
  end

  test "public: what telemetry shows" do
    dp = DP.step(dp(), %{x: -1.0, y: 0.0}, 0.0, 0.02)

    assert %{x: +0.0, y: +0.0, heading: +0.0, phase: "hold", distance: 1.0, output: out} =
             DP.public(dp)

    assert_in_delta out, 0.4, 1.0e-12
  end
end
