defmodule Neptunus.Control.Demand do
  @moduledoc """
  A body-frame demand: `surge` (forward), `sway` (to starboard), `heave` (down) and `yaw`
  (bow to starboard), each in `[-1, 1]` of what the vehicle can push on that axis. Pure.

  Position hold and mission guidance produce their horizontal output as a demand
  (`from_ned/3` turns a north/east force into surge and sway), so they do not depend on how a
  vehicle is actuated: `to_motion/1` gives the three-thruster vehicle's motion command (surge,
  heave, yaw — it has no sway, and says what it dropped), and a vehicle that can sway takes
  the demand as it is.

      iex> d = Neptunus.Control.Demand.from_ned({0.2, 0.0}, :math.pi() / 2)
      iex> {Float.round(d.surge, 6), Float.round(d.sway, 6)}
      {0.0, -0.2}
  """

  @type t :: %{surge: float(), sway: float(), heave: float(), yaw: float()}

  @doc "No demand."
  @spec zero() :: t()
  def zero, do: %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}

  @doc """
  The body-frame surge and sway of a horizontal force `{north, east}` (in the demand's units)
  for a vehicle heading `psi` (rad), as a demand with no heave or yaw.
  """
  @spec from_ned({float(), float()}, float()) :: t()
  def from_ned({fn_, fe}, psi) do
    {c, s} = {:math.cos(psi), :math.sin(psi)}
    %{zero() | surge: c * fn_ + s * fe, sway: -s * fn_ + c * fe}
  end

  @doc "Each axis clamped to `[-1, 1]`."
  @spec saturate(t()) :: t()
  def saturate(d), do: Map.new(d, fn {axis, v} -> {axis, sat(v)} end)

  @doc """
  The three-thruster vehicle's motion command (`Neptunus.Allocation.motion/2`'s input) and
  the sway it cannot give.

      iex> Neptunus.Control.Demand.to_motion(%{surge: 0.3, sway: 0.1, heave: -0.2, yaw: 0.05})
      {%{surge: 0.3, heave: -0.2, yaw: 0.05}, 0.1}
  """
  @spec to_motion(t()) :: {%{surge: float(), heave: float(), yaw: float()}, float()}
  def to_motion(%{surge: surge, sway: sway, heave: heave, yaw: yaw}),
    do: {%{surge: surge, heave: heave, yaw: yaw}, sway}

  defp sat(x), do: x |> max(-1.0) |> min(1.0) |> Kernel.*(1.0) |> Kernel.+(0.0)
end
