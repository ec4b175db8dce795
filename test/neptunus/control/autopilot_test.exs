defmodule Neptunus.Control.AutopilotTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.Autopilot, as: AP

  @gains [kp: 2.0, ki: 0.5, kd: 1.0]
  @pi :math.pi()

  defp depth, do: AP.new(:depth, @gains)
  defp heading, do: AP.new(:heading, @gains)

  test "a new axis is off: no output, no setpoint" do
    ap = depth()
    refute AP.engaged?(ap) or AP.holding?(ap)
    assert AP.output(ap) == nil and AP.setpoint(ap) == nil and AP.public(ap) == nil
    assert AP.step(ap, 1.0, 0.0, 0.02) == ap
    assert AP.pilot(ap, true, 1.0, 0.0) == ap
  end

  describe "engage" do
    test "hold: at the current value, bumpless (no output at rest)" do
      ap = AP.engage(depth(), :hold, 3.2, 0.0, false)
      assert AP.holding?(ap) and AP.setpoint(ap) == 3.2
      assert AP.output(ap) == 0.0
      assert %{setpoint: 3.2, output: +0.0, overridden: false} = AP.public(ap)
      ap = AP.step(ap, 3.2, 0.0, 0.02)
      assert AP.output(ap) == 0.0
    end

    test "hold while descending: the derivative brakes at once, the integral starts at zero" do
      # depth rate +0.3 m/s (down): the output pushes up, and only by kd · rate
      ap = AP.engage(depth(), :hold, 2.0, 0.3, false)
      assert_in_delta AP.output(ap), -0.3, 1.0e-12
      assert ap.pid.integral == 0.0
    end

    test "a setpoint engages at that value, from where the vehicle is: no output jump" do
      ap = AP.engage(depth(), 5.0, 2.0, 0.0, false)
      assert AP.setpoint(ap) == 5.0
      # the reference starts at the vehicle (kp · 3 m would saturate at once)
      assert AP.output(ap) == 0.0
      assert %{reference: 2.0, reference_rate: +0.0} = AP.public(ap)
      # and moves towards the setpoint within its limits: the output grows with it
      ap = Enum.reduce(1..10, ap, fn _, ap -> AP.step(ap, 2.0, 0.0, 0.02) end)
      %{reference: r, reference_rate: v} = AP.public(ap)
      assert r > 2.0 and v > 0.0 and v <= 0.2 * 0.2 + 1.0e-12
      assert AP.output(ap) > 0.0 and AP.output(ap) < 1.0
    end

    test "changing the setpoint of an engaged axis keeps the learnt trim" do
      ap = AP.engage(depth(), :hold, 2.0, 0.0, false)
      ap = Enum.reduce(1..50, ap, fn _, ap -> AP.step(ap, 1.9, 0.0, 0.1) end)
      trim = ap.pid.integral
      assert trim > 0
      ap = AP.engage(ap, 2.5, 1.9, 0.0, false)
      assert ap.pid.integral == trim and AP.setpoint(ap) == 2.5
      # re-capturing with hold keeps it too
      ap = AP.engage(ap, :hold, 2.4, 0.0, false)
      assert ap.pid.integral == trim and AP.setpoint(ap) == 2.4
    end

    test "headings are normalised to [0, 2π)" do
      ap = AP.engage(heading(), -@pi / 2, 0.0, 0.0, false)
      assert_in_delta AP.setpoint(ap), 3 * @pi / 2, 1.0e-12
    end

    test "engaging while the pilot moves the axis starts overridden" do
      ap = AP.engage(depth(), :hold, 2.0, 0.3, true)
      assert AP.engaged?(ap) and not AP.holding?(ap)
      assert AP.output(ap) == nil
      assert %{overridden: true, output: +0.0} = AP.public(ap)
    end
  end

  describe "pilot override and re-capture" do
    setup do
      ap = AP.engage(depth(), 2.0, 2.0, 0.0, false)
      ap = Enum.reduce(1..20, ap, fn _, ap -> AP.step(ap, 1.95, 0.0, 0.1) end)
      {:ok, ap: ap}
    end

    test "pilot input overrides; the PID follows without integrating", %{ap: ap} do
      trim = ap.pid.integral
      ap = AP.pilot(ap, true, 1.95, 0.0)
      assert AP.output(ap) == nil and AP.engaged?(ap)
      ap = AP.step(ap, 2.5, 0.5, 0.1)
      assert ap.pid.integral == trim and ap.pid.last == 2.5
      # still overriding: more input changes nothing
      assert AP.pilot(ap, true, 2.6, 0.5) == ap
    end

    test "release re-captures at the value estimated then, keeping the trim", %{ap: ap} do
      trim = ap.pid.integral
      ap = ap |> AP.pilot(true, 1.95, 0.0) |> AP.step(3.0, 0.0, 0.1) |> AP.pilot(false, 3.1, 0.0)
      assert AP.holding?(ap) and AP.setpoint(ap) == 3.1
      assert ap.pid.integral == trim
      assert_in_delta AP.output(ap), trim, 1.0e-12
    end

    test "a setpoint commanded during the override is taken on release", %{ap: ap} do
      ap = ap |> AP.pilot(true, 1.95, 0.0) |> AP.engage(4.0, 2.2, 0.0, true)
      assert AP.setpoint(ap) == 4.0 and not AP.holding?(ap)
      assert %{setpoint: 4.0, overridden: true} = AP.public(ap)
      ap = AP.pilot(ap, false, 2.3, 0.0)
      assert AP.holding?(ap) and AP.setpoint(ap) == 4.0 and ap.pending == nil
    end

    test "hold during the override re-captures on release", %{ap: ap} do
      ap = ap |> AP.pilot(true, 1.95, 0.0) |> AP.engage(4.0, 2.2, 0.0, true)
      ap = AP.engage(ap, :hold, 2.2, 0.0, true)
      ap = AP.pilot(ap, false, 2.4, 0.0)
      assert AP.setpoint(ap) == 2.4
    end

    test "release without an estimate stays overridden", %{ap: ap} do
      ap = AP.pilot(ap, true, 1.95, 0.0)
      assert AP.pilot(ap, false, nil, nil) == ap
    end
  end

  test "disengage forgets setpoint and trim" do
    ap = AP.engage(depth(), :hold, 2.0, 0.0, false)
    ap = Enum.reduce(1..20, ap, fn _, ap -> AP.step(ap, 1.9, 0.0, 0.1) end)
    ap = AP.disengage(ap)
    refute AP.engaged?(ap)
    assert ap.pid.integral == 0.0 and ap.pid.last == nil and AP.public(ap) == nil
  end

  test "idle: zero output, the trim kept, no derivative memory" do
    ap = AP.engage(depth(), 2.0, 1.5, 0.0, false) |> AP.step(1.5, 0.0, 0.1)
    idle = AP.idle(ap)
    assert idle.output == 0.0 and idle.pid.integral == ap.pid.integral and idle.pid.last == nil
  end

  test "retarget moves an engaged setpoint only" do
    assert AP.retarget(depth(), 3.0) == depth()
    ap = AP.engage(heading(), 0.5, 0.5, 0.0, false) |> AP.retarget(-0.5)
    assert_in_delta AP.setpoint(ap), 2 * @pi - 0.5, 1.0e-12
  end

  test "heading hold turns the short way across north" do
    # held at 350°, the vehicle at 10°: turn to port (negative yaw)
    ap = AP.engage(heading(), 350 * @pi / 180, 10 * @pi / 180, 0.0, false)
    assert ap |> AP.step(10 * @pi / 180, 0.0, 0.02) |> AP.output() < 0
    ap = AP.engage(heading(), 10 * @pi / 180, 350 * @pi / 180, 0.0, false)
    assert ap |> AP.step(350 * @pi / 180, 0.0, 0.02) |> AP.output() > 0
  end
end
