defmodule Neptunus.Dynamics.State do
  @moduledoc """
  Vehicle state for `Neptunus.Dynamics`, SI units.

  Position and attitude in NED (`η`), velocities in the body frame (`ν`):

    * `x`, `y`, `z` — north, east, down position (m); `z` is depth
    * `phi`, `theta`, `psi` — roll, pitch, yaw (rad); `psi` is kept wrapped to
      `[-π, π)` by `Neptunus.Dynamics.step/4`
    * `u`, `v`, `w` — surge, sway, heave velocity (m/s)
    * `p`, `q`, `r` — roll, pitch, yaw rate (rad/s)

  In the 4-DOF model `phi`, `theta`, `p` and `q` stay `0.0`.

  `Neptunus.Dynamics.derivative/3` also returns this struct, with each field
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
end

defmodule Neptunus.Dynamics.Params do
  @moduledoc """
  Model coefficients for `Neptunus.Dynamics`, SI units.

  Vectors and matrices are plain lists in the degree-of-freedom order of
  `ν = [u v w r]` (surge, sway, heave, yaw):

    * `mass` — `M = M_A + M_RB` (kg, kg·m, kg·m²), list of rows
    * `mass_inv` — `M⁻¹`, precomputed once since `M` is constant
    * `d_l` — diagonal of the linear damping `D_l`
    * `d_q` — diagonal of the quadratic damping `D_q`; term `i` multiplies `|ν_i|`
    * `g` — restoring force vector (N, N·m); positive `g_w` means buoyant
    * `thruster_force` — `f`, force of one thruster at full command (N)
    * `yaw_arm` — `l`, moment arm of the side thrusters about the yaw axis (m)

  Build it with `Neptunus.Dynamics.params/1`; if you build one by hand,
  `mass_inv` must be the inverse of `mass`.
  """

  @enforce_keys [:mass, :mass_inv, :d_l, :d_q, :g, :thruster_force, :yaw_arm]
  defstruct @enforce_keys

  @type vector :: [float]
  @type matrix :: [vector]

  @type t :: %__MODULE__{
          mass: matrix,
          mass_inv: matrix,
          d_l: vector,
          d_q: vector,
          g: vector,
          thruster_force: float,
          yaw_arm: float
        }
end

defmodule Neptunus.Dynamics do
  @moduledoc """
  The thesis' 4-DOF vehicle model (ch. 12) integrated with classical RK4.

  Pure functions, SI units, radians.

  ## Model

  States `η = [x y z ψ]` (NED position and heading) and `ν = [u v w r]` (body
  velocities). Roll and pitch are zero; Coriolis and centripetal terms are
  neglected at these low speeds (eqs. 12.1–12.5):

      η̇ = J(ψ) ν                  ẋ = u cos ψ − v sin ψ
                                   ẏ = u sin ψ + v cos ψ
                                   ż = w
                                   ψ̇ = r

      M ν̇ + D(ν) ν + g = τ        ⇒  ν̇ = M⁻¹ (τ − D(ν) ν − g)

  with (eqs. 12.7–12.13, rows/columns in the order u, v, w, r)

      M   = M_A + M_RB
      M_A = [2.055 0 0 0; 0 14.6033 0 −0.8926; 0 0 2.3295 0; 0 −0.8926 0 0.1498]
      M_RB = diag(3.46, 3.46, 3.46, 0.399)
      D(ν) = D_l + D_q(ν)
      D_l = diag(2.2907, 4.9804, 15.1897, 0.2605)
      D_q = diag(4.008 |u|, 35.216 |v|, 10.304 |w|, 0.320 |r|)
      g   = [0, 0, 0.0234, 0]

  `g` is on the left-hand side, so the positive `g_w` accelerates the vehicle
  towards negative `w`: it is slightly buoyant and rises slowly with no thrust.
  The sway–yaw coupling `−0.8926` in `M_A` makes a yaw moment induce a transient
  sway velocity. Water current is ignored (`ν_r = ν`).

  `M` is constant, so `M⁻¹` is computed once (Gauss–Jordan) by `params/1`.

  ## Thrust

  `tau_from_thrusters/2` maps the three normalised thruster commands
  (see `Neptunus.Allocation`: positive = forward for port/starboard, down for
  vertical) to `τ = [X Y Z N]`:

      τ_X = f (u_port + u_starboard) / 2
      τ_Y = 0
      τ_Z = f u_vertical
      τ_N = f l (u_port − u_starboard)

  Derivation: with the unsaturated allocation of eq. 9.3,
  `u_port = k(X + M)`, `u_starboard = k(X − M)`, `u_vertical = k Z`, this gives
  `τ_X = f k X`, `τ_Z = f k Z`, `τ_N = f l · 2 k M`, which is exactly eq. 12.6
  `τ = [f k X, 0, f k Z, 2 f k l M]`. A positive `τ_N` (port pushing harder
  than starboard) turns the bow to starboard, positive `r`.

  Note that eq. 12.6, followed here as published, is not self-consistent about
  `f`: the yaw term treats `f` as the force of *each* side thruster (two
  thrusters at arm `l`), while the surge term gives only `f` (not `2f`) with
  both side thrusters at full command.

  ## Integration

  `step/4` performs one classical fourth-order Runge–Kutta step of the coupled
  kinematics and kinetics, with `τ` held constant over the step. After the step
  `ψ` is wrapped to `[-π, π)`; `heading/1` gives it in `[0, 2π)` for display.
  """

  alias Neptunus.Dynamics.{Params, State}

  @typedoc "Generalised body-frame force `{X, Y, Z, N}` in N, N, N and N·m."
  @type tau :: {x :: float, y :: float, z :: float, n :: float}

  # Body velocities that carry kinetics, in the row order of the Params matrices.
  @nu [:u, :v, :w, :r]
  @fields [:x, :y, :z, :phi, :theta, :psi, :u, :v, :w, :p, :q, :r]
  @two_pi 2 * :math.pi()

  @doc """
  Model coefficients. `:thesis_4dof` is the thesis' model (eqs. 12.6–12.13).
  """
  @spec params(:thesis_4dof) :: Params.t()
  def params(:thesis_4dof) do
    m_a = [
      [2.055, 0.0, 0.0, 0.0],
      [0.0, 14.6033, 0.0, -0.8926],
      [0.0, 0.0, 2.3295, 0.0],
      [0.0, -0.8926, 0.0, 0.1498]
    ]

    m_rb = diagonal([3.46, 3.46, 3.46, 0.399])
    mass = mat_add(m_a, m_rb)

    %Params{
      mass: mass,
      mass_inv: invert(mass),
      d_l: [2.2907, 4.9804, 15.1897, 0.2605],
      d_q: [4.008, 35.216, 10.304, 0.320],
      g: [0.0, 0.0, 0.0234, 0.0],
      thruster_force: 12.0,
      yaw_arm: 0.045
    }
  end

  @doc """
  Generalised force from the three normalised thruster commands.

  Commands are clamped to `[-1, 1]` (a thruster cannot exceed full force).
  See the moduledoc for the derivation from eq. 12.6.

      iex> p = Neptunus.Dynamics.params(:thesis_4dof)
      iex> Neptunus.Dynamics.tau_from_thrusters(%{port: 1.0, vertical: -0.5, starboard: 1.0}, p)
      {12.0, 0.0, -6.0, 0.0}
  """
  @spec tau_from_thrusters(Neptunus.Allocation.thrusters(), Params.t()) :: tau()
  def tau_from_thrusters(%{port: port, vertical: vertical, starboard: starboard}, %Params{
        thruster_force: f,
        yaw_arm: l
      }) do
    port = clamp_unit(port)
    vertical = clamp_unit(vertical)
    starboard = clamp_unit(starboard)

    {f * (port + starboard) / 2, 0.0, f * vertical, f * l * (port - starboard)}
  end

  @doc """
  Time derivative of the state under constant `tau`.

  Returns a `State` whose fields hold the derivatives (`x` holds `ẋ`, `u` holds
  `u̇`, …). `phi`, `theta`, `p` and `q` derivatives are zero in this model.
  """
  @spec derivative(State.t(), tau(), Params.t()) :: State.t()
  def derivative(%State{} = s, {tx, ty, tz, tn}, %Params{} = params) do
    nu = Enum.map(@nu, &Map.fetch!(s, &1))
    tau = [tx, ty, tz, tn]

    damping =
      [params.d_l, params.d_q, nu]
      |> Enum.zip_with(fn [dl, dq, n] -> (dl + dq * abs(n)) * n end)

    rhs =
      [tau, damping, params.g]
      |> Enum.zip_with(fn [t, d, g] -> t - d - g end)

    [u_dot, v_dot, w_dot, r_dot] = mat_vec(params.mass_inv, rhs)

    cos_psi = :math.cos(s.psi)
    sin_psi = :math.sin(s.psi)

    %State{
      x: s.u * cos_psi - s.v * sin_psi,
      y: s.u * sin_psi + s.v * cos_psi,
      z: s.w,
      psi: s.r,
      u: u_dot,
      v: v_dot,
      w: w_dot,
      r: r_dot
    }
  end

  @doc """
  Advances the state by `dt` seconds with one classical RK4 step.

  `tau` is held constant over the step. `psi` is wrapped to `[-π, π)` afterwards.
  """
  @spec step(State.t(), tau(), number(), Params.t()) :: State.t()
  def step(%State{} = s, tau, dt, %Params{} = params) when is_number(dt) and dt > 0 do
    k1 = derivative(s, tau, params)
    k2 = derivative(add_scaled(s, dt / 2, k1), tau, params)
    k3 = derivative(add_scaled(s, dt / 2, k2), tau, params)
    k4 = derivative(add_scaled(s, dt, k3), tau, params)

    next =
      Map.new(@fields, fn field ->
        slope =
          (Map.fetch!(k1, field) + 2 * Map.fetch!(k2, field) + 2 * Map.fetch!(k3, field) +
             Map.fetch!(k4, field)) / 6

        {field, Map.fetch!(s, field) + dt * slope}
      end)

    struct!(State, %{next | psi: wrap_pi(next.psi)})
  end

  @doc """
  Heading `ψ` in `[0, 2π)` radians.

      iex> Neptunus.Dynamics.heading(%Neptunus.Dynamics.State{psi: -:math.pi() / 2})
      3 * :math.pi() / 2
  """
  @spec heading(State.t()) :: float
  def heading(%State{psi: psi}) do
    h = psi - @two_pi * :math.floor(psi / @two_pi)
    if h >= 0.0 and h < @two_pi, do: h + 0.0, else: 0.0
  end

  # ψ wrapped to [-π, π). Rounding can land exactly on π; fold it back to -π.
  defp wrap_pi(angle) do
    wrapped = angle - @two_pi * :math.floor((angle + :math.pi()) / @two_pi)

    cond do
      wrapped >= :math.pi() -> wrapped - @two_pi
      wrapped < -:math.pi() -> wrapped + @two_pi
      true -> wrapped + 0.0
    end
  end

  defp add_scaled(%State{} = s, h, %State{} = ds) do
    Enum.reduce(@fields, s, fn field, acc ->
      Map.put(acc, field, Map.fetch!(s, field) + h * Map.fetch!(ds, field))
    end)
  end

  defp clamp_unit(value) when is_number(value),
    do: value |> max(-1.0) |> min(1.0) |> Kernel.*(1.0)

  # --- small dense linear algebra on lists of rows ---

  defp diagonal(values) do
    n = length(values)

    values
    |> Enum.with_index()
    |> Enum.map(fn {value, i} -> List.duplicate(0.0, n) |> List.replace_at(i, value) end)
  end

  defp mat_add(a, b) do
    Enum.zip_with(a, b, fn row_a, row_b -> Enum.zip_with(row_a, row_b, &(&1 + &2)) end)
  end

  defp mat_vec(m, vec) do
    Enum.map(m, fn row -> row |> Enum.zip_with(vec, &(&1 * &2)) |> Enum.sum() end)
  end

  # Gauss–Jordan elimination with partial pivoting on [A | I]. Raises on a singular matrix.
  defp invert(a) do
    n = length(a)
    identity = diagonal(List.duplicate(1.0, n))
    augmented = Enum.zip_with(a, identity, &(&1 ++ &2))

    0..(n - 1)
    |> Enum.reduce(augmented, fn col, rows ->
      {pivot_row, pivot_index} =
        rows
        |> Enum.with_index()
        |> Enum.drop(col)
        |> Enum.max_by(fn {row, _} -> abs(Enum.at(row, col)) end)

      pivot = Enum.at(pivot_row, col)
      if abs(pivot) < 1.0e-12, do: raise(ArgumentError, "mass matrix is singular")

      normalised = Enum.map(pivot_row, &(&1 / pivot))

      rows
      |> List.replace_at(pivot_index, Enum.at(rows, col))
      |> List.replace_at(col, normalised)
      |> Enum.with_index()
      |> Enum.map(fn
        {row, ^col} ->
          row

        {row, _} ->
          factor = Enum.at(row, col)
          Enum.zip_with(row, normalised, fn x, y -> x - factor * y end)
      end)
    end)
    |> Enum.map(&Enum.drop(&1, n))
  end
end
