defmodule Neptunus.Position.Reading do
  @moduledoc """
  What a position source's decoded report means for navigation (pure): the drivers
  (`Neptunus.Position.DVL`, `Neptunus.Position.UGPS`) and the headless runner turn the
  protocols' reports into `Neptunus.Navigation.Position` reports with these functions, so a
  headless run judges exactly what a live vehicle does.

  ## The time a measurement was made

  Navigation's position filter applies each measurement at the time it was *made*:

    * a **DVL** velocity report says how old it is in its own clock:
      `time_of_transmission − time_of_validity` (the echo's flight and the DVL's processing;
      the two clocks need not agree with ours, only with each other). The measurement was
      made that long before it arrived (the network's few milliseconds are not counted).
      A report without the two stamps is taken as measured on arrival.
    * an **Underwater GPS** fix carries no time. It was made about `latency` s (the
      topside's processing and averaging, default #{0.5} s) before the topside served it;
      the driver's polling adds up to one period more, which the filter's gate and noise
      absorb.

  ## Frames

  A fix's `x`, `y` are in the topside's frame. `rotation` (rad, default 0) is the direction
  of the topside's `x` axis from north, `origin` `{north, east}` where the topside is in
  navigation's frame (default the origin: positions are then relative to the topside).
  """

  alias Neptunus.Protocol.WaterLinkedDVL

  @default_latency 0.5

  @doc "The default age (s) of an Underwater GPS fix when served."
  @spec default_latency() :: float()
  def default_latency, do: @default_latency

  @doc """
  A DVL report (`Neptunus.Protocol.WaterLinkedDVL.report()`) that arrived at `arrived` (s)
  as a navigation report, or nil for one navigation does not use (a command's response,
  another type).
  """
  @spec dvl(WaterLinkedDVL.report(), float()) :: Neptunus.Navigation.Position.report() | nil
  def dvl({:velocity, v}, arrived) do
    age =
      case {v.time_of_validity_us, v.time_of_transmission_us} do
        {tov, tot} when is_integer(tov) and is_integer(tot) and tot >= tov -> (tot - tov) / 1.0e6
        _ -> 0.0
      end

    {:velocity,
     %{
       t: arrived - min(age, 2.0),
       vx: v.vx,
       vy: v.vy,
       fom: v.fom,
       covariance: v.covariance,
       altitude: v.altitude,
       valid: v.valid,
       tracking: v.tracking
     }}
  end

  def dvl({:position_local, p}, _arrived),
    do: {:dead_reckoning, %{x: p.x, y: p.y, z: p.z, std: p.std}}

  def dvl(_report, _arrived), do: nil

  @doc """
  An Underwater GPS fix (`Neptunus.Protocol.UnderwaterGPS.fix()`) read at `read` (s) as a
  navigation report. Options: `latency` (s), `rotation` (rad), `origin` `{n, e}` (m),
  `frame` (the frame's name, default `:usbl`).

      iex> {:fix, fix} = Neptunus.Position.Reading.ugps(
      ...>   %{x: 10.0, y: 0.0, z: 3.0, std: 0.4, valid: true, receivers: []}, 100.0,
      ...>   rotation: :math.pi() / 2, origin: {1.0, 2.0})
      iex> {fix.t, Float.round(fix.north, 6), Float.round(fix.east, 6), fix.std, fix.frame}
      {99.5, 1.0, 12.0, 0.4, :usbl}
  """
  @spec ugps(Neptunus.Protocol.UnderwaterGPS.fix(), float(), keyword()) ::
          Neptunus.Navigation.Position.report()
  def ugps(fix, read, opts \\ []) do
    latency = Keyword.get(opts, :latency, @default_latency)
    rotation = Keyword.get(opts, :rotation, 0.0)
    {on, oe} = Keyword.get(opts, :origin, {0.0, 0.0})
    {c, s} = {:math.cos(rotation), :math.sin(rotation)}

    {:fix,
     %{
       t: read - latency,
       north: on + c * fix.x - s * fix.y,
       east: oe + s * fix.x + c * fix.y,
       std: fix.std,
       valid: fix.valid,
       frame: Keyword.get(opts, :frame, :usbl)
     }}
  end
end
