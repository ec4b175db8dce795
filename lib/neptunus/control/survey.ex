defmodule Neptunus.Control.Survey do
  @moduledoc """
  A lawnmower survey as a list of mission waypoints (pure): parallel lines `length` m long in
  the direction `heading` (rad from north), `spacing` m apart, covering a strip `width` m wide
  to starboard of the first line, which starts at `origin` `{north, east}`. The lines are
  run alternately there and back, so the waypoints are the lines' ends in order:

      origin ─────────────▶ ┐      line 0
                            │ spacing
             ◀───────────── ┘      line 1
            ┌ …

  There are `floor(width / spacing) + 1` lines (the last one at most `spacing` short of the
  far edge, never beyond it), so `2 · lines` waypoints, each at `depth` with the mission's
  `speed` and acceptance `radius`; the heading along each line is left to the guidance
  (`heading: nil`).

      iex> wps = Neptunus.Control.Survey.waypoints(%{origin: {0.0, 0.0}, heading: 0.0,
      ...>   length: 10.0, width: 4.0, spacing: 2.0, depth: 3.0, speed: 0.3, radius: 0.5})
      iex> Enum.map(wps, &{round(&1.north), round(&1.east)})
      [{0, 0}, {10, 0}, {10, 2}, {0, 2}, {0, 4}, {10, 4}]
  """

  @typedoc "A survey's settings (SI, `heading` in rad)."
  @type t :: %{
          origin: {float(), float()},
          heading: float(),
          length: float(),
          width: float(),
          spacing: float(),
          depth: float(),
          speed: float(),
          radius: float()
        }

  @doc "The survey's waypoints (see the moduledoc)."
  @spec waypoints(t()) :: [Neptunus.Control.Mission.waypoint()]
  def waypoints(%{origin: {n0, e0}, heading: a} = s) do
    lines = floor(s.width / s.spacing + 1.0e-9) + 1
    {c, si} = {:math.cos(a), :math.sin(a)}
    # starboard of the line direction
    {sc, ss} = {-si, c}

    for i <- 0..(lines - 1), k <- ends(i) do
      offset = i * s.spacing
      along = k * s.length

      %{
        north: n0 + along * c + offset * sc,
        east: e0 + along * si + offset * ss,
        depth: s.depth * 1.0,
        heading: nil,
        speed: s.speed * 1.0,
        radius: s.radius * 1.0
      }
    end
  end

  defp ends(i) when rem(i, 2) == 0, do: [0, 1]
  defp ends(_i), do: [1, 0]

  @doc "How many waypoints a survey of `width` and `spacing` makes."
  @spec count(number(), number()) :: pos_integer()
  def count(width, spacing), do: 2 * (floor(width / spacing + 1.0e-9) + 1)
end
