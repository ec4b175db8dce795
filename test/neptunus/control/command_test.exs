defmodule Neptunus.Control.CommandTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.Command

  doctest Neptunus.Control.Command

  defp v(event, payload), do: Command.validate(event, payload)
  defp error(event, payload), do: elem({:error, _} = v(event, payload), 1)

  test "the events" do
    assert Command.events() ==
             ~w(set_control_mode thrust set_gain set_lights set_laser set_tilt autopilot set_run_mode
                mission)
  end

  describe "mission" do
    test "start and plan take waypoints or a survey; the others only an action" do
      wp = %{"north" => 5, "east" => 1, "depth" => 2}

      assert {:ok,
              {:mission,
               {:start,
                [%{north: 5.0, east: 1.0, depth: 2.0, speed: 0.3, radius: 0.5, heading: nil}]}}} =
               Command.validate("mission", %{"action" => "start", "waypoints" => [wp]})

      survey = %{
        "north" => 0,
        "east" => 0,
        "heading" => 0,
        "length" => 10,
        "width" => 4,
        "spacing" => 2,
        "depth" => 3
      }

      assert {:ok, {:mission, {:plan, wps}}} =
               Command.validate("mission", %{"action" => "plan", "survey" => survey})

      assert length(wps) == 6

      for action <- ~w(pause resume abort) do
        assert {:ok, {:mission, a}} = Command.validate("mission", %{"action" => action})
        assert Atom.to_string(a) == action
      end
    end

    test "malformed missions are refused with a reason naming the field" do
      assert error("mission", %{}) == "missing field: action"
      assert error("mission", %{"action" => "fly"}) =~ ~s(action must be "start")
      assert error("mission", %{"action" => "pause", "x" => 1}) =~ "unknown field: x"

      assert error("mission", %{"action" => "start"}) ==
               "a mission needs waypoints (a list) or a survey (an object)"

      assert error("mission", %{"action" => "start", "waypoints" => []}) ==
               "a mission needs at least one waypoint"

      assert error("mission", %{
               "action" => "start",
               "waypoints" => [%{"north" => 1, "east" => 1, "depth" => 2, "speed" => 3}]
             }) ==
               "waypoints[0].speed must be a number in [0.05, 1], got 3"

      assert error("mission", %{
               "action" => "start",
               "waypoints" => [%{"north" => 1, "depth" => 2}]
             }) ==
               "missing field: waypoints[0].east"

      too_many = for i <- 1..101, do: %{"north" => i, "east" => 0, "depth" => 1}

      assert error("mission", %{"action" => "start", "waypoints" => too_many}) =~
               "at most 100 waypoints"

      dense = %{
        "north" => 0,
        "east" => 0,
        "heading" => 0,
        "length" => 10,
        "width" => 500,
        "spacing" => 1,
        "depth" => 3
      }

      assert error("mission", %{"action" => "start", "survey" => dense}) =~
               "the survey makes 1002 waypoints"
    end
  end

  test "every payload must be an object" do
    for event <- Command.events() do
      assert error(event, [1]) == "#{event} payload must be an object, got [1]"
    end

    assert error("fly", %{}) == "unknown control command: fly"
  end

  describe "set_control_mode and set_run_mode" do
    test "valid modes" do
      assert v("set_control_mode", %{"mode" => "motion"}) == {:ok, {:set_control_mode, :motion}}
      assert v("set_control_mode", %{"mode" => "manual"}) == {:ok, {:set_control_mode, :manual}}
      assert v("set_control_mode", %{"mode" => "dp"}) == {:ok, {:set_control_mode, :dp}}
      assert v("set_run_mode", %{"mode" => "normal"}) == {:ok, {:set_run_mode, :normal}}
      assert v("set_run_mode", %{"mode" => "simulator"}) == {:ok, {:set_run_mode, :simulator}}
    end

    test "errors" do
      assert error("set_control_mode", %{"mode" => "auto"}) ==
               ~s(mode must be one of "dp", "manual", "motion", got "auto")

      assert error("set_control_mode", %{"mode" => 1}) ==
               ~s(mode must be one of "dp", "manual", "motion", got 1)

      assert error("set_control_mode", %{}) == "missing field: mode"

      assert error("set_control_mode", %{"mode" => "dp", "x" => 1}) ==
               "unknown field: x (expected one of: mode)"

      assert error("set_run_mode", %{"mode" => "sim"}) ==
               ~s(mode must be one of "normal", "simulator", got "sim")
    end
  end

  describe "thrust" do
    test "motion and manual, numbers as floats" do
      assert v("thrust", %{"mode" => "motion", "surge" => 1, "heave" => -0.5, "yaw" => 0}) ==
               {:ok, {:thrust, :motion, %{surge: 1.0, heave: -0.5, yaw: 0.0}}}

      assert v("thrust", %{"mode" => "manual", "port" => 0.2, "vertical" => -1, "starboard" => 1}) ==
               {:ok, {:thrust, :manual, %{port: 0.2, vertical: -1.0, starboard: 1.0}}}
    end

    test "errors name the field" do
      assert error("thrust", %{}) == "missing field: mode"

      assert error("thrust", %{"mode" => "dp"}) ==
               ~s(mode must be "motion" or "manual", got "dp")

      assert error("thrust", %{"mode" => "motion", "surge" => 2, "heave" => 0, "yaw" => 0}) ==
               "surge must be a number in [-1, 1], got 2"

      assert error("thrust", %{"mode" => "manual", "port" => 0, "vertical" => 0}) ==
               "missing field: starboard"

      assert error("thrust", %{
               "mode" => "manual",
               "port" => 0,
               "vertical" => "up",
               "starboard" => 0
             }) ==
               ~s(vertical must be a number in [-1, 1], got "up")

      assert error("thrust", %{
               "mode" => "motion",
               "surge" => 0,
               "heave" => 0,
               "yaw" => 0,
               "roll" => 0
             }) =~
               "unknown field: roll"
    end
  end

  describe "gain, lights, laser, tilt" do
    test "valid values" do
      assert v("set_gain", %{"value" => 0}) == {:ok, {:set_gain, 0.0}}
      assert v("set_gain", %{"value" => 1}) == {:ok, {:set_gain, 1.0}}
      assert v("set_lights", %{"value" => 0}) == {:ok, {:set_lights, 0}}
      assert v("set_laser", %{"value" => 255}) == {:ok, {:set_laser, 255}}
      assert v("set_tilt", %{"value" => -0.5}) == {:ok, {:set_tilt, -0.5}}
      assert {:ok, {:set_tilt, max}} = v("set_tilt", %{"value" => :math.pi() / 4})
      assert max == Command.tilt_max()
    end

    test "out of range or wrong type" do
      assert error("set_gain", %{"value" => -0.1}) == "value must be a number in [0, 1], got -0.1"
      assert error("set_gain", %{"value" => "1"}) == ~s(value must be a number in [0, 1], got "1")
      assert error("set_gain", %{}) == "missing field: value"

      assert error("set_lights", %{"value" => 256}) ==
               "value must be an integer in [0, 255], got 256"

      assert error("set_lights", %{"value" => 12.5}) ==
               "value must be an integer in [0, 255], got 12.5"

      assert error("set_laser", %{"value" => -1}) ==
               "value must be an integer in [0, 255], got -1"

      assert error("set_laser", %{"value" => true}) ==
               "value must be an integer in [0, 255], got true"

      assert error("set_tilt", %{"value" => 0.8}) ==
               "value must be a number in [-0.7854, 0.7854] (rad, ±45°), got 0.8"

      assert error("set_tilt", %{"value" => nil}) ==
               "value must be a number in [-0.7854, 0.7854] (rad, ±45°), got null"

      assert error("set_lights", %{"value" => 1, "on" => true}) ==
               "unknown field: on (expected one of: value)"
    end
  end

  describe "autopilot" do
    test "numbers, hold, null, absent" do
      assert v("autopilot", %{"depth" => 2}) ==
               {:ok, {:autopilot, %{depth: 2.0, heading: :unchanged}}}

      assert v("autopilot", %{"heading" => "hold", "depth" => nil}) ==
               {:ok, {:autopilot, %{depth: nil, heading: :hold}}}

      assert v("autopilot", %{"heading" => 1.5}) ==
               {:ok, {:autopilot, %{depth: :unchanged, heading: 1.5}}}
    end

    test "headings are wrapped to [0, 2π)" do
      assert {:ok, {:autopilot, %{heading: h}}} = v("autopilot", %{"heading" => -:math.pi() / 2})
      assert_in_delta h, 3 * :math.pi() / 2, 1.0e-12

      assert {:ok, {:autopilot, %{heading: +0.0}}} =
               v("autopilot", %{"heading" => 2 * :math.pi()})
    end

    test "errors" do
      assert error("autopilot", %{}) ==
               ~s|autopilot needs depth and/or heading (a setpoint, "hold" or null)|

      assert error("autopilot", %{"depth" => -1}) ==
               ~s(depth must be a depth in [0, 200] m, "hold" or null, got -1)

      assert error("autopilot", %{"depth" => "deep"}) ==
               ~s(depth must be a depth in [0, 200] m, "hold" or null, got "deep")

      # degrees by mistake are caught
      assert error("autopilot", %{"heading" => 90}) ==
               ~s(heading must be a heading in [-6.2832, 6.2832] rad, "hold" or null, got 90)

      assert error("autopilot", %{"pitch" => 1}) =~ "unknown field: pitch"
    end
  end
end
