defmodule Neptunus.Navigation.GeoTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Navigation.Geo

  import Neptunus.Test.Properties

  alias Neptunus.Navigation.Geo

  @deg :math.pi() / 180

  test "a metre north is 1/R rad of latitude; east shrinks with the latitude's cosine" do
    origin = %{lat: 60 * @deg, lon: 10 * @deg}
    p = Geo.offset(origin, 1000.0, 1000.0)

    # 1 km north: 0.008983° of latitude; 1 km east at 60°: twice the longitude it is at the equator
    assert_in_delta (p.lat - origin.lat) / @deg, 0.0089832, 1.0e-6
    assert_in_delta (p.lon - origin.lon) / @deg, 2 * 0.0089832, 1.0e-6
    assert Geo.offset(origin, 0.0, 0.0) == origin
  end

  test "origin/3 undoes offset/3 within a kilometre, anywhere but the poles" do
    check(
      :proper_types.tuple([
        :proper_types.float(-80.0, 80.0),
        :proper_types.float(-180.0, 180.0),
        :proper_types.float(-1000.0, 1000.0),
        :proper_types.float(-1000.0, 1000.0)
      ]),
      fn {lat, lon, north, east} ->
        origin = %{lat: lat * @deg, lon: lon * @deg}
        back = origin |> Geo.offset(north, east) |> Geo.origin(north, east)
        abs(back.lat - origin.lat) < 1.0e-12 and abs(back.lon - origin.lon) < 1.0e-12
      end
    )
  end
end
