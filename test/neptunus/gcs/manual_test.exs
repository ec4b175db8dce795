defmodule Neptunus.GCS.ManualTest do
  use ExUnit.Case, async: true
  doctest Neptunus.GCS.Manual

  import Neptunus.Test.Properties

  alias Neptunus.GCS.Manual
  alias Neptunus.Test.MAVLinkGen, as: Gen

  test "neutral sticks are a neutral demand; ArduSub's directions are ours" do
    assert Manual.neutral?(Manual.axes(%{x: 0, y: 0, z: 500, r: 0}))
    # forward, up (z above 500), yaw to starboard
    assert %{surge: 1.0, heave: -1.0, yaw: 1.0} = Manual.axes(%{x: 1000, y: 0, z: 1000, r: 1000})
    # our heave is positive down: z below 500
    assert %{heave: 1.0} = Manual.axes(%{x: 0, y: 0, z: 0, r: 0})

    assert Manual.neutral?(
             Manual.rc_axes(%{chan3_raw: 1500, chan4_raw: 1500, chan5_raw: 1500, chan6_raw: 1500})
           )
  end

  test "lateral is sway to starboard: MANUAL_CONTROL y, RC channel 6" do
    assert %{sway: 1.0, surge: +0.0} = Manual.axes(%{x: 0, y: 1000, z: 500, r: 0})
    assert %{sway: -0.5} = Manual.axes(%{x: 0, y: -500, z: 500, r: 0})

    assert %{sway: 0.5} =
             Manual.rc_axes(%{chan3_raw: 1500, chan4_raw: 1500, chan5_raw: 1500, chan6_raw: 1700})

    refute Manual.neutral?(Manual.axes(%{x: 0, y: 300, z: 500, r: 0}))
  end

  describe "the thrust payload: sway only to a vehicle that can sway" do
    @stick %{x: 400, y: -600, z: 250, r: 100}
    @sways [:surge, :sway, :heave, :yaw]
    @three [:surge, :heave, :yaw]

    test "a vehicle with sway (ArduSub, neptunus-sway) gets y as sway" do
      assert %{
               "mode" => "motion",
               "surge" => 0.4,
               "sway" => -0.6,
               "heave" => 0.5,
               "yaw" => 0.1,
               "epoch" => 9
             } == Manual.thrust_payload(Manual.axes(@stick), @sways, 9)
    end

    test "a vehicle without sway (OpenROV, the simulated three-thruster) never gets sway: y is ignored" do
      payload = Manual.thrust_payload(Manual.axes(@stick), @three, 9)
      refute Map.has_key?(payload, "sway")
      assert payload == Manual.thrust_payload(Manual.axes(%{@stick | y: 0}), @three, 9)
      # a vehicle not running here: its axes unknown, no sway
      refute Map.has_key?(Manual.thrust_payload(Manual.axes(@stick), [], 9), "sway")
    end

    test "any MANUAL_CONTROL makes a payload Control takes as the vehicle's command" do
      check(Gen.message(:manual_control), fn {:manual_control, fields} ->
        axes = Manual.axes(fields)

        Enum.all?([@sways, @three], fn vehicle_axes ->
          payload = Manual.thrust_payload(axes, vehicle_axes, 1)

          match?(
            {:ok, {:thrust, :motion, _}},
            Neptunus.Control.Command.validate("thrust", Map.delete(payload, "epoch"))
          ) and Map.has_key?(payload, "sway") == :sway in vehicle_axes
        end)
      end)
    end
  end

  test "any MANUAL_CONTROL is a demand within [-1, 1] on every axis, never -0.0 at neutral" do
    check(Gen.message(:manual_control), fn {:manual_control, fields} ->
      axes = Manual.axes(fields)

      Map.keys(axes) == [:heave, :surge, :sway, :yaw] and
        Enum.all?(Map.values(axes), &(&1 >= -1 and &1 <= 1))
    end)
  end

  test "any RC override is a demand within [-1, 1]" do
    check(Gen.message(:rc_channels_override), fn {:rc_channels_override, fields} ->
      fields |> Manual.rc_axes() |> Map.values() |> Enum.all?(&(&1 >= -1 and &1 <= 1))
    end)
  end
end
