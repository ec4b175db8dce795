defmodule Neptunus.AllocationTest do
  use ExUnit.Case, async: true

  alias Neptunus.Allocation

  doctest Neptunus.Allocation

  defp motion(x, z, m), do: %{surge: x, heave: z, yaw: m}

  describe "motion/2 (eq. 9.3)" do
    test "pure surge drives both side thrusters equally" do
      assert Allocation.motion(motion(0.6, 0.0, 0.0), 1.0) ==
               %{port: 0.6, vertical: 0.0, starboard: 0.6}
    end

    test "pure heave drives only the vertical thruster" do
      assert Allocation.motion(motion(0.0, -0.7, 0.0), 1.0) ==
               %{port: 0.0, vertical: -0.7, starboard: 0.0}
    end

    test "pure yaw drives the side thrusters in opposition, port forward for +M" do
      assert Allocation.motion(motion(0.0, 0.0, 0.4), 1.0) ==
               %{port: 0.4, vertical: 0.0, starboard: -0.4}

      assert Allocation.motion(motion(0.0, 0.0, -0.4), 1.0) ==
               %{port: -0.4, vertical: 0.0, starboard: 0.4}
    end

    test "surge plus yaw saturates the port thruster" do
      assert Allocation.motion(motion(1.0, 0.0, 1.0), 1.0) ==
               %{port: 1.0, vertical: 0.0, starboard: 0.0}

      assert Allocation.motion(motion(0.8, 0.0, 0.5), 1.0) ==
               %{port: 1.0, vertical: 0.0, starboard: 0.30000000000000004}
    end

    test "negative saturation" do
      assert Allocation.motion(motion(-1.0, -1.0, -1.0), 1.0) ==
               %{port: -1.0, vertical: -1.0, starboard: 0.0}

      assert Allocation.motion(motion(-1.0, 0.0, 1.0), 1.0) ==
               %{port: 0.0, vertical: 0.0, starboard: -1.0}
    end

    test "gain 0 gives neutral" do
      assert Allocation.motion(motion(1.0, -1.0, 0.5), 0.0) == Allocation.neutral()
      assert Allocation.motion(motion(-1.0, 1.0, -0.5), 0) == Allocation.neutral()
    end

    test "gain 0.5 scales every output" do
      assert Allocation.motion(motion(1.0, 1.0, 0.0), 0.5) ==
               %{port: 0.5, vertical: 0.5, starboard: 0.5}

      assert Allocation.motion(motion(0.5, -0.5, 0.5), 0.5) ==
               %{port: 0.5, vertical: -0.25, starboard: 0.0}
    end

    test "gain 0.5 with X = M = 1 is exactly at the saturation limit" do
      assert Allocation.motion(motion(1.0, 0.0, 1.0), 0.5) ==
               %{port: 1.0, vertical: 0.0, starboard: 0.0}
    end

    test "integer inputs still give floats" do
      result = Allocation.motion(motion(1, 0, 0), 1)
      assert result == %{port: 1.0, vertical: 0.0, starboard: 1.0}
      assert Enum.all?(Map.values(result), &is_float/1)
    end

    test "never returns -0.0" do
      %{port: p, vertical: v, starboard: s} = Allocation.motion(motion(-0.0, -0.0, 0.0), 1.0)
      for value <- [p, v, s], do: assert(<<value::float>> == <<0.0::float>>)
    end

    test "out-of-range inputs are still clamped to [-1, 1]" do
      assert Allocation.motion(motion(3.0, -5.0, 0.0), 2.0) ==
               %{port: 1.0, vertical: -1.0, starboard: 1.0}
    end
  end

  test "neutral/0 is all zero floats" do
    assert Allocation.neutral() == %{port: 0.0, vertical: 0.0, starboard: 0.0}
  end

  describe "to_us/1" do
    test "endpoints and neutral" do
      assert Allocation.to_us(-1.0) == 1000
      assert Allocation.to_us(0.0) == 1500
      assert Allocation.to_us(1.0) == 2000
      assert Allocation.to_us(-1) == 1000
      assert Allocation.to_us(0) == 1500
      assert Allocation.to_us(1) == 2000
    end

    test "linear in between" do
      assert Allocation.to_us(0.5) == 1750
      assert Allocation.to_us(-0.5) == 1250
      assert Allocation.to_us(0.1) == 1550
    end

    test "rounds to the nearest microsecond" do
      assert Allocation.to_us(0.0012) == 1501
      assert Allocation.to_us(0.0008) == 1500
      assert Allocation.to_us(-0.0012) == 1499
      assert Allocation.to_us(0.0009) == 1500
      assert is_integer(Allocation.to_us(0.123456))
    end

    test "clamps out-of-range values" do
      assert Allocation.to_us(1.5) == 2000
      assert Allocation.to_us(-7) == 1000
      assert Allocation.to_us(1.0e9) == 2000
    end
  end

  test "thrusters_to_us/1 maps each thruster" do
    assert Allocation.thrusters_to_us(%{port: -1.0, vertical: 0.0, starboard: 0.5}) ==
             %{port: 1000, vertical: 1500, starboard: 1750}

    assert Allocation.thrusters_to_us(Allocation.neutral()) ==
             %{port: 1500, vertical: 1500, starboard: 1500}
  end

  describe "properties" do
    test "for any inputs in range, outputs are floats in [-1, 1] and PWM in 1000..2000" do
      unit = :proper_types.float(-1.0, 1.0)
      gen = {unit, unit, unit, :proper_types.float(0.0, 1.0)}

      property =
        :proper.forall(gen, fn {x, z, m, k} ->
          thrusters = Allocation.motion(motion(x, z, m), k)
          pwm = Allocation.thrusters_to_us(thrusters)

          Enum.all?(Map.values(thrusters), &(is_float(&1) and &1 >= -1.0 and &1 <= 1.0)) and
            Enum.all?(Map.values(pwm), &(is_integer(&1) and &1 in 1000..2000))
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end

    test "unsaturated allocation is eq. 9.3 exactly" do
      unit = :proper_types.float(-0.5, 0.5)
      gen = {unit, :proper_types.float(-1.0, 1.0), unit, :proper_types.float(0.0, 1.0)}

      property =
        :proper.forall(gen, fn {x, z, m, k} ->
          Allocation.motion(motion(x, z, m), k) ==
            %{port: k * (x + m) + 0.0, vertical: k * z + 0.0, starboard: k * (x - m) + 0.0}
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end

    test "to_us is monotonic and clamped for any number" do
      gen = {:proper_types.float(), :proper_types.float()}

      property =
        :proper.forall(gen, fn {a, b} ->
          {lo, hi} = {min(a, b), max(a, b)}
          us_lo = Allocation.to_us(lo)
          us_hi = Allocation.to_us(hi)
          us_lo in 1000..2000 and us_hi in 1000..2000 and us_lo <= us_hi
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end
  end
end
