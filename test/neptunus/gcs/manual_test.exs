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
    assert Manual.neutral?(Manual.rc_axes(%{chan3_raw: 1500, chan4_raw: 1500, chan5_raw: 1500}))
  end

  test "any MANUAL_CONTROL is a demand within [-1, 1] on every axis, never -0.0 at neutral" do
    check(Gen.message(:manual_control), fn {:manual_control, fields} ->
      axes = Manual.axes(fields)

      Map.keys(axes) == [:heave, :surge, :yaw] and
        Enum.all?(Map.values(axes), &(&1 >= -1 and &1 <= 1))
    end)
  end

  test "any RC override is a demand within [-1, 1]" do
    check(Gen.message(:rc_channels_override), fn {:rc_channels_override, fields} ->
      fields |> Manual.rc_axes() |> Map.values() |> Enum.all?(&(&1 >= -1 and &1 <= 1))
    end)
  end
end
