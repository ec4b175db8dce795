defmodule Neptunus.Vehicle.ModelsTest do
  # NEPTUNUS_MODELS end to end: the configured parameter set reaches the simulator and the
  # navigation filter of a vehicle started from the configuration.
  use ExUnit.Case, async: true

  alias Neptunus.{Config, Fleet}
  alias Neptunus.Navigation.Model
  alias Neptunus.Vehicle.{Board, Navigation}

  @moduletag :capture_log

  test "a simulated vehicle flies and filters with its configured parameter set" do
    id = "m-#{System.unique_integer([:positive])}"

    [vehicle] =
      Config.Vehicles.vehicles!(%{
        "NEPTUNUS_VEHICLES" => "#{id}=simulated",
        "NEPTUNUS_MODELS" => "#{id}=thesis-4dof"
      })

    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})

    assert Board.Simulated.state(id).sim.params.name == "thesis-4dof"

    navigation = :sys.get_state(Fleet.via(Navigation, id))
    assert navigation.estimator_opts[:vehicle] == "thesis-4dof"
    model = navigation.estimator.model
    assert {model.heave, model.yaw} == take(Model.from_params("thesis-4dof"))
    refute {model.heave, model.yaw} == take(Model.from_params("neptunus"))
  end

  defp take(%Model{heave: heave, yaw: yaw}), do: {heave, yaw}

  test "without a model the simulator and the filter use neptunus" do
    id = "m-#{System.unique_integer([:positive])}"
    [vehicle] = Config.Vehicles.vehicles!(%{"NEPTUNUS_VEHICLES" => "#{id}=simulated"})
    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})

    assert Board.Simulated.state(id).sim.params.name == "neptunus"
    assert :sys.get_state(Fleet.via(Navigation, id)).estimator_opts[:vehicle] == "neptunus"
  end

  test "run mode simulator on a real board flies the configured parameter set" do
    id = "m-#{System.unique_integer([:positive])}"

    vehicle = %{
      id: id,
      board: Board.Test,
      report_to: self(),
      sim: [vehicle: "thesis-4dof"],
      helm: [tick_ms: 3_600_000]
    }

    Neptunus.PubSub.subscribe(Neptunus.Vehicle.Telemetry.topic(id))
    start_supervised!({Neptunus.Vehicle.Supervisor, vehicle})
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}

    assert {:ok, %{control: %{run_mode: "simulator"}}} =
             Neptunus.Vehicle.Control.command(id, "set_run_mode", %{"mode" => "simulator"})

    sim = Neptunus.Vehicle.Control.simulator(id)
    assert :sys.get_state(sim).sim.params.name == "thesis-4dof"
  end
end
