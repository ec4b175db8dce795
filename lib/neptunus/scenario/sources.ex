defmodule Neptunus.Scenario.Sources do
  @moduledoc """
  The position sources of a headless run (pure): the simulated DVL (`Neptunus.Sim.DVL`)
  and USBL (`Neptunus.Sim.USBL`) measuring the simulator's true state, their reports read
  as the live drivers read them (`Neptunus.Position.Reading`) and judged and fused by
  navigation's position estimator (`Neptunus.Navigation.Position`).

  What a live vehicle adds between the simulated sources and the drivers — the TCP and HTTP
  links — is not here; what the drivers do is: a DVL report is read when it is sent (its
  age from its own stamps), the Underwater GPS is polled every `poll` s (default
  #{0.25} s: the driver's) and a fix is read when it differs from the last one read, and
  the vehicle's depth estimate is sent to the topside every #{0.5} s.
  """

  alias Neptunus.Navigation.Position
  alias Neptunus.Position.Reading
  alias Neptunus.Sim.{DVL, USBL}

  @poll 0.25
  @depth_every 0.5

  defstruct [:position, :dvl, :usbl, next_poll: 0.0, next_depth: 0.0, ready: nil, read: nil]

  @type t :: %__MODULE__{
          position: Position.t(),
          dvl: DVL.t() | nil,
          usbl: USBL.t() | nil,
          next_poll: float(),
          next_depth: float(),
          ready: map() | nil,
          read: map() | nil
        }

  @doc """
  The sources of `%{dvl: settings | nil, usbl: settings | nil}` (`Neptunus.Scenario`),
  seeded from `seed`.
  """
  @spec new(%{dvl: map() | nil, usbl: map() | nil}, integer()) :: t()
  def new(%{dvl: dvl, usbl: usbl}, seed) do
    names = Enum.reject([dvl && :dvl, usbl && :usbl], &is_nil/1)

    %__MODULE__{
      position: Position.new(sources: names),
      dvl: dvl && DVL.new(dvl, seed),
      usbl: usbl && USBL.new(usbl, seed)
    }
  end

  @doc """
  Advances to `t` (s) with the true state `truth` (`Neptunus.Dynamics.State` fields) and
  navigation's heading `{ψ, σ_ψ}` (or nil) and depth (or nil) estimates.
  """
  @spec step(t(), float(), map(), {float(), float()} | nil, float() | nil) :: t()
  def step(%__MODULE__{} = s, t, truth, heading, depth) do
    position =
      case heading do
        {psi, std} -> Position.heading(s.position, t, psi, std)
        nil -> s.position
      end
      |> Position.depth(depth)

    %{s | position: position}
    |> dvl(t, truth)
    |> usbl(t, truth, depth)
    |> then(&%{&1 | position: Position.tick(&1.position, t)})
  end

  defp dvl(%__MODULE__{dvl: nil} = s, _t, _truth), do: s

  defp dvl(s, t, truth) do
    {reports, dvl} = DVL.step(s.dvl, t, truth)

    position =
      Enum.reduce(reports, s.position, fn report, position ->
        case Reading.dvl(report, t) do
          nil -> position
          reading -> Position.report(position, :dvl, reading, t)
        end
      end)

    %{s | dvl: dvl, position: position}
  end

  defp usbl(%__MODULE__{usbl: nil} = s, _t, _truth, _depth), do: s

  defp usbl(s, t, truth, depth) do
    usbl =
      if t >= s.next_depth and is_number(depth),
        do: USBL.depth(s.usbl, t, {max(depth, 0.0), 10.0}),
        else: s.usbl

    next_depth = if t >= s.next_depth, do: s.next_depth + @depth_every, else: s.next_depth
    {fixes, usbl} = USBL.step(usbl, t, truth)
    ready = List.last(fixes) || s.ready
    s = %{s | usbl: usbl, ready: ready, next_depth: next_depth}

    if t >= s.next_poll do
      s = %{s | next_poll: s.next_poll + @poll}

      if ready != nil and ready != s.read do
        position = Position.report(s.position, :usbl, Reading.ugps(ready, t), t)
        %{s | position: position, read: ready}
      else
        s
      end
    else
      s
    end
  end

  @doc "Navigation's position estimate at `t` (`Neptunus.Navigation.Position.estimate/2`)."
  @spec estimate(t(), float()) :: map()
  def estimate(%__MODULE__{position: position}, t), do: Position.estimate(position, t)

  @doc "The position's status at `t` (`Neptunus.Navigation.Position.status/2`)."
  @spec status(t(), float()) :: map()
  def status(%__MODULE__{position: position}, t), do: Position.status(position, t)
end
