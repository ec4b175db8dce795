defmodule Neptunus.Position.ClosedLoopTest do
  @moduledoc """
  Position, position hold and a mission in the simulator, headless (`Neptunus.Scenario.Run`:
  the live navigation filter and control on simulated time), in a 0.1 m/s current, on the
  simulated DVL and USBL with their noise, dropouts, delay and outliers. The errors are the
  truth's. Seeded: the same run every time. Figures over many seeds: bench/position.
  """
  use ExUnit.Case, async: true

  alias Neptunus.Scenario
  alias Neptunus.Scenario.Run

  @current [0.0, 0.1, 0.0]

  defp run(vehicle, position, duration, events, seed \\ 7) do
    {:ok, s} =
      Scenario.validate(%{
        "vehicle" => vehicle,
        "duration" => duration,
        "seed" => seed,
        "noise" => true,
        "current" => @current,
        "initial" => %{"z" => 2.0},
        "position" => position,
        "events" => events
      })

    cols = Run.columns() |> Enum.with_index() |> Map.new()
    rows = s |> Run.rows(10) |> Enum.to_list()
    {rows, fn row, name -> Enum.at(row, Map.fetch!(cols, name)) end}
  end

  @dp [
    %{"t" => 0, "autopilot" => %{"depth" => "hold", "heading" => "hold"}},
    %{"t" => 5, "control_mode" => "dp"}
  ]

  defp p95(values), do: Neptunus.Scenario.MonteCarlo.percentile(values, 95)

  defp hold_radius(rows, at, from_t) do
    for row <- rows, at.(row, "t") >= from_t, tn = at.(row, "target_north"), is_number(tn) do
      :math.sqrt(
        :math.pow(at.(row, "x") - tn, 2) + :math.pow(at.(row, "y") - at.(row, "target_east"), 2)
      )
    end
  end

  describe "position hold in a 0.1 m/s sideways current, DVL and USBL" do
    test "the three-thruster vehicle keeps within its 1 m radius, bow into the current" do
      {rows, at} = run("neptunus", %{"dvl" => true, "usbl" => true}, 120, @dp)
      radii = hold_radius(rows, at, 40)
      assert length(radii) > 700
      assert p95(radii) < 1.0, "radius p95 #{p95(radii)} m"

      # it weathervanes: the current flows east, the bow turns west, into it (it started
      # heading north)
      heading = at.(List.last(rows), "psi")
      assert :math.sin(heading) < -0.5, "heading #{heading} rad"
    end

    test "the fully actuated vehicle holds its point within 0.3 m" do
      {rows, at} = run("neptunus-sway", %{"dvl" => true, "usbl" => true}, 120, @dp)
      radii = hold_radius(rows, at, 40)
      assert p95(radii) < 0.3, "radius p95 #{p95(radii)} m"
    end

    test "on the USBL alone it still holds, on fixes, within a few metres" do
      {rows, at} = run("neptunus", %{"usbl" => true}, 120, @dp)
      radii = hold_radius(rows, at, 40)
      assert p95(radii) < 3.0, "radius p95 #{p95(radii)} m"
    end
  end

  test "the estimate against the truth: position RMS with DVL and USBL in motion" do
    {rows, at} =
      run("neptunus", %{"dvl" => true, "usbl" => true}, 90, [
        %{"t" => 0, "autopilot" => %{"depth" => "hold"}},
        %{
          "t" => 10,
          "thrust" => %{"mode" => "motion", "surge" => 0.5, "heave" => 0, "yaw" => 0.1}
        }
      ])

    errors =
      for row <- rows,
          at.(row, "t") >= 10,
          at.(row, "position_valid") == 1.0,
          do:
            :math.pow(at.(row, "north_est") - at.(row, "x"), 2) +
              :math.pow(at.(row, "east_est") - at.(row, "y"), 2)

    assert length(errors) > 700
    rms = :math.sqrt(Enum.sum(errors) / length(errors))
    assert rms < 0.3, "position RMS #{rms} m"
  end

  test "a four-waypoint mission in the current: every waypoint reached, close to the lines" do
    square = [{10.0, 0.0}, {10.0, 10.0}, {0.0, 10.0}, {0.0, 0.0}]
    waypoints = for {n, e} <- square, do: %{"north" => n, "east" => e, "depth" => 3.0}

    {rows, at} =
      run(
        "neptunus",
        %{"dvl" => true, "usbl" => true},
        260,
        @dp ++ [%{"t" => 30, "mission" => %{"waypoints" => waypoints}}]
      )

    legs = Enum.zip([{0.0, 0.0} | square], square)

    cross_track =
      for row <- rows, leg = at.(row, "leg"), is_number(leg) and leg >= 2 do
        {{an, ae}, {bn, be}} = Enum.at(legs, trunc(leg) - 1)
        {dn, de} = {bn - an, be - ae}
        abs((at.(row, "x") - an) * de - (at.(row, "y") - ae) * dn) / :math.sqrt(dn * dn + de * de)
      end

    assert p95(cross_track) < 0.5, "cross-track p95 #{p95(cross_track)} m"

    # done: holding at the last waypoint, and there
    last = List.last(rows)
    assert at.(last, "leg") == 4.0
    assert at.(last, "mission_done") == 1
    assert Enum.any?(rows, &(at.(&1, "mission_done") == 0))
    assert at.(last, "target_north") == 0.0 and at.(last, "target_east") == 0.0
    assert :math.sqrt(:math.pow(at.(last, "x"), 2) + :math.pow(at.(last, "y"), 2)) < 1.0
    assert_in_delta at.(last, "z"), 3.0, 0.2
  end
end
