defmodule Neptunus.Dynamics.State do
  @moduledoc """
  Vehicle state for `Neptunus.Dynamics`, SI units.

  Position and attitude in NED (`η`), velocities in the body frame (`ν`, relative to the
  earth, not to the water):

    * `x`, `y`, `z` — north, east, down position (m); `z` is depth
    * `phi`, `theta`, `psi` — roll, pitch, yaw (rad); `phi` and `psi` are kept wrapped to
      `[-π, π)` by `Neptunus.Dynamics.step/5`
    * `u`, `v`, `w` — surge, sway, heave velocity (m/s)
    * `p`, `q`, `r` — roll, pitch, yaw rate (rad/s)

  With a 4-DOF parameter set (`thesis-4dof`) `phi`, `theta`, `p` and `q` stay `0.0`.

  `Neptunus.Dynamics.derivative/4` also returns this struct, with each field
  holding the time derivative of that field.
  """

  defstruct x: 0.0,
            y: 0.0,
            z: 0.0,
            phi: 0.0,
            theta: 0.0,
            psi: 0.0,
            u: 0.0,
            v: 0.0,
            w: 0.0,
            p: 0.0,
            q: 0.0,
            r: 0.0

  @type t :: %__MODULE__{
          x: float,
          y: float,
          z: float,
          phi: float,
          theta: float,
          psi: float,
          u: float,
          v: float,
          w: float,
          p: float,
          q: float,
          r: float
        }

  @doc "The field names in order: `η` then `ν`."
  @spec fields() :: [atom()]
  def fields, do: [:x, :y, :z, :phi, :theta, :psi, :u, :v, :w, :p, :q, :r]

  @doc "The state from a 12-tuple in the order of `fields/0`."
  @spec from_tuple(tuple()) :: t()
  def from_tuple({x, y, z, phi, theta, psi, u, v, w, p, q, r}) do
    %__MODULE__{
      x: x,
      y: y,
      z: z,
      phi: phi,
      theta: theta,
      psi: psi,
      u: u,
      v: v,
      w: w,
      p: p,
      q: q,
      r: r
    }
  end

  @doc "The state as a 12-tuple in the order of `fields/0`."
  @spec to_tuple(t()) :: tuple()
  def to_tuple(%__MODULE__{} = s),
    do: {s.x, s.y, s.z, s.phi, s.theta, s.psi, s.u, s.v, s.w, s.p, s.q, s.r}
end

defmodule Neptunus.Dynamics do
  @moduledoc """
  The 6-DOF vehicle model (Fossen 2011) integrated with classical RK4. Pure functions, SI
  units, radians. The coefficients come from a parameter set (`Neptunus.Dynamics.Params`,
  `priv/vehicles/*.json`); `thesis-4dof` reproduces the thesis' chapter 12 model exactly.

  ## Equations of motion

  `η = [x y z φ θ ψ]` (NED position, Euler angles zyx), `ν = [u v w p q r]` (body velocities
  relative to the earth), `ν_c = [R(Θ)ᵀ v_cⁿ; 0]` the water current in the body frame and
  `ν_r = ν − ν_c` the velocity relative to the water:

      η̇ = J(η) ν
      M ν̇_r + C(ν_r) ν_r + D(ν_r) ν_r + g(η) = τ + τ_tether
      ν̇ = ν̇_r + [v_c × ω; 0]        (v̇_c = −ω × v_c: the current is constant in NED)

  This relative-velocity form (Fossen 2011, §10.3, Property 10.1) holds for an irrotational
  current that is constant in NED; a passive, neutrally buoyant vehicle then drifts with
  the current (`ν_r → 0`).

    * `M = M_RB + M_A` — rigid-body and added mass (constant; `M⁻¹` precomputed).
    * `C(ν) ν = [ω × a; v × a + ω × b]` with `[a; b] = M' ν` — the Coriolis–centripetal
      terms (Fossen eqs. 3.46 and 6.43, written as cross products). The formula is linear
      in `M'`: `"coriolis": "full"` uses `M' = M_RB + M_A` (`C_RB(ν)ν + C_A(ν)ν`, including
      the added-mass Munk moments), `"rigid_body"` uses `M' = M_RB`, `"none"` drops them.
    * `D(ν_r) = D_l + D_q(ν_r)`, diagonal: `D_q = diag(d_qi |ν_ri|)`.
    * `g(η)` — restoring forces of weight `W` at `r_g` and buoyancy `B` at `r_b`
      (Fossen eq. 4.6):

          g = [ (W−B) sθ,  −(W−B) cθ sφ,  −(W−B) cθ cφ,
                −(y_g W − y_b B) cθ cφ + (z_g W − z_b B) cθ sφ,
                 (z_g W − z_b B) sθ + (x_g W − x_b B) cθ cφ,
                −(x_g W − x_b B) cθ sφ − (y_g W − y_b B) sθ ]

      With the centre of buoyancy above the centre of gravity these moments level a
      tilted vehicle.
    * `J(η) = diag(R(Θ), T(Θ))` with `R = R_z(ψ) R_y(θ) R_x(φ)` and

          T(Θ) = [1  sφ tθ  cφ tθ;  0  cφ  −sφ;  0  sφ/cθ  cφ/cθ]

  **Singularity.** `T(Θ)` divides by `cos θ`: Euler angles cannot represent pitch
  `θ = ±90°`. The metacentric restoring moment keeps a vehicle like ours within a few
  degrees of level; a parameter set or force that drives `|θ|` to within 10⁻⁶ rad of 90°
  makes `derivative/4` and `step/5` raise `ArgumentError` (use a quaternion model for
  vehicles that loop).

  **4-DOF sets** (`"dof": 4`, `thesis-4dof`): roll and pitch are fixed: `M⁻¹` is taken over
  `[u v w r]` only and `φ̇ = θ̇ = ṗ = q̇ = 0`. With `"coriolis": "none"`, `r_g = r_b = 0`
  and no current this is exactly the thesis' eqs. 12.1–12.13:
  `η̇ = J(ψ)ν`, `M ν̇ + D(ν)ν + g = τ`, `g = [0 0 0.0234 0]` (slightly buoyant: rises at
  about 1.5 mm/s with no thrust).

  ## Tether

  The deployed umbilical (length `L`, diameter `d`, normal drag coefficient `C_d`) hangs from
  a fixed point at the surface to the attachment point `r_t` on the vehicle. Its element at
  fraction `s` of the length from the top moves horizontally with `s · v_t` (`v_t` the
  attachment point's NED velocity) through water moving with `v_c`; the normal drag on it,
  `−½ ρ C_d d |w| w` per metre with `w = s v_t − v_c`, is carried by the vehicle in
  proportion `s` (a cable pivoting about its top end):

      F_tether = −½ ρ C_d d L ∫₀¹ s |w(s)| w(s) ds           (horizontal, NED)

  evaluated with 2-point Gauss–Legendre quadrature (exact while `w` keeps its direction).
  It is applied at `r_t` (force and moment `r_t × F`). Moving at speed `V` in still water
  this is `½ρC_d d L V²/4` against the motion; holding station in a current `V_c`,
  `½ρC_d d L V_c²/2` downstream. With `L = 0` it vanishes.

  ## Thrust

  `tau_from_forces/2` sums the thrusters' wrenches (`Neptunus.Dynamics.Thruster`),
  `tau_from_thrusters/2` does so for the static force of a command. In `thesis-4dof` the
  side thrusters push 6 N each at `y = ∓0.09 m` and the vertical 12 N, which is exactly
  eq. 12.6 with the allocation of eq. 9.3: `τ = [f k X, 0, f k Z, 0, 0, 2 f k l M]`,
  `f = 12 N`, `l = 0.045 m`. (Eq. 12.6 as published treats `f` as the force of each side
  thruster in yaw but of both together in surge; this geometry satisfies both.)

  ## Integration

  `step/5` performs one classical fourth-order Runge–Kutta step of the coupled kinematics
  and kinetics, with `τ` and the current held constant over the step. Accuracy, measured
  against RK4 at `dt = 0.0005 s` over 5 s of turning, surging and diving in a current
  (`test/neptunus/dynamics/six_dof_test.exs`): RK4 at the default `dt = 0.01 s` is within
  about 10⁻⁸ m and m/s; the thesis' forward Euler at the same step is off by about 1 cm in
  position (its error falls only as `dt`, RK4's as `dt⁴` where the model is smooth — the
  `|ν_r|` of quadratic damping is not, at zero crossings).
  After the step `φ` and `ψ` are wrapped to `[-π, π)`; `heading/1` gives `ψ` in `[0, 2π)`.

  **Stiffness and sub-steps.** Explicit RK4 is stable only while `dt · λ` stays below about
  2.8, `λ` the fastest rate at which the model pulls a velocity back. Quadratic drag makes
  `λ` grow with speed, and the tether's drag with its length: 1 000 m of tether in a 7 m/s
  horizontal current gives `λ` in the thousands per second, and one step of 0.01 s then
  overshoots, oscillates and overflows within a few steps (an `ArithmeticError`, and the
  live simulated vehicle restarted). Every input `sim_set` and the scenarios accept must
  keep the model finite, so `step/5` splits a step into `n` equal RK4 sub-steps,
  `n = ⌈dt · λ̂ / 2⌉` (at least 1, at most 1 000), where `λ̂` (`substeps/4`) bounds `λ` from
  the state at the start of the step: the damping slopes `d_l + 2 d_q (|ν| + |v_c|)` through
  `|M⁻¹|`, the tether's drag slope `k_t (|v_t| + |v_c|)` through the attachment point's
  lever arm and `M⁻¹`, and `2 |ω|` for the rotation. In any ordinary condition `n = 1` and
  the step is exactly the single RK4 step it always was; only the stiff corners pay for
  sub-steps (30 to 90, about 0.5 ms of a step on the BEAM, for 1 000 m of tether in the
  strongest current). Sub-stepping was
  chosen over clamping the state (which would hide the instability as a vehicle shaking
  between limits) and over refusing combinations of current and tether length (whose
  stable region depends on the state and the thrust, not only on the inputs).
  `test/neptunus/sim/finite_test.exs` checks the accepted ranges with a property; the C
  loop (`Neptunus.Dynamics.Native`) takes the same sub-steps, bit for bit.
  """

  alias Neptunus.Dynamics.{Params, State, Thruster}

  @typedoc "Generalised body-frame force `{X, Y, Z, K, M, N}` in N and N·m."
  @type tau :: {float, float, float, float, float, float}

  @typedoc "The thesis' 4-DOF force `{X, Y, Z, N}` (accepted wherever `t:tau/0` is)."
  @type tau4 :: {float, float, float, float}

  @typedoc "Water current in NED, m/s."
  @type current :: {float, float, float}

  @still {0.0, 0.0, 0.0}
  # sub-steps: h·λ at most this (RK4 is stable on the negative real axis up to 2.78)
  @rk4_limit 2.0
  @max_substeps 1000
  @two_pi 2 * :math.pi()
  # 2-point Gauss–Legendre nodes on [0, 1] (weights 1/2 each)
  @gauss_1 0.5 - :math.sqrt(3) / 6
  @gauss_2 0.5 + :math.sqrt(3) / 6

  @doc """
  A parameter set from `priv/vehicles/` (cached; see `Neptunus.Dynamics.Params.fetch!/1`).
  `:thesis_4dof` is the thesis' model (eqs. 12.6–12.13), `:neptunus` the full 6-DOF vehicle.
  """
  @spec params(atom() | String.t()) :: Params.t()
  def params(name), do: Params.fetch!(name)

  @doc """
  Generalised force from the static thrust of the three normalised thruster commands
  (see `Neptunus.Allocation`: positive = forward for port/starboard, down for vertical).
  Commands are clamped to `[-1, 1]`; deadband and forward/reverse asymmetry apply, the
  thrusters' lag does not (see `Neptunus.Sim` for that).

      iex> p = Neptunus.Dynamics.params(:thesis_4dof)
      iex> Neptunus.Dynamics.tau_from_thrusters(%{port: 1.0, vertical: -0.5, starboard: 1.0}, p)
      {12.0, 0.0, -6.0, 0.0, 0.0, 0.0}
  """
  @spec tau_from_thrusters(map(), Params.t()) :: tau()
  def tau_from_thrusters(commands, %Params{thrusters: thrusters} = params) do
    forces = Enum.map(thrusters, &Thruster.force(&1, Map.get(commands, &1.name, 0.0)))
    tau_from_forces(forces, params)
  end

  @doc "Generalised force of the thrusters pushing with `forces` (N, in the order of `params.thrusters`)."
  @spec tau_from_forces([float()] | tuple(), Params.t()) :: tau()
  def tau_from_forces(forces, %Params{thrusters: thrusters}) when is_tuple(forces),
    do: tau_from_forces(Tuple.to_list(forces), thrusters, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0})

  def tau_from_forces(forces, %Params{thrusters: thrusters}),
    do: tau_from_forces(forces, thrusters, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0})

  defp tau_from_forces([f | fs], [%Thruster{wrench: w} | ts], {a, b, c, d, e, g}) do
    {w1, w2, w3, w4, w5, w6} = w

    tau_from_forces(
      fs,
      ts,
      {a + f * w1, b + f * w2, c + f * w3, d + f * w4, e + f * w5, g + f * w6}
    )
  end

  defp tau_from_forces([], [], tau), do: tau

  @doc "Sum of two generalised forces."
  @spec add_tau(tau(), tau()) :: tau()
  def add_tau({a1, a2, a3, a4, a5, a6}, {b1, b2, b3, b4, b5, b6}),
    do: {a1 + b1, a2 + b2, a3 + b3, a4 + b4, a5 + b5, a6 + b6}

  @doc """
  Time derivative of the state under constant `tau` and water `current` (NED, m/s).

  Returns a `State` whose fields hold the derivatives (`x` holds `ẋ`, `u` holds `u̇`, …).
  """
  @spec derivative(State.t(), tau() | tau4(), Params.t(), current()) :: State.t()
  def derivative(%State{} = s, tau, %Params{compiled: k}, current \\ @still),
    do: State.from_tuple(f(to_tuple(s), tau6(tau), kernel(k), float3(current)))

  @doc """
  Advances the state by `dt` seconds with one classical RK4 step, `tau` and `current`
  (NED, m/s) held constant over the step. `phi` and `psi` are wrapped to `[-π, π)`.
  """
  @spec step(State.t(), tau() | tau4(), number(), Params.t(), current()) :: State.t()
  def step(%State{} = s, tau, dt, %Params{compiled: k}, current \\ @still)
      when is_number(dt) and dt > 0 do
    s = to_tuple(s)
    c = float3(current)
    dt = dt * 1.0
    n = count_substeps(s, c, dt, k)
    state = State.from_tuple(rk4_n(s, tau6(tau), dt / n, k, c, n))
    %State{state | phi: wrap_pi(state.phi), psi: wrap_pi(state.psi)}
  end

  @doc """
  How many RK4 sub-steps `step/5` takes for a step of `dt` from `state` in `current`: 1 in
  any ordinary condition, more where the model is stiff (see "Integration" in the moduledoc).
  """
  @spec substeps(State.t(), current(), number(), Params.t()) :: pos_integer()
  def substeps(%State{} = s, current, dt, %Params{compiled: k}),
    do: count_substeps(to_tuple(s), float3(current), dt * 1.0, k)

  # as C's `b > a ? b : a`
  defp fmax(a, b) when b > a, do: b
  defp fmax(a, _b), do: a

  defp rk4_n(s, _tau, _h, _k, _c, 0), do: s
  defp rk4_n(s, tau, h, k, c, n), do: s |> rk4(tau, h, k, c) |> rk4_n(tau, h, k, c, n - 1)

  @doc """
  The tether's generalised force (body frame) in this state and current: see the moduledoc.
  Zero for a zero deployed length.
  """
  @spec tether_tau(State.t(), Params.t(), current()) :: tau()
  def tether_tau(%State{} = s, %Params{compiled: k}, current \\ @still) do
    {cn, ce, _cd} = float3(current)
    {_, _, _, phi, theta, psi, u, v, w, p, q, r} = to_tuple(s)
    {r11, r12, r13, r21, r22, r23, _r31, _r32, _r33} = rotation(phi, theta, psi)
    tether(u, v, w, p, q, r, r11, r12, r13, r21, r22, r23, cn, ce, k.tether_k, k.tether_at)
  end

  @doc """
  The rotation matrix `R(Θ)` body → NED, row-major, `R = R_z(ψ) R_y(θ) R_x(φ)`.

      iex> Neptunus.Dynamics.rotation(0.0, 0.0, 0.0)
      {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}
  """
  @spec rotation(float(), float(), float()) :: tuple()
  def rotation(phi, theta, psi) do
    sphi = :math.sin(phi)
    cphi = :math.cos(phi)
    sth = :math.sin(theta)
    cth = :math.cos(theta)
    spsi = :math.sin(psi)
    cpsi = :math.cos(psi)

    {cpsi * cth, -spsi * cphi + cpsi * sth * sphi, spsi * sphi + cpsi * cphi * sth, spsi * cth,
     cpsi * cphi + sphi * sth * spsi, -cpsi * sphi + sth * spsi * cphi, -sth, cth * sphi,
     cth * cphi}
  end

  @doc """
  Heading `ψ` in `[0, 2π)` radians.

      iex> Neptunus.Dynamics.heading(%Neptunus.Dynamics.State{psi: -:math.pi() / 2})
      3 * :math.pi() / 2
  """
  @spec heading(State.t()) :: float
  def heading(%State{psi: psi}), do: wrap_2pi(psi)

  @doc "An angle wrapped to `[0, 2π)`."
  @spec wrap_2pi(float()) :: float()
  def wrap_2pi(angle) do
    h = angle - @two_pi * :math.floor(angle / @two_pi)
    if h >= 0.0 and h < @two_pi, do: h + 0.0, else: 0.0
  end

  @doc "An angle wrapped to `[-π, π)`."
  @spec wrap_pi(float()) :: float()
  def wrap_pi(angle) do
    wrapped = angle - @two_pi * :math.floor((angle + :math.pi()) / @two_pi)

    # rounding can land exactly on π; fold it back to -π
    cond do
      wrapped >= :math.pi() -> wrapped - @two_pi
      wrapped < -:math.pi() -> wrapped + @two_pi
      true -> wrapped + 0.0
    end
  end

  @doc false
  # raised where pitch reaches ±90° (here and by Neptunus.Sim's C loop)
  @spec singular!(float()) :: no_return()
  def singular!(theta) do
    raise ArgumentError,
          "pitch θ = #{theta} rad is at ±90°, where Euler angles are singular " <>
            "(see Neptunus.Dynamics, Singularity)"
  end

  # --- the integration loop, on 12-tuples ---
  #
  # Written out in scalars with `is_float` guards on every input: the compiler then keeps
  # the arithmetic in float registers instead of boxing each intermediate result (about
  # twice as fast on OTP 25). This is most of the simulator's CPU time.

  # `is_float(a) and is_float(b) and …` for a list of variables, usable in guards
  defmacrop floats(vars) do
    vars
    |> Enum.map(&quote(do: is_float(unquote(&1))))
    |> Enum.reduce(&quote(do: unquote(&2) and unquote(&1)))
  end

  defp to_tuple(%State{x: x, y: y, z: z, phi: phi, theta: th, psi: psi} = s)
       when floats([x, y, z, phi, th, psi]) and floats([s.u, s.v, s.w, s.p, s.q, s.r]),
       do: {x, y, z, phi, th, psi, s.u, s.v, s.w, s.p, s.q, s.r}

  defp to_tuple(%State{} = s) do
    {s.x * 1.0, s.y * 1.0, s.z * 1.0, s.phi * 1.0, s.theta * 1.0, s.psi * 1.0, s.u * 1.0,
     s.v * 1.0, s.w * 1.0, s.p * 1.0, s.q * 1.0, s.r * 1.0}
  end

  defp tau6({x, y, z, k, m, n} = tau) when floats([x, y, z, k, m, n]), do: tau
  defp tau6({x, y, z, k, m, n}), do: {x * 1.0, y * 1.0, z * 1.0, k * 1.0, m * 1.0, n * 1.0}
  defp tau6({x, y, z, n}), do: {x * 1.0, y * 1.0, z * 1.0, 0.0, 0.0, n * 1.0}

  defp float3({a, b, c} = v) when floats([a, b, c]), do: v
  defp float3({a, b, c}), do: {a * 1.0, b * 1.0, c * 1.0}

  defp count_substeps(
         {_x, _y, _z, _phi, _theta, _psi, u, v, w, p, q, r},
         {cn, ce, cd},
         dt,
         %{tether_k: kt, d_l: dl, d_q: dq, stiffness: {m_abs, arm, gain}}
       )
       when floats([u, v, w, p, q, r, cn, ce, cd, dt, kt, arm, gain]) do
    {dl1, dl2, dl3, dl4, dl5, dl6} = dl
    {dq1, dq2, dq3, dq4, dq5, dq6} = dq
    vel = abs(u) + abs(v) + abs(w)
    rot = abs(p) + abs(q) + abs(r)
    c1 = abs(cn) + abs(ce) + abs(cd)

    # damping: |M⁻¹| times the slope of each DOF's damping, |ν_r| bounded by |ν| + |v_c|
    {b1, b2, b3, b4, b5, b6} =
      mat_vec(
        m_abs,
        dl1 + 2.0 * dq1 * (abs(u) + c1),
        dl2 + 2.0 * dq2 * (abs(v) + c1),
        dl3 + 2.0 * dq3 * (abs(w) + c1),
        dl4 + 2.0 * dq4 * (abs(p) + c1),
        dl5 + 2.0 * dq5 * (abs(q) + c1),
        dl6 + 2.0 * dq6 * (abs(r) + c1)
      )

    lam_d = b1 |> fmax(b2) |> fmax(b3) |> fmax(b4) |> fmax(b5) |> fmax(b6)
    # tether: drag slope kt · |w| with |w| ≤ attachment point speed + horizontal current
    lam_t = kt * (vel + rot * arm + (abs(cn) + abs(ce))) * gain
    lam = lam_d + lam_t + 2.0 * rot
    n = Float.ceil(dt * lam / @rk4_limit)

    cond do
      n <= 1.0 -> 1
      n >= @max_substeps -> @max_substeps
      true -> trunc(n)
    end
  end

  defp kernel(%{kernel: kernel}), do: kernel

  defp rk4(s, tau, dt, k, c) do
    kern = kernel(k)
    h = dt / 2
    k1 = f(s, tau, kern, c)
    k2 = f(axpy(s, h, k1), tau, kern, c)
    k3 = f(axpy(s, h, k2), tau, kern, c)
    k4 = f(axpy(s, dt, k3), tau, kern, c)
    combine(s, dt, k1, k2, k3, k4)
  end

  defp combine(
         {s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12},
         dt,
         {a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12},
         {b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11, b12},
         {c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12},
         {d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12}
       )
       when floats([s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12, dt]) and
              floats([a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12]) and
              floats([b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11, b12]) and
              floats([c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12]) and
              floats([d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12]) do
    {s1 + dt * ((a1 + 2.0 * b1 + 2.0 * c1 + d1) / 6.0),
     s2 + dt * ((a2 + 2.0 * b2 + 2.0 * c2 + d2) / 6.0),
     s3 + dt * ((a3 + 2.0 * b3 + 2.0 * c3 + d3) / 6.0),
     s4 + dt * ((a4 + 2.0 * b4 + 2.0 * c4 + d4) / 6.0),
     s5 + dt * ((a5 + 2.0 * b5 + 2.0 * c5 + d5) / 6.0),
     s6 + dt * ((a6 + 2.0 * b6 + 2.0 * c6 + d6) / 6.0),
     s7 + dt * ((a7 + 2.0 * b7 + 2.0 * c7 + d7) / 6.0),
     s8 + dt * ((a8 + 2.0 * b8 + 2.0 * c8 + d8) / 6.0),
     s9 + dt * ((a9 + 2.0 * b9 + 2.0 * c9 + d9) / 6.0),
     s10 + dt * ((a10 + 2.0 * b10 + 2.0 * c10 + d10) / 6.0),
     s11 + dt * ((a11 + 2.0 * b11 + 2.0 * c11 + d11) / 6.0),
     s12 + dt * ((a12 + 2.0 * b12 + 2.0 * c12 + d12) / 6.0)}
  end

  defp axpy(
         {s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12},
         h,
         {d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12}
       )
       when floats([s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12, h]) and
              floats([d1, d2, d3, d4, d5, d6, d7, d8, d9, d10, d11, d12]) do
    {s1 + h * d1, s2 + h * d2, s3 + h * d3, s4 + h * d4, s5 + h * d5, s6 + h * d6, s7 + h * d7,
     s8 + h * d8, s9 + h * d9, s10 + h * d10, s11 + h * d11, s12 + h * d12}
  end

  # The right-hand side: {η̇, ν̇} as a 12-tuple.
  defp f({_x, _y, _z, phi, theta, psi, u, v, w, p, q, r}, tau, kern, {cn, ce, cd})
       when floats([phi, theta, psi, u, v, w, p, q, r, cn, ce, cd]) do
    sphi = :math.sin(phi)
    cphi = :math.cos(phi)
    sth = :math.sin(theta)
    cth = :math.cos(theta)
    spsi = :math.sin(psi)
    cpsi = :math.cos(psi)

    if abs(cth) < 1.0e-6, do: singular!(theta)

    # R(Θ) = Rz(ψ) Ry(θ) Rx(φ), body → NED
    r11 = cpsi * cth
    r12 = -spsi * cphi + cpsi * sth * sphi
    r13 = spsi * sphi + cpsi * cphi * sth
    r21 = spsi * cth
    r22 = cpsi * cphi + sphi * sth * spsi
    r23 = -cpsi * sphi + sth * spsi * cphi
    r31 = -sth
    r32 = cth * sphi
    r33 = cth * cphi

    {m_c, m_inv, d_l, d_q, restoring, coriolis, locked, kt, at} = kern

    # kinematics η̇ = J(η) ν
    xd = r11 * u + r12 * v + r13 * w
    yd = r21 * u + r22 * v + r23 * w
    zd = r31 * u + r32 * v + r33 * w

    {phid, thd, psid} =
      if locked do
        {0.0, 0.0, r}
      else
        rot = sphi * q + cphi * r
        {p + rot * sth / cth, cphi * q - sphi * r, rot / cth}
      end

    # current in the body frame, v_c = Rᵀ v_cⁿ, and the relative velocity
    uc = r11 * cn + r21 * ce + r31 * cd
    vc = r12 * cn + r22 * ce + r32 * cd
    wc = r13 * cn + r23 * ce + r33 * cd
    ur = u - uc
    vr = v - vc
    wr = w - wc

    # Coriolis–centripetal C(ν_r) ν_r = [ω × a; v_r × a + ω × b], [a; b] = M ν_r
    cor =
      if coriolis do
        {a1, a2, a3, b1, b2, b3} = mat_vec(m_c, ur, vr, wr, p, q, r)
        coriolis_terms(ur, vr, wr, p, q, r, a1, a2, a3, b1, b2, b3)
      else
        {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
      end

    ext =
      if kt > 0.0 do
        tether(u, v, w, p, q, r, r11, r12, r13, r21, r22, r23, cn, ce, kt, at)
      else
        {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
      end

    {n1, n2, n3, n4, n5, n6} =
      kinetics(
        tau,
        ext,
        cor,
        d_l,
        d_q,
        restoring,
        m_inv,
        ur,
        vr,
        wr,
        p,
        q,
        r,
        sphi,
        cphi,
        sth,
        cth
      )

    # ν̇ = ν̇_r + v̇_c with v̇_c = v_c × ω
    {xd, yd, zd, phid, thd, psid, n1 + (vc * r - wc * q), n2 + (wc * p - uc * r),
     n3 + (uc * q - vc * p), n4, n5, n6}
  end

  defp coriolis_terms(ur, vr, wr, p, q, r, a1, a2, a3, b1, b2, b3)
       when floats([ur, vr, wr, p, q, r, a1, a2, a3, b1, b2, b3]) do
    {q * a3 - r * a2, r * a1 - p * a3, p * a2 - q * a1, vr * a3 - wr * a2 + q * b3 - r * b2,
     wr * a1 - ur * a3 + r * b1 - p * b3, ur * a2 - vr * a1 + p * b2 - q * b1}
  end

  # M ν̇_r = τ + τ_ext − C(ν_r)ν_r − D(ν_r)ν_r − g(η)
  defp kinetics(
         {t1, t2, t3, t4, t5, t6},
         {e1, e2, e3, e4, e5, e6},
         {c1, c2, c3, c4, c5, c6},
         {dl1, dl2, dl3, dl4, dl5, dl6},
         {dq1, dq2, dq3, dq4, dq5, dq6},
         {wb, gx, gy, gz},
         m_inv,
         ur,
         vr,
         wr,
         p,
         q,
         r,
         sphi,
         cphi,
         sth,
         cth
       )
       when floats([t1, t2, t3, t4, t5, t6, e1, e2, e3, e4, e5, e6]) and
              floats([c1, c2, c3, c4, c5, c6, dl1, dl2, dl3, dl4, dl5, dl6]) and
              floats([dq1, dq2, dq3, dq4, dq5, dq6, wb, gx, gy, gz]) and
              floats([ur, vr, wr, p, q, r, sphi, cphi, sth, cth]) do
    # restoring forces g(η)
    cthcphi = cth * cphi
    cthsphi = cth * sphi
    g1 = wb * sth
    g2 = -wb * cthsphi
    g3 = -wb * cthcphi
    g4 = -gy * cthcphi + gz * cthsphi
    g5 = gz * sth + gx * cthcphi
    g6 = -gx * cthsphi - gy * sth

    mat_vec(
      m_inv,
      t1 + e1 - c1 - (dl1 + dq1 * abs(ur)) * ur - g1,
      t2 + e2 - c2 - (dl2 + dq2 * abs(vr)) * vr - g2,
      t3 + e3 - c3 - (dl3 + dq3 * abs(wr)) * wr - g3,
      t4 + e4 - c4 - (dl4 + dq4 * abs(p)) * p - g4,
      t5 + e5 - c5 - (dl5 + dq5 * abs(q)) * q - g5,
      t6 + e6 - c6 - (dl6 + dq6 * abs(r)) * r - g6
    )
  end

  defp tether(u, v, w, p, q, r, r11, r12, r13, r21, r22, r23, cn, ce, kt, {ax, ay, az})
       when floats([u, v, w, p, q, r, r11, r12, r13, r21, r22, r23, cn, ce, kt, ax, ay, az]) do
    # attachment point velocity: body, then horizontal NED
    vx = u + q * az - r * ay
    vy = v + r * ax - p * az
    vz = w + p * ay - q * ax
    vn = r11 * vx + r12 * vy + r13 * vz
    ve = r21 * vx + r22 * vy + r23 * vz

    # −kt ∫₀¹ s |w(s)| w(s) ds, w(s) = s v_t − v_c, by 2-point Gauss–Legendre
    w1n = @gauss_1 * vn - cn
    w1e = @gauss_1 * ve - ce
    w2n = @gauss_2 * vn - cn
    w2e = @gauss_2 * ve - ce
    m1 = @gauss_1 * :math.sqrt(w1n * w1n + w1e * w1e)
    m2 = @gauss_2 * :math.sqrt(w2n * w2n + w2e * w2e)
    f_n = -kt * 0.5 * (m1 * w1n + m2 * w2n)
    f_e = -kt * 0.5 * (m1 * w1e + m2 * w2e)

    # to the body frame (Rᵀ), applied at the attachment point
    fx = r11 * f_n + r21 * f_e
    fy = r12 * f_n + r22 * f_e
    fz = r13 * f_n + r23 * f_e

    {fx, fy, fz, ay * fz - az * fy, az * fx - ax * fz, ax * fy - ay * fx}
  end

  defp mat_vec(
         {m11, m12, m13, m14, m15, m16, m21, m22, m23, m24, m25, m26, m31, m32, m33, m34, m35,
          m36, m41, m42, m43, m44, m45, m46, m51, m52, m53, m54, m55, m56, m61, m62, m63, m64,
          m65, m66},
         a,
         b,
         c,
         d,
         e,
         f
       )
       when floats([m11, m12, m13, m14, m15, m16, m21, m22, m23, m24, m25, m26]) and
              floats([m31, m32, m33, m34, m35, m36, m41, m42, m43, m44, m45, m46]) and
              floats([m51, m52, m53, m54, m55, m56, m61, m62, m63, m64, m65, m66]) and
              floats([a, b, c, d, e, f]) do
    {m11 * a + m12 * b + m13 * c + m14 * d + m15 * e + m16 * f,
     m21 * a + m22 * b + m23 * c + m24 * d + m25 * e + m26 * f,
     m31 * a + m32 * b + m33 * c + m34 * d + m35 * e + m36 * f,
     m41 * a + m42 * b + m43 * c + m44 * d + m45 * e + m46 * f,
     m51 * a + m52 * b + m53 * c + m54 * d + m55 * e + m56 * f,
     m61 * a + m62 * b + m63 * c + m64 * d + m65 * e + m66 * f}
  end
end
