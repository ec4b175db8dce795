defmodule Neptunus.Control.DP do
  @moduledoc """
  Dynamic positioning (position hold) for a vehicle with **no sway thruster**: two stern
  thrusters (surge and yaw) and a vertical one. Pure; `Neptunus.Control.Core` runs it in
  control mode `dp` together with the depth and heading autopilots.

  ## What it can and cannot hold

  The vehicle can only push along its own heading, so it cannot hold a position *and* an
  arbitrary heading against a force from the side. DP therefore:

    * **holds the heading** given (the heading autopilot's setpoint) and **the position along
      that heading** — a surge PID on the along-track error `e_along = cos ψ·Δx + sin ψ·Δy`
      (Δ = target − position, NED) — while the vehicle is within `return_radius`
      (default #{2.0} m) of the target. The **cross-track** error (sideways) is *not*
      corrected in this phase: a side current or a tether pulling sideways makes the vehicle
      drift;
    * when the vehicle is farther than `return_radius`, it **returns**: the heading setpoint
      becomes the bearing to the target, surge follows a PID on the distance (scaled by the
      cosine of the heading error, so it does not drive off while still turning), until it is
      within `capture_radius` (default #{0.3} m); then it turns back to the held heading.

  So in still water or with the disturbance along the held heading it holds position within
  a few centimetres; with a steady sideways disturbance it holds the heading and keeps the
  vehicle within about `return_radius` of the target by returning to it now and then. Depth
  is the depth autopilot's.

  The position comes from a *position source* — the simulator's truth, or a position field
  from the board (a DVL/USBL). Without one the mode is refused (see `Neptunus.Control.Core`).
  """

  alias Neptunus.PID

  @return_radius 2.0
  @capture_radius 0.3

  @enforce_keys [:target, :heading, :pid]
  defstruct [
    :target,
    :heading,
    :pid,
    :last,
    phase: :hold,
    output: 0.0,
    distance: 0.0,
    return_radius: @return_radius,
    capture_radius: @capture_radius
  ]

  @typedoc """
  * `target` — `{x, y}` held (m, NED); `heading` — the heading held (rad, `[0, 2π)`)
  * `phase` — `:hold` (heading and along-track position) or `:return` (towards the target)
  * `pid` — the surge PID; `output` — the last surge command in `[-1, 1]`
  * `distance` — the last distance to the target (m); `last` — the last position `{x, y}`
  """
  @type t :: %__MODULE__{
          target: {float(), float()},
          heading: float(),
          pid: PID.t(),
          phase: :hold | :return,
          output: float(),
          distance: float(),
          last: {float(), float()} | nil,
          return_radius: float(),
          capture_radius: float()
        }

  @doc """
  DP engaged at `position` `%{x, y}` holding `heading` (rad). Options: `gains` (the surge
  PID's `kp`, `ki`, `kd`), `return_radius`, `capture_radius` (m).
  """
  @spec new(%{x: number(), y: number()}, number(), keyword()) :: t()
  def new(%{x: x, y: y}, heading, opts) do
    return = Keyword.get(opts, :return_radius, @return_radius) * 1.0
    capture = Keyword.get(opts, :capture_radius, @capture_radius) * 1.0

    if not (capture > 0 and capture < return),
      do: raise(ArgumentError, "DP needs 0 < capture_radius < return_radius")

    %__MODULE__{
      target: {x * 1.0, y * 1.0},
      heading: PID.wrap_2pi(heading),
      pid: opts |> Keyword.fetch!(:gains) |> PID.new() |> PID.engage(0.0, 0.0),
      return_radius: return,
      capture_radius: capture
    }
  end

  @doc "Holds a new heading (from the pilot's heading setpoint)."
  @spec set_heading(t(), number()) :: t()
  def set_heading(%__MODULE__{} = dp, heading), do: %{dp | heading: PID.wrap_2pi(heading)}

  @doc "The heading the heading autopilot should hold now (the held one, or the bearing back)."
  @spec heading_setpoint(t(), %{x: number(), y: number()} | nil) :: float()
  def heading_setpoint(%__MODULE__{phase: :return, target: {tx, ty}}, %{x: x, y: y}),
    do: PID.wrap_2pi(:math.atan2(ty - y, tx - x))

  def heading_setpoint(%__MODULE__{heading: heading}, _position), do: heading

  @doc """
  One control period of `dt` s at `position` `%{x, y}` with heading `psi` (rad): advances the
  phase and returns DP with its surge `output` in `[-1, 1]`.
  """
  @spec step(t(), %{x: number(), y: number()}, number(), number()) :: t()
  def step(%__MODULE__{target: {tx, ty}} = dp, %{x: x, y: y}, psi, dt) do
    dx = tx - x
    dy = ty - y
    distance = :math.sqrt(dx * dx + dy * dy)

    # the vehicle's velocity over the ground from successive positions (not from the
    # projection on a noisy heading)
    {vx, vy} =
      case dp.last do
        {lx, ly} when dt > 0 -> {(x - lx) / dt, (y - ly) / dt}
        _ -> {0.0, 0.0}
      end

    phase =
      case dp.phase do
        :hold -> if distance > dp.return_radius, do: :return, else: :hold
        :return -> if distance < dp.capture_radius, do: :hold, else: :return
      end

    # the surge PID's "measurement" is minus the error to close (so its setpoint is 0), with
    # its rate
    {measured, rate, scale} =
      case phase do
        :hold ->
          {c, s} = {:math.cos(psi), :math.sin(psi)}
          {-(c * dx + s * dy), c * vx + s * vy, 1.0}

        :return ->
          bearing_error = PID.wrap_pi(:math.atan2(dy, dx) - psi)
          rate = if distance > 0, do: (dx * vx + dy * vy) / distance, else: 0.0
          {-distance, rate, max(:math.cos(bearing_error), 0.0)}
      end

    {output, pid} = PID.update(dp.pid, 0.0, measured, dt, rate)

    %{
      dp
      | phase: phase,
        pid: pid,
        output: output * scale,
        distance: distance,
        last: {x * 1.0, y * 1.0}
    }
  end

  @doc "As telemetry shows it: `%{x, y, heading, phase, distance, output}`."
  @spec public(t()) :: map()
  def public(%__MODULE__{target: {x, y}} = dp) do
    %{
      x: x,
      y: y,
      heading: dp.heading,
      phase: Atom.to_string(dp.phase),
      distance: dp.distance,
      output: dp.output
    }
  end
end
