defmodule Neptunus.Control.ScenarioControlTest do
  # Control in headless scenarios: `autopilot` and `control_mode` events, and the acceptance
  # figures of issue 4 on the shipped scenarios (simulated time, the `neptunus` vehicle with
  # realistic sensors and navigation's estimator — no wall clock involved).
  use ExUnit.Case, async: true

  alias Neptunus.{PID, Scenario}
  alias Neptunus.Control.Autopilot
  alias Neptunus.Scenario.Run

  @minimal %{"vehicle" => "neptunus", "duration" => 1}
  @pi :math.pi()

  defp with_events(events), do: Map.put(@minimal, "events", events)
  defp error(map), do: elem({:error, _} = Scenario.validate(map), 1)

  defp scenario!(name) do
    {:ok, s} =
      Scenario.parse(File.read!(Path.join([:code.priv_dir(:neptunus), "scenarios", name])))

    s
  end

  # the rows as maps by column
  defp run(scenario) do
    columns = Enum.map(Run.columns(), &String.to_atom/1)
    scenario |> Run.rows() |> Enum.map(&(columns |> Enum.zip(&1) |> Map.new()))
  end

  describe "validation" do
    test "autopilot events: metres, degrees, hold, null" do
      {:ok, s} =
        Scenario.validate(
          with_events([
            %{"t" => 0, "autopilot" => %{"depth" => 1.5, "heading" => -90}},
            %{"t" => 0.5, "autopilot" => %{"depth" => "hold", "heading" => nil}},
            %{"t" => 0.6, "autopilot" => %{"heading" => "hold"}}
          ])
        )

      [a, b, c] = Enum.map(s.events, & &1.autopilot)
      assert a.depth == 1.5
      assert_in_delta a.heading, 3 * @pi / 2, 1.0e-12
      assert b == %{depth: :hold, heading: nil}
      assert c == %{depth: :unchanged, heading: :hold}
    end

    test "autopilot errors name the field" do
      assert error(with_events([%{"t" => 0, "autopilot" => %{"depth" => -1}}])) ==
               "events[0].autopilot.depth must be a number in [0, 200], got -1"

      assert error(with_events([%{"t" => 0, "autopilot" => %{"heading" => 400}}])) ==
               "events[0].autopilot.heading must be a number in [-360, 360], got 400"

      assert error(with_events([%{"t" => 0, "autopilot" => %{}}])) ==
               ~s|events[0].autopilot needs depth and/or heading (a setpoint, "hold" or null)|

      assert error(with_events([%{"t" => 0, "autopilot" => %{"roll" => 1}}])) =~
               "unknown field: events[0].autopilot.roll"
    end

    test "control modes along the events" do
      assert error(with_events([%{"t" => 0, "control_mode" => "auto"}])) ==
               ~s(events[0].control_mode must be "motion", "manual" or "dp", got "auto")

      manual = %{"mode" => "manual", "port" => 0, "vertical" => 0, "starboard" => 0}

      # a manual thrust switches to manual: no autopilots there
      assert error(
               with_events([
                 %{"t" => 0, "thrust" => manual},
                 %{"t" => 0.5, "autopilot" => %{"depth" => 1}}
               ])
             ) == "events[1].autopilot: autopilots are not available in manual mode"

      assert error(
               with_events([
                 %{"t" => 0, "control_mode" => "dp"},
                 %{"t" => 0.5, "autopilot" => %{"depth" => nil}}
               ])
             ) =~ "events[1].autopilot: dp holds depth and heading"

      assert error(with_events([%{"t" => 0, "control_mode" => "dp", "thrust" => manual}])) ==
               "events[0].thrust.mode must be the event's control_mode (dp), got manual"

      assert {:ok, _} =
               Scenario.validate(
                 with_events([
                   %{"t" => 0, "control_mode" => "manual"},
                   %{"t" => 0.5, "control_mode" => "motion", "autopilot" => %{"depth" => 1}}
                 ])
               )
    end
  end

  describe "runs" do
    test "the setpoint columns follow the autopilots" do
      {:ok, s} =
        Scenario.validate(%{
          "vehicle" => "neptunus",
          "duration" => 1,
          "initial" => %{"z" => 1.0},
          "events" => [
            %{"t" => 0.2, "autopilot" => %{"depth" => "hold", "heading" => 45}},
            %{"t" => 0.6, "autopilot" => %{"heading" => nil}}
          ]
        })

      rows = run(s)
      assert Enum.at(rows, 10).depth_setpoint == nil
      at = Enum.at(rows, 30)
      assert_in_delta at.depth_setpoint, 1.0, 0.01
      assert_in_delta at.heading_setpoint, @pi / 4, 1.0e-12
      assert %{depth_setpoint: d, heading_setpoint: nil} = List.last(rows)
      assert is_float(d)
    end

    test "a thrust in another mode switches mode (neutral first) as on a live vehicle" do
      {:ok, s} =
        Scenario.validate(%{
          "vehicle" => "neptunus",
          "duration" => 0.5,
          "gain" => 1,
          "initial" => %{"z" => 1.0},
          "events" => [
            %{"t" => 0, "autopilot" => %{"depth" => "hold"}},
            %{
              "t" => 0.1,
              "thrust" => %{"mode" => "manual", "port" => 0.5, "vertical" => 0, "starboard" => 0}
            }
          ]
        })

      rows = run(s)
      assert %{port: 0.5, vertical: +0.0, depth_setpoint: nil} = List.last(rows)
    end
  end

  describe "acceptance figures (issue 4)" do
    test "depth step 0 → 1 m: within ±5 cm in < 10 s, overshoot < 10 cm" do
      rows = run(scenario!("autopilot-depth-step.json"))
      after_step = Enum.filter(rows, &(&1.t >= 2.0))
      overshoot = Enum.max(Enum.map(after_step, & &1.z)) - 1.0
      last_out = after_step |> Enum.filter(&(abs(&1.z - 1.0) > 0.05)) |> Enum.map(& &1.t)
      settle = Enum.max(last_out, fn -> 2.0 end) - 2.0

      assert overshoot < 0.10
      assert settle < 10.0
      report("depth step 0 → 1 m: overshoot #{cm(overshoot)}, within ±5 cm after #{s(settle)}")

      # no jerk: the autopilot tracked a reference within the default limits, not the step
      %{rate: rate, accel: accel} = Map.new(Autopilot.default_limits().depth)
      {max_rate, max_accel} = profile(rows, :depth_reference, false)
      assert max_rate <= rate + 1.0e-9 and max_accel <= accel + 1.0e-6
      assert max_rate > rate / 2
      report("depth reference: at most #{max_rate} m/s, #{Float.round(max_accel, 3)} m/s²")
    end

    test "heading step 0 → 90° in a 0.1 m/s cross current: within ±2° in < 8 s" do
      rows = run(scenario!("autopilot-heading-step.json"))
      after_step = Enum.filter(rows, &(&1.t >= 5.0))
      errors = Enum.map(after_step, &{&1.t, PID.wrap_pi(&1.psi - @pi / 2) * 180 / @pi})
      last_out = for {t, e} <- errors, abs(e) > 2.0, do: t
      settle = Enum.max(last_out, fn -> 5.0 end) - 5.0
      overshoot = errors |> Enum.map(&elem(&1, 1)) |> Enum.max()

      assert settle < 8.0
      report("heading step 0 → 90°: within ±2° after #{s(settle)}, overshoot #{deg(overshoot)}")

      %{rate: rate, accel: accel} = Map.new(Autopilot.default_limits().heading)
      {max_rate, max_accel} = profile(rows, :heading_reference, true)
      assert max_rate <= rate + 1.0e-9 and max_accel <= accel + 1.0e-6
      assert max_rate > rate / 2
    end

    test "depth hold engaged while descending at 0.3 m/s: depth change < 15 cm" do
      rows = run(scenario!("autopilot-depth-engage.json"))
      engage = Enum.find(rows, &(&1.t >= 6.0))
      assert_in_delta engage.w, 0.3, 0.03

      change =
        rows |> Enum.filter(&(&1.t >= 6.0)) |> Enum.map(&abs(&1.z - engage.z)) |> Enum.max()

      final = List.last(rows).z - engage.z

      assert change < 0.15
      assert abs(final) < 0.05
      report("engaged at #{Float.round(engage.w, 3)} m/s down: depth change #{cm(change)}")
    end

    test "dp: holds position against a head current; bounded in a cross current" do
      rows = run(scenario!("dp-station-keeping.json"))
      distance = fn r -> :math.sqrt(r.x * r.x + r.y * r.y) end
      head = rows |> Enum.filter(&(&1.t >= 10 and &1.t < 40)) |> Enum.map(distance) |> Enum.max()
      cross = rows |> Enum.filter(&(&1.t >= 40)) |> Enum.map(distance) |> Enum.max()
      depth = rows |> Enum.filter(&(&1.t >= 2)) |> Enum.map(&abs(&1.z - 2.0)) |> Enum.max()

      assert head < 0.05
      assert cross < 2.5
      assert depth < 0.05

      report(
        "dp: #{cm(head)} from target in a head current, at most #{Float.round(cross, 2)} m " <>
          "in a cross current, depth within #{cm(depth)}"
      )
    end
  end

  # the largest rate and acceleration of a reference column, from its values at the control
  # ticks (every other row: a tick every 0.02 s, rows every 0.01 s)
  defp profile(rows, column, wrap?) do
    values =
      rows |> Enum.take_every(2) |> Enum.map(&Map.fetch!(&1, column)) |> Enum.reject(&is_nil/1)

    diff = fn a, b -> if wrap?, do: PID.wrap_pi(b - a), else: b - a end

    rates =
      values |> Enum.chunk_every(2, 1, :discard) |> Enum.map(fn [a, b] -> diff.(a, b) / 0.02 end)

    accels =
      rates |> Enum.chunk_every(2, 1, :discard) |> Enum.map(fn [a, b] -> (b - a) / 0.02 end)

    {rates |> Enum.map(&abs/1) |> Enum.max(), accels |> Enum.map(&abs/1) |> Enum.max()}
  end

  defp report(line), do: if(System.get_env("REPORT"), do: IO.puts("\n  " <> line))
  defp cm(m), do: "#{Float.round(m * 100, 1)} cm"
  defp s(s), do: "#{Float.round(s, 2)} s"
  defp deg(d), do: "#{Float.round(d, 2)}°"
end
