defmodule Neptunus.Dynamics.NativeTest do
  # The C loop must be the same model as the Elixir one, bit for bit: every comparison here
  # is exact (==), over random states, commands, currents, forces and parameter sets.
  use ExUnit.Case, async: true

  import Neptunus.Test.Vehicles, only: [variant: 1]

  alias Neptunus.{Dynamics, Sim}
  alias Neptunus.Dynamics.{Native, Params, State}

  @cases 60

  # every kind of parameter set the loop distinguishes: 4-DOF, each Coriolis model, with
  # and without tether, thrusters with and without lag
  defp parameter_sets do
    [
      Dynamics.params(:thesis_4dof),
      Dynamics.params(:neptunus),
      variant(&Map.put(&1, "coriolis", "full")),
      variant(&Map.put(&1, "coriolis", "none")),
      variant(&put_in(&1, ["tether", "length"], 0)),
      variant(&put_in(&1, ["tether", "length"], 80.0))
    ]
  end

  defp uniform(rand, lo, hi) do
    {x, rand} = :rand.uniform_s(rand)
    {lo + (hi - lo) * x, rand}
  end

  defp uniforms(rand, n, lo, hi) do
    Enum.map_reduce(1..n, rand, fn _, r -> uniform(r, lo, hi) end)
  end

  defp random_state(%Params{dof: dof}, rand) do
    {[x, y, z, psi, u, v, w, r], rand} = uniforms(rand, 8, -2.0, 2.0)
    {[phi, theta, p, q], rand} = uniforms(rand, 4, -0.6, 0.6)

    angles =
      if dof == 4,
        do: [phi: 0.0, theta: 0.0, p: 0.0, q: 0.0],
        else: [phi: phi, theta: theta, p: p, q: q]

    fields = [x: x, y: y, z: abs(z) * 3, psi: psi * 2, u: u, v: v / 2, w: w / 2, r: r] ++ angles
    {fields, rand}
  end

  defp random_options(params, rand) do
    {initial, rand} = random_state(params, rand)
    {[cn, ce, cd], rand} = uniforms(rand, 3, -0.3, 0.3)
    {[variation], rand} = uniforms(rand, 1, 0.0, 1.0)
    {[seed], rand} = uniforms(rand, 1, 0.0, 1.0e6)

    opts = [
      vehicle: params,
      initial: initial,
      current: {cn, ce, cd / 10},
      seed: round(seed),
      noise: variation > 0.5
    ]

    opts =
      if variation > 0.7,
        do: opts ++ [current_variation: [sigma: 0.05, time_constant: 5.0]],
        else: opts

    {opts, rand}
  end

  defp random_command(rand) do
    {[port, vertical, starboard], rand} = uniforms(rand, 3, -1.0, 1.0)
    {%{port: port, vertical: vertical, starboard: starboard}, rand}
  end

  # the same run with both loops: commands and external forces change between chunks of
  # steps of random lengths (across sensor readings and the 1 000-step chunk limit)
  defp both(opts, plan) do
    elixir = Sim.new(opts)
    native = Sim.new(opts ++ [native: true])
    assert native.native
    refute elixir.native

    Enum.reduce(plan, {elixir, native}, fn {command, tau, steps}, {e, n} ->
      e = e |> Sim.command(command) |> Sim.external_force(tau) |> Sim.step(steps)
      n = n |> Sim.command(command) |> Sim.external_force(tau) |> Sim.step(steps)
      assert_same(e, n)
      {e, n}
    end)
  end

  defp assert_same(%Sim{} = e, %Sim{} = n) do
    assert n.dyn == e.dyn, "state differs after #{e.steps} steps"
    assert n.forces == e.forces
    assert n.steps == e.steps
    assert n.measurement == e.measurement
    assert n.current == e.current
    assert Sim.fault_counts(n) == Sim.fault_counts(e)
  end

  test "the library is built and loaded (mix compile builds it)" do
    assert Native.available?(), "not loaded: #{inspect(Native.load_error())}"
  end

  test "bit-identical to the Elixir loop on random runs of every kind of parameter set" do
    rand = :rand.seed_s(:exsss, {7, 11, 13})

    Enum.reduce(parameter_sets(), rand, fn params, rand ->
      Enum.reduce(1..div(@cases, 6), rand, fn _, rand ->
        {opts, rand} = random_options(params, rand)

        {plan, rand} =
          Enum.map_reduce(1..4, rand, fn _, rand ->
            {command, rand} = random_command(rand)
            {tau, rand} = uniforms(rand, 6, -3.0, 3.0)
            {[steps], rand} = uniforms(rand, 1, 1.0, 1_500.0)
            {{command, List.to_tuple(tau), round(steps)}, rand}
          end)

        both(opts, plan)
        rand
      end)
    end)
  end

  test "identical at the surface: a buoyant vehicle rising is held at z = 0" do
    opts = [vehicle: "neptunus", initial: [z: 0.05, w: -0.4]]
    {e, _n} = both(opts, [{%{vertical: -1.0}, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}, 300}])
    assert e.dyn.z == 0.0
  end

  test "identical through angle wrapping (spinning in yaw past ±π many times)" do
    opts = [vehicle: "neptunus", initial: [z: 2.0, r: 3.0]]
    tau = {0.0, 0.0, 0.0, 0.0, 0.0, 5.0}
    {e, _} = both(opts, [{%{}, tau, 700}, {%{port: 1.0, starboard: -1.0}, tau, 700}])
    assert e.dyn.psi >= -:math.pi() and e.dyn.psi < :math.pi()
  end

  test "the pitch singularity raises the same error as in Elixir" do
    opts = [vehicle: "neptunus", initial: [z: 2.0, theta: :math.pi() / 2]]
    elixir = assert_raise ArgumentError, fn -> opts |> Sim.new() |> Sim.step() end

    native =
      assert_raise ArgumentError, fn -> (opts ++ [native: true]) |> Sim.new() |> Sim.step() end

    assert native.message == elixir.message
    assert native.message =~ "singular"
  end

  test "malformed arguments are refused (ArgumentError), never read out of bounds" do
    p = Dynamics.params(:neptunus)
    k = p.compiled.native
    s = {0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
    f = [0.0, 0.0, 0.0]
    lags = [{0.5, 0.5}, {0.5, 0.5}, {0.5, 0.5}]
    tau = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}
    c = {0.0, 0.0, 0.0}

    assert {_, [_, _, _]} = Native.run(k, s, f, f, lags, tau, c, 0.01, 10)
    # ints are numbers too
    assert {_, _} = Native.run(k, put_elem(s, 0, 1), f, f, lags, tau, {0, 0, 0}, 0.01, 1)

    bad = [
      {:kernel, [binary_part(k, 0, 100)]},
      {:kernel, [k <> <<0>>]},
      {:kernel, [:not_a_binary]},
      {:state, [Tuple.delete_at(s, 0)]},
      {:state, [put_elem(s, 3, :x)]},
      {:forces, [[0.0, 0.0]]},
      {:targets, [[0.0, 0.0, 0.0, 0.0]]},
      {:lags, [[{0.5, 0.5}, {0.5}, {0.5, 0.5}]]},
      {:tau, [{0.0, 0.0, 0.0}]},
      {:current, [{0.0, 0.0}]},
      {:current, [[c, c]]},
      {:dt, [0.0]},
      {:dt, [-0.01]},
      {:n, [0]},
      {:n, [100_001]}
    ]

    names = [:kernel, :state, :forces, :targets, :lags, :tau, :current, :dt, :n]
    good = [k, s, f, f, lags, tau, c, 0.01, 10]

    for {name, [value]} <- bad do
      args = List.replace_at(good, Enum.find_index(names, &(&1 == name)), value)

      assert_raise ArgumentError, fn -> apply(Native, :run, args) end
    end

    # a list of currents must have one per step
    assert {_, _} = Native.run(k, s, f, f, lags, tau, [c, c], 0.01, 2)
  end

  test "without native: true, or with it when unavailable, the Elixir loop runs" do
    refute Sim.new(vehicle: "neptunus").native
    assert Sim.new(vehicle: "neptunus", native: true).native == Native.available?()
    assert %State{} = Sim.new(vehicle: "neptunus", native: true) |> Sim.step(3) |> Map.get(:dyn)
  end
end
