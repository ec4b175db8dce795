defmodule Neptunus.SimTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Sim}

  doctest Neptunus.Sim

  test "starts at rest at 1 m depth, neutral" do
    sim = Sim.new()
    assert sim.dyn.z == 1.0 and sim.dyn.u == 0.0
    assert sim.thrusters == Allocation.neutral()
    assert Sim.time(sim) == 0.0
  end

  test "steps advance time and follow the command" do
    sim = Sim.new() |> Sim.command(Allocation.motion(%{surge: 1.0, heave: 0.0, yaw: 0.0}, 1.0))
    sim = Sim.step(sim, 100)
    assert_in_delta Sim.time(sim), 1.0, 1.0e-9
    assert sim.dyn.u > 0.5 and sim.dyn.x > 0.2
  end

  test "n steps at once equal n single steps" do
    sim = Sim.new() |> Sim.command(%{port: 0.3, vertical: -0.2, starboard: 0.9})
    assert Sim.step(sim, 25) == Enum.reduce(1..25, sim, fn _, s -> Sim.step(s) end)
  end

  test "the surface holds a buoyant vehicle at z = 0" do
    sim = Sim.new(initial: [z: 0.01]) |> Sim.command(%{port: 0.0, vertical: -1.0, starboard: 0.0})
    sim = Sim.step(sim, 300)
    assert sim.dyn.z == 0.0
    assert sim.dyn.w == 0.0
  end

  test "the sample reports measurements and truth in SI units" do
    sim = Sim.new(initial: [z: 2.5, psi: -:math.pi() / 2])
    %{t: t, measurement: m, sim: truth} = Sim.sample(sim)
    assert t == 0.0
    assert m.depth == 2.5
    assert_in_delta m.heading, 3 * :math.pi() / 2, 1.0e-12
    assert_in_delta m.voltage, 12.6 - 0.25 * 0.3, 1.0e-12
    assert truth.z == 2.5
  end

  test "current draw grows with thrust" do
    idle = Sim.new() |> Sim.sample()
    busy = Sim.new() |> Sim.command(%{port: 1.0, vertical: 1.0, starboard: 1.0}) |> Sim.sample()
    assert busy.measurement.current > idle.measurement.current
    assert busy.measurement.voltage < idle.measurement.voltage
  end
end

defmodule Neptunus.SimSixDofTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Dynamics, Sim}
  alias Neptunus.Sim.{Current, Sensors}

  @cmd %{port: 0.6, vertical: -0.4, starboard: 0.2}

  defp noisy(opts \\ []),
    do:
      Sim.new(
        Keyword.merge([vehicle: "neptunus", noise: true, seed: 42, initial: [z: 2.0]], opts)
      )

  test "the same options and commands give the same run, bit for bit" do
    a = noisy() |> Sim.command(@cmd) |> Sim.step(500)
    b = noisy() |> Sim.command(@cmd) |> Sim.step(500)
    assert Sim.sample(a) == Sim.sample(b)
    assert a == b
  end

  test "another seed gives other noise but the same truth" do
    a = noisy() |> Sim.command(@cmd) |> Sim.step(500)
    b = noisy(seed: 43) |> Sim.command(@cmd) |> Sim.step(500)
    assert Sim.sample(a).sim == Sim.sample(b).sim
    assert Sim.sample(a).measurement != Sim.sample(b).measurement
  end

  test "n steps at once equal n single steps, with noise and a varying current (property)" do
    base =
      noisy(current: {0.1, 0.0, 0.0}, current_variation: [sigma: 0.05, time_constant: 5])
      |> Sim.command(@cmd)

    property =
      :proper.forall(:proper_types.integer(1, 60), fn n ->
        Sim.step(base, n) == Enum.reduce(1..n, base, fn _, s -> Sim.step(s) end)
      end)

    assert :proper.quickcheck(property, [:quiet, {:numtests, 30}]) == true
  end

  test "with noise the measurement is the sensor reading, held between readings at the sensor rate" do
    sim = noisy() |> Sim.command(@cmd)
    # 20 Hz sensors at 100 Hz: a new reading every 5 steps
    assert sim.sensor_every == 5
    s1 = Sim.step(sim, 1)
    s4 = Sim.step(sim, 4)
    s5 = Sim.step(sim, 5)
    assert Sim.sample(s1).measurement == Sim.sample(sim).measurement
    assert Sim.sample(s4).measurement == Sim.sample(sim).measurement
    assert Sim.sample(s5).measurement != Sim.sample(sim).measurement
    # the truth moves every step
    assert Sim.sample(s1).sim != Sim.sample(sim).sim
  end

  test "noise is small: the readings scatter around the truth" do
    sim = noisy(sensors: %{wild_rate: 0.0, mixup_rate: 0.0})

    errors =
      1..400
      |> Enum.scan(sim, fn _, s -> Sim.step(s, 5) end)
      |> Enum.map(fn s -> Sim.sample(s).measurement.depth - s.dyn.z end)

    mean = Enum.sum(errors) / length(errors)
    sd = :math.sqrt(Enum.sum(Enum.map(errors, &((&1 - mean) ** 2))) / length(errors))
    assert abs(mean) < 0.003
    assert_in_delta sd, 0.01, 0.002
  end

  test "ideal sensors report the truth at every step" do
    sim =
      Sim.new(vehicle: "neptunus", initial: [z: 2.0, psi: -1.0])
      |> Sim.command(@cmd)
      |> Sim.step(7)

    %{measurement: m, sim: truth} = Sim.sample(sim)
    assert m.depth == truth.z
    assert m.roll == truth.phi and m.pitch == truth.theta
    assert m.heading == Dynamics.wrap_2pi(truth.psi)
    assert Sim.fault_counts(sim) == %{wild: 0, mixup: 0}
  end

  test "sensor overrides: channels and rates" do
    sim =
      noisy(
        sensors: %{rate: 100.0, depth: %{bias: 0.5, noise: 0.0}, wild_rate: 0.0, mixup_rate: 0.0}
      )

    assert sim.sensor_every == 1
    assert_in_delta Sim.sample(sim).measurement.depth, 2.5, 1.0e-12

    assert_raise ArgumentError, ~r/unknown sensor setting/, fn ->
      noisy(sensors: %{sonar: %{}})
    end
  end

  test "reset/1 starts again from the options, keeping the current set since" do
    sim = noisy() |> Sim.command(@cmd) |> Sim.step(300) |> Sim.set_current([0.1, 0.2, 0.0])
    again = Sim.reset(sim)
    assert again.steps == 0 and again.dyn.z == 2.0
    assert Sim.current(again) == {0.1, 0.2, 0.0}
    assert again.thrusters == %{port: 0.0, vertical: 0.0, starboard: 0.0}
    assert Sim.sample(again) == Sim.sample(noisy(current: {0.1, 0.2, 0.0}))
  end

  test "external force (scenario tau) acts like thrust, without thruster dynamics" do
    pushed = Sim.new() |> Sim.external_force({12, 0, 0, 0, 0, 0}) |> Sim.step(6000)
    # thesis-4dof: 4.008u² + 2.2907u = 12
    assert_in_delta pushed.dyn.u,
                    (-2.2907 + :math.sqrt(2.2907 ** 2 + 4 * 4.008 * 12)) / (2 * 4.008),
                    1.0e-9
  end

  test "set_tether_length/2 and the tether_length option" do
    assert Sim.new(vehicle: "neptunus", tether_length: 0).params.compiled.tether_k == 0.0
    sim = Sim.new(vehicle: "neptunus") |> Sim.set_tether_length(25)
    assert sim.params.tether.length == 25.0
    assert Sim.status(sim).tether_length == 25.0
    assert Sim.reset(sim).params.tether.length == 25.0
  end

  test "a 4-DOF set refuses roll and pitch in the initial state; bad options raise" do
    assert_raise ArgumentError, ~r/initial phi must be 0/, fn -> Sim.new(initial: [phi: 0.1]) end
    assert_raise ArgumentError, ~r/unknown vehicle/, fn -> Sim.new(vehicle: "submarine") end
    assert_raise ArgumentError, ~r/dt must be > 0/, fn -> Sim.new(dt: 0) end
    assert_raise KeyError, fn -> Sim.new(initial: [depth: 1]) end
    assert %Sim{} = Sim.new(vehicle: "neptunus", initial: [phi: 0.1])
  end

  test "status/1 summarises the settings" do
    assert %{
             vehicle: "neptunus",
             t: 0.0,
             dt: 0.01,
             current: [0.0, 0.0, 0.0],
             noise: true,
             seed: 42
           } = Sim.status(noisy())
  end

  describe "current" do
    test "constant without variation" do
      c = Current.new({0.1, 0.2, 0.0}, 0.01)
      assert Current.ned(Current.step(c)) == {0.1, 0.2, 0.0}
    end

    test "the variation is seeded, slow and has the configured spread" do
      c = Current.new([0.1, 0.0, 0.0], 0.1, sigma: 0.05, time_constant: 2.0, seed: 9)
      run = Enum.scan(1..20_000, c, fn _, c -> Current.step(c) end)
      assert run == Enum.scan(1..20_000, c, fn _, c -> Current.step(c) end)

      norths = Enum.map(run, &elem(Current.ned(&1), 0))
      mean = Enum.sum(norths) / length(norths)
      sd = :math.sqrt(Enum.sum(Enum.map(norths, &((&1 - mean) ** 2))) / length(norths))
      assert_in_delta mean, 0.1, 0.01
      assert_in_delta sd, 0.05, 0.01
      # vertical stays at its mean
      assert Enum.all?(run, &(elem(Current.ned(&1), 2) == 0.0))
      # slow: consecutive values correlate as e^(−dt/T)
      pairs = norths |> Enum.map(&(&1 - mean)) |> Enum.chunk_every(2, 1, :discard)
      lag1 = Enum.sum(Enum.map(pairs, fn [a, b] -> a * b end)) / (length(pairs) * sd * sd)
      assert_in_delta lag1, :math.exp(-0.1 / 2.0), 0.02
    end
  end

  describe "sensors (thesis §8.3 faults)" do
    @truth %{depth: 2.0, heading: 1.0, roll: 0.1, pitch: -0.2, voltage: 12.0, current: 1.5}

    defp config(wild, mixup, noise \\ 0.0) do
      channel = %{noise: noise, bias: 0.0}

      %{
        rate: 20.0,
        wild_rate: wild,
        mixup_rate: mixup,
        channels: Map.new(Sensors.channels(), &{&1, channel})
      }
    end

    defp readings(config, n, seed \\ 1) do
      {list, sensors} =
        Enum.map_reduce(1..n, Sensors.new(config, seed), fn _, s -> Sensors.measure(s, @truth) end)

      {list, sensors}
    end

    test "wild points appear at the configured rate with a fixed seed, as ×0.1, ×10 or ×100" do
      n = 20_000
      {list, sensors} = readings(config(0.05, 0.0), n)

      wild =
        for m <- list, ch <- Sensors.channels(), m[ch] != @truth[ch] do
          ratio = m[ch] / @truth[ch]
          assert Enum.any?([0.1, 10.0, 100.0], &(abs(ratio - &1) < 1.0e-9)), "#{ch}: #{ratio}"
          ratio
        end

      expected = 0.05 * n * 6
      sigma = :math.sqrt(expected * 0.95)
      assert abs(length(wild) - expected) < 4 * sigma
      assert sensors.counts == %{wild: length(wild), mixup: 0}

      # each factor about a third of the time
      for factor <- [0.1, 10.0, 100.0] do
        share = Enum.count(wild, &(abs(&1 - factor) < 1.0e-9)) / length(wild)
        assert_in_delta share, 1 / 3, 0.03
      end

      # the same seed, the same faults
      assert elem(readings(config(0.05, 0.0), n), 0) == list
    end

    test "field mix-ups carry another channel's value" do
      {list, sensors} = readings(config(0.0, 0.02), 10_000)
      values = Map.values(@truth)

      mixups =
        for m <- list, ch <- Sensors.channels(), m[ch] != @truth[ch] do
          assert m[ch] in (values -- [@truth[ch]])
        end

      assert length(mixups) == sensors.counts.mixup
      assert_in_delta length(mixups), 0.02 * 60_000, 4 * :math.sqrt(0.02 * 60_000)
    end

    test "no faults at zero rates; noise has the configured spread; heading wraps" do
      {list, sensors} = readings(config(0.0, 0.0, 0.01), 5_000)
      assert sensors.counts == %{wild: 0, mixup: 0}
      depths = Enum.map(list, & &1.depth)
      mean = Enum.sum(depths) / length(depths)
      sd = :math.sqrt(Enum.sum(Enum.map(depths, &((&1 - mean) ** 2))) / length(depths))
      assert_in_delta mean, 2.0, 0.001
      assert_in_delta sd, 0.01, 0.0005

      {[m], _} =
        Sensors.new(config(0.0, 0.0), 1)
        |> then(fn s ->
          {[elem(Sensors.measure(s, %{@truth | heading: 2 * :math.pi() - 1.0e-12}), 0)], s}
        end)

      assert m.heading >= 0.0 and m.heading < 2 * :math.pi()
    end
  end
end
