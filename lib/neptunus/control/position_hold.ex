defmodule Neptunus.Control.PositionHold do
  @moduledoc """
  Holding a point in north and east. Pure; `Neptunus.Control.DP` runs it (with the depth
  and heading autopilots) in control mode `dp`.

  ## The loops

  A cascade: the position error `p_t − p` makes a desired velocity towards the target,
  `v_d = k_p (p_t − p)` (`kp`, or `soft_kp` when the velocity is not measured) limited to `v_max` (default #{0.3} m/s, so a far target is
  approached at that speed and a jump of the estimate never makes a jump of thrust), and
  `Neptunus.Control.VelocityLoop` makes the force that brings the velocity there. What the
  vehicle does with that force depends on what it can push.

  ## A fully actuated vehicle (surge and sway: an ArduSub vectored frame)

  Holds **north, east, depth and heading** independently: the force goes out as surge and
  sway in the body frame (`Neptunus.Control.Demand.from_ned/2`), the heading is the pilot's
  (the heading autopilot holds it), so the pilot can turn the camera around a fixed point.

  ## The three-thruster vehicle (no sway)

  It can push only along its heading, so it **cannot hold a point and a heading at once**
  against anything that pushes sideways. It keeps **within a radius** of the point (`radius`,
  default #{1.0} m):

    * **hold** (inside the radius): surge is the force's component along the heading; the
      sideways part cannot be made. The heading is turned **into the disturbance**: once
      the loop's integral (the steady force the vehicle needs there — a current, a tether)
      is longer than `vane_min` (default #{0.015}, about 0.2 N for this vehicle), the heading
      to hold is its direction, so the thrusters push straight against it and nothing is
      left sideways (weathervaning). In still water the pilot's heading is kept.
    * **return** (beyond the radius): the heading is the bearing to the point, surge the
      force's component along it times `cos` of the heading error (no driving off while
      still turning), until the vehicle is within half the radius.

  So in still water it holds its point and the pilot's heading; in a current it holds its
  point with the bow into the current, whatever heading the pilot asked for; the depth is
  the depth autopilot's either way.
  """

  alias Neptunus.Control.{Demand, VelocityLoop}

  @defaults %{kp: 0.4, soft_kp: 0.2, v_max: 0.3, radius: 1.0, vane_min: 0.015}

  @enforce_keys [:target, :heading, :actuation, :loop]
  defstruct [
    :target,
    :heading,
    :actuation,
    :loop,
    kp: 0.4,
    soft_kp: 0.2,
    v_max: 0.3,
    radius: 1.0,
    vane_min: 0.015,
    phase: :hold,
    heading_setpoint: nil,
    distance: 0.0,
    demand: %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
  ]

  @typedoc """
  * `target` — `{north, east}` (m); `heading` — the pilot's heading (rad)
  * `actuation` — `:full` (surge and sway) or `:surge` (no sway)
  * `loop` — the velocity loop; `kp` (1/s), `v_max` (m/s), `radius` (m), `vane_min`
  * `phase` — `:hold` or `:return` (`:surge` only); `heading_setpoint` — the heading to hold
    now; `distance` — to the target (m); `demand` — the last surge and sway
  """
  @type t :: %__MODULE__{
          target: {float(), float()},
          heading: float(),
          actuation: :full | :surge,
          loop: VelocityLoop.t(),
          kp: float(),
          soft_kp: float(),
          v_max: float(),
          radius: float(),
          vane_min: float(),
          phase: :hold | :return,
          heading_setpoint: float() | nil,
          distance: float(),
          demand: Demand.t()
        }

  @doc "The default settings."
  @spec defaults() :: map()
  def defaults, do: @defaults

  @doc """
  Holds `target` `{n, e}` with the pilot's `heading` (rad). Options: `actuation` (`:full` or
  `:surge`, required), `kp`, `v_max`, `radius`, `vane_min`, `loop` (a
  `Neptunus.Control.VelocityLoop` to carry on with, or its options).
  """
  @spec new({number(), number()}, number(), keyword()) :: t()
  def new({n, e}, heading, opts) do
    loop =
      case Keyword.get(opts, :loop, []) do
        %VelocityLoop{} = loop -> loop
        loop_opts -> VelocityLoop.new(loop_opts)
      end

    %__MODULE__{
      target: {n * 1.0, e * 1.0},
      heading: heading * 1.0,
      actuation: Keyword.fetch!(opts, :actuation),
      loop: loop,
      kp: Keyword.get(opts, :kp, @defaults.kp) * 1.0,
      soft_kp: Keyword.get(opts, :soft_kp, @defaults.soft_kp) * 1.0,
      v_max: Keyword.get(opts, :v_max, @defaults.v_max) * 1.0,
      radius: Keyword.get(opts, :radius, @defaults.radius) * 1.0,
      vane_min: Keyword.get(opts, :vane_min, @defaults.vane_min) * 1.0,
      heading_setpoint: heading * 1.0
    }
  end

  @doc "The pilot's new heading."
  @spec set_heading(t(), number()) :: t()
  def set_heading(ph, heading), do: %{ph | heading: heading * 1.0}

  @doc "Moves the target by `{dn, de}` (a change of the position's frame)."
  @spec shift(t(), {number(), number()}) :: t()
  def shift(%__MODULE__{target: {n, e}} = ph, {dn, de}), do: %{ph | target: {n + dn, e + de}}

  @doc """
  One period of `dt` s at position `p` `{n, e}` with velocity `v` `{vₙ, vₑ}` (m/s) and
  heading `psi` (rad): the new `demand` (surge, sway) and `heading_setpoint`. With a
  velocity that is not `measured?` (no DVL) the soft gains apply (`soft_kp` and the loop's,
  see `Neptunus.Control.VelocityLoop`).
  """
  @spec step(t(), {float(), float()}, {float(), float()}, float(), float(), boolean()) :: t()
  def step(%__MODULE__{target: {tn, te}} = ph, {n, e}, v, psi, dt, measured? \\ true) do
    {en, ee} = {tn - n, te - e}
    distance = :math.sqrt(en * en + ee * ee)
    kp = if measured?, do: ph.kp, else: ph.soft_kp
    {desired, _} = VelocityLoop.limit({kp * en, kp * ee}, ph.v_max)
    loop = VelocityLoop.step(ph.loop, desired, v, dt, measured?)
    ph = %{ph | loop: loop, distance: distance}

    case ph.actuation do
      :full -> %{ph | demand: Demand.from_ned(loop.output, psi), heading_setpoint: ph.heading}
      :surge -> surge_only(ph, {en, ee}, psi)
    end
  end

  defp surge_only(ph, {en, ee}, psi) do
    phase =
      case ph.phase do
        :hold -> if ph.distance > ph.radius, do: :return, else: :hold
        :return -> if ph.distance < ph.radius / 2, do: :hold, else: :return
      end

    {in_, ie} = ph.loop.integral

    heading =
      case phase do
        :return ->
          :math.atan2(ee, en)

        :hold ->
          if :math.sqrt(in_ * in_ + ie * ie) > ph.vane_min,
            do: :math.atan2(ie, in_),
            else: ph.heading
      end

    %{surge: surge} = Demand.from_ned(ph.loop.output, psi)

    surge =
      if phase == :return,
        do: surge * max(:math.cos(Neptunus.Control.Guidance.wrap_pi(heading - psi)), 0.0),
        else: surge

    %{ph | phase: phase, heading_setpoint: heading, demand: %{Demand.zero() | surge: surge}}
  end

  @doc "No position to act on: no horizontal demand; the heading setpoint stays where it is."
  @spec idle(t()) :: t()
  def idle(ph), do: %{ph | loop: VelocityLoop.idle(ph.loop), demand: Demand.zero()}
end
