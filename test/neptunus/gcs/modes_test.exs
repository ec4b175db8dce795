defmodule Neptunus.GCS.ModesTest do
  use ExUnit.Case, async: true
  doctest Neptunus.GCS.Modes

  alias Neptunus.GCS.Modes

  # the control state after a command (as Control answers, for a vehicle with a position)
  defp apply_command({"set_control_mode", %{"mode" => mode}}, control) do
    autopilot = if mode == "dp", do: %{depth: 1.0, heading: 1.0}, else: control.autopilot

    %{control | mode: mode, autopilot: autopilot}
  end

  defp apply_command({"autopilot", payload}, control) do
    value = fn
      "hold" -> 1.0
      nil -> nil
    end

    %{
      control
      | autopilot: %{depth: value.(payload["depth"]), heading: value.(payload["heading"])}
    }
  end

  test "every mode that can be set is the mode the vehicle then reports, from any mode" do
    states = [
      %{mode: "motion", autopilot: %{depth: nil, heading: nil}},
      %{mode: "motion", autopilot: %{depth: 2.0, heading: 1.0}},
      %{mode: "motion", autopilot: %{depth: 2.0, heading: nil}},
      %{mode: "dp", autopilot: %{depth: 1.0, heading: 1.0}},
      %{mode: "manual", autopilot: %{depth: nil, heading: nil}}
    ]

    for from <- states, {mode, name} <- Modes.names(), name != "THRUSTERS" do
      {:ok, commands} = Modes.commands(mode, from)
      to = Enum.reduce(commands, from, &apply_command/2)
      assert Modes.current(to, nil) == mode, "#{name} from #{inspect(from)}: #{inspect(to)}"
    end
  end

  test "a mode that is not there, and manual per-thruster mode, are refused with the reason" do
    assert {:error, "no flight mode 7 here: " <> known} = Modes.commands(7, nil)
    assert known =~ "19 MANUAL"
    assert {:error, _} = Modes.commands(101, %{mode: "motion"})
  end

  test "an ArduSub vehicle reports its own mode; before any state, MANUAL" do
    assert Modes.current(%{mode: "motion", autopilot: %{depth: 1.0, heading: 1.0}}, "MANUAL") ==
             19

    assert Modes.current(nil, "SURFACE") == 9
    assert Modes.current(nil, nil) == 19
    assert Modes.current(%{mode: "manual"}, nil) == 101
  end
end
