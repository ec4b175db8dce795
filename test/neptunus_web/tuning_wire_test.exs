defmodule NeptunusWeb.TuningWireTest do
  # Autopilot tuning over the wire (docs/API.md "Tuning"): `get_tuning` for anyone,
  # `set_tuning` and `step_response` for the pilot (or the main station).
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  @moduletag :capture_log

  setup do
    vehicle = start_vehicle!("tunewire")

    on_exit(fn ->
      Neptunus.Settings.delete({:vehicle, vehicle.id}, "tuning")
      Neptunus.Settings.delete({:vehicle, vehicle.id}, "camera.rotation")
    end)

    {:ok, vehicle}
  end

  defp client(topic, name), do: client!(topic, %{"name" => name})
  defp push(c, event, payload \\ %{}), do: push_and_reply(c.ws, c.jr, c.topic, event, payload)

  test "anyone reads the tuning; only the pilot (any of their connections) tunes and previews",
       %{topic: topic} do
    ada = client(topic, "Ada")
    bob = client(topic, "Bob")
    # Ada's developer page: another connection of the user who pilots
    ada_dev = client(topic, "Ada")

    assert {"ok",
            %{
              "gains" => %{"depth" => %{"kp" => 3.0}, "heading" => %{"kd" => 2.0}},
              "defaults" => %{"depth" => %{"kp" => 3.0}},
              "ranges" => %{"kp" => [0, 20]},
              "model" => "neptunus"
            }} = push(bob, "get_tuning")

    assert {"error",
            %{"reason" => "tuning is for the pilot or the main station: Bob does not pilot"}} =
             push(bob, "set_tuning", %{"depth" => %{"kp" => 5}})

    assert {"error", %{"reason" => "tuning is for the pilot or the main station" <> _}} =
             push(bob, "step_response", %{"axis" => "depth", "step" => 1})

    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")

    assert {"ok", %{"t" => [_ | _], "value" => [_ | _], "reference" => [_ | _], "settle" => s}} =
             push(ada_dev, "step_response", %{
               "axis" => "depth",
               "step" => 0.5,
               "gains" => %{"depth" => %{"kp" => 5}}
             })

    assert is_number(s)

    assert {"error", %{"reason" => "depth.kp must be a number in [0, 20], got -1"}} =
             push(ada, "set_tuning", %{"depth" => %{"kp" => -1}})

    assert {"ok", %{"tuning" => %{"depth" => %{"kp" => 5.0}}}} =
             push(ada_dev, "set_tuning", %{"depth" => %{"kp" => 5}})

    assert {"ok", %{"gains" => %{"depth" => %{"kp" => 5.0}}}} = push(bob, "get_tuning")
  end

  test "the camera rotation is a vehicle setting: set by the pilot, in every snapshot, broadcast",
       %{topic: topic} do
    ada = client(topic, "Ada")
    bob = client(topic, "Bob")
    assert bob.snapshot["settings"] == %{"camera_rotation" => 0}

    assert {"error",
            %{"reason" => "the camera rotation is for the pilot or the main station: " <> _}} =
             push(bob, "set_camera_rotation", %{"value" => 90})

    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")

    assert {"error", %{"reason" => "value must be one of 0, 90, 180, 270 (degrees), got 45"}} =
             push(ada, "set_camera_rotation", %{"value" => 45})

    assert {"ok", %{"camera_rotation" => 180}} =
             push(ada, "set_camera_rotation", %{"value" => 180})

    # every page is told, and a page that joins later gets it in its snapshot
    assert %{"camera_rotation" => 180} = event!(bob.ws, "vehicle_settings", fn _ -> true end)
    assert client(topic, "Cy").snapshot["settings"] == %{"camera_rotation" => 180}
  end
end
