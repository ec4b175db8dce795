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
    assert header =~ ~r/,port,vertical,starboard,lateral,north_est,.*,cross_track,leg$/
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
  end
end
