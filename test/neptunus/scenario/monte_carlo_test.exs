defmodule Neptunus.Scenario.MonteCarloTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Scenario
  alias Neptunus.Scenario.{MonteCarlo, Run}

  doctest MonteCarlo

  defp config!(opts) do
    {:ok, config} = MonteCarlo.config(opts)
    config
  end

  defp scenario!(map) do
    {:ok, s} = Scenario.validate(Map.merge(%{"vehicle" => "neptunus", "duration" => 10}, map))
    s
  end

  describe "config" do
    test "defaults, and every option read" do
      assert config!([]) == MonteCarlo.defaults()

      c =
        config!(
          runs: 4,
          seed: -3,
          every: 5,
          settle: "12.5",
          current_speed: "0.05:0.1",
          current_direction: "-90:90",
          dvl_noise: "0",
          usbl_noise: "1:3",
          out: "ignored.csv"
        )

      assert c == %{
               runs: 4,
               seed: -3,
               every: 5,
               settle: 12.5,
               current_speed: {0.05, 0.1},
               current_direction: {-90.0, 90.0},
               dvl_noise: {0.0, 0.0},
               usbl_noise: {1.0, 3.0}
             }
    end

    test "bad values are refused, naming the option" do
      for {opts, message} <- [
            {[runs: 0], "--runs must be an integer in 1..10000, got 0"},
            {[runs: -2], "--runs must be an integer in 1..10000, got -2"},
            {[runs: 10_001], "--runs must be an integer in 1..10000, got 10001"},
            {[every: 0], "--every must be a positive integer, got 0"},
            {[settle: "-1"], ~s(--settle must be a number of seconds ≥ 0, got "-1")},
            {[settle: "soon"], ~s(--settle must be a number of seconds ≥ 0, got "soon")},
            {[current_speed: "0.2:0.1"],
             ~s(--current-speed must be LO:HI with LO ≤ HI, got "0.2:0.1")},
            {[current_speed: "-0.1:0.1"],
             ~s[--current-speed must be within 0.0:2.0 (m/s), got "-0.1:0.1"]},
            {[current_direction: "0:400"],
             ~s[--current-direction must be within -360.0:360.0 (degrees), got "0:400"]},
            {[dvl_noise: "x"],
             ~s[--dvl-noise must be a number or LO:HI (a scale of the noise), got "x"]},
            {[usbl_noise: "1:2:3"],
             ~s[--usbl-noise must be a number or LO:HI (a scale of the noise), got "1:2:3"]},
            {[usbl_noise: ""],
             ~s[--usbl-noise must be a number or LO:HI (a scale of the noise), got ""]},
            {[dvl_noise: "1:"],
             ~s[--dvl-noise must be a number or LO:HI (a scale of the noise), got "1:"]}
          ] do
        assert MonteCarlo.config(opts) == {:error, message}
      end
    end
  end

  describe "draws" do
    test "run k has seed S + k − 1; each draw is within its ranges and a function of its seed" do
      c = config!(runs: 50, seed: 10)
      seeds = MonteCarlo.seeds(c)
      assert seeds == Enum.to_list(10..59)
      draws = Enum.map(seeds, &MonteCarlo.draw(c, &1))
      assert draws == Enum.map(seeds, &MonteCarlo.draw(c, &1))
      assert length(Enum.uniq(draws)) == 50

      for d <- draws do
        assert d.current_speed >= 0.0 and d.current_speed <= 0.2
        assert d.current_direction >= 0.0 and d.current_direction <= 2 * :math.pi()
        assert d.dvl_noise >= 0.5 and d.dvl_noise <= 2.0
        assert d.usbl_noise >= 0.5 and d.usbl_noise <= 2.0
      end

      # the same seed alone (one run) draws the same
      assert MonteCarlo.draw(config!(runs: 1, seed: 33), 33) == Enum.at(draws, 23)
    end

    test "a fixed range gives its value; one range does not change another's draw" do
      a = MonteCarlo.draw(config!([]), 7)
      b = MonteCarlo.draw(config!(current_speed: "0.15", dvl_noise: "0:0"), 7)
      assert b.current_speed == 0.15
      assert b.dvl_noise == 0.0
      assert {b.current_direction, b.usbl_noise} == {a.current_direction, a.usbl_noise}
    end

    test "property: the reproduce options read back to the same draw" do
      range = fn lo, hi ->
        bind(
          {:proper_types.float(lo, hi), :proper_types.float(lo, hi)},
          fn {a, b} -> {min(a, b), max(a, b)} end
        )
      end

      check(
        {:proper_types.integer(), range.(0.0, 2.0), range.(-360.0, 360.0), range.(0.0, 100.0),
         range.(0.0, 100.0)},
        fn {seed, speed, direction, dvl, usbl} ->
          c = %{
            MonteCarlo.defaults()
            | seed: seed,
              current_speed: speed,
              current_direction: direction,
              dvl_noise: dvl,
              usbl_noise: usbl
          }

          draw = MonteCarlo.draw(c, seed)
          {opts, [], []} = OptionParser.parse(MonteCarlo.reproduce(c, draw), strict: switches())
          {:ok, again} = MonteCarlo.config(opts)
          again.runs == 1 and MonteCarlo.draw(again, again.seed) == draw
        end,
        300
      )
    end

    test "a draw makes the scenario's seed, current and position sources' noise" do
      s =
        scenario!(%{
          "current" => [0.3, 0.0, 0.05],
          "position" => %{"dvl" => %{"noise" => 0.01}, "usbl" => true}
        })

      draw = %{
        seed: 99,
        current_speed: 0.2,
        current_direction: :math.pi() / 2,
        dvl_noise: 2.0,
        usbl_noise: 0.0
      }

      d = MonteCarlo.apply_draw(s, draw)
      assert d.seed == 99
      {n, e, down} = d.current
      assert_in_delta n, 0.0, 1.0e-12
      assert_in_delta e, 0.2, 1.0e-12
      assert down == 0.05
      dvl = Neptunus.Sim.DVL.defaults()
      assert d.position.dvl == %{noise: 0.02, noise_per_m: 2 * dvl.noise_per_m}
      assert d.position.usbl == %{noise: 0.0, noise_per_m: 0.0}
      # everything else as it was
      assert %{d | seed: s.seed, current: s.current, position: s.position} == s

      # the truth as the position, no sources: nothing to scale
      t = MonteCarlo.apply_draw(scenario!(%{}), draw)
      assert t.position == :truth
    end
  end

  defp switches do
    [
      runs: :integer,
      seed: :integer,
      every: :integer,
      current_speed: :string,
      current_direction: :string,
      dvl_noise: :string,
      usbl_noise: :string,
      settle: :string
    ]
  end

  describe "figures of a run" do
    # rows by column name; the others nil
    defp rows(list) do
      columns = Run.columns()
      for r <- list, do: Enum.map(columns, &Map.get(r, String.to_atom(&1)))
    end

    defp base(t),
      do: %{t: t, x: 0.0, y: 0.0, position_valid: 0, north_est: nil, east_est: nil}

    test "estimate RMS while valid, hold p95 from settle on, no mission" do
      s = scenario!(%{})

      list = [
        # invalid: not counted
        %{base(0.0) | x: 5.0},
        # valid, errors 3 and 4 → RMS √((9 + 16)/2)
        %{base(1.0) | position_valid: 1, north_est: 3.0, east_est: 0.0},
        Map.merge(%{base(2.0) | position_valid: 1, north_est: 0.0, east_est: 4.0}, %{
          target_north: 10.0,
          target_east: 0.0
        }),
        # holding, radii 1 and 2 (t ≥ settle)
        Map.merge(base(3.0), %{x: 1.0, target_north: 0.0, target_east: 0.0}),
        Map.merge(base(4.0), %{y: 2.0, target_north: 0.0, target_east: 0.0})
      ]

      f = MonteCarlo.figures(rows(list), Run.columns(), s, 3.0)
      assert_in_delta f.estimate_rms, :math.sqrt(12.5), 1.0e-12
      assert f.valid == 0.4
      assert f.hold_p95 == 2.0
      assert f.cross_track_p95 == nil
      assert f.mission == nil
      assert f.error == nil

      # settle 0: the 10 m radius of t = 2 counts too
      assert MonteCarlo.figures(rows(list), Run.columns(), s, 0.0).hold_p95 == 10.0
    end

    test "a mission: cross-track from the second leg, paused rows left out, done after" do
      wps = [
        %{"north" => 10, "east" => 0, "depth" => 2},
        %{"north" => 10, "east" => 10, "depth" => 2}
      ]

      s =
        scenario!(%{
          "duration" => 100,
          "events" => [
            %{"t" => 0, "control_mode" => "dp"},
            %{"t" => 20, "mission" => %{"waypoints" => wps}}
          ]
        })

      m = fn t, x, y, leg, done ->
        Map.merge(base(t), %{x: x, y: y, leg: leg, mission_done: done})
      end

      list = [
        # leg 1: from wherever the vehicle was, not counted
        m.(21.0, 5.0, 3.0, 1, 0),
        # leg 2 runs north 10 → east: cross-track is |x − 10|
        m.(40.0, 10.3, 2.0, 2, 0),
        m.(41.0, 9.9, 5.0, 2, 0),
        # paused (a hold target set, not done): neither
        Map.merge(m.(42.0, 7.0, 5.0, 2, 0), %{target_north: 7.0, target_east: 5.0}),
        # done at 60 s: holding at the last waypoint
        Map.merge(m.(60.0, 10.0, 9.5, 2, 1), %{target_north: 10.0, target_east: 10.0})
      ]

      f = MonteCarlo.figures(rows(list), Run.columns(), s)
      assert_in_delta f.cross_track_p95, 0.3, 1.0e-9
      assert f.mission == {:done, 40.0}
      assert f.hold_p95 == 0.5

      # never done
      f = MonteCarlo.figures(rows(Enum.take(list, 3)), Run.columns(), s)
      assert f.mission == :not_done
      assert f.hold_p95 == nil
    end
  end

  describe "statistics" do
    test "rms, percentile and stats" do
      assert MonteCarlo.rms([]) == nil
      assert MonteCarlo.rms([2.0]) == 2.0
      assert MonteCarlo.percentile([], 95) == nil
      assert MonteCarlo.percentile([5], 95) == 5
      assert MonteCarlo.percentile(Enum.to_list(1..100), 95) == 96
      assert MonteCarlo.percentile(Enum.to_list(1..100), 50) == 51
      assert MonteCarlo.stats([]) == nil
      assert MonteCarlo.stats([1, 3, 2]) == %{n: 3, mean: 2.0, p50: 2.0, p95: 3.0, max: 3.0}
    end

    defp run(seed, figures) do
      {%{seed: seed},
       Map.merge(
         %{
           estimate_rms: nil,
           valid: nil,
           hold_p95: nil,
           cross_track_p95: nil,
           mission: nil,
           error: nil
         },
         figures
       )}
    end

    test "summary over the runs, and the worst run" do
      runs = [
        run(1, %{estimate_rms: 0.1, valid: 1.0, hold_p95: 0.5}),
        run(2, %{estimate_rms: 0.3, valid: 0.5, hold_p95: 0.2}),
        run(3, %{estimate_rms: 0.2, valid: 1.0})
      ]

      s = MonteCarlo.summary(runs)
      assert s.estimate_rms.n == 3
      assert_in_delta s.estimate_rms.mean, 0.2, 1.0e-12
      assert s.estimate_rms.max == 0.3
      assert s.hold_p95 == %{n: 2, mean: 0.35, p50: 0.5, p95: 0.5, max: 0.5}
      assert s.cross_track_p95 == nil
      assert s.missions == nil
      # the largest hold p95 is the worst
      assert {%{seed: 1}, _} = s.worst

      # a mission not finished is worse than any figure; a failed run worse still
      missions = [
        run(1, %{cross_track_p95: 0.9, mission: {:done, 100.0}}),
        run(2, %{cross_track_p95: 0.1, mission: :not_done}),
        run(3, %{cross_track_p95: 0.2, mission: {:done, 90.0}})
      ]

      assert MonteCarlo.summary(missions).missions == {2, 3}
      assert {%{seed: 2}, _} = MonteCarlo.worst(missions)
      failed = {%{seed: 4}, MonteCarlo.failed("refused")}
      assert {%{seed: 4}, _} = MonteCarlo.worst(missions ++ [failed])
      # equals: the first
      assert {%{seed: 1}, _} = MonteCarlo.worst([run(1, %{}), run(2, %{})])
      assert MonteCarlo.worst([]) == nil
    end
  end
end
