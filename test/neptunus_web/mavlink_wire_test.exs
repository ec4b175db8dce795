defmodule NeptunusWeb.MAVLinkWireTest do
  # A mavlink vehicle flown through a WebSocket against the fake ArduSub (pymavlink): what the
  # vehicle receives is what the fake reports.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias Neptunus.Test.{FakeArduSub, Patience, Pty}

  @moduletag :external
  @moduletag :capture_log

  @refusal "PreArm: Must assign a disarm or arm_toggle button or disarm aux function"

  # the fake's frame: `@tag frame: n` (its FRAME_CONFIG; vectored by default); with
  # `@tag answer_params: false` it does not answer the board's frame request
  setup ctx do
    fake = FakeArduSub.start!(:udp, frame: Map.get(ctx, :frame, 1))

    if ctx[:answer_params] == false do
      FakeArduSub.tell(fake, %{answer_params: false})
      FakeArduSub.expect!(fake, &(&1["event"] == "answer_params"))
    end

    id = "mav-#{System.unique_integer([:positive])}"

    # The pilots here are the test's connections, which send no heartbeat between their
    # steps: the helm's deadman (tested in the helm's and the channel's tests) is set beyond
    # a test's length, so a busy machine cannot trip it between two steps and disarm the
    # vehicle (a deadman trip is a pilot loss).
    vehicle = %{
      id: id,
      board: :mavlink,
      link: {:udpout, "127.0.0.1", fake.udp},
      system: 255,
      component: 190,
      disarm_delay: 0.5,
      helm: [deadman_ms: 600_000]
    }

    {:ok, _} = Neptunus.Fleet.start_vehicle(vehicle)
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    # the board is a ground station to the vehicle from the start
    FakeArduSub.expect!(fake, &(&1["event"] == "heartbeat" and &1["sysid"] == 255))
    link_up!(id)
    # its axes are known once its frame is (the board asks as the link comes up)
    if ctx[:answer_params] != false, do: frame_known!(id)
    %{fake: fake, id: id, topic: "vehicle:" <> id}
  end

  defp client(topic, name), do: client!(topic, %{"name" => name})
  defp push(c, event, payload \\ %{}), do: push_and_reply(c.ws, c.jr, c.topic, event, payload)

  # ArduSub's joystick gain heard by the board (it divides it out of MANUAL_CONTROL)
  defp gain_heard!(id, gain, left \\ 500) do
    cond do
      Neptunus.Vehicle.Board.link_status(id).mavlink.pilot_gain == gain -> :ok
      left == 0 -> flunk("the board did not hear ArduSub's PilotGain #{gain}")
      true -> Process.sleep(10) && gain_heard!(id, gain, left - 1)
    end
  end

  defp pilot(topic) do
    ada = client(topic, "Ada")
    {"ok", %{"grant" => %{"epoch" => epoch}}} = push(ada, "request_control")
    Map.put(ada, :epoch, epoch)
  end

  # arms through the channel: the reply carries the vehicle's answer, or `pending` and then
  # the `vehicle_answer` event
  defp arm!(c, fake) do
    case push(c, "arm") do
      {"ok", %{"status" => "ok"}} -> :ok
      {"ok", %{"status" => "pending"}} -> assert %{"ok" => true} = event!(c.ws, "vehicle_answer")
    end

    FakeArduSub.expect!(fake, &(&1["event"] == "armed" and &1["armed"] == true))
  end

  defp manual_control!(fake, pred),
    do: FakeArduSub.expect!(fake, &(&1["event"] == "manual_control" and pred.(&1)))

  test "neutral MANUAL_CONTROL from 255 to target 1 while nobody pilots", %{fake: fake} do
    mc = manual_control!(fake, fn _ -> true end)
    assert %{"x" => 0, "y" => 0, "z" => 500, "r" => 0, "buttons" => 0} = mc
    assert %{"sysid" => 255, "target" => 1, "accepted" => true} = mc
  end

  test "the pilot arms, drives and sees MANUAL_CONTROL; a stop sends neutral at once", ctx do
    %{fake: fake, topic: topic} = ctx
    gain_heard!(ctx.id, 0.5)
    ada = pilot(topic)
    arm!(ada, fake)

    # our gain 0.5: surge 0.8 → 0.4, heave 0.4 (down) → 0.2, yaw −0.2 → −0.1; ArduSub's own
    # joystick gain (0.5, its PilotGain) is divided out: x 800, z 300, r −200
    payload = %{"mode" => "motion", "surge" => 0.8, "heave" => 0.4, "yaw" => -0.2}
    assert {"ok", _} = push(ada, "thrust", Map.put(payload, "epoch", ada.epoch))

    assert %{"armed" => true} =
             manual_control!(fake, &(&1["x"] == 800 and &1["z"] == 300 and &1["r"] == -200))

    # still sent at the pilot's values while piloted (10 Hz)
    manual_control!(fake, &(&1["x"] == 800))

    assert {"ok", _} = push(ada, "stop")
    manual_control!(fake, &(&1["x"] == 0 and &1["z"] == 500 and &1["r"] == 0))

    # and the page sees the armed vehicle in telemetry
    assert %{"link" => %{"mavlink" => %{"armed" => true, "mode" => "MANUAL"}}} =
             event!(ada.ws, "telemetry", &get_in(&1, ["link", "mavlink", "armed"]))
  end

  test "an ArduSub pilot strafes; one gain: the motors move by the demand", ctx do
    %{fake: fake, topic: topic} = ctx
    gain_heard!(ctx.id, 0.5)
    ada = pilot(topic)

    assert %{"axes" => ["surge", "sway", "heave", "yaw"], "autopilots" => "vehicle"} =
             ada.snapshot["vehicle"]

    arm!(ada, fake)

    # gain 0.5 (ours), sway 0.6 → demand 0.3 → y 600 at ArduSub's gain 0.5; its vectored
    # frame's horizontal motors are ±lateral: 1500 ± 400·0.3
    payload = %{"mode" => "motion", "surge" => 0.0, "sway" => 0.6, "heave" => 0.0, "yaw" => 0.0}

    assert {"ok", %{"command" => %{"sway" => 0.6}}} =
             push(ada, "thrust", Map.put(payload, "epoch", ada.epoch))

    beating!(ada, fake, &manual_control?(&1, y: 600, x: 0))
    assert servos!(ada) == [1620, 1380, 1620, 1380, 1500, 1500]

    # surge 1 and yaw 1 together: ArduSub mixes them, nothing saturates on our side
    payload = %{payload | "surge" => 1.0, "sway" => 0.0, "yaw" => 1.0}
    assert {"ok", _} = push(ada, "thrust", Map.put(payload, "epoch", ada.epoch))
    beating!(ada, fake, &manual_control?(&1, x: 1000, r: 1000, y: 0))

    # ArduSub's gain stepped up to 1 (its gain buttons): the command follows, same thrust
    FakeArduSub.tell(fake, %{gain: 1.0})
    beating!(ada, fake, &manual_control?(&1, x: 500, r: 500))
  end

  describe "the vehicle's frame (FRAME_CONFIG) decides whether it sways" do
    @axes ["surge", "sway", "heave", "yaw"]
    @no_sway ["surge", "heave", "yaw"]

    # the first telemetry with these axes and this frame (control reports the axes, the board
    # the frame: either may come first)
    defp frame_telemetry!(c, axes, frame),
      do:
        event!(
          c.ws,
          "telemetry",
          &(&1["axes"] == axes and get_in(&1, ["link", "mavlink", "frame"]) == frame)
        )

    defp sway(c, sway),
      do:
        push(c, "thrust", %{
          "mode" => "motion",
          "surge" => 0.6,
          "sway" => sway,
          "heave" => 0.0,
          "yaw" => 0.0,
          "epoch" => c.epoch
        })

    test "a vectored frame (a BlueROV2) strafes: the page, a ground station and control have sway",
         %{id: id, topic: topic} do
      ada = pilot(topic)
      assert ada.snapshot["vehicle"]["axes"] == @axes
      frame_telemetry!(ada, @axes, "Vectored")
      # what the ground station endpoint gives a stick's lateral to
      assert Neptunus.Vehicle.Board.capabilities(id).axes == [:surge, :sway, :heave, :yaw]
      assert {"ok", %{"command" => %{"sway" => 0.5}}} = sway(ada, 0.5)
    end

    @tag frame: 4
    test "a SimpleROV-3 has no lateral thruster: no sway on the page, for a ground station, nor to the vehicle",
         %{fake: fake, id: id, topic: topic} = ctx do
      gain_heard!(ctx.id, 0.5)
      ada = pilot(topic)
      assert ada.snapshot["vehicle"]["axes"] == @no_sway
      frame_telemetry!(ada, @no_sway, "SimpleROV-3")

      # a ground station's stick: its lateral is left out (Neptunus.GCS.Intents reads these)
      vehicle_axes = Neptunus.Vehicle.Board.capabilities(id).axes
      assert vehicle_axes == [:surge, :heave, :yaw]
      stick = Neptunus.GCS.Manual.axes(%{x: 600, y: 800, z: 500, r: 0})
      refute Map.has_key?(Neptunus.GCS.Manual.thrust_payload(stick, vehicle_axes, 1), "sway")

      # the page's sway is refused; the vehicle never gets a lateral command
      arm!(ada, fake)

      assert {"error", %{"reason" => "this vehicle has no sway" <> _}} = sway(ada, 0.5)
      assert {"ok", _} = sway(ada, 0.0)
      # our gain 0.5 and ArduSub's 0.5: surge 0.6 → x 600
      mc = beating!(ada, fake, &manual_control?(&1, x: 600))
      assert mc["y"] == 0
    end

    @tag answer_params: false
    test "no sway until the vehicle tells its frame, asked again until it does; then the page is offered sway",
         %{fake: fake, topic: topic} do
      ada = pilot(topic)
      assert ada.snapshot["vehicle"]["axes"] == @no_sway
      frame_telemetry!(ada, @no_sway, nil)
      assert {"error", %{"reason" => "this vehicle has no sway" <> _}} = sway(ada, 0.5)

      # asked, and asked again
      unanswered? =
        &(&1["event"] == "param_request_read" and &1["param_id"] == "FRAME_CONFIG" and
            &1["answered"] == false and &1["sysid"] == 255)

      FakeArduSub.expect!(fake, unanswered?)
      FakeArduSub.expect!(fake, unanswered?)

      FakeArduSub.tell(fake, %{answer_params: true})
      FakeArduSub.expect!(fake, &(&1["event"] == "param_request_read" and &1["answered"]))

      # the page follows (telemetry's axes), and so does control
      frame_telemetry!(ada, @axes, "Vectored")
      assert {"ok", %{"command" => %{"sway" => 0.5}}} = sway(ada, 0.5)
    end
  end

  defp manual_control?(report, values),
    do:
      report["event"] == "manual_control" and
        Enum.all?(values, fn {k, v} -> report[Atom.to_string(k)] == v end)

  # the fake's next report for which `pred` is true, the pilot's heartbeat keeping the deadman
  # away meanwhile
  defp beating!(c, fake, pred, tries \\ 50) do
    assert {"ok", _} = push(c, "heartbeat")

    case FakeArduSub.expect(fake, pred, 100) do
      {:ok, report} -> report
      :timeout when tries > 0 -> beating!(c, fake, pred, tries - 1)
      :timeout -> flunk("the fake ArduSub did not report what was expected in time")
    end
  end

  # the vehicle's motor outputs 1..6 in telemetry once they settle on a new command
  defp servos!(c, tries \\ 100) do
    # the pilot's heartbeat keeps the deadman away meanwhile
    assert {"ok", _} = push(c, "heartbeat")

    servos =
      c.ws
      |> event!(
        "telemetry",
        &match?([_, _, _, _, _, _ | _], get_in(&1, ["link", "mavlink", "servo_us"]))
      )
      |> get_in(["link", "mavlink", "servo_us"])
      |> Enum.take(6)

    cond do
      servos != [1500, 1500, 1500, 1500, 1500, 1500] -> servos
      tries == 0 -> servos
      true -> servos!(c, tries - 1)
    end
  end

  test "disarm; only the pilot arms", %{fake: fake, topic: topic} do
    bob = client(topic, "Bob")
    assert {"error", %{"reason" => "not_in_control"}} = push(bob, "arm")
    ada = pilot(topic)
    arm!(ada, fake)

    case push(ada, "disarm") do
      {"ok", %{"status" => "ok"}} ->
        :ok

      {"ok", %{"status" => "pending"}} ->
        assert %{"ok" => true} = event!(ada.ws, "vehicle_answer")
    end

    FakeArduSub.expect!(fake, &(&1["event"] == "armed" and &1["armed"] == false))
  end

  test "a refusal gives ArduSub's own text", %{fake: fake, topic: topic} do
    FakeArduSub.tell(fake, %{refuse_arm: @refusal})
    FakeArduSub.expect!(fake, &(&1["event"] == "refuse_arm"))
    ada = pilot(topic)

    reason =
      case push(ada, "arm") do
        {"error", %{"reason" => reason}} ->
          reason

        {"ok", %{"status" => "pending"}} ->
          assert %{"ok" => false, "reason" => r} = event!(ada.ws, "vehicle_answer")
          r
      end

    assert reason == @refusal
  end

  test "pilot loss disarms the vehicle after the delay", %{fake: fake, topic: topic} do
    ada = pilot(topic)
    arm!(ada, fake)
    NeptunusWeb.Test.WSClient.close(ada.ws)
    assert %{"why" => "gcs"} = FakeArduSub.expect!(fake, &(&1["event"] == "armed"))
  end

  test "a handover keeps the vehicle armed", %{fake: fake, topic: topic, id: id} do
    ada = pilot(topic)
    arm!(ada, fake)
    bob = client(topic, "Bob")
    {"ok", %{"status" => "pending"}} = push(bob, "request_control")
    event!(ada.ws, "control_request")
    {"ok", _} = push(ada, "answer_request", %{"accept" => true})
    %{"epoch" => epoch} = event!(bob.ws, "control_granted")

    # Bob drives: once his command reaches the vehicle, the board has had the handover's
    # stop and the helm's new pilot (both broadcast before Bob's command ran), and no disarm
    # is due
    thrust = %{"mode" => "motion", "surge" => 0.8, "heave" => 0.0, "yaw" => 0.0}
    assert {"ok", _} = push(bob, "thrust", Map.put(thrust, "epoch", epoch))
    assert %{"armed" => true} = manual_control!(fake, &(&1["x"] > 0))
    refute Neptunus.Vehicle.Board.link_status(id).mavlink.disarm_pending
    refute_armed_change(fake)
  end

  test "when Neptunus falls silent, ArduSub's own pilot-input failsafe disarms", ctx do
    %{fake: fake, topic: topic, id: id} = ctx
    ada = pilot(topic)
    arm!(ada, fake)
    Neptunus.Fleet.stop_vehicle(id)
    # the board's last word is neutral; then nothing comes, and 3 s later the vehicle disarms
    manual_control!(fake, &(&1["x"] == 0 and &1["z"] == 500))

    assert %{"why" => "pilot_input_failsafe"} =
             FakeArduSub.expect!(fake, &(&1["event"] == "armed"), 3_000 + Patience.ms())
  end

  test "lights and camera tilt through the vehicle's own commands", %{fake: fake, topic: topic} do
    ada = pilot(topic)
    assert {"ok", %{"control" => %{"lights" => 255}}} = push(ada, "set_lights", %{"value" => 255})

    assert %{"params" => [9.0, 1900.0 | _], "result" => 0} =
             FakeArduSub.expect!(fake, &(&1["event"] == "command" and &1["command"] == 183))

    assert {"ok", _} = push(ada, "set_tilt", %{"value" => -0.5})

    assert %{"params" => [pitch | _]} =
             FakeArduSub.expect!(fake, &(&1["event"] == "command" and &1["command"] == 205))

    assert_in_delta pitch, -0.5 * 180 / :math.pi(), 1.0e-3

    assert {"error", %{"reason" => "an ArduSub vehicle has no laser"}} =
             push(ada, "set_laser", %{"value" => 3})
  end

  test "manual per-thruster mode is refused with a reason", %{topic: topic} do
    ada = pilot(topic)

    assert {"error", %{"reason" => "manual per-thruster mode is not available" <> _}} =
             push(ada, "set_control_mode", %{"mode" => "manual"})
  end

  test "depth hold sets ALT_HOLD; a setpoint is refused", %{fake: fake, topic: topic} do
    ada = pilot(topic)

    case push(ada, "autopilot", %{"depth" => "hold", "heading" => "hold"}) do
      {"ok", %{"status" => "ok"}} ->
        :ok

      {"ok", %{"status" => "pending"}} ->
        assert %{"ok" => true} = event!(ada.ws, "vehicle_answer")
    end

    assert %{"mode" => "ALT_HOLD"} = FakeArduSub.expect!(fake, &(&1["event"] == "mode"))

    assert {"error", %{"reason" => "ArduSub holds the depth" <> _}} =
             push(ada, "autopilot", %{"depth" => 3})
  end

  test "ArduSub's own position (LOCAL_POSITION_NED) is the vehicle's: a valid position in the ardusub frame with its geodetic origin, served to a ground station",
       %{fake: fake, id: id, topic: topic} do
    Neptunus.PubSub.subscribe(topic)
    # no position before the vehicle has one
    assert_receive {:pubsub, _, "telemetry", %{position: %{valid: false, sources: []}}}

    # its EKF origin (a GPS at the surface), then a position (a DVL)
    FakeArduSub.tell(fake, %{origin: %{lat: 59.8, lon: 10.7}})
    FakeArduSub.expect!(fake, &(&1["event"] == "origin"))
    FakeArduSub.tell(fake, %{position: %{north: 3.0, east: -2.0}})
    FakeArduSub.expect!(fake, &(&1["event"] == "position"))

    assert_receive {:pubsub, _, "telemetry",
                    %{
                      position: %{
                        valid: true,
                        frame: "ardusub",
                        north: north,
                        east: east,
                        origin: %{lat: lat0, lon: lon0},
                        sources: [%{name: "ardusub", kind: "fix", state: "valid"}]
                      }
                    }}

    assert_in_delta north, 3.0, 0.05
    assert_in_delta east, -2.0, 0.05
    # the origin ArduSub's GLOBAL_POSITION_INT and LOCAL_POSITION_NED give (degE7: 1.1 cm)
    deg = :math.pi() / 180
    assert_in_delta lat0, 59.8 * deg, 2.0e-9
    assert_in_delta lon0, 10.7 * deg, 2.0e-9

    # a ground station sees it as Neptunus' vehicle's LOCAL_POSITION_NED
    gcs = %{
      endpoints: [
        %{
          kind: :udpin,
          address: {127, 0, 0, 1},
          port: 0,
          loopback: true,
          gcs: nil,
          spec: "udpin (test)",
          link_id: 0
        }
      ],
      systems: %{id => 4},
      keys: %{},
      trusted: [],
      unsigned: :none,
      mode: :local
    }

    start_supervised!({Neptunus.GCS, gcs: gcs, vehicles: [%{id: id, board: :mavlink}]})
    port = Neptunus.GCS.Endpoint.stats(Neptunus.GCS.Endpoint.name(0)).port
    client = Neptunus.Test.GCSClient.start!(port)

    Neptunus.Test.GCSClient.send!(client, :heartbeat, %{
      type: 6,
      autopilot: 8,
      base_mode: 0,
      custom_mode: 0,
      system_status: 4
    })

    assert %{system: 4, fields: %{x: x, y: y}} =
             Neptunus.Test.GCSClient.expect!(
               client,
               &(&1.name == :local_position_ned),
               Patience.ms()
             )

    assert_in_delta x, 3.0, 0.05
    assert_in_delta y, -2.0, 0.05

    # and, the frame's origin being known, where it is on the Earth
    assert %{system: 4, fields: %{lat: lat, lon: lon, relative_alt: relative_alt}} =
             Neptunus.Test.GCSClient.expect!(
               client,
               &(&1.name == :global_position_int),
               Patience.ms()
             )

    here = Neptunus.Navigation.Geo.offset(%{lat: 59.8 * deg, lon: 10.7 * deg}, 3.0, -2.0)
    # within 5 cm (the estimate's filtering), in degE7
    assert_in_delta lat, here.lat / deg * 1.0e7, 5
    assert_in_delta lon, here.lon / deg * 1.0e7, 10
    assert relative_alt <= 0

    # without its position again, the estimate is lost (invalid once its fixes stop for 5 s):
    # no more LOCAL_POSITION_NED for ground stations
    FakeArduSub.tell(fake, %{position: :null})
    drain_telemetry()

    assert_receive {:pubsub, _, "telemetry",
                    %{position: %{valid: false, frame: "ardusub", reason: reason}}},
                   Patience.ms() + 10_000

    assert reason =~ "ardusub"

    # the ground station is told so once the vehicle's source has heard it (REQUEST_MESSAGE
    # FAILS), and from then on gets none
    no_position!(client, 4, div(Patience.ms(), 100))
    Neptunus.Test.GCSClient.flush(client)
    refute Neptunus.Test.GCSClient.arrives?(client, &(&1.name == :local_position_ned), 1_000)
  end

  # forgets the telemetry received so far (the broadcasts from before a change)
  defp drain_telemetry do
    receive do
      {:pubsub, _, "telemetry", _} -> drain_telemetry()
    after
      0 -> :ok
    end
  end

  # asks ground station system `sysid` for LOCAL_POSITION_NED until it answers FAILED (no
  # position), once per tick of the vehicle's source (an ATTITUDE comes with each tenth)
  defp no_position!(client, sysid, tries) do
    Neptunus.Test.GCSClient.command!(client, sysid, 512, [32])

    ack =
      Neptunus.Test.GCSClient.expect!(
        client,
        &(&1.name == :command_ack and &1.fields.command == 512),
        Patience.ms()
      )

    cond do
      ack.fields.result == 4 ->
        :ok

      tries == 0 ->
        flunk("the ground station still gets a position")

      true ->
        Neptunus.Test.GCSClient.expect!(client, &(&1.name == :attitude), Patience.ms())
        no_position!(client, sysid, tries - 1)
    end
  end

  defp link_up!(id),
    do: Pty.wait_until(fn -> Neptunus.Vehicle.Board.link_status(id).up end, "the mavlink link up")

  defp frame_known!(id),
    do:
      Pty.wait_until(
        fn -> Neptunus.Vehicle.Board.link_status(id).mavlink.frame != nil end,
        "the vehicle's frame known"
      )

  defp refute_armed_change(%{port: port}) do
    receive do
      {^port, {:data, {:eol, line}}} ->
        report = :jiffy.decode(line, [:return_maps])
        refute report["event"] == "armed", "the vehicle was disarmed: #{line}"
        refute_armed_change(%{port: port})
    after
      0 -> :ok
    end
  end
end
