defmodule Neptunus.PIDTest do
  use ExUnit.Case, async: true

  alias Neptunus.PID

  doctest Neptunus.PID

  @pi :math.pi()

  defp pid(opts \\ []), do: PID.new(Keyword.merge([kp: 1.0, ki: 0.0, kd: 0.0], opts))

  # runs `n` steps at a constant measurement, returning the outputs and the PID
  defp run(pid, setpoint, measured, n, dt \\ 0.02) do
    Enum.map_reduce(1..n, pid, fn _, pid -> PID.update(pid, setpoint, measured, dt) end)
  end

  describe "new/1" do
    test "gains must be numbers >= 0 and the limits ordered" do
      assert %PID{kp: 2.0, ki: +0.0, kd: 1.0, min: -1.0, max: 1.0, wrap: false} =
               PID.new(kp: 2, ki: 0, kd: 1)

      assert_raise ArgumentError, ~r/kp must be a number >= 0/, fn ->
        PID.new(kp: -1, ki: 0, kd: 0)
      end

      assert_raise ArgumentError, ~r/ki must be a number >= 0/, fn -> PID.new(kp: 1, kd: 0) end
      assert_raise ArgumentError, ~r/min must be < max/, fn -> pid(min: 1, max: 1) end
    end
  end

  describe "update/5" do
    test "proportional: kp times the error, clamped to the limits" do
      assert {0.5, _} = PID.update(pid(kp: 2.0), 1.0, 0.75, 0.02)
      assert {-0.5, _} = PID.update(pid(kp: 2.0), 0.75, 1.0, 0.02)
      assert {1.0, _} = PID.update(pid(kp: 10.0), 1.0, 0.0, 0.02)
      assert {-1.0, _} = PID.update(pid(kp: 10.0), -1.0, 0.0, 0.02)
      assert {0.3, _} = PID.update(pid(kp: 10.0, min: -0.3, max: 0.3), 1.0, 0.0, 0.02)
    end

    test "integral: ki times the integrated error, in output units" do
      {outputs, pid} = run(pid(kp: 0.0, ki: 0.5), 1.0, 0.0, 10, 0.1)
      # 0.5 · 1 · 0.1 per step
      assert_in_delta List.last(outputs), 0.5, 1.0e-12
      assert_in_delta pid.integral, 0.5, 1.0e-12
    end

    test "derivative on the measurement: a setpoint step gives no kick" do
      p = pid(kp: 0.0, kd: 1.0) |> PID.engage(0.0)
      {u1, p} = PID.update(p, 0.0, 0.0, 0.02)
      {u2, _} = PID.update(p, 5.0, 0.0, 0.02)
      assert u1 == 0.0 and u2 == 0.0
    end

    test "derivative: from the measured rate when given, else from successive measurements" do
      p = pid(kp: 0.0, kd: 0.5)
      # the first step has nothing to differentiate
      {u0, p} = PID.update(p, 0.0, 0.0, 0.02)
      assert u0 == 0.0
      # moving up by 0.01 in 0.02 s: 0.5 m/s → −kd · 0.5
      {u1, p} = PID.update(p, 0.0, 0.01, 0.02)
      assert_in_delta u1, -0.25, 1.0e-12
      # a given rate wins
      {u2, _} = PID.update(p, 0.0, 0.02, 0.02, -0.2)
      assert_in_delta u2, 0.1, 1.0e-12
    end

    test "dt = 0 computes the output without integrating (capture)" do
      p = pid(kp: 1.0, ki: 1.0, kd: 1.0) |> PID.engage(0.0, 0.2)
      {u, p2} = PID.update(p, 0.1, 0.0, 0.0)
      assert_in_delta u, 0.3, 1.0e-12
      assert p2.integral == p.integral
      {u, _} = PID.update(p, 0.0, 0.0, 0.0, 0.1)
      assert_in_delta u, 0.1, 1.0e-12
    end

    test "anti-windup: no integration while saturated the way the error pushes" do
      p = pid(kp: 1.0, ki: 1.0)
      # a large error for a long time: the output saturates, the integral stays small
      {outputs, p} = run(p, 10.0, 0.0, 500, 0.02)
      assert Enum.all?(outputs, &(&1 == 1.0))
      assert p.integral <= 1.0
      # as soon as the error reverses the output leaves the limit (no wound-up integral)
      {u, _} = PID.update(p, 0.0, 0.5, 0.02)
      assert u < 1.0
    end

    test "anti-windup: the integral itself is clamped to the output limits" do
      p = pid(kp: 0.0, ki: 10.0)
      {_, p} = run(p, 1.0, 0.0, 100)
      assert p.integral == 1.0
      {_, p} = run(p, -1.0, 0.0, 100)
      assert p.integral == -1.0
    end
  end

  describe "engage/3 and track/2" do
    test "bumpless: the first output at zero error and rest is the output given" do
      p = pid(kp: 3.0, ki: 0.2, kd: 1.0) |> PID.engage(1.5, -0.4)
      assert {-0.4, _} = PID.update(p, 1.5, 1.5, 0.02)
      # clamped to the limits
      assert PID.engage(p, 0.0, 7.0).integral == 1.0
    end

    test "track follows the measurement and keeps the integral" do
      p = pid(kd: 1.0) |> PID.engage(0.0, 0.3) |> PID.track(2.0)
      assert p.last == 2.0 and p.integral == 0.3
      # no derivative spike from the jump to 2.0
      {u, _} = PID.update(p, 2.0, 2.0, 0.02)
      assert_in_delta u, 0.3, 1.0e-12
    end
  end

  describe "angles" do
    test "the error is wrapped to [-π, π): the short way across north" do
      p = pid(kp: 1.0, wrap: true)
      assert_in_delta PID.error(p, 0.1, 2 * @pi - 0.1), 0.2, 1.0e-12
      assert_in_delta PID.error(p, 2 * @pi - 0.1, 0.1), -0.2, 1.0e-12
      assert_in_delta PID.error(p, @pi / 2, 3 * @pi / 2), -@pi, 1.0e-12
      assert PID.error(pid(), 0.1, 2 * @pi - 0.1) < -6
    end

    test "finite differences are wrapped too" do
      p = pid(kp: 0.0, kd: 1.0, wrap: true) |> PID.engage(2 * @pi - 0.01)
      {u, _} = PID.update(p, 0.0, 0.01, 0.02)
      # +0.02 rad in 0.02 s = 1 rad/s, not −314 rad/s
      assert_in_delta u, -1.0, 1.0e-9
    end

    test "wrap_pi and wrap_2pi" do
      for a <- [-10.0, -@pi, -1.0, 0.0, 1.0, @pi, 7.0, 100.0] do
        w = PID.wrap_pi(a)
        assert w >= -@pi and w < @pi
        assert_in_delta :math.sin(w), :math.sin(a), 1.0e-9
        assert_in_delta :math.cos(w), :math.cos(a), 1.0e-9

        h = PID.wrap_2pi(a)
        assert h >= 0 and h < 2 * @pi
        assert_in_delta :math.sin(h), :math.sin(a), 1.0e-9
      end

      assert PID.wrap_pi(@pi) == -@pi
      assert PID.wrap_2pi(2 * @pi) == 0.0
    end
  end

  test "a closed loop settles a first-order plant without steady-state error" do
    # ẋ = u − 0.5 (a constant disturbance the integral must learn)
    p = PID.new(kp: 2.0, ki: 1.0, kd: 0.0)

    {x, _} =
      Enum.reduce(1..2_000, {0.0, p}, fn _, {x, p} ->
        {u, p} = PID.update(p, 1.0, x, 0.01)
        {x + (u - 0.5) * 0.01, p}
      end)

    assert_in_delta x, 1.0, 1.0e-3
  end
end
