defmodule Neptunus.Navigation.ModelTest do
  use ExUnit.Case, async: true

  alias Neptunus.{Dynamics, Sim}
  alias Neptunus.Dynamics.Params
  alias Neptunus.Navigation.Model

  test "axes from the neptunus parameter set: effective mass, damping, net weight" do
    params = Params.fetch!("neptunus")
    model = Model.from_params(params)

    inv = params.mass_inv
    assert_in_delta model.heave.mass, 1 / (inv |> Enum.at(2) |> Enum.at(2)), 1.0e-12
    # rigid body + added mass in heave, uncoupled
    assert_in_delta model.heave.mass, 3.46 + 2.3295, 1.0e-6
    assert model.heave.d_l == 15.1897 and model.heave.d_q == 10.304
    assert model.heave.f0 == -0.0234

    # yaw is coupled to sway through the added mass (a yaw moment also pushes the vehicle
    # sideways): less than Izz + N_r' alone, by about Y_r'² / (m + Y_v')
    assert_in_delta model.yaw.mass, 0.399 + 0.1498 - 0.8926 ** 2 / (3.46 + 14.6033), 2.0e-3
    assert_in_delta model.yaw.mass, 1 / (inv |> Enum.at(5) |> Enum.at(5)), 1.0e-12
    assert model.yaw.d_l == 0.2605 and model.yaw.f0 == 0.0

    assert Model.from_params("neptunus") == model
  end

  test "commands are clamped; missing or non-numeric ones are neutral" do
    model = Model.from_params("neptunus")
    m = Model.command(model, %{port: 3, vertical: "x", extra: 1.0})
    assert m.commands == %{port: 1.0, vertical: 0.0, starboard: 0.0}
    assert Model.command(model, :garbage).commands == %{port: 0.0, vertical: 0.0, starboard: 0.0}
  end

  test "the thrust follows the simulator's thrusters: deadband, asymmetry, lag" do
    params = Params.fetch!("neptunus")
    thrusters = %{port: 0.8, vertical: -0.6, starboard: -0.3}
    sim = Sim.new(vehicle: params, dt: 0.01) |> Sim.command(thrusters)
    model = Model.from_params(params) |> Model.command(thrusters)

    Enum.reduce(1..60, {sim, model}, fn _, {sim, model} ->
      sim = Sim.step(sim)
      {model, _mean} = Model.advance(model, 0.01)
      {_, _, z, _, _, n} = Dynamics.tau_from_forces(sim.forces, params)
      {heave, yaw} = Model.force(model)
      assert_in_delta heave, z, 1.0e-9
      assert_in_delta yaw, n, 1.0e-9
      {sim, model}
    end)
  end

  test "the mean force over a step lies between its start and end (first-order lag)" do
    model = Model.from_params("neptunus") |> Model.command(%{vertical: 1.0})
    {model, {mean, _}} = Model.advance(model, 0.2)
    {end_force, _} = Model.force(model)
    assert mean > 0.0 and mean < end_force
    # 12 N after the deadband, e^-1 short after one time constant
    assert_in_delta end_force, 12.0 * (1 - :math.exp(-1.0)), 1.0e-9
  end

  test "differential thrust turns to starboard (positive yaw moment)" do
    model = Model.from_params("neptunus") |> Model.command(%{port: 1.0, starboard: -1.0})
    {model, _} = Model.advance(model, 5.0)
    {heave, yaw} = Model.force(model)
    assert_in_delta heave, 0.0, 1.0e-9
    assert yaw > 0.8
  end
end
