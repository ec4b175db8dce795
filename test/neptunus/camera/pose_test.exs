defmodule Neptunus.Camera.PoseTest do
  # The simulators publish the vehicle's true pose and devices for the simulated camera
  # (Neptunus.Camera.Pose): the built-in simulator and the SITL board.
  use ExUnit.Case, async: true

  @moduletag :capture_log

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Vehicle.Board.OpenROV.Wiring
  alias Neptunus.Camera.Pose
  alias Neptunus.Vehicle.Board

  defp start(vehicle) do
    PubSub.subscribe(Pose.topic(vehicle.id))
    {:ok, _} = Fleet.start_vehicle(vehicle)
    on_exit(fn -> Fleet.stop_vehicle(vehicle.id) end)
    vehicle.id
  end

  test "the built-in simulator: its true pose at every step, with lights, laser and tilt" do
    id = start(%{id: "pose-#{System.unique_integer([:positive])}", board: :simulated})
    assert_receive {:pubsub, _, "pose", %{z: z, psi: _, u: _, lights: 0.0}}
    assert_in_delta z, 1.0, 0.2

    Board.lights(id, 255)
    Board.tilt(id, 0.3)
    assert_receive {:pubsub, _, "pose", %{lights: 1.0, tilt: 0.3}}
  end

  @tag :uart
  test "the SITL board: the same, from the simulated OpenROV board's firmware" do
    sitl = "pose-sitl-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Neptunus.Vehicle.Telemetry.topic(sitl))

    id =
      start(%{
        id: sitl,
        board: :sitl,
        wiring: Wiring.default(),
        sim: [noise: false]
      })

    assert_receive {:pubsub, _, "pose", %{z: _, lights: 0.0, tilt: tilt}}
    assert_in_delta tilt, 0.0, 1.0e-9
    # commands reach the board once its link is up
    assert_receive {:pubsub, _, "link", %{up: true}}
    Board.lights(id, 255)
    assert_receive {:pubsub, _, "pose", %{lights: 1.0}}
  end
end
