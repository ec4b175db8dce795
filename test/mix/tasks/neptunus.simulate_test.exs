defmodule Mix.Tasks.Neptunus.SimulateTest do
  use ExUnit.Case, async: false

  import ExUnit.CaptureIO

  alias Mix.Tasks.Neptunus.Simulate

  @moduletag :tmp_dir

  @scenario ~s({"vehicle": "thesis-4dof", "duration": 0.5, "gain": 1,
                "events": [{"t": 0, "thrust": {"mode": "motion", "surge": 1, "heave": 0, "yaw": 0}}]})

  defp write!(dir, name, text) do
    path = Path.join(dir, name)
    File.write!(path, text)
    path
  end

  test "writes the CSV to --out and reports it", %{tmp_dir: dir} do
    scenario = write!(dir, "s.json", @scenario)
    out = Path.join(dir, "run.csv")
    info = capture_io(fn -> Simulate.run([scenario, "--out", out]) end)

    assert info =~ "run.csv: 51 rows, thesis-4dof"
    [header | rows] = out |> File.read!() |> String.split("\n", trim: true)
    assert header =~ ~r/^t,x,y,z,phi,theta,psi,u,v,w,p,q,r,depth_meas,heading_meas,/

    assert header =~
             ~r/,port,vertical,starboard,lateral,north_est,.*,cross_track,leg,mission_done$/

    assert length(rows) == 51
    assert "0.5," <> _ = List.last(rows)
    # nothing else left in the directory (the temporary file was renamed)
    assert Enum.sort(File.ls!(dir)) == ["run.csv", "s.json"]
  end

  test "without --out the CSV goes to stdout; --every thins it", %{tmp_dir: dir} do
    scenario = write!(dir, "s.json", @scenario)
    csv = capture_io(fn -> Simulate.run([scenario, "--every", "10"]) end)
    lines = String.split(csv, "\n", trim: true)
    assert length(lines) == 1 + 6
    assert Enum.map(tl(lines), &(&1 |> String.split(",") |> hd())) == ~w(0.0 0.1 0.2 0.3 0.4 0.5)
  end

  test "a bad scenario stops with the field named and leaves no file", %{tmp_dir: dir} do
    bad = write!(dir, "bad.json", ~s({"vehicle": "thesis-4dof", "duration": -3}))
    out = Path.join(dir, "run.csv")

    error = assert_raise Mix.Error, fn -> Simulate.run([bad, "--out", out]) end
    assert error.message == "#{bad}: duration must be a number > 0, got -3"

    unknown = write!(dir, "unknown.json", ~s({"vehicle": "submarine", "duration": 3}))
    error = assert_raise Mix.Error, fn -> Simulate.run([unknown, "--out", out]) end

    assert error.message =~
             ~s|vehicle: unknown vehicle "submarine" (available: neptunus, neptunus-sway, thesis-4dof)|

    error = assert_raise Mix.Error, fn -> Simulate.run([Path.join(dir, "missing.json")]) end
    assert error.message =~ "cannot read: no such file or directory"

    assert_raise Mix.Error, ~r/usage: mix neptunus.simulate/, fn -> Simulate.run([]) end

    assert_raise Mix.Error, ~r/unknown or invalid option --speed/, fn ->
      Simulate.run([bad, "--speed", "2"])
    end

    assert_raise Mix.Error, ~r/--every must be a positive integer/, fn ->
      Simulate.run([bad, "--every", "0"])
    end

    refute File.exists?(out)
    assert Enum.sort(File.ls!(dir)) == ["bad.json", "unknown.json"]
  end

  test "as a command: exit status 0, or non-zero with the message on stderr", %{tmp_dir: dir} do
    good = write!(dir, "good.json", @scenario)

    bad =
      write!(dir, "bad.json", ~s({"vehicle": "neptunus", "duration": 1, "events": [{"t": 0}]}))

    out = Path.join(dir, "run.csv")
    # the port is taken by the test server: the task must not start the endpoint
    env = [{"MIX_ENV", "test"}, {"NEPTUNUS_PORT", to_string(NeptunusWeb.Test.Wire.port())}]

    {output, status} =
      System.cmd("mix", ["neptunus.simulate", good, "--out", out],
        env: env,
        stderr_to_stdout: true
      )

    assert status == 0, output
    assert File.exists?(out)

    {output, status} =
      System.cmd("mix", ["neptunus.simulate", bad], env: env, stderr_to_stdout: true)

    assert status != 0

    assert output =~
             "events[0] must have at least one of: autopilot, control_mode, current, gain, mission, mission_control, tau, thrust"

    {output, status} =
      System.cmd("mix", ["neptunus.simulate", good, "--runs", "-1"],
        env: env,
        stderr_to_stdout: true
      )

    assert status != 0
    assert output =~ "--runs must be an integer in 1..10000, got -1"
  end

  describe "Monte Carlo (--runs)" do
    # position hold on the simulated DVL and USBL, short
    @hold ~s({"vehicle": "neptunus", "duration": 20, "noise": true, "initial": {"z": 2.0},
              "position": {"dvl": true, "usbl": true},
              "events": [{"t": 0, "autopilot": {"depth": "hold", "heading": "hold"}},
                         {"t": 2, "control_mode": "dp"}]})

    defp monte_carlo(args) do
      text = capture_io(fn -> Simulate.run(args) end)
      lines = String.split(text, "\n", trim: true)
      runs = for "| " <> _ = line <- lines, line =~ ~r/^\| \d+ \|/, do: cells(line)
      {text, lines, runs}
    end

    defp cells(line), do: line |> String.split("|", trim: true) |> Enum.map(&String.trim/1)

    defp number(cell) do
      {x, ""} = Float.parse(cell)
      x
    end

    test "prints each run's draw and figures, the statistics and how to run the worst again",
         %{tmp_dir: dir} do
      file = write!(dir, "hold.json", @hold)
      args = [file, "--runs", "3", "--seed", "4", "--settle", "8"]
      {text, lines, runs} = monte_carlo(args)

      assert text =~ "Monte Carlo of #{file}: neptunus, 20.0 s, 3 runs (seeds 4..6)"
      assert text =~ "position: DVL + USBL"
      assert Enum.map(runs, &Enum.take(&1, 2)) == [~w(1 4), ~w(2 5), ~w(3 6)]

      # each run: a draw within the default ranges, an estimate RMS, a hold radius, no mission
      for [_k, _seed, speed, towards, dvl, usbl, rms, valid, hold, cross, mission] <- runs do
        assert number(speed) >= 0 and number(speed) <= 0.2
        assert number(towards) >= 0 and number(towards) <= 360
        assert number(dvl) >= 0.5 and number(dvl) <= 2 and number(usbl) >= 0.5
        assert number(rms) > 0 and number(rms) < 1
        assert number(valid) > 50
        assert number(hold) >= 0
        assert {cross, mission} == {"—", "—"}
      end

      # the summary agrees with the runs
      ["estimate RMS (m)", "3", _mean, _p50, _p95, max] =
        lines |> Enum.find(&String.starts_with?(&1, "| estimate RMS")) |> cells()

      assert max == runs |> Enum.map(&Enum.at(&1, 6)) |> Enum.max_by(&number/1)

      # the same seed: the same figures
      {_, _, again} = monte_carlo(args)
      assert again == runs

      # the worst run, again alone, from the options printed
      "reproduce: mix neptunus.simulate " <> options =
        Enum.find(lines, &String.starts_with?(&1, "reproduce:"))

      [_file | repro] = String.split(options, " ")
      {_, _, [alone]} = monte_carlo([file | repro])
      [_ | worst] = Enum.find(runs, &(Enum.at(&1, 1) == Enum.at(alone, 1)))
      assert tl(alone) == worst
      # the worst has the largest hold p95
      assert Enum.at(alone, 8) == runs |> Enum.map(&Enum.at(&1, 8)) |> Enum.max_by(&number/1)
    end

    test "no noise and no current estimate closer than large noise", %{tmp_dir: dir} do
      file = write!(dir, "hold.json", @hold)
      quiet = ~w(--current-speed 0 --dvl-noise 0 --usbl-noise 0)
      loud = ~w(--current-speed 0 --dvl-noise 30 --usbl-noise 10)
      {_, _, calm} = monte_carlo([file, "--runs", "2" | quiet])
      {_, _, noisy} = monte_carlo([file, "--runs", "2" | loud])

      assert length(calm) == 2

      for {a, b} <- Enum.zip(calm, noisy) do
        # the same seeds, no current; no noise against large noise
        assert Enum.at(a, 1) == Enum.at(b, 1)
        assert {Enum.at(a, 2), Enum.at(b, 2)} == {"0.000", "0.000"}
        assert {Enum.at(a, 4), Enum.at(a, 5)} == {"0.00", "0.00"}
        assert {Enum.at(b, 4), Enum.at(b, 5)} == {"30.00", "10.00"}
        assert number(Enum.at(a, 6)) < number(Enum.at(b, 6)), "#{inspect(a)} vs #{inspect(b)}"
      end
    end

    test "a mission: cross-track, finished or not", %{tmp_dir: dir} do
      mission = write!(dir, "mission.json", ~s({"vehicle": "neptunus-sway", "duration": 60,
          "initial": {"z": 2.0}, "position": {"dvl": true, "usbl": true},
          "events": [{"t": 0, "autopilot": {"depth": "hold", "heading": "hold"}},
                     {"t": 2, "control_mode": "dp"},
                     {"t": 5, "mission": {"waypoints": [
                        {"north": 3, "east": 0, "depth": 2, "speed": 0.5},
                        {"north": 3, "east": 3, "depth": 2, "speed": 0.5}]}}]}))

      {text, _lines, [[_, _, _, _, _, _, _, _, _, cross, done]]} =
        monte_carlo([mission, "--runs", "1", "--current-speed", "0"])

      assert number(cross) < 0.5
      assert done =~ ~r/^done in \d+\.\d s$/
      assert text =~ "missions finished: 1/1"

      # too short to finish it
      short =
        write!(
          dir,
          "short.json",
          String.replace(File.read!(mission), ~s("duration": 60), ~s("duration": 12))
        )

      {text, _lines, [run]} = monte_carlo([short, "--runs", "1", "--current-speed", "0"])
      assert List.last(run) == "not done"
      assert text =~ "missions finished: 0/1"
      assert text =~ "worst run: seed 1 (current 0.000 m/s"
      assert text =~ "mission not done"

      # a mission the control refuses (no position: the DVL's bottom out of its range): that
      # run failed, with the reason, and is the worst
      refused =
        write!(
          dir,
          "refused.json",
          String.replace(File.read!(short), ~s("dvl": true), ~s("dvl": {"seabed": 100}))
          |> String.replace(~s("usbl": true), ~s("usbl": false))
        )

      {text, _lines, [run]} = monte_carlo([refused, "--runs", "1"])

      assert List.last(run) =~
               "failed: scenario event at t = 5.0 s: a mission needs a valid position"

      assert text =~ "runs failed: 1/1"
      assert text =~ ~r/worst run: seed 1 .*: failed: scenario event/
    end

    test "bad options stop with a clear error, before any run", %{tmp_dir: dir} do
      file = write!(dir, "hold.json", @hold)

      for {args, message} <- [
            {~w(--runs 0), "--runs must be an integer in 1..10000, got 0"},
            {~w(--runs -4), "--runs must be an integer in 1..10000, got -4"},
            {~w(--runs 2 --dvl-noise 2:1), ~s(--dvl-noise must be LO:HI with LO ≤ HI, got "2:1")},
            {~w(--runs 2 --current-speed fast),
             ~s[--current-speed must be a number or LO:HI (m/s), got "fast"]},
            {~w(--runs 2 --out x.csv), "--out writes one run's CSV: it does not go with --runs"},
            {~w(--seed 3), "--seed is an option of a Monte Carlo: add --runs N"},
            {~w(--usbl-noise 2), "--usbl-noise is an option of a Monte Carlo: add --runs N"}
          ] do
        error = assert_raise Mix.Error, fn -> Simulate.run([file | args]) end
        assert error.message == message
      end

      assert_raise Mix.Error, ~r/unknown or invalid option --noise/, fn ->
        Simulate.run([file, "--runs", "2", "--noise", "2"])
      end

      assert_raise Mix.Error, ~r/unknown or invalid option --runs/, fn ->
        Simulate.run([file, "--runs", "many"])
      end

      assert Enum.sort(File.ls!(dir)) == ["hold.json"]
    end
  end
end
