defmodule NeptunusWeb.ControlWireTest do
  # The control commands over the wire (docs/API.md "Control"): pilot only, `ok {control}`
  # with the new state or `error {reason}` with nothing changed; telemetry carries the state.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  @moduletag :capture_log

  setup do
    {:ok, start_vehicle!("ctlwire")}
  end

  defp client(topic, name), do: client!(topic, %{"name" => name})

  defp push(c, event, payload \\ %{}), do: push_and_reply(c.ws, c.jr, c.topic, event, payload)

  test "the snapshot and the grant carry the whole control state", %{topic: topic} do
    ada = client(topic, "Ada")

    assert %{
             "mode" => "motion",
             "gain" => 0.5,
             "lights" => 0,
             "laser" => 0,
             "tilt" => +0.0,
             "run_mode" => "normal",
             "autopilot" => %{"depth" => nil, "heading" => nil, "position" => nil},
             "command" => %{"surge" => +0.0},
             "thrusters" => %{"port_us" => 1500}
           } = ada.snapshot["control"]

    assert {"ok", %{"status" => "granted", "grant" => %{"control" => control}}} =
             push(ada, "request_control")

    assert control["run_mode"] == "normal"
  end

  test "only the pilot commands; replies carry the new state or a reason", %{topic: topic} do
    ada = client(topic, "Ada")
    bob = client(topic, "Bob")

    assert {"error", %{"reason" => "not_in_control"}} = push(ada, "set_lights", %{"value" => 10})

    assert {"ok", %{"status" => "granted", "grant" => %{"epoch" => epoch}}} =
             push(ada, "request_control")

    assert {"ok", %{"control" => %{"lights" => 10}}} = push(ada, "set_lights", %{"value" => 10})
    assert {"ok", %{"control" => %{"gain" => 1.0}}} = push(ada, "set_gain", %{"value" => 1})
    assert {"ok", %{"control" => %{"tilt" => 0.5}}} = push(ada, "set_tilt", %{"value" => 0.5})

    assert {"error", %{"reason" => "not_in_control"}} =
             push(bob, "set_control_mode", %{"mode" => "manual"})

    assert {"ok", %{"control" => %{"mode" => "manual", "gain" => 1.0}}} =
             push(ada, "set_control_mode", %{"mode" => "manual"})

    assert %{"reason" => "control_mode_changed"} =
             event!(bob.ws, "stopped", &(&1["reason"] == "control_mode_changed"))

    manual = %{"mode" => "manual", "port" => 0.5, "vertical" => 0, "starboard" => 0.5}

    assert {"ok", %{"command" => %{"port" => 0.5}, "thrusters" => %{"port_us" => 1750}}} =
             push(ada, "thrust", Map.put(manual, "epoch", epoch))

    assert {"error", %{"reason" => "thrust mode motion does not match control mode manual"}} =
             push(ada, "thrust", %{
               "mode" => "motion",
               "surge" => 0,
               "heave" => 0,
               "yaw" => 0,
               "epoch" => epoch
             })

    assert {"error", %{"reason" => "autopilots are not available in manual mode" <> _}} =
             push(ada, "autopilot", %{"depth" => "hold"})

    assert {"error", %{"reason" => "run mode simulator needs a vehicle with a real board" <> _}} =
             push(ada, "set_run_mode", %{"mode" => "simulator"})

    assert {"error", %{"reason" => ~s(mode must be one of "dp", "manual", "motion", got "x")}} =
             push(ada, "set_control_mode", %{"mode" => "x"})
  end

  test "autopilots and DP on the simulator; telemetry shows them", %{topic: topic} do
    ada = client(topic, "Ada")
    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")
    # wait for an estimate from navigation
    event!(ada.ws, "telemetry", &is_number(get_in(&1, ["estimate", "depth"])))

    assert {"ok", %{"control" => %{"autopilot" => %{"depth" => d, "heading" => h}}}} =
             push(ada, "autopilot", %{"depth" => "hold", "heading" => "hold"})

    assert is_float(d) and is_float(h)

    assert %{"autopilot" => %{"depth" => %{"setpoint" => ^d, "overridden" => false}}} =
             event!(ada.ws, "telemetry", &is_map(get_in(&1, ["autopilot", "depth"])))

    # this vehicle has no position source: DP holds depth and heading only, and says so
    assert {"ok",
            %{
              "control" => %{
                "mode" => "dp",
                "dp_holds" => ["depth", "heading"],
                "autopilot" => %{"position" => nil}
              }
            }} = push(ada, "set_control_mode", %{"mode" => "dp"})

    assert %{
             "position" => %{"valid" => false, "reason" => "no position source"},
             "autopilot" => %{"position" => %{"phase" => "waiting"}}
           } = event!(ada.ws, "telemetry", &(get_in(&1, ["control", "mode"]) == "dp"))

    assert {"error", %{"reason" => "dp holds depth and heading" <> _}} =
             push(ada, "autopilot", %{"heading" => nil})
  end

  test "DP on a simulated vehicle with the simulated DVL and USBL holds its position" do
    %{topic: topic} =
      start_vehicle!("ctlwire-pos", %{position: [{:sim_dvl, []}, {:sim_usbl, []}]})

    ada = client(topic, "Ada")
    assert {"ok", %{"status" => "granted"}} = push(ada, "request_control")
    # the position sources report through the real drivers: a valid position
    event!(ada.ws, "telemetry", &(get_in(&1, ["position", "valid"]) == true), 30_000)

    assert {"ok",
            %{
              "control" => %{
                "mode" => "dp",
                "dp_holds" => ["depth", "heading", "position"],
                "autopilot" => %{"position" => %{"x" => x, "y" => y}}
              }
            }} = push(ada, "set_control_mode", %{"mode" => "dp"})

    assert is_float(x) and is_float(y)

    assert %{"autopilot" => %{"position" => %{"phase" => phase, "x" => ^x}}} =
             event!(ada.ws, "telemetry", &(get_in(&1, ["control", "mode"]) == "dp"))

    assert phase in ["hold", "return"]
  end
end
