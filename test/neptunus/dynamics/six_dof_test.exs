defmodule Neptunus.Dynamics.SixDofTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Vehicles, only: [variant: 1]

  alias Neptunus.{Dynamics, Sim}
  alias Neptunus.Dynamics.{Linear, Params, State}

  doctest Neptunus.Dynamics.Linear

  @neptunus Dynamics.params(:neptunus)
  @dt 0.01
  @zero {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}

  defp run(state, tau, seconds, params, current \\ {0.0, 0.0, 0.0}, dt \\ @dt) do
    Enum.reduce(1..round(seconds / dt), state, fn _, s ->
      Dynamics.step(s, tau, dt, params, current)
    end)
  end

  # ½ νᵀ M ν + potential of weight and buoyancy (W = B, offsets along z only)
  defp energy(%State{} = s, %Params{} = p) do
    nu = [s.u, s.v, s.w, s.p, s.q, s.r]
    kinetic = 0.5 * Linear.dot(nu, Linear.mat_vec(p.mass_matrix, nu))
    [_, _, zg] = p.r_g
    [_, _, zb] = p.r_b
    bg = zg - zb
    kinetic + Params.weight(p) * bg * (1 - :math.cos(s.phi) * :math.cos(s.theta))
  end

  defp neutral_variant(coriolis, damping? \\ true) do
    variant(fn map ->
      map
      |> put_in(["restoring", "net_buoyancy"], 0)
      |> put_in(["tether", "length"], 0)
      |> put_in(["coriolis"], coriolis)
      |> then(fn m ->
        if damping?,
          do: m,
          else:
            put_in(m, ["damping"], %{
              "linear" => List.duplicate(0, 6),
              "quadratic" => List.duplicate(0, 6)
            })
      end)
    end)
  end

  @moving %State{
    z: 5.0,
    phi: 0.2,
    theta: 0.1,
    psi: 0.3,
    u: 0.5,
    v: 0.2,
    w: 0.1,
    p: 0.3,
    q: -0.2,
    r: 0.4
  }

  describe "params(:neptunus)" do
    test "6 DOF, thesis coefficients in surge, sway, heave and yaw" do
      p = @neptunus
      assert %Params{name: "neptunus", dof: 6, coriolis: :rigid_body} = p
      assert Enum.at(p.d_l, 0) == 2.2907 and Enum.at(p.d_l, 5) == 0.2605
      assert Enum.at(p.d_q, 1) == 35.216
      assert p.net_buoyancy == 0.0234
      assert length(p.thrusters) == 3
      assert Enum.map(p.thrusters, & &1.name) == [:port, :vertical, :starboard]
    end

    test "M_RB is [m I, −m S(r_g); m S(r_g), I_o] and M = M_RB + M_A is symmetric positive definite" do
      p = @neptunus
      [_, _, zg] = p.r_g
      m = p.mass
      rb = p.rigid_body_matrix

      # r_g = (0, 0, z_g): −m S(r_g) has (0, 4) = m z_g and (1, 3) = −m z_g; m S(r_g) (4, 0) = m z_g
      assert_in_delta Enum.at(Enum.at(rb, 0), 4), m * zg, 1.0e-12
      assert_in_delta Enum.at(Enum.at(rb, 1), 3), -m * zg, 1.0e-12
      assert_in_delta Enum.at(Enum.at(rb, 4), 0), m * zg, 1.0e-12
      assert Linear.transpose(p.mass_matrix) == p.mass_matrix
      assert Linear.positive_definite?(p.mass_matrix)

      identity = Linear.mul(p.mass_matrix, p.mass_inv)

      for {row, i} <- Enum.with_index(identity), {x, j} <- Enum.with_index(row) do
        assert_in_delta x, if(i == j, do: 1.0, else: 0.0), 1.0e-12
      end
    end
  end

  describe "energy" do
    test "decays with zero input, to nearly nothing (rigid-body and full Coriolis)" do
      for coriolis <- ["rigid_body", "full"] do
        p = neutral_variant(coriolis)

        energies =
          1..2000
          |> Enum.scan(@moving, fn _, s -> Dynamics.step(s, @zero, @dt, p) end)
          |> Enum.map(&energy(&1, p))

        e0 = energy(@moving, p)

        energies
        |> Enum.chunk_every(2, 1, :discard)
        |> Enum.each(fn [a, b] -> assert b <= a + 1.0e-12, "energy grew (#{coriolis})" end)

        assert List.last(energies) < 0.01 * e0
      end
    end

    test "is conserved without damping: the Coriolis terms do no work" do
      for coriolis <- ["rigid_body", "full"] do
        p = neutral_variant(coriolis, false)
        e0 = energy(@moving, p)
        final = run(@moving, @zero, 10.0, p)

        assert abs(energy(final, p) - e0) < 1.0e-7 * e0,
               "#{coriolis}: #{energy(final, p)} vs #{e0}"

        # and the motion did couple between the axes
        assert abs(final.u - @moving.u) > 1.0e-3
      end
    end
  end

  describe "restoring" do
    test "the moments level a tilted vehicle at rest" do
      tilted = %State{z: 3.0, phi: 0.3, theta: -0.2}
      d = Dynamics.derivative(tilted, @zero, @neptunus)
      # CB above CG: roll and pitch accelerate back towards level
      assert d.p < 0.0
      assert d.q > 0.0

      final = run(tilted, @zero, 30.0, @neptunus)
      assert abs(final.phi) < 1.0e-3
      assert abs(final.theta) < 1.0e-3
      assert abs(final.p) < 1.0e-3 and abs(final.q) < 1.0e-3
    end

    test "roll period and damping are those the parameter file describes" do
      # small roll oscillation: time between downward zero crossings ≈ 2π / ω_d ≈ 3.8 s
      states =
        Enum.scan(1..1000, %State{z: 3.0, phi: 0.05}, fn _, s ->
          Dynamics.step(s, @zero, @dt, @neptunus)
        end)

      crossings =
        states
        |> Enum.with_index()
        |> Enum.chunk_every(2, 1, :discard)
        |> Enum.filter(fn [{a, _}, {b, _}] -> a.phi > 0 and b.phi <= 0 end)
        |> Enum.map(fn [_, {_, i}] -> i * @dt end)

      assert [first, second | _] = crossings
      assert_in_delta second - first, 4.4, 0.8
    end

    test "with net buoyancy the vehicle rises at the terminal speed of the heave damping" do
      final = run(%State{z: 5.0}, @zero, 20.0, variant(&put_in(&1, ["tether", "length"], 0)))
      # 15.1897 w + 10.304 w|w| = −0.0234
      expected = -(-15.1897 + :math.sqrt(15.1897 ** 2 + 4 * 10.304 * 0.0234)) / (2 * 10.304)
      assert_in_delta final.w, expected, 1.0e-9
    end
  end

  describe "kinematics" do
    test "the rotation matrix is orthonormal (property)" do
      angle = :proper_types.float(-3.14, 3.14)
      pitch = :proper_types.float(-1.5, 1.5)

      property =
        :proper.forall({angle, pitch, angle}, fn {phi, theta, psi} ->
          r = Dynamics.rotation(phi, theta, psi) |> Tuple.to_list() |> Enum.chunk_every(3)
          product = Linear.mul(r, Linear.transpose(r))

          Enum.all?(
            for i <- 0..2, j <- 0..2 do
              abs(Enum.at(Enum.at(product, i), j) - if(i == j, do: 1.0, else: 0.0)) < 1.0e-12
            end
          )
        end)

      assert :proper.quickcheck(property, [:quiet, {:numtests, 300}]) == true
    end

    test "η̇ = J(η) ν with the Euler-angle rates of T(Θ)" do
      s = %State{phi: 0.1, theta: 0.2, psi: 0.3, u: 1.0, v: 0.5, w: 0.25, p: 0.1, q: 0.2, r: 0.3}
      d = Dynamics.derivative(s, @zero, @neptunus)
      r = Dynamics.rotation(0.1, 0.2, 0.3) |> Tuple.to_list() |> Enum.chunk_every(3)
      [xd, yd, zd] = Linear.mat_vec(r, [1.0, 0.5, 0.25])
      assert_in_delta d.x, xd, 1.0e-15
      assert_in_delta d.y, yd, 1.0e-15
      assert_in_delta d.z, zd, 1.0e-15

      {sp, cp, tt, ct} = {:math.sin(0.1), :math.cos(0.1), :math.tan(0.2), :math.cos(0.2)}
      assert_in_delta d.phi, 0.1 + sp * tt * 0.2 + cp * tt * 0.3, 1.0e-15
      assert_in_delta d.theta, cp * 0.2 - sp * 0.3, 1.0e-15
      assert_in_delta d.psi, (sp * 0.2 + cp * 0.3) / ct, 1.0e-15
    end

    test "pitch at ±90° is the documented Euler singularity" do
      assert_raise ArgumentError, ~r/singular/, fn ->
        Dynamics.step(%State{theta: :math.pi() / 2}, @zero, @dt, @neptunus)
      end
    end

    test "phi and psi stay wrapped to [-π, π)" do
      s = Dynamics.step(%State{phi: 3.14159, p: 1.0, z: 3.0}, @zero, @dt, @neptunus)
      assert s.phi < 0.0 and s.phi >= -:math.pi()
    end
  end

  describe "RK4 accuracy (moduledoc figures)" do
    @tau {10.0, 0.0, 5.0, 0.0, 0.0, 0.6}
    @start %State{psi: 0.2, u: 0.1, z: 1.0}
    @current {0.1, 0.05, 0.0}

    defp position_error(a, b),
      do: [:x, :y, :z] |> Enum.map(&abs(Map.fetch!(a, &1) - Map.fetch!(b, &1))) |> Enum.max()

    defp euler(state, tau, seconds, dt, p, c) do
      Enum.reduce(1..round(seconds / dt), state, fn _, s ->
        d = Dynamics.derivative(s, tau, p, c)
        Map.merge(s, Map.new(State.fields(), &{&1, Map.fetch!(s, &1) + dt * Map.fetch!(d, &1)}))
      end)
    end

    test "RK4 at dt 0.01 is within 1e-7 of dt 0.0005; forward Euler is off by about 1 cm" do
      fine = run(@start, @tau, 5.0, @neptunus, @current, 0.0005)
      rk4 = run(@start, @tau, 5.0, @neptunus, @current, 0.01)
      euler = euler(@start, @tau, 5.0, 0.01, @neptunus, @current)

      for field <- State.fields() -- [:psi] do
        assert abs(Map.fetch!(rk4, field) - Map.fetch!(fine, field)) < 1.0e-7, "#{field}"
      end

      assert position_error(rk4, fine) < 1.0e-7
      assert position_error(euler, fine) > 3.0e-3
      assert position_error(euler, fine) < 3.0e-2
    end
  end

  describe "thrusters" do
    test "static thrust: asymmetric forward/reverse, deadband, clamping" do
      p = @neptunus
      [port, vertical, _] = p.thrusters
      alias Neptunus.Dynamics.Thruster
      assert Thruster.force(port, 1.0) == 6.0
      assert Thruster.force(port, -1.0) == -4.0
      assert Thruster.force(port, 0.05) == 0.0
      assert Thruster.force(port, -0.04) == 0.0
      assert_in_delta Thruster.force(port, 0.525), 3.0, 1.0e-12
      assert Thruster.force(vertical, 3.0) == 12.0
      assert Thruster.force(vertical, -1.0) == -8.0
    end

    test "rise: the force follows a command with the first-order time constant" do
      sim =
        Sim.new(vehicle: "neptunus", dt: 0.01)
        |> Sim.command(%{port: 1.0, vertical: 0.0, starboard: -1.0})

      tc = hd(@neptunus.thrusters).time_constant

      after_tc = Sim.step(sim, round(tc / 0.01))
      assert_in_delta Sim.thrust_forces(after_tc).port, 6.0 * (1 - :math.exp(-1)), 1.0e-12
      assert_in_delta Sim.thrust_forces(after_tc).starboard, -4.0 * (1 - :math.exp(-1)), 1.0e-12

      after_5tc = Sim.step(sim, round(5 * tc / 0.01))
      assert_in_delta Sim.thrust_forces(after_5tc).port, 6.0 * (1 - :math.exp(-5)), 1.0e-12

      # back to neutral: decays with the same time constant
      back = after_5tc |> Sim.command(%{port: 0.0, vertical: 0.0, starboard: 0.0}) |> Sim.step(20)

      assert_in_delta Sim.thrust_forces(back).port,
                      6.0 * (1 - :math.exp(-5)) * :math.exp(-1),
                      1.0e-12
    end

    test "no lag in thesis-4dof: full force in the first step" do
      sim = Sim.new() |> Sim.command(%{port: 1.0, vertical: 1.0, starboard: 1.0}) |> Sim.step()
      assert Sim.thrust_forces(sim) == %{port: 6.0, vertical: 12.0, starboard: 6.0}
    end

    test "side thrusters: wrench of position × direction" do
      # port at (−0.1, −0.09, 0) pushing 1 N forward: X = 1, N = −y·F = 0.09 (bow to starboard)
      {x, y, z, k, m, n} = Dynamics.tau_from_forces([1.0, 0.0, 0.0], @neptunus)
      assert {x, y, z, k, m} == {1.0, 0.0, 0.0, 0.0, 0.0}
      assert_in_delta n, 0.09, 1.0e-15
    end
  end

  describe "tether" do
    @kt 0.5 * 1000.0 * 1.2 * 0.003 * 10.0

    test "drag opposes the motion with ½ρC_d d L V²/4" do
      {x, y, _, _, _, n} = Dynamics.tether_tau(%State{u: 1.0}, @neptunus)
      assert_in_delta x, -@kt / 4, 1.0e-12
      assert_in_delta y, 0.0, 1.0e-15
      assert_in_delta n, 0.0, 1.0e-15

      {x, _, _, _, _, _} = Dynamics.tether_tau(%State{u: -0.5}, @neptunus)
      assert_in_delta x, @kt / 4 * 0.25, 1.0e-12
    end

    test "sway and yaw at the stern attachment: the moment opposes the turn" do
      {_, y, _, _, _, _} = Dynamics.tether_tau(%State{v: 0.5}, @neptunus)
      assert y < 0.0
      {_, _, _, _, _, n} = Dynamics.tether_tau(%State{r: 1.0}, @neptunus)
      assert n < 0.0
    end

    test "a current drags a stationary vehicle downstream with ½ρC_d d L V_c²/2" do
      {x, y, _, _, _, _} = Dynamics.tether_tau(%State{}, @neptunus, {0.2, 0.0, 0.0})
      assert_in_delta x, @kt * 0.04 / 2, 1.0e-12
      assert_in_delta y, 0.0, 1.0e-15

      # heading east, the same northward current pushes the vehicle to port (−y)
      {x, y, _, _, _, _} =
        Dynamics.tether_tau(%State{psi: :math.pi() / 2}, @neptunus, {0.2, 0.0, 0.0})

      assert_in_delta x, 0.0, 1.0e-12
      assert_in_delta y, -@kt * 0.04 / 2, 1.0e-12
    end

    test "vanishes with zero length; slows the vehicle down otherwise" do
      short = Params.with_tether_length(@neptunus, 0)
      assert Dynamics.tether_tau(%State{u: 1.0}, short, {0.3, 0.1, 0.0}) == @zero

      thrust = Dynamics.tau_from_thrusters(%{port: 1.0, vertical: 0.0, starboard: 1.0}, @neptunus)
      free = run(%State{z: 3.0}, thrust, 30.0, short)
      towed = run(%State{z: 3.0}, thrust, 30.0, @neptunus)
      assert towed.u < free.u - 0.2
      # free: 4.008 u² + 2.2907 u = 12
      assert_in_delta free.u,
                      (-2.2907 + :math.sqrt(2.2907 ** 2 + 4 * 4.008 * 12)) / (2 * 4.008),
                      1.0e-3
    end
  end

  describe "current" do
    test "a passive vehicle drifts at the current's speed" do
      for vehicle <- ["neptunus", "thesis-4dof"] do
        sim =
          Sim.new(
            vehicle: vehicle,
            current: {0.2, -0.1, 0.0},
            tether_length: 0,
            initial: [z: 5.0]
          )
          |> Sim.step(6000)

        s = sim.dyn
        r = Dynamics.rotation(s.phi, s.theta, s.psi) |> Tuple.to_list() |> Enum.chunk_every(3)
        [vn, ve, _] = Linear.mat_vec(r, [s.u, s.v, s.w])
        assert_in_delta vn, 0.2, 1.0e-4, vehicle
        assert_in_delta ve, -0.1, 1.0e-4, vehicle
        assert_in_delta s.x, 0.2 * 60, 1.0
        assert_in_delta s.y, -0.1 * 60, 0.5
      end
    end

    test "the damping acts on the velocity relative to the water" do
      # moving with the water: no damping force; still in moving water: a force downstream
      with_water =
        Dynamics.derivative(
          %State{u: 0.3, z: 2.0},
          @zero,
          Params.with_tether_length(@neptunus, 0),
          {0.3, 0.0, 0.0}
        )

      assert_in_delta with_water.u, 0.0, 1.0e-12
      still = Dynamics.derivative(%State{z: 2.0}, @zero, @neptunus, {0.3, 0.0, 0.0})
      assert still.u > 0.0
    end
  end
end
