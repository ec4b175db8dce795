defmodule Neptunus.GCS.ParamsTest do
  use ExUnit.Case, async: true
  doctest Neptunus.GCS.Params

  alias Neptunus.GCS.Params

  @sources %{
    control: %{gain: 0.5, lights: 10, tilt: -:math.pi() / 4},
    gains: %{
      "depth" => %{"kp" => 3.0, "ki" => 0.1, "kd" => 1.5},
      "heading" => %{"kp" => 2.0, "ki" => 0.0, "kd" => 0.5}
    },
    limits: %{depth: %{rate: 0.3, accel: 0.2}, heading: %{rate: 0.4, accel: 0.3}},
    helm: %{deadman_ms: 500, request_timeout_ms: 10_000, takeover_ms: 3_000},
    wiring: nil
  }

  test "the parameters in their fixed order, names within MAVLink's 16 characters" do
    params = Params.list(@sources)

    assert Enum.map(params, & &1.name) ==
             ~w(PILOT_GAIN LIGHTS CAM_TILT_DEG DEPTH_KP DEPTH_KI DEPTH_KD HDG_KP HDG_KI HDG_KD
                DEPTH_RATE_MAX DEPTH_ACC_MAX HDG_RATE_MAX HDG_ACC_MAX DEADMAN_MS REQ_TIMEOUT_MS TAKEOVER_MS)

    values = Map.new(params, &{&1.name, &1.value})
    assert values["CAM_TILT_DEG"] == -45.0
    assert_in_delta values["HDG_RATE_MAX"], 22.918, 0.001
    assert Enum.all?(params, &(byte_size(&1.name) <= 16 and is_float(&1.value)))
  end

  test "a uart or sitl vehicle's wiring, read-only" do
    params = Params.list(%{@sources | wiring: Neptunus.Vehicle.Board.OpenROV.Wiring.default()})
    values = Map.new(params, &{&1.name, &1.value})

    assert %{
             "WIRE_PORT_POS" => 1.0,
             "WIRE_PORT_REV" => 1.0,
             "WIRE_VERT_POS" => 2.0,
             "WIRE_STBD_POS" => 3.0,
             "WIRE_STBD_REV" => 0.0
           } = values

    assert {:error, "WIRE_PORT_POS is read-only" <> _} = Params.set("WIRE_PORT_POS", 2.0)
  end

  test "what is unknown is left out" do
    assert Params.list(%{control: nil, gains: nil, limits: nil, helm: nil, wiring: nil}) == []
  end

  test "setting: the pages' commands and tuning, values checked there; NaN refused here" do
    assert Params.set("PILOT_GAIN", 0.25) == {:control, "set_gain", %{"value" => 0.25}}
    assert {:control, "set_tilt", %{"value" => tilt}} = Params.set("CAM_TILT_DEG", 45.0)
    assert_in_delta tilt, :math.pi() / 4, 1.0e-12
    assert Params.set("HDG_KI", 0.2) == {:tune, %{"heading" => %{"ki" => 0.2}}}
    assert {:error, _} = Params.set("LIGHTS", 256.0)
    assert {:error, _} = Params.set("LIGHTS", :nan)
    assert Params.set("X", 1.0) == {:error, "no parameter X"}
    assert Params.pilot_only?("LIGHTS") and not Params.pilot_only?("DEPTH_KP")
  end
end
