defmodule Neptunus.ScenarioTest do
  use ExUnit.Case, async: true

  alias Neptunus.Scenario
  alias Neptunus.Scenario.Run

  @minimal %{"vehicle" => "thesis-4dof", "duration" => 1}

  defp scenario!(map) do
    {:ok, scenario} = Scenario.validate(map)
    scenario
  end

  defp error(map) do
    assert {:error, reason} = Scenario.validate(map)
    reason
  end

  defp with_event(event), do: Map.put(@minimal, "events", [event])

  describe "parse/1" do
    test "the shipped example scenarios parse" do
      files = Path.wildcard(Path.join(:code.priv_dir(:neptunus), "scenarios/*.json"))
      assert length(files) >= 4

      for file <- files do
        assert {:ok, %Scenario{}} = file |> File.read!() |> Scenario.parse(), file
      end
    end

    test "defaults" do
      s = scenario!(@minimal)
      assert %Scenario{vehicle: "thesis-4dof", duration: 1.0, dt: 0.01, seed: 0, noise: false} = s
      assert s.current == {0.0, 0.0, 0.0} and s.gain == 0.5 and s.events == []
      assert s.initial == [z: 1.0]
      assert Scenario.steps(s) == 100
    end

    test "all fields" do
      json = ~s({
        "description": "everything", "vehicle": "neptunus", "duration": 2.5, "dt": 0.005,
        "seed": -3, "noise": true, "current": [0.1, -0.2, 0], "tether_length": 12,
        "current_variation": {"sigma": 0.02},
        "sensors": {"wild_rate": 0.1, "depth": {"bias": 0.05}},
        "initial": {"z": 2, "psi": 1.5, "u": 0.2}, "gain": 1,
        "events": [
          {"t": 0, "thrust": {"mode": "motion", "surge": 1, "heave": 0, "yaw": -0.5}},
          {"t": 0.5, "gain": 0.2, "current": [0, 0, 0]},
          {"t": 1, "tau": [1, 2, 3, 4, 5, 6]},
          {"t": 1, "thrust": {"mode": "manual", "port": -1, "vertical": 0.5, "starboard": 0}}
        ]})

      assert {:ok, s} = Scenario.parse(json)
      assert s.params.name == "neptunus"
      assert s.current_variation == %{sigma: 0.02, time_constant: 60.0}
      assert s.sensors == %{wild_rate: 0.1, depth: %{bias: 0.05}}
      assert s.initial == [z: 2.0, psi: 1.5, u: 0.2]
      assert Scenario.steps(s) == 500

      assert [
               %{t: 0.0, thrust: {:motion, %{surge: 1.0, heave: 0.0, yaw: -0.5}}},
               %{t: 0.5, gain: 0.2, current: {0.0, 0.0, 0.0}, thrust: nil},
               %{t: 1.0, tau: {1.0, 2.0, 3.0, 4.0, 5.0, 6.0}},
               %{t: 1.0, thrust: {:manual, %{port: -1.0, vertical: 0.5, starboard: 0.0}}}
             ] = s.events

      opts = Scenario.sim_options(s)
      assert opts[:tether_length] == 12.0
      assert opts[:current_variation] == [sigma: 0.02, time_constant: 60.0]
    end
  end

  describe "every error names the field" do
    test "document and JSON" do
      assert {:error, "invalid JSON at byte " <> _} = Scenario.parse(~s({"vehicle": ))
      assert {:error, "empty JSON input"} = Scenario.parse("")
      assert error([1, 2]) == "the document must be an object, got [1,2]"
    end

    test "top-level fields" do
      assert error(%{"duration" => 1}) == "missing field: vehicle"
      assert error(%{"vehicle" => "neptunus"}) == "missing field: duration"
      assert error(Map.put(@minimal, "speed", 3)) =~ "unknown field: speed (expected one of: "

      assert error(%{@minimal | "vehicle" => "submarine"}) =~
               ~s(vehicle: unknown vehicle "submarine")

      assert error(%{@minimal | "vehicle" => 7}) == "vehicle must be a string, got 7"
      assert error(%{@minimal | "duration" => -1}) == "duration must be a number > 0, got -1"
      assert error(%{@minimal | "duration" => 0}) == "duration must be a number > 0, got 0"

      assert error(%{@minimal | "duration" => "60"}) ==
               ~s(duration must be a number > 0, got "60")

      assert error(Map.put(@minimal, "dt", 0)) == "dt must be a number in (0, 1], got 0"
      assert error(%{@minimal | "duration" => 1.0e6}) =~ "duration / dt must be at most"
      assert error(Map.put(@minimal, "seed", 1.5)) == "seed must be an integer, got 1.5"

      assert error(Map.put(@minimal, "noise", "yes")) ==
               ~s(noise must be true or false, got "yes")

      assert error(Map.put(@minimal, "gain", 2)) == "gain must be a number in [0, 1], got 2"
      assert error(Map.put(@minimal, "description", 1)) == "description must be a string, got 1"

      assert error(Map.put(@minimal, "tether_length", -2)) ==
               "tether_length must be a number >= 0, got -2"
    end

    test "current and its variation" do
      assert error(Map.put(@minimal, "current", [1, 2])) ==
               "current must be a list of 3 numbers, got [1,2]"

      assert error(Map.put(@minimal, "current", [1, "a", 0])) =~
               "current[1] must be a number in [-10, 10]"

      assert error(Map.put(@minimal, "current", [0, 11, 0])) =~
               "current[1] must be a number in [-10, 10], got 11"

      assert error(Map.put(@minimal, "current_variation", %{"time_constant" => 3})) ==
               "missing field: current_variation.sigma"

      assert error(
               Map.put(@minimal, "current_variation", %{"sigma" => 0.1, "time_constant" => 0})
             ) ==
               "current_variation.time_constant must be a number > 0, got 0"
    end

    test "sensors" do
      assert error(Map.put(@minimal, "sensors", %{"sonar" => 1})) =~
               "unknown field: sensors.sonar"

      assert error(Map.put(@minimal, "sensors", %{"rate" => 0})) ==
               "sensors.rate must be a number > 0, got 0"

      assert error(Map.put(@minimal, "sensors", %{"depth" => %{"noise" => -1}})) ==
               "sensors.depth.noise must be a number >= 0, got -1"

      assert error(Map.put(@minimal, "sensors", %{"depth" => %{"drift" => 1}})) =~
               "unknown field: sensors.depth.drift"

      assert error(Map.put(@minimal, "sensors", %{"wild_rate" => 0.7, "mixup_rate" => 0.4})) ==
               "sensors.wild_rate + sensors.mixup_rate must be at most 1"
    end

    test "initial state" do
      assert error(Map.put(@minimal, "initial", %{"depth" => 1})) =~
               "unknown field: initial.depth"

      assert error(Map.put(@minimal, "initial", %{"z" => "deep"})) =~
               ~s(initial.z must be a number >= 0, got "deep")

      assert error(Map.put(@minimal, "initial", %{"z" => -1})) ==
               "initial.z must be a number >= 0, got -1"

      assert error(Map.put(@minimal, "initial", %{"phi" => 0.1})) ==
               "initial.phi must be 0 for vehicle thesis-4dof (roll and pitch are fixed)"

      assert error(%{@minimal | "vehicle" => "neptunus"} |> Map.put("initial", %{"theta" => 1.6})) ==
               "initial.theta must be a number in [-1.5, 1.5], got 1.6"

      assert scenario!(
               %{@minimal | "vehicle" => "neptunus"}
               |> Map.put("initial", %{"phi" => 0.1})
             ).initial ==
               [phi: 0.1]
    end

    test "events" do
      assert error(Map.put(@minimal, "events", %{})) == "events must be a list, got {}"
      assert error(with_event(3)) == "events[0] must be an object, got 3"
      assert error(with_event(%{"gain" => 1})) == "missing field: events[0].t"

      assert error(with_event(%{"t" => 0})) ==
               "events[0] must have at least one of: autopilot, control_mode, current, gain, " <>
                 "mission, mission_control, tau, thrust"

      assert error(with_event(%{"t" => 0, "foo" => 1})) =~ "unknown field: events[0].foo"

      assert error(with_event(%{"t" => -1, "gain" => 1})) ==
               "events[0].t must be a number in [0, 1], got -1"

      assert error(with_event(%{"t" => 2, "gain" => 1})) ==
               "events[0].t must be a number in [0, 1], got 2"

      assert error(with_event(%{"t" => 0, "gain" => 1.5})) ==
               "events[0].gain must be a number in [0, 1], got 1.5"

      assert error(with_event(%{"t" => 0, "tau" => [1, 2, 3]})) ==
               "events[0].tau must be a list of 6 numbers, got [1,2,3]"

      assert error(with_event(%{"t" => 0, "current" => "east"})) =~
               "events[0].current must be a list of 3 numbers"

      # autopilot and control_mode events: test/neptunus/control/scenario_control_test.exs

      assert error(
               Map.put(@minimal, "events", [
                 %{"t" => 0.5, "gain" => 1},
                 %{"t" => 0.2, "gain" => 0}
               ])
             ) == "events[1].t must not be before events[0].t (events are in time order), got 0.2"
    end

    test "thrust" do
      assert error(with_event(%{"t" => 0, "thrust" => 1})) ==
               "events[0].thrust must be an object, got 1"

      assert error(with_event(%{"t" => 0, "thrust" => %{"surge" => 1}})) ==
               "missing field: events[0].thrust.mode"

      assert error(with_event(%{"t" => 0, "thrust" => %{"mode" => "dp"}})) ==
               ~s(events[0].thrust.mode must be "motion" or "manual", got "dp")

      motion = %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0}

      assert error(with_event(%{"t" => 0, "thrust" => %{motion | "surge" => 2}})) ==
               "events[0].thrust.surge must be a number in [-1, 1], got 2"

      assert error(with_event(%{"t" => 0, "thrust" => Map.delete(motion, "yaw")})) ==
               "missing field: events[0].thrust.yaw"

      assert error(with_event(%{"t" => 0, "thrust" => Map.put(motion, "port", 1)})) =~
               "unknown field: events[0].thrust.port"

      manual = %{"mode" => "manual", "port" => 1, "vertical" => 0, "starboard" => "x"}

      assert error(with_event(%{"t" => 0, "thrust" => manual})) ==
               ~s(events[0].thrust.starboard must be a number in [-1, 1], got "x")
    end
  end

  describe "Run" do
    test "one row per step from t = 0 to the duration, in the documented columns" do
      rows = @minimal |> scenario!() |> Run.rows() |> Enum.to_list()
      assert length(rows) == 101
      assert Enum.all?(rows, &(length(&1) == length(Run.columns())))
      assert hd(rows) |> hd() == 0.0
      assert_in_delta rows |> List.last() |> hd(), 1.0, 1.0e-12

      assert Run.columns() ==
               ~w(t x y z phi theta psi u v w p q r depth_meas heading_meas roll_meas pitch_meas
                  voltage_meas current_meas depth_est depth_rate_est heading_est yaw_rate_est roll_est pitch_est
                  depth_setpoint heading_setpoint depth_reference heading_reference port
                  vertical starboard lateral north_est east_est velocity_north_est
                  velocity_east_est position_std position_valid target_north target_east
                  cross_track leg mission_done)
    end

    test "events take effect at their step; gain scales motion and manual thrust" do
      s =
        scenario!(
          Map.merge(@minimal, %{
            "gain" => 1,
            "events" => [
              %{
                "t" => 0.1,
                "thrust" => %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0.5}
              },
              %{"t" => 0.5, "gain" => 0.5},
              %{
                "t" => 0.7,
                "thrust" => %{
                  "mode" => "manual",
                  "port" => -1,
                  "vertical" => 0.4,
                  "starboard" => 1
                }
              }
            ]
          })
        )

      rows = s |> Run.rows() |> Enum.to_list()
      port = Enum.find_index(Run.columns(), &(&1 == "port"))
      thrusters = fn k -> rows |> Enum.at(k) |> Enum.slice(port, 3) end
      assert thrusters.(9) == [0.0, 0.0, 0.0]
      assert thrusters.(10) == [1.0, 0.0, 0.5]
      assert thrusters.(49) == [1.0, 0.0, 0.5]
      assert thrusters.(50) == [0.75, 0.0, 0.25]
      assert thrusters.(70) == [-0.5, 0.2, 0.5]
      # the vehicle only starts moving after the thrust event
      u = fn k -> rows |> Enum.at(k) |> Enum.at(7) end
      assert u.(10) == 0.0 and u.(11) > 0.0
    end

    test "tau and current events act on the simulation" do
      s =
        scenario!(
          Map.merge(@minimal, %{
            "duration" => 2,
            "events" => [
              %{"t" => 0, "tau" => [0, 0, 0, 0, 0, 1]},
              %{"t" => 1, "tau" => [0, 0, 0, 0, 0, 0], "current" => [0.5, 0, 0]}
            ]
          })
        )

      rows = s |> Run.rows() |> Enum.to_list()
      # yaw rate from the external moment
      assert rows |> Enum.at(50) |> Enum.at(12) > 0.1
      # the current carries the vehicle north once it flows
      x = fn k -> rows |> Enum.at(k) |> Enum.at(1) end
      assert x.(200) - x.(100) > 0.1
    end

    test "every N keeps every N-th row (and the last); events between rows still apply on time" do
      s =
        scenario!(
          Map.merge(@minimal, %{
            "events" => [
              %{
                "t" => 0.33,
                "thrust" => %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0}
              }
            ]
          })
        )

      all = s |> Run.rows() |> Enum.to_list()
      some = s |> Run.rows(7) |> Enum.to_list()
      assert length(some) == 16
      assert Enum.map(some, &hd/1) == Enum.map(Enum.take_every(all, 7) ++ [List.last(all)], &hd/1)

      for row <- some do
        assert row == Enum.find(all, &(hd(&1) == hd(row)))
      end
    end

    test "runs are reproducible from the seed; CSV has a header and one line per row" do
      s = scenario!(Map.merge(@minimal, %{"vehicle" => "neptunus", "noise" => true, "seed" => 5}))
      assert Enum.to_list(Run.rows(s)) == Enum.to_list(Run.rows(s))

      csv = s |> Run.csv() |> Enum.to_list() |> IO.iodata_to_binary()
      [header | lines] = String.split(csv, "\n", trim: true)
      assert header == Enum.join(Run.columns(), ",")
      assert length(lines) == 101
      assert "0.01," <> _ = Enum.at(lines, 1)

      for line <- lines do
        values = String.split(line, ",")
        assert length(values) == length(Run.columns())
        # the autopilot setpoints and references are empty while disengaged
        assert ["", "", "", ""] = Enum.slice(values, 25, 4)

        Enum.each(
          Enum.reject(values, &(&1 == "")),
          &String.to_float(if String.contains?(&1, "."), do: &1, else: &1 <> ".0")
        )
      end
    end
  end
end
