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

  describe "validate_motion/1" do
    test "accepts floats in range" do
      assert Allocation.validate_motion(%{"surge" => 0.5, "heave" => -1.0, "yaw" => 1.0}) ==
               {:ok, %{surge: 0.5, heave: -1.0, yaw: 1.0}}
    end

    test "accepts integers and returns floats" do
      assert {:ok, motion} =
               Allocation.validate_motion(%{"surge" => 1, "heave" => 0, "yaw" => -1})

      assert motion == %{surge: 1.0, heave: 0.0, yaw: -1.0}
      assert Enum.all?(Map.values(motion), &is_float/1)
    end

    test "ignores a mode key" do
      assert Allocation.validate_motion(%{
               "mode" => "motion",
               "surge" => 0,
               "heave" => 0,
               "yaw" => 0
             }) == {:ok, %{surge: 0.0, heave: 0.0, yaw: 0.0}}
    end

    test "rejects strings" do
      assert Allocation.validate_motion(%{"surge" => "abc", "heave" => 0, "yaw" => 0}) ==
               {:error, "surge must be a number in [-1, 1], got \"abc\""}

      assert Allocation.validate_motion(%{"surge" => 0, "heave" => "0.5", "yaw" => 0}) ==
               {:error, "heave must be a number in [-1, 1], got \"0.5\""}
    end

    test "rejects nil, booleans, lists and maps" do
      assert Allocation.validate_motion(%{"surge" => 0, "heave" => 0, "yaw" => nil}) ==
               {:error, "yaw must be a number in [-1, 1], got nil"}

      assert Allocation.validate_motion(%{"surge" => true, "heave" => 0, "yaw" => 0}) ==
               {:error, "surge must be a number in [-1, 1], got true"}

      assert {:error, "heave must be a number" <> _} =
               Allocation.validate_motion(%{"surge" => 0, "heave" => [1], "yaw" => 0})

      assert {:error, "yaw must be a number" <> _} =
               Allocation.validate_motion(%{"surge" => 0, "heave" => 0, "yaw" => %{}})
    end

    test "rejects values out of range" do
      assert Allocation.validate_motion(%{"surge" => 1.01, "heave" => 0, "yaw" => 0}) ==
               {:error, "surge must be a number in [-1, 1], got 1.01"}

      assert Allocation.validate_motion(%{"surge" => 0, "heave" => -2, "yaw" => 0}) ==
               {:error, "heave must be a number in [-1, 1], got -2"}

      assert Allocation.validate_motion(%{"surge" => 0, "heave" => 0, "yaw" => 1.0e308}) ==
               {:error, "yaw must be a number in [-1, 1], got 1.0e308"}
    end

    test "accepts the exact bounds" do
      assert {:ok, _} = Allocation.validate_motion(%{"surge" => -1, "heave" => 1, "yaw" => -1.0})
    end

    test "reports missing fields" do
      assert Allocation.validate_motion(%{"surge" => 0, "yaw" => 0}) ==
               {:error, "missing field: heave"}

      assert Allocation.validate_motion(%{"heave" => 0, "yaw" => 0}) ==
               {:error, "missing field: surge"}

      assert Allocation.validate_motion(%{"surge" => 0, "heave" => 0}) ==
               {:error, "missing field: yaw"}

      assert Allocation.validate_motion(%{}) == {:error, "missing field: surge"}
      assert Allocation.validate_motion(%{"mode" => "motion"}) == {:error, "missing field: surge"}
    end

    test "reports unknown fields" do
      assert Allocation.validate_motion(%{"surge" => 0, "heave" => 0, "yaw" => 0, "foo" => 1}) ==
               {:error, "unknown field: foo"}

      assert Allocation.validate_motion(%{"surge" => 0, "heave" => 0, "yaw" => 0, "Surge" => 1}) ==
               {:error, "unknown field: Surge"}
    end

    test "atom keys are not the JSON keys" do
      assert Allocation.validate_motion(%{surge: 0, heave: 0, yaw: 0}) ==
               {:error, "unknown field: :heave"}
    end

    test "rejects non-maps" do
      assert Allocation.validate_motion(nil) == {:error, "motion must be an object, got nil"}
      assert {:error, "motion must be an object" <> _} = Allocation.validate_motion([1, 2, 3])
      assert {:error, "motion must be an object" <> _} = Allocation.validate_motion("surge")
    end

    test "a validated command can be allocated" do
      {:ok, motion} = Allocation.validate_motion(%{"surge" => 1, "heave" => 0, "yaw" => 1})
      assert Allocation.motion(motion, 1.0) == %{port: 1.0, vertical: 0.0, starboard: 0.0}
    end
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

    test "validate_motion accepts every in-range command and returns it as floats" do
      number = :proper_types.union([:proper_types.float(-1.0, 1.0), :proper_types.integer(-1, 1)])

      property =
        :proper.forall({number, number, number}, fn {x, z, m} ->
          Allocation.validate_motion(%{"surge" => x, "heave" => z, "yaw" => m}) ==
            {:ok, %{surge: x * 1.0, heave: z * 1.0, yaw: m * 1.0}}
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end
  end
end
