defmodule Neptunus.EstimatorQualityTest do
  # Issue 4's navigation figures on the simulator with realistic sensors (noise, wild points,
  # field mix-ups), seeded, in simulated time: depth RMS error < 2 cm, heading RMS error < 1°.
  # The runs are the headless scenario runner's, so the estimate is exactly what
  # `mix neptunus.simulate` writes in its `*_est` columns.
  use ExUnit.Case, async: true

  alias Neptunus.{Dynamics, Estimator, Scenario, Sim}
  alias Neptunus.Scenario.Run

  # dive, level off, turn both ways at full differential thrust, a cross current, and
  # external pushes in heave and yaw that the filter's model knows nothing about
  @manoeuvres %{
    "vehicle" => "neptunus",
    "duration" => 60,
    "noise" => true,
    "initial" => %{"z" => 0.5},
    "current" => [0.1, 0.1, 0],
    "events" => [
      %{"t" => 1, "thrust" => %{"mode" => "motion", "surge" => 0, "heave" => 1, "yaw" => 0}},
      %{"t" => 5, "tau" => [0, 0, 6, 0, 0, 0.4]},
      %{"t" => 8, "tau" => [0, 0, 0, 0, 0, 0]},
      %{"t" => 9, "thrust" => %{"mode" => "motion", "surge" => 0, "heave" => -0.6, "yaw" => 1}},
      %{
        "t" => 12,
        "gain" => 1.0,
        "thrust" => %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => -1}
      },
      %{"t" => 20, "tau" => [0, 0, -8, 0, 0, -0.6]},
      %{"t" => 22, "tau" => [0, 0, 0, 0, 0, 0]},
      %{
        "t" => 30,
        "thrust" => %{"mode" => "manual", "port" => 1, "vertical" => 1, "starboard" => -1}
      },
      %{"t" => 40, "thrust" => %{"mode" => "motion", "surge" => 0, "heave" => 0, "yaw" => 0}}
    ]
  }

  defp shipped(name) do
    {:ok, scenario} = Scenario.parse(File.read!(Path.join("priv/scenarios", name <> ".json")))
    scenario
  end

  defp manoeuvres(seed, extra \\ %{}) do
    {:ok, scenario} = Scenario.validate(Map.merge(@manoeuvres, Map.put(extra, "seed", seed)))
    scenario
  end

  # RMS errors of the estimate (and of the raw measurements) against the truth, over the run
  defp errors(%Scenario{} = scenario) do
    columns = Run.columns()
    at = fn name -> Enum.find_index(columns, &(&1 == name)) end

    [z, psi, z_est, psi_est, z_meas, psi_meas] =
      Enum.map(~w(z psi depth_est heading_est depth_meas heading_meas), at)

    rows = scenario |> Run.rows() |> Enum.to_list()

    rms = fn f ->
      :math.sqrt(Enum.sum(Enum.map(rows, fn row -> :math.pow(f.(row), 2) end)) / length(rows))
    end

    heading_error = fn row, col ->
      Dynamics.wrap_pi(Enum.at(row, col) - Enum.at(row, psi)) * 180 / :math.pi()
    end

    %{
      depth_cm: rms.(&((Enum.at(&1, z_est) - Enum.at(&1, z)) * 100)),
      heading_deg: rms.(&heading_error.(&1, psi_est)),
      depth_meas_cm: rms.(&((Enum.at(&1, z_meas) - Enum.at(&1, z)) * 100)),
      heading_meas_deg: rms.(&heading_error.(&1, psi_meas))
    }
  end

  describe "RMS error of the estimate, scenario runs with noise and wild points" do
    for name <- ~w(dive-and-turn wild-points station-keeping-tether) do
      test "#{name}.json: depth < 2 cm, heading < 1°, better than the sensors themselves" do
        e = errors(shipped(unquote(name)))
        assert e.depth_cm < 2.0 and e.heading_deg < 1.0
        # the depth sensor's noise is 1 cm, the compass' 0.5°: the filter does better
        assert e.depth_cm < 1.0 and e.heading_deg < 0.5
        # while the raw readings, wild points and all, are far off
        assert e.depth_meas_cm > 10 * e.depth_cm
      end
    end

    test "manoeuvres with unknown pushes and a cross current, three seeds" do
      for seed <- 1..3 do
        e = errors(manoeuvres(seed))
        assert e.depth_cm < 1.0 and e.heading_deg < 0.5, "seed #{seed}: #{inspect(e)}"
      end
    end

    test "manoeuvres with ten times the wild points and mix-ups" do
      e = errors(manoeuvres(4, %{"sensors" => %{"wild_rate" => 0.02, "mixup_rate" => 0.005}}))
      assert e.depth_cm < 2.0 and e.heading_deg < 1.0
    end
  end

  test "no depth reading off by more than 5 cm, no heading by more than 3°, is ever accepted" do
    scenario = manoeuvres(5, %{"sensors" => %{"wild_rate" => 0.02, "mixup_rate" => 0.01}})
    sim = Sim.new(Scenario.sim_options(scenario))
    est = Estimator.new(vehicle: scenario.params)
    control = %{gain: scenario.gain, thrust: {:motion, %{surge: 0.0, heave: 0.0, yaw: 0.0}}}

    {_sim, est, _events, _control, bad} =
      Enum.reduce(
        0..(Scenario.steps(scenario) - 1),
        {sim, est, scenario.events, control, []},
        &step/2
      )

    assert bad == []
    counts = Estimator.wild_points(est)
    assert counts.by_field.depth > 10 and counts.by_field.heading > 10
    assert counts.reacquired == 0
  end

  # step k of the run: the events due, the command in force, the sample, the filter
  defp step(k, {sim, est, events, control, bad}) do
    {sim, events, control} = due(sim, events, control, (k + 0.5) * sim.dt)
    est = Estimator.command(est, sim.thrusters)
    sim = Sim.step(sim)
    %{t: t, measurement: m, sim: truth} = Sim.sample(sim)
    est = Estimator.update(est, t, m)
    v = Estimator.verdicts(est)

    off? =
      (v.depth == :accepted and abs(m.depth - truth.z) > 0.05) or
        (v.heading == :accepted and
           abs(Dynamics.wrap_pi(m.heading - truth.psi)) > 3 * :math.pi() / 180)

    {sim, est, events, control, if(off?, do: [{t, m, truth} | bad], else: bad)}
  end

  # the scenario's events due by `until`, applied as the scenario runner does
  defp due(sim, [%{t: t} = event | rest], control, until) when t <= until do
    control = if event.gain, do: %{control | gain: event.gain}, else: control
    control = if event.thrust, do: %{control | thrust: event.thrust}, else: control
    sim = if event.gain || event.thrust, do: Sim.command(sim, thrusters(control)), else: sim
    sim = if event.tau, do: Sim.external_force(sim, event.tau), else: sim
    sim = if event.current, do: Sim.set_current(sim, event.current), else: sim
    due(sim, rest, control, until)
  end

  defp due(sim, events, control, _until), do: {sim, events, control}

  defp thrusters(%{gain: k, thrust: {:motion, motion}}), do: Neptunus.Allocation.motion(motion, k)

  defp thrusters(%{gain: k, thrust: {:manual, m}}),
    do: %{port: k * m.port, vertical: k * m.vertical, starboard: k * m.starboard}
end
