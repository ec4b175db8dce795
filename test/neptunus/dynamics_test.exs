defmodule Neptunus.DynamicsTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Dynamics}
  alias Neptunus.Dynamics.{Linear, Params, State}

  doctest Neptunus.Dynamics

  @params Dynamics.params(:thesis_4dof)
  @dt 0.01
  @pi :math.pi()
  # the free DOFs of the 4-DOF model in ν = [u v w p q r]
  @free [0, 1, 2, 5]

  defp run(state, tau, seconds, dt \\ @dt) do
    steps = round(seconds / dt)
    Enum.reduce(1..steps, state, fn _, s -> Dynamics.step(s, tau, dt, @params) end)
  end

  # Positive root of a x² + b x − c = 0 (steady speed of D_l x + D_q x|x| = c, c > 0).
  defp steady(d_l, d_q, c), do: (-d_l + :math.sqrt(d_l * d_l + 4 * d_q * c)) / (2 * d_q)

  defp assert_rel(actual, expected, rel) do
    assert abs(actual - expected) <= rel * abs(expected),
           "expected #{actual} within #{rel * 100} % of #{expected}"
  end

  describe "params(:thesis_4dof)" do
    test "holds the thesis coefficients (eqs. 12.7-12.13)" do
      assert %Params{name: "thesis-4dof", dof: 4, coriolis: :none} = @params
      assert @params.d_l == [2.2907, 4.9804, 15.1897, 0.0, 0.0, 0.2605]
      assert @params.d_q == [4.008, 35.216, 10.304, 0.0, 0.0, 0.320]
      # g = [0, 0, 0.0234, 0]: W − B = −0.0234 N, no CG/CB offset
      assert @params.net_buoyancy == 0.0234
      assert @params.r_g == [0.0, 0.0, 0.0] and @params.r_b == [0.0, 0.0, 0.0]
      assert @params.tether.length == 0.0

      expected_mass = [
        [5.515, 0.0, 0.0, 0.0],
        [0.0, 18.0633, 0.0, -0.8926],
        [0.0, 0.0, 5.7895, 0.0],
        [0.0, -0.8926, 0.0, 0.5488]
      ]

      for {row, expected_row} <- Enum.zip(Linear.take(@params.mass_matrix, @free), expected_mass),
          {value, expected} <- Enum.zip(row, expected_row) do
        assert_in_delta value, expected, 1.0e-12
      end
    end

    test "mass_inv is the inverse of mass on [u v w r] and zero on roll and pitch" do
      free_inv = Linear.take(@params.mass_inv, @free)

      for {row, i} <- Enum.with_index(Linear.take(@params.mass_matrix, @free)), j <- 0..3 do
        column = Enum.map(free_inv, &Enum.at(&1, j))
        product = row |> Enum.zip_with(column, &(&1 * &2)) |> Enum.sum()
        assert_in_delta product, if(i == j, do: 1.0, else: 0.0), 1.0e-12
      end

      for i <- [3, 4], j <- 0..5 do
        assert Enum.at(Enum.at(@params.mass_inv, i), j) == 0.0
        assert Enum.at(Enum.at(@params.mass_inv, j), i) == 0.0
      end
    end

    test "sway-yaw block matches the analytic 2x2 inverse" do
      [a, b, d] = [18.0633, -0.8926, 0.5488]
      det = a * d - b * b
      inv = fn i, j -> @params.mass_inv |> Enum.at(i) |> Enum.at(j) end
      assert_in_delta inv.(1, 1), d / det, 1.0e-12
      assert_in_delta inv.(1, 5), -b / det, 1.0e-12
      assert_in_delta inv.(5, 5), a / det, 1.0e-12
      assert_in_delta inv.(0, 0), 1 / 5.515, 1.0e-12
      assert_in_delta inv.(2, 2), 1 / 5.7895, 1.0e-12
    end
  end

  describe "steady state" do
    test "(a) surge speed under τ_X = 12 N is the root of 4.008u² + 2.2907u − 12 = 0" do
      expected = steady(2.2907, 4.008, 12.0)
      assert_in_delta expected, 1.468, 1.0e-3

      final = run(%State{}, {12.0, 0.0, 0.0, 0.0}, 60.0)

      assert_rel(final.u, expected, 0.005)
      # tighter than required: RK4 at dt 0.01 lands on the root
      assert_in_delta final.u, expected, 1.0e-9
      assert final.x > 0.95 * expected * 60.0
      assert final.v == 0.0 and final.r == 0.0 and final.psi == 0.0 and final.y == 0.0
    end

    test "(a) reverse surge is symmetric" do
      final = run(%State{}, {-12.0, 0.0, 0.0, 0.0}, 60.0)
      assert_rel(final.u, -steady(2.2907, 4.008, 12.0), 0.005)
      assert final.x < 0.0
    end

    test "(b) heave speed under τ_Z = 12 N accounts for buoyancy g" do
      expected = steady(15.1897, 10.304, 12.0 - 0.0234)
      final = run(%State{}, {0.0, 0.0, 12.0, 0.0}, 60.0)

      assert_rel(final.w, expected, 0.005)
      assert_in_delta final.w, expected, 1.0e-9
      assert final.z > 0.0
      assert final.u == 0.0 and final.x == 0.0 and final.psi == 0.0
    end

    test "(b) upward heave is faster than downward heave by the buoyancy" do
      up = run(%State{}, {0.0, 0.0, -12.0, 0.0}, 60.0)
      # D_l w + D_q w|w| = −12 − 0.0234
      assert_in_delta up.w, -steady(15.1897, 10.304, 12.0 + 0.0234), 1.0e-9
      assert up.z < 0.0
    end

    test "(c) yaw rate under a pure moment; yaw acceleration induces transient sway" do
      n = 2 * 12.0 * 0.045
      expected = steady(0.2605, 0.320, n)

      first = Dynamics.step(%State{}, {0.0, 0.0, 0.0, n}, @dt, @params)
      # M_A sway–yaw coupling: M⁻¹[v][r] = 0.8926 / det > 0, so +N gives +v̇
      assert first.v > 0.0
      assert first.r > 0.0

      after_1s = run(%State{}, {0.0, 0.0, 0.0, n}, 1.0)
      final = run(after_1s, {0.0, 0.0, 0.0, n}, 59.0)

      assert abs(after_1s.v) > 1.0e-3
      assert abs(final.v) < 1.0e-6
      assert abs(final.v) < abs(after_1s.v) / 1000
      assert_rel(final.r, expected, 0.005)
      assert_in_delta final.r, expected, 1.0e-7
      # surge untouched; heave only from the buoyancy g
      assert final.u == 0.0
      assert_in_delta final.w, -steady(15.1897, 10.304, 0.0234), 1.0e-9
    end
  end

  test "(d) zero thrust from rest: only a slow rise from buoyancy" do
    final = run(%State{}, {0.0, 0.0, 0.0, 0.0}, 10.0)

    assert final.z < 0.0
    assert final.w < 0.0
    # terminal rise speed, D_l w + D_q w|w| = −0.0234: about 1.5 mm/s
    assert_in_delta final.w, -steady(15.1897, 10.304, 0.0234), 1.0e-9
    assert final.w > -0.002

    assert %State{x: 0.0, y: 0.0, psi: 0.0, u: 0.0, v: 0.0, r: 0.0} = final
    assert %State{phi: 0.0, theta: 0.0, p: 0.0, q: 0.0} = final
  end

  describe "(e) heading" do
    test "psi wraps to [-π, π) while turning" do
      n = 2 * 12.0 * 0.045

      psis =
        1..2000
        |> Enum.scan(%State{}, fn _, s -> Dynamics.step(s, {0.0, 0.0, 0.0, n}, @dt, @params) end)
        |> Enum.map(& &1.psi)

      assert Enum.all?(psis, &(&1 >= -@pi and &1 < @pi))
      # 20 s at ~1.5 rad/s turns several times, so the wrap happened
      assert Enum.any?(psis, &(&1 < -3.0))
      assert Enum.any?(psis, &(&1 > 3.0))
    end

    test "crossing π from below lands just above -π" do
      s = %State{psi: @pi - 0.001, r: 1.0}
      next = Dynamics.step(s, {0.0, 0.0, 0.0, 0.0}, @dt, @params)
      assert next.psi < -@pi + 0.01 and next.psi >= -@pi
    end

    test "crossing -π from above lands just below π" do
      s = %State{psi: -@pi + 0.001, r: -1.0}
      next = Dynamics.step(s, {0.0, 0.0, 0.0, 0.0}, @dt, @params)
      assert next.psi > @pi - 0.01 and next.psi < @pi
    end

    test "a step from psi = π (out of range) wraps to -π" do
      next = Dynamics.step(%State{psi: @pi}, {0.0, 0.0, 0.0, 0.0}, @dt, @params)
      assert next.psi == -@pi
    end

    test "heading/1 is in [0, 2π)" do
      assert Dynamics.heading(%State{psi: 0.0}) == 0.0
      assert_in_delta Dynamics.heading(%State{psi: -@pi / 2}), 3 * @pi / 2, 1.0e-15
      assert_in_delta Dynamics.heading(%State{psi: -@pi}), @pi, 1.0e-15
      assert_in_delta Dynamics.heading(%State{psi: @pi / 4}), @pi / 4, 1.0e-15
      assert Dynamics.heading(%State{psi: -1.0e-20}) == 0.0
      assert_in_delta Dynamics.heading(%State{psi: 7 * @pi}), @pi, 1.0e-12
    end

    test "heading/1 is in [0, 2π) for any angle (property)" do
      property =
        :proper.forall(:proper_types.float(-1.0e4, 1.0e4), fn psi ->
          h = Dynamics.heading(%State{psi: psi})
          wrapped = Dynamics.step(%State{psi: psi}, {0.0, 0.0, 0.0, 0.0}, @dt, @params).psi

          is_float(h) and h >= 0.0 and h < 2 * @pi and
            abs(:math.sin(h) - :math.sin(psi)) < 1.0e-9 and
            abs(:math.cos(h) - :math.cos(psi)) < 1.0e-9 and
            wrapped >= -@pi and wrapped < @pi and
            abs(:math.sin(wrapped) - :math.sin(psi)) < 1.0e-9
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end
  end

  describe "(f) kinematics" do
    test "heading east (ψ = π/2), forward surge moves +y" do
      s = %State{psi: @pi / 2, u: 1.0}
      final = run(s, {12.0, 0.0, 0.0, 0.0}, 2.0)

      assert final.y > 2.0
      assert abs(final.x) < 1.0e-12
      assert_in_delta final.psi, @pi / 2, 1.0e-15
    end

    test "heading north, forward surge moves +x; heading south moves -x" do
      north = run(%State{}, {12.0, 0.0, 0.0, 0.0}, 1.0)
      assert north.x > 0.0 and north.y == 0.0

      south = run(%State{psi: -@pi}, {12.0, 0.0, 0.0, 0.0}, 1.0)
      assert_in_delta south.x, -north.x, 1.0e-12
      assert abs(south.y) < 1.0e-12
    end

    test "positive sway at ψ = 0 moves east; derivative is J(ψ)ν" do
      d =
        Dynamics.derivative(
          %State{psi: 0.3, u: 0.5, v: 0.2, w: 0.1, r: 0.05},
          {0.0, 0.0, 0.0, 0.0},
          @params
        )

      assert_in_delta d.x, 0.5 * :math.cos(0.3) - 0.2 * :math.sin(0.3), 1.0e-15
      assert_in_delta d.y, 0.5 * :math.sin(0.3) + 0.2 * :math.cos(0.3), 1.0e-15
      assert d.z == 0.1
      assert d.psi == 0.05
      assert d.phi == 0.0 and d.theta == 0.0 and d.p == 0.0 and d.q == 0.0
    end

    test "derivative kinetics is M⁻¹(τ − D(ν)ν − g)" do
      s = %State{u: 0.5, v: -0.2, w: 0.3, r: -0.4}
      d = Dynamics.derivative(s, {6.0, 0.0, -3.0, 0.5}, @params)

      rhs = [
        6.0 - (2.2907 + 4.008 * 0.5) * 0.5,
        0.0 - (4.9804 + 35.216 * 0.2) * -0.2,
        -3.0 - (15.1897 + 10.304 * 0.3) * 0.3 - 0.0234,
        0.5 - (0.2605 + 0.320 * 0.4) * -0.4
      ]

      # M ν̇ must give back the right-hand side
      nu_dot = [d.u, d.v, d.w, d.r]
      assert d.p == 0.0 and d.q == 0.0

      for {row, expected} <- Enum.zip(Linear.take(@params.mass_matrix, @free), rhs) do
        assert_in_delta row |> Enum.zip_with(nu_dot, &(&1 * &2)) |> Enum.sum(), expected, 1.0e-12
      end
    end

    test "the 4-tuple {X, Y, Z, N} is the 6-tuple with K = M = 0" do
      s = %State{u: 0.5, v: -0.2, w: 0.3, r: -0.4, psi: 1.0}

      assert Dynamics.derivative(s, {6.0, 1.0, -3.0, 0.5}, @params) ==
               Dynamics.derivative(s, {6.0, 1.0, -3.0, 0.0, 0.0, 0.5}, @params)
    end
  end

  describe "(g) RK4 convergence" do
    @tau {10.0, 0.0, 5.0, 0.6}
    @start %State{psi: 0.2, u: 0.1}

    defp max_error(a, b) do
      [:x, :y, :z, :psi, :u, :v, :w, :r]
      |> Enum.map(&abs(Map.fetch!(a, &1) - Map.fetch!(b, &1)))
      |> Enum.max()
    end

    test "dt = 0.01 agrees with dt = 0.0005 over 5 s" do
      coarse = run(@start, @tau, 5.0, 0.01)
      fine = run(@start, @tau, 5.0, 0.0005)
      assert max_error(coarse, fine) < 1.0e-8
    end

    test "error falls roughly as dt⁴" do
      reference = run(@start, @tau, 2.0, 0.00025)
      e1 = max_error(run(@start, @tau, 2.0, 0.08), reference)
      e2 = max_error(run(@start, @tau, 2.0, 0.04), reference)

      ratio = e1 / e2
      assert ratio > 10 and ratio < 24, "error ratio for halving dt was #{ratio}"
    end
  end

  describe "(h) tau_from_thrusters/2" do
    test "reproduces eq. 12.6 for unsaturated allocation outputs" do
      f = 12.0
      l = 0.045

      for x <- [-0.5, -0.2, 0.0, 0.3, 0.5],
          z <- [-1.0, -0.4, 0.0, 0.7, 1.0],
          m <- [-0.5, -0.1, 0.0, 0.25, 0.5],
          k <- [0.0, 0.3, 0.5, 1.0] do
        thrusters = Allocation.motion(%{surge: x, heave: z, yaw: m}, k)
        {tx, ty, tz, tk, tm, tn} = Dynamics.tau_from_thrusters(thrusters, @params)

        assert_in_delta tx, f * k * x, 1.0e-12
        assert ty == 0.0 and tk == 0.0 and tm == 0.0
        assert_in_delta tz, f * k * z, 1.0e-12
        assert_in_delta tn, 2 * f * k * l * m, 1.0e-12
      end
    end

    test "reproduces eq. 12.6 for random unsaturated commands (property)" do
      half = :proper_types.float(-0.5, 0.5)
      gen = {half, :proper_types.float(-1.0, 1.0), half, :proper_types.float(0.0, 1.0)}

      property =
        :proper.forall(gen, fn {x, z, m, k} ->
          {tx, ty, tz, _k, _m, tn} =
            Dynamics.tau_from_thrusters(
              Allocation.motion(%{surge: x, heave: z, yaw: m}, k),
              @params
            )

          abs(tx - 12.0 * k * x) < 1.0e-12 and ty == 0.0 and abs(tz - 12.0 * k * z) < 1.0e-12 and
            abs(tn - 2 * 12.0 * k * 0.045 * m) < 1.0e-12
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 500}]) == true
    end

    test "signs: port harder turns to starboard (+N), vertical positive pushes down (+Z)" do
      assert {0.0, 0.0, 0.0, 0.0, 0.0, 0.0} =
               Dynamics.tau_from_thrusters(Allocation.neutral(), @params)

      {_, _, _, _, _, n} =
        Dynamics.tau_from_thrusters(%{port: 1.0, vertical: 0.0, starboard: -1.0}, @params)

      assert_in_delta n, 2 * 12.0 * 0.045, 1.0e-12

      assert {0.0, 0.0, 12.0, 0.0, 0.0, 0.0} ==
               Dynamics.tau_from_thrusters(%{port: 0.0, vertical: 1.0, starboard: 0.0}, @params)
    end

    test "saturated allocation gives less than the unsaturated eq. 12.6 force" do
      thrusters = Allocation.motion(%{surge: 1.0, heave: 0.0, yaw: 1.0}, 1.0)
      {x, 0.0, 0.0, 0.0, 0.0, n} = Dynamics.tau_from_thrusters(thrusters, @params)
      assert x == 6.0
      assert_in_delta n, 12.0 * 0.045, 1.0e-15
    end

    test "out-of-range commands are clamped to full thrust" do
      assert Dynamics.tau_from_thrusters(%{port: 2.0, vertical: -3.0, starboard: 2.0}, @params) ==
               {12.0, 0.0, -12.0, 0.0, 0.0, 0.0}
    end

    test "a full-surge allocation drives the vehicle to the steady speed of (a)" do
      tau =
        Dynamics.tau_from_thrusters(
          Allocation.motion(%{surge: 1.0, heave: 0.0, yaw: 0.0}, 1.0),
          @params
        )

      assert tau == {12.0, 0.0, 0.0, 0.0, 0.0, 0.0}
      final = run(%State{}, tau, 30.0)
      assert_rel(final.u, steady(2.2907, 4.008, 12.0), 0.005)
    end
  end

  test "step/4 keeps every field a float and the 4-DOF fields at zero" do
    final = run(%State{}, {5.0, 0.0, -2.0, 0.3}, 3.0)

    for {key, value} <- Map.from_struct(final), do: assert(is_float(value), "#{key} not a float")
    assert %State{phi: 0.0, theta: 0.0, p: 0.0, q: 0.0} = final
  end
end
