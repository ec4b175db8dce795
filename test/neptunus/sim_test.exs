defmodule Neptunus.SimTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Sim}

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
