defmodule Neptunus.Navigation.Geo do
  @moduledoc """
  Geodetic points near a local north-east frame (pure): a point's latitude and longitude
  (rad, WGS 84) from a frame's origin and a north/east offset (m), and back. A local tangent
  plane on a sphere of the WGS 84 equatorial radius — what ArduPilot does for its own
  offsets; within the few hundred metres a small ROV works in, its error is millimetres.

      iex> alias Neptunus.Navigation.Geo
      iex> origin = %{lat: 1.047, lon: 0.18}
      iex> p = Geo.offset(origin, 100.0, -50.0)
      iex> back = Geo.origin(p, 100.0, -50.0)
      iex> {Float.round(back.lat, 12), Float.round(back.lon, 12)}
      {1.047, 0.18}
  """

  @radius 6_378_137.0

  @type point :: %{lat: float(), lon: float()}

  @doc "The point `north`, `east` metres from `origin`."
  @spec offset(point(), number(), number()) :: point()
  def offset(%{lat: lat, lon: lon}, north, east) do
    %{lat: lat + north / @radius, lon: lon + east / (@radius * :math.cos(lat))}
  end

  @doc "The origin from which `point` is `north`, `east` metres (the inverse of `offset/3`)."
  @spec origin(point(), number(), number()) :: point()
  def origin(%{lat: lat, lon: lon}, north, east) do
    lat0 = lat - north / @radius
    %{lat: lat0, lon: lon - east / (@radius * :math.cos(lat0))}
  end
end
