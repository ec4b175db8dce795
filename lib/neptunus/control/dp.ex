defmodule Neptunus.Control.DP do
  @moduledoc """
  Control mode `dp`: position hold (`Neptunus.Control.PositionHold`) and missions
  (`Neptunus.Control.Mission`) on navigation's position estimate, with depth and heading
  held by their autopilots. Pure; `Neptunus.Control.Core` runs it each control period and
  applies what it decides: a horizontal body-frame demand (`Neptunus.Control.Demand`: surge,
  and sway on a vehicle that has it), the heading the heading autopilot should hold, and —
  during a mission — the depth the depth autopilot should hold.

  ## What each vehicle can hold

  `actuation` says what the vehicle can push horizontally:

    * `:full` — surge and sway (an ArduSub vectored frame): holds **north, east, depth and
      heading** independently; on a mission it moves along the line with sway correcting the
      cross-track error and the bow where the waypoint says (else along the line).
    * `:surge` — the three-thruster layout (two stern thrusters and a vertical one, no
      sway): it cannot push sideways, so it cannot hold a point and a heading at once against
      a sideways push. It keeps **within a radius** of the point — steering back to it,
      surging, then holding its heading into the current (`Neptunus.Control.PositionHold`) —
      and on a mission it steers the course the guidance asks for, its heading corrected by
      the crab angle the current makes (`Neptunus.Control.Guidance.heading/3`).

  ## Without a valid position

  The position estimate (`Neptunus.Navigation.Position`) says whether it is valid. While it
  is not, DP gives no horizontal demand and keeps the heading setpoint where it was (no
  jump): depth and heading hold as before, and `holds/1` says so (`["depth", "heading"]`).
  When a position becomes valid (again) DP holds it — the target it had, or where the
  vehicle is if it had none. A running mission waits, and goes on when the position is
  back. A change of the position's frame (`epoch`) with a known `shift` moves the target and
  the waypoints with it; one without (the estimate was lost and started again) drops them:
  they were in a frame that no longer exists.

  The events `step/5` returns are `{:notice, text}` for the pilot and `:mission` (the
  mission or its waypoints changed: the caller broadcasts it).
  """

  alias Neptunus.Control.{Demand, Guidance, Mission, PositionHold, VelocityLoop}

  @enforce_keys [:actuation, :heading, :opts]
  defstruct [
    :actuation,
    :heading,
    :opts,
    :hold,
    :mission,
    :epoch,
    :heading_setpoint,
    :depth_setpoint,
    :waiting,
    loop: nil,
    measured: true,
    demand: %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0},
    missions: 0
  ]

  @typedoc """
  * `actuation` — `:full` or `:surge` (see the moduledoc); `opts` — PositionHold's options
  * `heading` — the pilot's heading (rad)
  * `hold` — the position hold in force (nil: no target — no valid position yet, or a
    running mission); `mission` — the mission, or nil
  * `epoch` — the position frame's epoch the targets are in
  * `heading_setpoint`, `depth_setpoint` — what the autopilots should hold now (nil: the
    pilot's)
  * `waiting` — why there is no horizontal demand (no valid position), nil when acting
  * `loop` — the velocity loop, carried between hold and mission so the learnt force
    (integral) is kept; `measured` — whether the estimate's velocity is measured (a DVL:
    the stiff gains) or derived from fixes (the soft ones); `demand` — the last horizontal demand; `missions` — missions so far
  """
  @type t :: %__MODULE__{
          actuation: :full | :surge,
          heading: float(),
          opts: keyword(),
          hold: PositionHold.t() | nil,
          mission: Mission.t() | nil,
          epoch: non_neg_integer() | nil,
          heading_setpoint: float() | nil,
          depth_setpoint: float() | nil,
          waiting: String.t() | nil,
          loop: VelocityLoop.t() | nil,
          measured: boolean(),
          demand: Demand.t(),
          missions: non_neg_integer()
        }

  @type event :: {:notice, String.t()} | :mission

  @doc """
  DP engaged holding `heading` (rad) at the position `estimate` (`Neptunus.Navigation.Position`'s
  estimate, or nil). Options: `actuation` (`:full` or `:surge`, default `:surge`) and
  `Neptunus.Control.PositionHold`'s (`kp`, `v_max`, `radius`, `vane_min`, `loop`).
  """
  @spec new(map() | nil, number(), keyword()) :: t()
  def new(estimate, heading, opts \\ []) do
    {actuation, opts} = Keyword.pop(opts, :actuation, :surge)
    loop = VelocityLoop.new(Keyword.get(opts, :loop, []))

    dp = %__MODULE__{
      actuation: actuation,
      heading: wrap(heading),
      heading_setpoint: wrap(heading),
      opts: Keyword.delete(opts, :loop),
      loop: loop
    }

    case valid(estimate) do
      {n, e} -> %{dp | hold: hold(dp, {n, e}), epoch: estimate.epoch}
      nil -> %{dp | waiting: reason(estimate)}
    end
  end

  @doc "What DP holds: `[\"depth\", \"heading\", \"position\"]`, or without a position target `[\"depth\", \"heading\"]`."
  @spec holds(t()) :: [String.t()]
  def holds(%__MODULE__{waiting: nil, hold: %PositionHold{}}),
    do: ["depth", "heading", "position"]

  def holds(%__MODULE__{waiting: nil, mission: %Mission{state: :running}}),
    do: ["depth", "heading", "position"]

  def holds(%__MODULE__{}), do: ["depth", "heading"]

  @doc "Whether a mission is running (it then owns depth and heading)."
  @spec mission_running?(t()) :: boolean()
  def mission_running?(%__MODULE__{mission: %Mission{state: :running}}), do: true
  def mission_running?(_dp), do: false

  @doc "The pilot's new heading (rad)."
  @spec set_heading(t(), number()) :: t()
  def set_heading(%__MODULE__{} = dp, heading) do
    heading = wrap(heading)
    hold = dp.hold && PositionHold.set_heading(dp.hold, heading)
    %{dp | heading: heading, heading_setpoint: heading, hold: hold}
  end

  @doc "The target `{n, e}` held, or nil."
  @spec target(t()) :: {float(), float()} | nil
  def target(%__MODULE__{hold: %PositionHold{target: target}}), do: target
  def target(%__MODULE__{}), do: nil

  # --- missions --------------------------------------------------------------------------------

  @doc """
  Starts a mission over validated `waypoints` from the position `estimate` (it must be
  valid): the hold ends, the mission steers from here.
  """
  @spec start_mission(t(), [Mission.waypoint()], map()) :: {:ok, t()} | {:error, String.t()}
  def start_mission(%__MODULE__{} = dp, waypoints, estimate) do
    case valid(estimate) do
      nil ->
        {:error, "a mission needs a valid position: " <> (reason(estimate) || "none")}

      p ->
        id = dp.missions + 1
        mission = Mission.start(id, waypoints, p)
        {:ok, %{dp | mission: mission, hold: nil, missions: id, epoch: estimate.epoch}}
    end
  end

  @doc "Pauses the running mission: position hold where the vehicle is."
  @spec pause_mission(t(), map()) :: {:ok, t()} | {:error, String.t()}
  def pause_mission(%__MODULE__{mission: nil}, _estimate), do: {:error, "no mission to pause"}

  def pause_mission(%__MODULE__{} = dp, estimate) do
    with {:ok, mission} <- Mission.pause(dp.mission) do
      {:ok, %{dp | mission: mission} |> hold_here(estimate)}
    end
  end

  @doc "Resumes the paused mission on its leg."
  @spec resume_mission(t(), map()) :: {:ok, t()} | {:error, String.t()}
  def resume_mission(%__MODULE__{mission: nil}, _estimate), do: {:error, "no mission to resume"}

  def resume_mission(%__MODULE__{} = dp, estimate) do
    with {:ok, mission} <- Mission.resume(dp.mission) do
      case valid(estimate) do
        nil -> {:error, "a mission needs a valid position: " <> (reason(estimate) || "none")}
        _ -> {:ok, %{dp | mission: mission, hold: nil}}
      end
    end
  end

  @doc """
  Ends the mission: position hold where the vehicle is (with a valid position; else depth
  and heading only).
  """
  @spec abort_mission(t(), map() | nil) :: {:ok, t()} | {:error, String.t()}
  def abort_mission(%__MODULE__{mission: nil}, _estimate), do: {:error, "no mission to abort"}

  def abort_mission(%__MODULE__{} = dp, estimate),
    do: {:ok, %{dp | mission: nil, depth_setpoint: nil} |> hold_here(estimate)}

  defp hold_here(dp, estimate) do
    case valid(estimate) do
      nil -> %{dp | hold: nil}
      p -> %{dp | hold: hold(dp, p), epoch: estimate.epoch}
    end
  end

  defp hold(dp, p, heading \\ nil) do
    heading = heading || dp.heading_setpoint || dp.heading

    PositionHold.new(
      p,
      heading,
      [actuation: dp.actuation, loop: dp.loop] ++ dp.opts
    )
  end

  # --- the control period ------------------------------------------------------------------

  @doc """
  One control period of `dt` s with the position `estimate` and the heading `psi` (rad):
  updates the demand, the heading and depth setpoints; returns the events (see the
  moduledoc).
  """
  @spec step(t(), map() | nil, float(), float()) :: {t(), [event()]}
  def step(%__MODULE__{} = dp, estimate, psi, dt) do
    {dp, events} = frame(dp, estimate)

    case valid(estimate) do
      nil ->
        why = reason(estimate)

        notice =
          if dp.waiting == nil,
            do: [{:notice, "dp: no valid position (#{why}): holding depth and heading only"}],
            else: []

        {%{idle(dp) | waiting: why}, events ++ notice}

      p ->
        v = velocity(estimate)
        dp = %{dp | measured: Map.get(estimate, :velocity_measured, true)}

        notice =
          if dp.waiting != nil,
            do: [{:notice, "dp: position valid again: holding position"}],
            else: []

        dp = %{dp | waiting: nil}
        {dp, more} = act(dp, p, v, psi, dt)
        {dp, events ++ notice ++ more}
    end
  end

  # a change of the position's frame moves the targets, or drops them
  defp frame(%__MODULE__{epoch: nil} = dp, estimate) do
    case estimate do
      %{epoch: epoch} -> {%{dp | epoch: epoch}, []}
      _ -> {dp, []}
    end
  end

  defp frame(dp, %{epoch: epoch}) when epoch == dp.epoch, do: {dp, []}

  defp frame(dp, %{epoch: epoch, shift: {dn, de}}) when epoch == dp.epoch + 1 do
    hold = dp.hold && PositionHold.shift(dp.hold, {dn, de})
    mission = dp.mission && Mission.shift(dp.mission, {dn, de})

    text =
      "dp: the position moved to another frame: targets moved with it (#{fmt(dn)} m north, #{fmt(de)} m east)"

    {%{dp | hold: hold, mission: mission, epoch: epoch},
     [{:notice, text}] ++ if(mission, do: [:mission], else: [])}
  end

  defp frame(dp, %{epoch: epoch}) do
    lost = if dp.mission, do: [:mission], else: []
    text = "dp: the position estimate started again: the old target and mission are dropped"

    {%{dp | hold: nil, mission: nil, depth_setpoint: nil, epoch: epoch},
     [{:notice, text}] ++ lost}
  end

  defp frame(dp, _estimate), do: {dp, []}

  defp act(%__MODULE__{mission: %Mission{state: :running} = mission} = dp, p, v, psi, dt) do
    {mission, events} = Mission.step(mission, p)

    case mission.state do
      :done ->
        last = Mission.target(mission)
        heading = last.heading || psi

        dp = %{
          dp
          | mission: mission,
            hold: hold(%{dp | heading_setpoint: heading}, {last.north, last.east}, heading),
            depth_setpoint: last.depth
        }

        {dp, _} = act(dp, p, v, psi, dt)
        {dp, mission_events(events)}

      :running ->
        {track(%{dp | mission: mission}, mission.guidance, v, psi, dt), mission_events(events)}
    end
  end

  defp act(%__MODULE__{hold: nil} = dp, p, v, psi, dt) do
    # a valid position and nothing held: hold where the vehicle is
    act(%{dp | hold: hold(dp, p)}, p, v, psi, dt)
  end

  defp act(%__MODULE__{hold: hold} = dp, p, v, psi, dt) do
    hold = PositionHold.step(hold, p, v, psi, dt, measured?(dp))

    {%{
       dp
       | hold: hold,
         loop: hold.loop,
         demand: hold.demand,
         heading_setpoint: hold.heading_setpoint
     }, []}
  end

  defp mission_events(events) do
    Enum.flat_map(events, fn
      {:reached, i} -> [{:notice, "mission: waypoint #{i} reached"}, :mission]
      :done -> [{:notice, "mission: done, holding position at the last waypoint"}]
    end)
  end

  # follow the guidance: the velocity along the course at the waypoint's speed
  defp track(dp, g, v, psi, dt) do
    desired = {g.speed * :math.cos(g.course), g.speed * :math.sin(g.course)}
    loop = VelocityLoop.step(dp.loop, desired, v, dt, measured?(dp))

    {demand, heading} =
      case dp.actuation do
        :full ->
          {Demand.from_ned(loop.output, psi), g.heading || g.alpha}

        :surge ->
          heading = Guidance.heading(g.course, psi, v)
          %{surge: surge} = Demand.from_ned(loop.output, psi)
          turn = max(:math.cos(Guidance.wrap_pi(heading - psi)), 0.0)
          {%{Demand.zero() | surge: surge * turn}, heading}
      end

    %{dp | loop: loop, demand: demand, heading_setpoint: heading, depth_setpoint: g.depth}
  end

  @doc "No estimate at all (stale): no horizontal demand, setpoints kept."
  @spec idle(t()) :: t()
  def idle(%__MODULE__{} = dp) do
    %{
      dp
      | loop: VelocityLoop.idle(dp.loop),
        demand: Demand.zero(),
        hold: dp.hold && PositionHold.idle(dp.hold)
    }
  end

  defp measured?(%__MODULE__{measured: measured}), do: measured

  defp valid(%{valid: true, north: n, east: e}) when is_number(n) and is_number(e), do: {n, e}
  defp valid(_estimate), do: nil

  defp velocity(%{velocity_north: vn, velocity_east: ve}) when is_number(vn) and is_number(ve),
    do: {vn, ve}

  defp velocity(_estimate), do: {0.0, 0.0}

  defp reason(%{reason: reason}) when is_binary(reason), do: reason
  defp reason(nil), do: "no position source"
  defp reason(_estimate), do: nil

  # --- views -------------------------------------------------------------------------------------

  @doc """
  As telemetry shows it (`autopilot.position`): `%{x, y, heading, phase, distance, output,
  sway, waiting, mission}` — the target (nil without one), the heading held, `hold`,
  `return`, `mission` or `waiting`, the distance to the target or waypoint, the surge and
  sway demanded, why DP waits, and during a mission its guidance (`leg`, `cross_track`,
  `along`, `course`, `speed`).
  """
  @spec public(t()) :: map()
  def public(%__MODULE__{} = dp) do
    {x, y} = target(dp) || {nil, nil}

    phase =
      cond do
        dp.waiting != nil -> "waiting"
        mission_running?(dp) -> "mission"
        dp.hold != nil -> Atom.to_string(dp.hold.phase)
        true -> "waiting"
      end

    distance =
      cond do
        mission_running?(dp) and dp.mission.guidance -> dp.mission.guidance.distance
        dp.hold -> dp.hold.distance
        true -> nil
      end

    %{
      x: x,
      y: y,
      heading: dp.heading_setpoint || dp.heading,
      phase: phase,
      distance: distance,
      output: dp.demand.surge,
      sway: dp.demand.sway,
      waiting: dp.waiting,
      mission: mission_guidance(dp)
    }
  end

  defp mission_guidance(%__MODULE__{mission: %Mission{guidance: g} = m}) when g != nil do
    %{
      id: m.id,
      state: Atom.to_string(m.state),
      leg: m.leg + 1,
      cross_track: g.cross_track,
      along: g.along,
      course: g.course,
      speed: g.speed
    }
  end

  defp mission_guidance(%__MODULE__{mission: %Mission{} = m}),
    do: %{
      id: m.id,
      state: Atom.to_string(m.state),
      leg: m.leg + 1,
      cross_track: nil,
      along: nil,
      course: nil,
      speed: nil
    }

  defp mission_guidance(_dp), do: nil

  defp wrap(angle), do: Guidance.wrap_2pi(angle)
  defp fmt(x), do: :erlang.float_to_binary(x * 1.0, decimals: 1)
end
