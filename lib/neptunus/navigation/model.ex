defmodule Neptunus.Navigation.Model do
  @moduledoc """
  The vehicle model the estimator predicts with: how the commanded thrust moves the vehicle
  in heave and yaw. Pure; built from a `Neptunus.Dynamics.Params` set (`from_params/1`), so
  the filter knows the same thrusters, masses and damping as the simulator — and, on a real
  board, the vehicle's identified coefficients.

  ## Thrusters

  Each thruster's force follows the static force of its command
  (`Neptunus.Dynamics.Thruster.force/2`: deadband, forward/reverse asymmetry) through its
  first-order lag (`time_constant`), exactly as in `Neptunus.Sim`. `advance/2` moves the lag on by `dt` and returns the *mean* generalised
  force over that interval in heave (`Z`, N) and yaw (`N`, N·m).

  ## Axes

  Each axis is the 1-DOF equation

      m · v̇ = F_thrust + f₀ − d_l · v − d_q · |v| · v

  with, for heave (v = ż, m/s, down positive) and yaw (v = ψ̇, rad/s):

    * `m` — the effective mass or inertia `1 / (M⁻¹)ᵢᵢ` (rigid body plus added mass, with the
      coupling to the other DOFs through the mass matrix),
    * `d_l`, `d_q` — the linear and quadratic damping of the DOF,
    * `f₀` — the constant force: in heave the net weight `W − B = −net_buoyancy` of the level
      vehicle (it floats up slowly), 0 in yaw.

  Ignored (left to the filter's process noise): coupling through damping and Coriolis forces,
  tether drag, water current, roll and pitch (ż ≈ w and ψ̇ ≈ r for a vehicle near level).
  """

  alias Neptunus.Dynamics.{Params, Thruster}

  @typedoc "One axis' 1-DOF equation (see the moduledoc)."
  @type axis :: %{mass: float(), d_l: float(), d_q: float(), f0: float()}

  @enforce_keys [:thrusters, :heave, :yaw]
  defstruct [:thrusters, :heave, :yaw, commands: %{}, targets: [], forces: []]

  @typedoc """
  * `thrusters` — `{thruster, heave gain, yaw gain}` per thruster: the thruster and the heave
    force / yaw moment of 1 N of its thrust (its wrench's Z and N components)
  * `heave`, `yaw` — the axes' equations
  * `commands` — the command in force (`%{port, vertical, starboard}` in [-1, 1])
  * `targets`, `forces` — each thruster's static target force and lagged actual force (N)
  """
  @type t :: %__MODULE__{
          thrusters: [{Thruster.t(), float(), float()}],
          heave: axis(),
          yaw: axis(),
          commands: %{atom() => float()},
          targets: [float()],
          forces: [float()]
        }

  @doc "The model of a parameter set (a `Params` or its name, e.g. `\"neptunus\"`)."
  @spec from_params(Params.t() | String.t() | atom()) :: t()
  def from_params(%Params{} = params) do
    thrusters =
      Enum.map(params.thrusters, fn %Thruster{wrench: {_, _, z, _, _, n}} = thruster ->
        {thruster, z * 1.0, n * 1.0}
      end)

    zeros = Enum.map(thrusters, fn _ -> 0.0 end)

    %__MODULE__{
      thrusters: thrusters,
      heave: axis(params, 2, -params.net_buoyancy),
      yaw: axis(params, 5, 0.0),
      targets: zeros,
      forces: zeros
    }
  end

  def from_params(name) when is_binary(name) or is_atom(name),
    do: from_params(Params.fetch!(to_string(name)))

  defp axis(%Params{mass_inv: inv, d_l: d_l, d_q: d_q}, i, f0) do
    %{
      mass: 1.0 / (inv |> Enum.at(i) |> Enum.at(i)),
      d_l: Enum.at(d_l, i) * 1.0,
      d_q: Enum.at(d_q, i) * 1.0,
      f0: f0 * 1.0
    }
  end

  @doc """
  Sets the thruster command in force. Values outside `[-1, 1]` are clamped, missing or
  non-numeric ones are 0 (neutral).
  """
  @spec command(t(), map()) :: t()
  def command(%__MODULE__{} = model, thrusters) when is_map(thrusters) do
    commands =
      Map.new(model.thrusters, fn {%Thruster{name: name}, _, _} ->
        {name, clamp(Map.get(thrusters, name))}
      end)

    targets =
      Enum.map(model.thrusters, fn {%Thruster{name: name} = t, _, _} ->
        Thruster.force(t, Map.fetch!(commands, name))
      end)

    %{model | commands: commands, targets: targets}
  end

  def command(%__MODULE__{} = model, _not_a_map), do: command(model, %{})

  defp clamp(x) when is_number(x), do: x |> max(-1.0) |> min(1.0) |> Kernel.*(1.0)
  defp clamp(_), do: 0.0

  @doc """
  Advances the thrusters' lag by `dt` (s, > 0) and returns the mean heave force (N) and yaw
  moment (N·m) over it, with the updated model.
  """
  @spec advance(t(), float()) :: {t(), {float(), float()}}
  def advance(%__MODULE__{} = model, dt) when dt > 0 do
    {forces, heave, yaw} = lag(model.thrusters, model.targets, model.forces, dt, [], 0.0, 0.0)
    {%{model | forces: forces}, {heave, yaw}}
  end

  defp lag([{thruster, gz, gn} | ts], [target | targets], [force | forces], dt, acc, z, n) do
    {decay, mean} = Thruster.lag(thruster, dt)
    diff = force - target
    f_mean = target + diff * mean
    lag(ts, targets, forces, dt, [target + diff * decay | acc], z + gz * f_mean, n + gn * f_mean)
  end

  defp lag([], [], [], _dt, acc, z, n), do: {Enum.reverse(acc), z, n}

  @doc "The generalised heave force and yaw moment of the thrusters' present forces."
  @spec force(t()) :: {float(), float()}
  def force(%__MODULE__{thrusters: thrusters, forces: forces}) do
    thrusters
    |> Enum.zip(forces)
    |> Enum.reduce({0.0, 0.0}, fn {{_t, gz, gn}, f}, {z, n} -> {z + gz * f, n + gn * f} end)
  end
end
