defmodule Neptunus.RobustTest do
  # Robust by default: the default gains, reference limits and estimator meet the acceptance
  # figures when the vehicle differs from the model navigation and control were made for —
  # mass, inertia, damping and thrust each 30 % off, in all 16 corners (2^4), for the depth
  # step and the heading step (32 seeded scenario runs on simulated time, run in parallel, a
  # few seconds in all). Navigation's estimator keeps the nominal model (Scenario's `model`);
  # only the simulated vehicle changes (`Neptunus.Dynamics.Params.scaled/2`).
  # `REPORT=1 mix test test/neptunus/robust_test.exs` prints every corner and the worst case.
  use ExUnit.Case, async: true

  alias Neptunus.{PID, Scenario}
  alias Neptunus.Dynamics.Params
  alias Neptunus.Scenario.Run

  @pi :math.pi()
  @off 0.3
  @corners for m <- [-1, 1],
               i <- [-1, 1],
               d <- [-1, 1],
               t <- [-1, 1],
               do: %{
                 mass: 1 + m * @off,
                 inertia: 1 + i * @off,
                 damping: 1 + d * @off,
                 thrust: 1 + t * @off
               }

  defp scenario!(name) do
    {:ok, s} =
      Scenario.parse(File.read!(Path.join([:code.priv_dir(:neptunus), "scenarios", name])))

    s
  end

  defp rows(scenario) do
    columns = Enum.map(Run.columns(), &String.to_atom/1)
    scenario |> Run.rows() |> Enum.map(&(columns |> Enum.zip(&1) |> Map.new()))
  end

  # the shipped acceptance scenario on the vehicle off by `factors`, seeded per corner
  defp off(scenario, factors, seed) do
    {:ok, params} = Params.scaled(scenario.vehicle, factors)
    %{scenario | params: params, model: scenario.params, seed: seed}
  end

  defp depth_step(scenario) do
    after_step = scenario |> rows() |> Enum.filter(&(&1.t >= 2.0))
    overshoot = Enum.max(Enum.map(after_step, & &1.z)) - 1.0
    out = for r <- after_step, abs(r.z - 1.0) > 0.05, do: r.t
    %{overshoot: overshoot, settle: Enum.max(out, fn -> 2.0 end) - 2.0}
  end

  defp heading_step(scenario) do
    after_step = scenario |> rows() |> Enum.filter(&(&1.t >= 5.0))
    out = for r <- after_step, abs(PID.wrap_pi(r.psi - @pi / 2)) > 2 * @pi / 180, do: r.t
    %{settle: Enum.max(out, fn -> 5.0 end) - 5.0}
  end

  test "scaling the vehicle: factors apply, bad ones are refused" do
    {:ok, nominal} = Params.load("neptunus")
    {:ok, p} = Params.scaled("neptunus", %{mass: 1.3, thrust: 0.7})
    assert_in_delta p.mass, nominal.mass * 1.3, 1.0e-12
    assert_in_delta hd(p.thrusters).forward, hd(nominal.thrusters).forward * 0.7, 1.0e-12
    assert p.d_l == nominal.d_l and p.inertia == nominal.inertia
    assert {:error, "scale factor mass must be" <> _} = Params.scaled("neptunus", %{mass: 0})
    assert {:error, "scale factor weight" <> _} = Params.scaled("neptunus", %{weight: 1.1})
  end

  test "every corner of mass, inertia, damping and thrust ±30 % meets the acceptance figures" do
    depth = scenario!("autopilot-depth-step.json")
    heading = scenario!("autopilot-heading-step.json")

    results =
      @corners
      |> Enum.with_index()
      |> Task.async_stream(
        fn {factors, i} ->
          {factors, depth_step(off(depth, factors, 1000 + i)),
           heading_step(off(heading, factors, 2000 + i))}
        end,
        timeout: 120_000,
        max_concurrency: System.schedulers_online()
      )
      |> Enum.map(fn {:ok, result} -> result end)

    {wd_f, wd, _} = Enum.max_by(results, fn {_, d, _} -> d.settle end)
    {wo_f, wo, _} = Enum.max_by(results, fn {_, d, _} -> d.overshoot end)
    {wh_f, _, wh} = Enum.max_by(results, fn {_, _, h} -> h.settle end)

    worst =
      "worst depth settle #{Float.round(wd.settle, 2)} s at #{show(wd_f)}, " <>
        "worst depth overshoot #{Float.round(wo.overshoot * 100, 1)} cm at #{show(wo_f)}, " <>
        "worst heading settle #{Float.round(wh.settle, 2)} s at #{show(wh_f)}"

    if System.get_env("REPORT") do
      for {f, d, h} <- results do
        IO.puts(
          "\n  #{show(f)}: depth #{Float.round(d.settle, 2)} s, #{Float.round(d.overshoot * 100, 1)} cm; " <>
            "heading #{Float.round(h.settle, 2)} s"
        )
      end

      IO.puts("\n  " <> worst)
    end

    assert length(results) == 16
    assert wd.settle < 10.0, worst
    assert wo.overshoot < 0.10, worst
    assert wh.settle < 8.0, worst
  end

  defp show(factors) do
    factors
    |> Enum.sort()
    |> Enum.map_join(" ", fn {k, x} -> "#{k} ×#{Float.round(x * 1.0, 2)}" end)
  end
end
