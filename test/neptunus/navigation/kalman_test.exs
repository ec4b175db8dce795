defmodule Neptunus.Navigation.KalmanTest do
  use ExUnit.Case, async: true

  alias Neptunus.Navigation.Kalman

  @cv [q: 1.0, r: 1.0e-4, max_rate: 5.0]

  defp deg(d), do: d * :math.pi() / 180

  defp positive_definite?(%Kalman{p: {p11, p12, p22}}),
    do: p11 > 0 and p22 > 0 and p11 * p22 - p12 * p12 > 0

  describe "start, clear" do
    test "no estimate until started; started at the reading with variance r and rate_var0" do
      k = Kalman.new(@cv)
      refute Kalman.started?(k)
      assert Kalman.std(k) == nil
      assert Kalman.predict(k, 0.1, 5.0) == k

      k = Kalman.start(k, 2.5, 0.3)
      assert Kalman.started?(k)
      assert {k.x, k.v, k.p} == {2.5, 0.3, {1.0e-4, 0.0, 0.25}}
      refute Kalman.started?(Kalman.clear(k))
    end

    test "update before start starts; an angle starts wrapped; the rate is bounded" do
      assert Kalman.update(Kalman.new(@cv), 1.0).x == 1.0
      k = Kalman.new(@cv ++ [angle: true])
      assert_in_delta Kalman.start(k, -0.5).x, 2 * :math.pi() - 0.5, 1.0e-12
      assert Kalman.start(k, 1.0, 100.0).v == 5.0
    end
  end

  describe "prediction" do
    test "constant velocity: x moves by v·dt, the covariance grows" do
      k = Kalman.new(@cv) |> Kalman.start(1.0, 0.5) |> Kalman.predict(0.4, 0.0)
      assert_in_delta k.x, 1.2, 1.0e-12
      assert k.v == 0.5
      {p11, _, p22} = k.p
      assert p11 > 1.0e-4 and p22 > 0.25
      assert positive_definite?(k)
    end

    test "with an axis model the rate follows the force to the terminal rate (linear damping)" do
      # m v' = F − d v  →  v(t) = F/d · (1 − e^(−d t / m))
      k = Kalman.new(@cv ++ [mass: 2.0, d_l: 4.0]) |> Kalman.start(0.0)
      k = Enum.reduce(1..100, k, fn _, k -> Kalman.predict(k, 0.01, 2.0) end)
      assert_in_delta k.v, 0.5 * (1 - :math.exp(-2.0)), 2.0e-3
      # x = ∫v = F/d (t − m/d (1 − e^(−d t/m)))
      assert_in_delta k.x, 0.5 * (1.0 - 0.5 * (1 - :math.exp(-2.0))), 2.0e-3
    end

    test "one long step equals many short ones (sub-stepping)" do
      k = Kalman.new(@cv ++ [mass: 5.8, d_l: 15.2, d_q: 10.3, f0: -0.02]) |> Kalman.start(1.0)
      long = Kalman.predict(k, 0.5, 12.0)
      short = Enum.reduce(1..50, k, fn _, k -> Kalman.predict(k, 0.01, 12.0) end)
      assert_in_delta long.x, short.x, 1.0e-3
      assert_in_delta long.v, short.v, 1.0e-3
    end

    test "quadratic damping limits the rate; any force keeps |v| ≤ max_rate" do
      k = Kalman.new(@cv ++ [mass: 1.0, d_q: 1.0]) |> Kalman.start(0.0)
      k = Enum.reduce(1..500, k, fn _, k -> Kalman.predict(k, 0.02, 4.0) end)
      assert_in_delta k.v, 2.0, 1.0e-3

      k = Kalman.new(@cv) |> Kalman.start(0.0)
      k = Enum.reduce(1..100, k, fn _, k -> Kalman.predict(k, 0.05, 1.0e6) end)
      assert k.v == 5.0
    end

    test "an angle stays in [0, 2π)" do
      k = Kalman.new(@cv ++ [angle: true]) |> Kalman.start(6.2, 1.0) |> Kalman.predict(0.2, 0.0)
      assert_in_delta k.x, 6.4 - 2 * :math.pi(), 1.0e-9
    end
  end

  describe "update" do
    test "the innovation of an angle is wrapped: 359° → 1° is a +2° step" do
      k = Kalman.new(@cv ++ [angle: true]) |> Kalman.start(deg(359.0))
      {y, s} = Kalman.innovation(k, deg(1.0))
      assert_in_delta y, deg(2.0), 1.0e-9
      assert s == 2.0e-4

      k = Kalman.update(k, deg(1.0))
      # halfway (equal variances), through north
      assert_in_delta k.x, 0.0, 1.0e-9
    end

    test "tracks a ramp through noise better than the readings; covariance stays PD" do
      rand = :rand.seed_s(:exsss, 1)
      k = Kalman.new(q: 0.05, r: 1.0e-4, max_rate: 2.0)

      {k, errors, rates, _} =
        Enum.reduce(1..400, {k, [], [], rand}, fn i, {k, errors, rates, rand} ->
          t = i * 0.05
          {n, rand} = :rand.normal_s(rand)
          k = k |> Kalman.predict(0.05, 0.0) |> Kalman.update(0.3 * t + 0.01 * n)
          assert positive_definite?(k)

          if i > 100,
            do: {k, [k.x - 0.3 * t | errors], [k.v | rates], rand},
            else: {k, errors, rates, rand}
        end)

      rms = :math.sqrt(Enum.sum(Enum.map(errors, &(&1 * &1))) / length(errors))
      assert rms < 0.008
      assert_in_delta Enum.sum(rates) / length(rates), 0.3, 0.01
      {sx, sv} = Kalman.std(k)
      assert sx < 0.01 and sv < 0.1
    end

    test "the gate: within 5 σ of the innovation, or within min_gate" do
      k = Kalman.new(q: 0.05, r: 1.0e-4, max_rate: 2.0) |> Kalman.start(1.0)
      # S = 2e-4, σ ≈ 0.0141, 5 σ ≈ 0.0707
      assert Kalman.gate?(k, 1.07)
      refute Kalman.gate?(k, 1.072)
      refute Kalman.gate?(k, 0.9)
      assert Kalman.gate?(%{k | min_gate: 0.2}, 0.9)
      assert Kalman.gate?(Kalman.new(@cv), 1.0e9)
    end
  end
end
