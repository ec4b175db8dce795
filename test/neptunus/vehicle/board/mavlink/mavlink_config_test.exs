defmodule Neptunus.Vehicle.Board.MAVLinkConfigTest do
  use ExUnit.Case, async: true

  alias Neptunus.Config.Vehicles

  defp one(spec, env \\ %{}) do
    [vehicle] = Vehicles.vehicles!(Map.put(env, "NEPTUNUS_VEHICLES", spec))
    vehicle
  end

  test "the four links, our ids 255/190 by default" do
    assert %{id: "sub", board: :mavlink, link: {:udp, {0, 0, 0, 0}, 14_550}} =
             one("sub=mavlink:udp:0.0.0.0:14550")

    assert %{link: {:udpout, "192.168.2.2", 14_550}, system: 255, component: 190} =
             one("sub=mavlink:udpout:192.168.2.2:14550")

    assert %{link: {:tcp, "localhost", 5760}} = one("sub=mavlink:tcp:localhost:5760")
    assert %{link: {:serial, "/dev/ttyACM0", 115_200}} = one("sub=mavlink:serial:/dev/ttyACM0")

    assert %{link: {:serial, "/dev/ttyACM0", 57_600}} =
             one("sub=mavlink:serial:/dev/ttyACM0@57600")

    assert %{link: {:udp, {0, 0, 0, 0, 0, 0, 0, 1}, 14_550}} = one("sub=mavlink:udp:[::1]:14550")
  end

  test "a mavlink vehicle has no wiring or firmware, and is not given any" do
    vehicle = one("sub=mavlink:tcp:localhost:5760")
    refute Map.has_key?(vehicle, :wiring)
    refute Map.has_key?(vehicle, :firmware)
  end

  test "our system and component ids are settable per vehicle" do
    [a, b] =
      Vehicles.vehicles!(%{
        "NEPTUNUS_VEHICLES" => "a=mavlink:tcp:h:5760,b=mavlink:tcp:h:5761",
        "NEPTUNUS_MAVLINK_IDS" => "b=254/191"
      })

    assert {a.system, a.component} == {255, 190}
    assert {b.system, b.component} == {254, 191}
  end

  for {spec, ids, message} <- [
        {"s=mavlink", "", ~r/a known board in "s=mavlink"/},
        {"s=mavlink:bogus:1:2", "", ~r/mavlink:udp:ADDRESS:PORT.*udp, udpout, tcp or serial/},
        {"s=mavlink:udp:0.0.0.0", "", ~r/expected HOST:PORT/},
        {"s=mavlink:udp:myhost:14550", "", ~r/local IP address/},
        {"s=mavlink:udpout:h:0", "", ~r/port must be in 1..65535/},
        {"s=mavlink:tcp:h:65536", "", ~r/port must be in 1..65535/},
        {"s=mavlink:tcp::5760", "", ~r/expected HOST:PORT/},
        {"s=mavlink:tcp:h:57x", "", ~r/expected HOST:PORT/},
        {"s=mavlink:serial:ttyACM0", "", ~r/absolute path/},
        {"s=mavlink:serial:/dev/ttyACM0@1234", "", ~r/baud rate must be one of/},
        {"s=mavlink:tcp:h:5760", "s=255", ~r/NEPTUNUS_MAVLINK_IDS.*SYSTEM\/COMPONENT ids/},
        {"s=mavlink:tcp:h:5760", "s=0/190", ~r/SYSTEM\/COMPONENT ids in 1..255/},
        {"s=mavlink:tcp:h:5760", "s=255/256", ~r/SYSTEM\/COMPONENT ids in 1..255/},
        {"s=simulated", "s=255/190", ~r/mavlink vehicles \(s is simulated\)/},
        {"s=mavlink:tcp:h:5760", "t=255/190", ~r/no vehicle "t"/}
      ] do
    test "refuses #{spec} #{ids}" do
      assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
        Vehicles.vehicles!(%{
          "NEPTUNUS_VEHICLES" => unquote(spec),
          "NEPTUNUS_MAVLINK_IDS" => unquote(ids)
        })
      end
    end
  end

  test "the disarm delay after pilot loss is settable per vehicle" do
    [a, b] =
      Vehicles.vehicles!(%{
        "NEPTUNUS_VEHICLES" => "a=mavlink:tcp:h:5760,b=mavlink:tcp:h:5761",
        "NEPTUNUS_MAVLINK_DISARM_DELAY" => "b=0.5"
      })

    refute Map.has_key?(a, :disarm_delay)
    assert b.disarm_delay == 0.5

    for bad <- ["b=0", "b=61", "b=soon", "b"] do
      assert_raise ArgumentError, ~r/NEPTUNUS_MAVLINK_DISARM_DELAY/, fn ->
        Vehicles.vehicles!(%{
          "NEPTUNUS_VEHICLES" => "b=mavlink:tcp:h:5761",
          "NEPTUNUS_MAVLINK_DISARM_DELAY" => bad
        })
      end
    end
  end

  test "a wiring for a mavlink vehicle is refused" do
    assert_raise ArgumentError, ~r/NEPTUNUS_WIRING.*sitl or uart vehicles \(s is mavlink\)/, fn ->
      Vehicles.vehicles!(%{
        "NEPTUNUS_VEHICLES" => "s=mavlink:tcp:h:5760",
        "NEPTUNUS_WIRING" => "s=port/vertical/starboard"
      })
    end
  end
end
