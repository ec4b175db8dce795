defmodule Neptunus.Dynamics.Params do
  @moduledoc """
  A vehicle parameter set for `Neptunus.Dynamics` and `Neptunus.Sim`, loaded from
  `priv/vehicles/<name>.json` and validated. SI units; body frame x forward, y starboard,
  z down; DOF order `ν = [u v w p q r]` (surge, sway, heave, roll, pitch, yaw).

  Shipped sets (`available/0`):

    * `thesis-4dof` — exactly the thesis' equations 12.1–12.13: roll and pitch fixed at
      zero (`"dof": 4`), no Coriolis, constant restoring force, eq. 12.6 thrust, no thruster
      dynamics, no tether.
    * `neptunus` — the thesis' coefficients in surge, sway, heave and yaw plus roll/pitch
      inertia, added mass, damping and a metacentric height, Coriolis, thruster dynamics
      (rise, reverse/forward asymmetry, deadband) and a tether.

  ## File format

      {
        "name": "neptunus",                  // must match the file name
        "description": "…",
        "dof": 6,                            // 6, or 4: roll and pitch fixed at zero
        "coriolis": "rigid_body",            // C(ν_r)ν_r from M_RB, from M_RB + M_A ("full"), or "none"
        "water_density": 1000,               // kg/m³
        "rigid_body": {
          "mass": 3.46,                      // kg
          "inertia": [[Ixx, Ixy, Ixz], …],   // kg·m² about the body origin (CO)
          "r_g": [0, 0, 0]                   // centre of gravity from CO, m
        },
        "added_mass": [[…6…], …6 rows…],     // M_A (symmetric, positive semi-definite)
        "damping": {"linear": [6], "quadratic": [6]},   // diagonals of D_l and D_q
        "restoring": {"gravity": 9.81, "net_buoyancy": 0.0234, "r_b": [0, 0, -0.02]},
        "thrusters": [{"name": "port", "position": [x, y, z], "direction": [dx, dy, dz],
                       "forward": 6, "reverse": 4, "deadband": 0.05, "time_constant": 0.2}, …],
                                             // names: port, vertical, starboard, lateral
        "tether": {"length": 10, "diameter": 0.003, "drag_coefficient": 1.2,
                   "attachment": [x, y, z]},
        "sensors": {"rate": 20, "wild_rate": 0.002, "mixup_rate": 0.0005,
                    "depth": {"noise": σ, "bias": b}, "heading": …, "roll": …,
                    "pitch": …, "voltage": …, "current": …},
        "power": {"battery": 12.6, "resistance": 0.25, "idle": 0.3, "per_thruster": 2.0}
      }

  `net_buoyancy` is `B − W` in N (positive: the vehicle floats up); `W = mass · gravity`.
  The thruster, tether, sensor and power fields are documented in `Neptunus.Dynamics.Thruster`,
  `Neptunus.Dynamics`, `Neptunus.Sim.Sensors` and `Neptunus.Sim`.

  ## Derived fields

    * `rigid_body_matrix` — `M_RB = [m I, −m S(r_g); m S(r_g), I_o]` (Fossen 2011, eq. 3.44)
    * `mass_matrix` — `M = M_RB + M_A`
    * `mass_inv` — `M⁻¹` over the free DOFs (rows and columns of fixed DOFs are zero)
    * `compiled` — flattened tuples and constants used by the integration loop
  """

  alias Neptunus.Dynamics.{Linear, Thruster}
  alias Neptunus.Validate, as: V

  @enforce_keys [
    :name,
    :dof,
    :coriolis,
    :mass,
    :inertia,
    :r_g,
    :added_mass,
    :rigid_body_matrix,
    :mass_matrix,
    :mass_inv,
    :d_l,
    :d_q,
    :gravity,
    :net_buoyancy,
    :r_b,
    :water_density,
    :thrusters,
    :tether,
    :sensors,
    :power,
    :compiled
  ]
  defstruct [:description | @enforce_keys]

  @type vector :: [float()]
  @type matrix :: [vector()]

  @typedoc "Tether: deployed length, diameter (m), normal drag coefficient, attachment point (body, m)."
  @type tether :: %{
          length: float(),
          diameter: float(),
          drag_coefficient: float(),
          attachment: vector()
        }

  @typedoc "Noise standard deviation and constant bias of one measured channel (its SI unit)."
  @type channel :: %{noise: float(), bias: float()}

  @type sensors :: %{
          rate: float(),
          wild_rate: float(),
          mixup_rate: float(),
          channels: %{atom() => channel()}
        }

  @type power :: %{battery: float(), resistance: float(), idle: float(), per_thruster: float()}

  @type t :: %__MODULE__{
          name: String.t(),
          description: String.t() | nil,
          dof: 4 | 6,
          coriolis: :none | :rigid_body | :full,
          mass: float(),
          inertia: matrix(),
          r_g: vector(),
          added_mass: matrix(),
          rigid_body_matrix: matrix(),
          mass_matrix: matrix(),
          mass_inv: matrix(),
          d_l: vector(),
          d_q: vector(),
          gravity: float(),
          net_buoyancy: float(),
          r_b: vector(),
          water_density: float(),
          thrusters: [Thruster.t()],
          tether: tether(),
          sensors: sensors(),
          power: power(),
          compiled: map() | nil
        }

  @channels ~w(depth heading roll pitch voltage current)
  @thruster_names ~w(port vertical starboard lateral)
  @top ~w(name dof coriolis water_density rigid_body added_mass damping restoring thrusters
          tether sensors power)

  @doc "Names of the parameter sets in `priv/vehicles/`."
  @spec available() :: [String.t()]
  def available do
    dir()
    |> Path.join("*.json")
    |> Path.wildcard()
    |> Enum.map(&Path.basename(&1, ".json"))
    |> Enum.sort()
  end

  @doc """
  Loads and validates `priv/vehicles/<name>.json`. Names are `[a-z0-9-]+`; an atom is
  accepted with `_` for `-` (`:thesis_4dof`).
  """
  @spec load(String.t() | atom()) :: {:ok, t()} | {:error, String.t()}
  def load(name) when is_atom(name),
    do: name |> Atom.to_string() |> String.replace("_", "-") |> load()

  def load(name) when is_binary(name) do
    cond do
      not Regex.match?(~r/\A[a-z0-9][a-z0-9-]*\z/, name) ->
        {:error, "unknown vehicle #{inspect(name)} (available: #{Enum.join(available(), ", ")})"}

      not File.exists?(path(name)) ->
        {:error, "unknown vehicle #{inspect(name)} (available: #{Enum.join(available(), ", ")})"}

      true ->
        load_file(path(name), name)
    end
  end

  @doc "Loads and validates a parameter file; `name`, if given, must match its `name` field."
  @spec load_file(Path.t(), String.t() | nil) :: {:ok, t()} | {:error, String.t()}
  def load_file(file, name \\ nil) do
    with {:ok, json} <- V.read_file(file),
         {:ok, map} <- Neptunus.JSON.decode(json),
         {:ok, params} <- from_map(map),
         :ok <- check_name(params, name) do
      {:ok, params}
    else
      {:error, reason} -> {:error, "#{Path.relative_to_cwd(file)}: #{reason}"}
    end
  end

  @doc """
  Like `load/1` but cached in `:persistent_term`: parameter files are read once per node
  (use `load/1` to re-read one).
  """
  @spec load_cached(String.t() | atom()) :: {:ok, t()} | {:error, String.t()}
  def load_cached(name) do
    key = {__MODULE__, name}

    case :persistent_term.get(key, nil) do
      nil ->
        with {:ok, params} <- load(name) do
          :persistent_term.put(key, params)
          {:ok, params}
        end

      params ->
        {:ok, params}
    end
  end

  @doc "Like `load_cached/1`, raising `ArgumentError` on error."
  @spec fetch!(String.t() | atom()) :: t()
  def fetch!(name) do
    case load_cached(name) do
      {:ok, params} -> params
      {:error, reason} -> raise ArgumentError, reason
    end
  end

  @doc "Validates a decoded parameter document (string keys) and derives the model matrices."
  @spec from_map(term()) :: {:ok, t()} | {:error, String.t()}
  def from_map(map) do
    with :ok <- V.object(map, "", @top, ["description"]),
         {:ok, name} <- V.required(map, "", "name", &V.string/2),
         {:ok, description} <- V.optional(map, "", "description", nil, &V.string/2),
         {:ok, dof} <- V.required(map, "", "dof", &dof/2),
         {:ok, coriolis} <- V.required(map, "", "coriolis", &coriolis/2),
         {:ok, rho} <- V.required(map, "", "water_density", &positive/2),
         {:ok, rb} <- rigid_body(map["rigid_body"], "rigid_body"),
         {:ok, m_a} <- V.matrix(map["added_mass"], "added_mass", 6, 6),
         :ok <- symmetric(m_a, "added_mass"),
         {:ok, {d_l, d_q}} <- damping(map["damping"], "damping"),
         {:ok, restoring} <- restoring(map["restoring"], "restoring"),
         {:ok, thrusters} <- thrusters(map["thrusters"], "thrusters"),
         {:ok, tether} <- tether(map["tether"], "tether"),
         {:ok, sensors} <- sensors(map["sensors"], "sensors"),
         {:ok, power} <- power(map["power"], "power"),
         m_rb = rigid_body_matrix(rb),
         mass_matrix = Linear.add(m_rb, m_a),
         free = free_dofs(dof),
         :ok <- positive_definite(mass_matrix, free) do
      params = %__MODULE__{
        name: name,
        description: description,
        dof: dof,
        coriolis: coriolis,
        mass: rb.mass,
        rigid_body_matrix: m_rb,
        inertia: rb.inertia,
        r_g: rb.r_g,
        added_mass: m_a,
        mass_matrix: mass_matrix,
        mass_inv: inverse_on(mass_matrix, free),
        d_l: d_l,
        d_q: d_q,
        gravity: restoring.gravity,
        net_buoyancy: restoring.net_buoyancy,
        r_b: restoring.r_b,
        water_density: rho,
        thrusters: thrusters,
        tether: tether,
        sensors: sensors,
        power: power,
        compiled: nil
      }

      {:ok, compile(params)}
    end
  end

  @doc """
  Parameter set `name` with the vehicle differing from it by the given factors — the model
  is never exact, and the control must hold anyway (`test/neptunus/robust_test.exs`):

    * `mass` — the rigid-body mass and the translational block of the added mass;
    * `inertia` — the rigid-body inertia and the rotational block of the added mass (the
      coupling terms by `√(mass · inertia)`, so the mass matrix stays positive definite);
    * `damping` — the linear and quadratic damping;
    * `thrust` — every thruster's forward and reverse thrust.

  Factors default to 1 and must be > 0. The net buoyancy is kept (it is measured as such).
  """
  @spec scaled(String.t(), %{optional(atom()) => number()}) :: {:ok, t()} | {:error, String.t()}
  def scaled(name, factors) do
    f = fn key -> Map.get(factors, key, 1.0) * 1.0 end

    with :ok <- positive_factors(factors),
         {:ok, json} <- V.read_file(path(name)),
         {:ok, map} <- Neptunus.JSON.decode(json) do
      {m, i, d, t} = {f.(:mass), f.(:inertia), f.(:damping), f.(:thrust)}
      cross = :math.sqrt(m * i)

      block = fn r, c ->
        if r < 3 and c < 3, do: m, else: if(r >= 3 and c >= 3, do: i, else: cross)
      end

      map
      |> update_in(["rigid_body", "mass"], &(&1 * m))
      |> update_in(["rigid_body", "inertia"], &scale_matrix(&1, fn _, _ -> i end))
      |> update_in(["added_mass"], &scale_matrix(&1, block))
      |> update_in(["damping", "linear"], &Enum.map(&1, fn x -> x * d end))
      |> update_in(["damping", "quadratic"], &Enum.map(&1, fn x -> x * d end))
      |> update_in(["thrusters"], fn thrusters ->
        Enum.map(
          thrusters,
          &(&1
            |> Map.update!("forward", fn x -> x * t end)
            |> Map.update!("reverse", fn x -> x * t end))
        )
      end)
      |> from_map()
    end
  end

  defp positive_factors(factors) do
    case Enum.find(factors, fn {key, x} ->
           key not in [:mass, :inertia, :damping, :thrust] or not (is_number(x) and x > 0)
         end) do
      nil ->
        :ok

      {key, x} ->
        {:error,
         "scale factor #{key} must be one of mass, inertia, damping, thrust and > 0, got #{inspect(x)}"}
    end
  end

  defp scale_matrix(rows, factor) do
    rows
    |> Enum.with_index()
    |> Enum.map(fn {row, r} ->
      row |> Enum.with_index() |> Enum.map(fn {x, c} -> x * factor.(r, c) end)
    end)
  end

  @doc "The same parameters with another deployed tether length (m, ≥ 0)."
  @spec with_tether_length(t(), number()) :: t()
  def with_tether_length(%__MODULE__{} = params, length) when is_number(length) and length >= 0,
    do: compile(%{params | tether: %{params.tether | length: length * 1.0}})

  @doc "Weight `W = m g` (N)."
  @spec weight(t()) :: float()
  def weight(%__MODULE__{mass: m, gravity: g}), do: m * g

  @doc "Buoyancy `B = W + net_buoyancy` (N)."
  @spec buoyancy(t()) :: float()
  def buoyancy(%__MODULE__{} = p), do: weight(p) + p.net_buoyancy

  @doc "Indices (0..5 in `ν = [u v w p q r]`) of the DOFs that move: all 6, or u, v, w, r."
  @spec free_dofs(4 | 6) :: [0..5]
  def free_dofs(6), do: [0, 1, 2, 3, 4, 5]
  def free_dofs(4), do: [0, 1, 2, 5]

  # The constants of the integration loop, as flat tuples (see Neptunus.Dynamics).
  defp compile(%__MODULE__{} = p) do
    w = weight(p)
    b = buoyancy(p)
    [xg, yg, zg] = p.r_g
    [xb, yb, zb] = p.r_b
    t = p.tether

    compiled = %{
      # the matrix whose Coriolis–centripetal terms are modelled (nil: none)
      m: coriolis_matrix(p),
      m_inv: flat(p.mass_inv),
      d_l: List.to_tuple(p.d_l),
      d_q: List.to_tuple(p.d_q),
      # W − B is −net_buoyancy exactly (not the difference of two large numbers)
      wb: -p.net_buoyancy,
      gx: xg * w - xb * b,
      gy: yg * w - yb * b,
      gz: zg * w - zb * b,
      coriolis: p.coriolis != :none,
      locked: p.dof == 4,
      tether_k: 0.5 * p.water_density * t.drag_coefficient * t.diameter * t.length,
      tether_at: List.to_tuple(t.attachment)
    }

    compiled = Map.put(compiled, :stiffness, stiffness(compiled))

    # the same constants as one tuple, unpacked once per step by Neptunus.Dynamics
    kernel =
      {compiled.m, compiled.m_inv, compiled.d_l, compiled.d_q,
       {compiled.wb, compiled.gx, compiled.gy, compiled.gz}, compiled.coriolis, compiled.locked,
       compiled.tether_k, compiled.tether_at}

    compiled =
      compiled |> Map.put(:kernel, kernel) |> Map.put(:native, native_kernel(compiled, p))

    %{p | compiled: compiled}
  end

  # The constants of Neptunus.Dynamics' sub-step count (see "Integration" there):
  # {|M⁻¹| (entry by entry), arm, tether gain}. `arm` = |x_t| + |y_t| + |z_t| of the tether
  # attachment; the tether gain bounds how fast a change of the attachment point's velocity
  # changes ν̇ per unit of tether stiffness: ‖M⁻¹ Gᵀ‖∞ · (1 + arm), with Gᵀ the generalised
  # force of a unit force at the attachment point in each body axis. (The drag's slope is
  # k_t Σ g_i² |w_i| ≤ ⅔ k_t (|v_t| + |v_c|): the margin covers the rotation to NED.)
  defp stiffness(c) do
    {ax, ay, az} = c.tether_at
    m_abs = c.m_inv |> Tuple.to_list() |> Enum.map(&abs/1) |> List.to_tuple()
    arm = abs(ax) + abs(ay) + abs(az)
    rows = Tuple.to_list(c.m_inv) |> Enum.chunk_every(6)

    columns = [
      [1.0, 0.0, 0.0, 0.0, az, -ay],
      [0.0, 1.0, 0.0, -az, 0.0, ax],
      [0.0, 0.0, 1.0, ay, -ax, 0.0]
    ]

    gain =
      rows
      |> Enum.map(fn row ->
        columns
        |> Enum.map(fn col -> abs(Enum.zip_with(row, col, &(&1 * &2)) |> Enum.sum()) end)
        |> Enum.sum()
      end)
      |> Enum.max()

    {m_abs, arm, gain * (1.0 + arm)}
  end

  # The same constants as native-endian doubles for the C loop (Neptunus.Dynamics.Native;
  # the layout is documented in c_src/neptunus_dynamics_nif.c).
  defp native_kernel(c, %__MODULE__{thrusters: thrusters}) do
    m = c.m || List.to_tuple(List.duplicate(0.0, 36))
    flag = fn b -> if b, do: 1.0, else: 0.0 end

    values =
      Tuple.to_list(m) ++
        Tuple.to_list(c.m_inv) ++
        Tuple.to_list(c.d_l) ++
        Tuple.to_list(c.d_q) ++
        [c.wb, c.gx, c.gy, c.gz, flag.(c.coriolis), flag.(c.locked), c.tether_k] ++
        Tuple.to_list(c.tether_at) ++
        [length(thrusters) * 1.0] ++
        Enum.flat_map(thrusters, &Tuple.to_list(&1.wrench)) ++
        Tuple.to_list(elem(c.stiffness, 0)) ++
        [elem(c.stiffness, 1), elem(c.stiffness, 2)]

    for value <- values, into: <<>>, do: <<value * 1.0::float-64-native>>
  end

  defp coriolis_matrix(%__MODULE__{coriolis: :none}), do: nil
  defp coriolis_matrix(%__MODULE__{coriolis: :rigid_body} = p), do: flat(p.rigid_body_matrix)
  defp coriolis_matrix(%__MODULE__{coriolis: :full} = p), do: flat(p.mass_matrix)

  defp flat(matrix), do: matrix |> List.flatten() |> List.to_tuple()

  defp rigid_body_matrix(%{mass: m, inertia: inertia, r_g: r_g}) do
    s = Linear.skew(r_g)
    eye = Linear.diagonal([m, m, m])
    Linear.blocks(eye, Linear.scale(s, -m), Linear.scale(s, m), inertia)
  end

  defp inverse_on(matrix, free) do
    inv = matrix |> Linear.take(free) |> Linear.invert()
    position = free |> Enum.with_index() |> Map.new()

    for i <- 0..5 do
      for j <- 0..5 do
        case {position[i], position[j]} do
          {nil, _} -> 0.0
          {_, nil} -> 0.0
          {a, b} -> inv |> Enum.at(a) |> Enum.at(b)
        end
      end
    end
  end

  # --- validation of the sections ---

  defp coriolis("none", _path), do: {:ok, :none}
  defp coriolis("rigid_body", _path), do: {:ok, :rigid_body}
  defp coriolis("full", _path), do: {:ok, :full}

  defp coriolis(value, path),
    do: {:error, "#{path} must be \"none\", \"rigid_body\" or \"full\", got #{V.show(value)}"}

  defp dof(4, _path), do: {:ok, 4}
  defp dof(6, _path), do: {:ok, 6}
  defp dof(value, path), do: {:error, "#{path} must be 4 or 6, got #{V.show(value)}"}

  defp positive(value, path), do: V.number(value, path, greater_than: 0)
  defp non_negative(value, path), do: V.number(value, path, min: 0)

  defp rigid_body(map, path) do
    with :ok <- V.object(map, path, ~w(mass inertia r_g)),
         {:ok, mass} <- V.required(map, path, "mass", &positive/2),
         {:ok, inertia} <- V.matrix(map["inertia"], V.join(path, "inertia"), 3, 3),
         :ok <- symmetric(inertia, V.join(path, "inertia")),
         {:ok, r_g} <- V.vector(map["r_g"], V.join(path, "r_g"), 3) do
      {:ok, %{mass: mass, inertia: inertia, r_g: r_g}}
    end
  end

  defp damping(map, path) do
    with :ok <- V.object(map, path, ~w(linear quadratic)),
         {:ok, d_l} <- V.vector(map["linear"], V.join(path, "linear"), 6, min: 0),
         {:ok, d_q} <- V.vector(map["quadratic"], V.join(path, "quadratic"), 6, min: 0) do
      {:ok, {d_l, d_q}}
    end
  end

  defp restoring(map, path) do
    with :ok <- V.object(map, path, ~w(gravity net_buoyancy r_b)),
         {:ok, gravity} <- V.required(map, path, "gravity", &positive/2),
         {:ok, net} <- V.required(map, path, "net_buoyancy", &V.number/2),
         {:ok, r_b} <- V.vector(map["r_b"], V.join(path, "r_b"), 3) do
      {:ok, %{gravity: gravity, net_buoyancy: net, r_b: r_b}}
    end
  end

  defp thrusters(list, path) when is_list(list) and list != [] do
    list
    |> Enum.with_index()
    |> Enum.reduce_while({:ok, []}, fn {map, i}, {:ok, acc} ->
      case thruster(map, V.join(path, i)) do
        {:ok, thruster} ->
          if Enum.any?(acc, &(&1.name == thruster.name)),
            do: {:halt, {:error, "#{V.join(path, i)}.name #{thruster.name} is listed twice"}},
            else: {:cont, {:ok, [thruster | acc]}}

        error ->
          {:halt, error}
      end
    end)
    |> case do
      {:ok, acc} -> {:ok, Enum.reverse(acc)}
      error -> error
    end
  end

  defp thrusters(value, path),
    do: {:error, "#{path} must be a non-empty list of thrusters, got #{V.show(value)}"}

  defp thruster(map, path) do
    keys = ~w(name position direction forward reverse deadband time_constant)

    with :ok <- V.object(map, path, keys),
         {:ok, name} <- V.required(map, path, "name", &thruster_name/2),
         {:ok, position} <- V.vector(map["position"], V.join(path, "position"), 3),
         {:ok, direction} <- V.vector(map["direction"], V.join(path, "direction"), 3),
         {:ok, direction} <- unit(direction, V.join(path, "direction")),
         {:ok, forward} <- V.required(map, path, "forward", &non_negative/2),
         {:ok, reverse} <- V.required(map, path, "reverse", &non_negative/2),
         {:ok, deadband} <-
           V.required(map, path, "deadband", &V.number(&1, &2, min: 0, max: 0.99)),
         {:ok, tc} <- V.required(map, path, "time_constant", &non_negative/2) do
      {:ok,
       Thruster.new(
         name: name,
         position: position,
         direction: direction,
         forward: forward,
         reverse: reverse,
         deadband: deadband,
         time_constant: tc
       )}
    end
  end

  defp thruster_name(name, _path) when name in @thruster_names, do: {:ok, String.to_atom(name)}

  defp thruster_name(value, path),
    do:
      {:error, "#{path} must be one of port, vertical, starboard, lateral, got #{V.show(value)}"}

  defp unit([x, y, z], path) do
    norm = :math.sqrt(x * x + y * y + z * z)

    if norm < 1.0e-9,
      do: {:error, "#{path} must not be the zero vector"},
      else: {:ok, [x / norm, y / norm, z / norm]}
  end

  defp tether(map, path) do
    with :ok <- V.object(map, path, ~w(length diameter drag_coefficient attachment)),
         {:ok, length} <- V.required(map, path, "length", &non_negative/2),
         {:ok, diameter} <- V.required(map, path, "diameter", &positive/2),
         {:ok, cd} <- V.required(map, path, "drag_coefficient", &non_negative/2),
         {:ok, at} <- V.vector(map["attachment"], V.join(path, "attachment"), 3) do
      {:ok, %{length: length, diameter: diameter, drag_coefficient: cd, attachment: at}}
    end
  end

  defp sensors(map, path) do
    with :ok <- V.object(map, path, ~w(rate wild_rate mixup_rate) ++ @channels),
         {:ok, rate} <- V.required(map, path, "rate", &positive/2),
         {:ok, wild} <- V.required(map, path, "wild_rate", &V.number(&1, &2, min: 0, max: 1)),
         {:ok, mixup} <- V.required(map, path, "mixup_rate", &V.number(&1, &2, min: 0, max: 1)),
         {:ok, channels} <- channels(map, path) do
      if wild + mixup > 1.0,
        do: {:error, "#{path}.wild_rate + #{path}.mixup_rate must be at most 1"},
        else: {:ok, %{rate: rate, wild_rate: wild, mixup_rate: mixup, channels: channels}}
    end
  end

  defp channels(map, path) do
    Enum.reduce_while(@channels, {:ok, %{}}, fn key, {:ok, acc} ->
      cpath = V.join(path, key)

      with :ok <- V.object(map[key], cpath, ~w(noise bias)),
           {:ok, noise} <- V.required(map[key], cpath, "noise", &non_negative/2),
           {:ok, bias} <- V.required(map[key], cpath, "bias", &V.number/2) do
        {:cont, {:ok, Map.put(acc, String.to_atom(key), %{noise: noise, bias: bias})}}
      else
        error -> {:halt, error}
      end
    end)
  end

  defp power(map, path) do
    with :ok <- V.object(map, path, ~w(battery resistance idle per_thruster)),
         {:ok, battery} <- V.required(map, path, "battery", &positive/2),
         {:ok, resistance} <- V.required(map, path, "resistance", &non_negative/2),
         {:ok, idle} <- V.required(map, path, "idle", &non_negative/2),
         {:ok, per} <- V.required(map, path, "per_thruster", &non_negative/2) do
      {:ok, %{battery: battery, resistance: resistance, idle: idle, per_thruster: per}}
    end
  end

  defp symmetric(m, path) do
    n = length(m)

    asymmetric =
      for i <- 0..(n - 1), j <- (i + 1)..(n - 1)//1, reduce: nil do
        nil ->
          a = m |> Enum.at(i) |> Enum.at(j)
          b = m |> Enum.at(j) |> Enum.at(i)
          if abs(a - b) > 1.0e-9 * max(1.0, abs(a)), do: {i, j}, else: nil

        found ->
          found
      end

    case asymmetric do
      nil -> :ok
      {i, j} -> {:error, "#{path} must be symmetric: [#{i}][#{j}] differs from [#{j}][#{i}]"}
    end
  end

  defp positive_definite(mass_matrix, free) do
    if Linear.positive_definite?(Linear.take(mass_matrix, free)),
      do: :ok,
      else:
        {:error,
         "the mass matrix M = M_RB + M_A must be positive definite on the free DOFs " <>
           "(check rigid_body.mass, rigid_body.inertia and added_mass)"}
  end

  defp check_name(_params, nil), do: :ok
  defp check_name(%{name: name}, name), do: :ok

  defp check_name(%{name: other}, name),
    do: {:error, "name must match the file name #{inspect(name)}, got #{inspect(other)}"}

  defp path(name), do: Path.join(dir(), name <> ".json")

  defp dir do
    case :code.priv_dir(:neptunus) do
      {:error, _} -> Path.expand("../../../priv/vehicles", __DIR__)
      priv -> Path.join(priv, "vehicles")
    end
  end
end
