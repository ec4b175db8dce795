defmodule Neptunus.Vehicle.Board.MAVLink.CoreTest do
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink.Message
  alias Neptunus.Vehicle.Board.MAVLink.Core

  doctest Core

  @armed 128 + 64 + 16 + 1
  @disarmed 64 + 16 + 1

  defp msg(name, fields, system \\ 1, component \\ 1) do
    %Message{
      id: 0,
      name: name,
      system: system,
      component: component,
      seq: 0,
      version: 2,
      fields: fields
    }
  end

  defp heartbeat(opts \\ []) do
    msg(
      :heartbeat,
      %{
        type: Keyword.get(opts, :type, 12),
        autopilot: 3,
        base_mode: if(Keyword.get(opts, :armed, false), do: @armed, else: @disarmed),
        custom_mode: Keyword.get(opts, :mode, 19),
        system_status: 4,
        mavlink_version: 3
      },
      Keyword.get(opts, :system, 1),
      Keyword.get(opts, :component, 1)
    )
  end

  defp sends(actions, name), do: for({:send, ^name, f} <- actions, do: f)

  # a core with the vehicle heard at t = 0.5
  defp linked(opts \\ []) do
    core = Core.new(0, opts)
    {core, _} = Core.tick(core, 0)
    {core, _} = Core.receive(core, heartbeat(opts), 500)
    core
  end

  describe "time" do
    test "a GCS heartbeat every second, on the grid, from the start" do
      core = Core.new(10_000)
      {core, actions} = Core.tick(core, 10_000)
      assert [%{type: 6, autopilot: 8}] = sends(actions, :heartbeat)
      {core, actions} = Core.tick(core, 10_500)
      assert sends(actions, :heartbeat) == []
      # late: one heartbeat, the next on the grid
      {core, actions} = Core.tick(core, 13_200)
      assert length(sends(actions, :heartbeat)) == 1
      assert core.next_heartbeat_ms == 14_000
    end

    test "no MANUAL_CONTROL before a vehicle is known; neutral at 10 Hz after" do
      core = Core.new(0)
      {core, actions} = Core.tick(core, 0)
      assert sends(actions, :manual_control) == []
      {core, _} = Core.receive(core, heartbeat(), 50)
      {core, actions} = Core.tick(core, 100)

      assert [%{target: 1, x: 0, y: 0, z: 500, r: 0, buttons: 0}] =
               sends(actions, :manual_control)

      {core, actions} = Core.tick(core, 150)
      assert sends(actions, :manual_control) == []
      {_core, actions} = Core.tick(core, 200)
      assert length(sends(actions, :manual_control)) == 1
    end

    test "due/1 is the earliest deadline" do
      core = linked()

      assert Core.due(core) ==
               Enum.min([core.next_heartbeat_ms, core.next_manual_ms, core.next_timesync_ms])

      {core, _} = Core.arm(core, :me, true, 500)
      core = %{core | next_heartbeat_ms: 9_000, next_manual_ms: 9_000, next_timesync_ms: 9_000}
      assert Core.due(core) == 3_500
    end
  end

  describe "go → MANUAL_CONTROL" do
    @zero %{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}
    @ahead %{@zero | surge: 0.5}

    defp demand(axes), do: Map.merge(@zero, Map.new(axes))

    defp named_float(name, value),
      do: msg(:named_value_float, %{time_boot_ms: 0, name: name, value: value})

    test "the demand axis by axis: x surge, y sway, z 500 − 500·heave, r yaw, buttons 0" do
      for {axes, expected} <- [
            {[], %{x: 0, y: 0, z: 500, r: 0}},
            {[surge: 0.5], %{x: 500, y: 0, z: 500, r: 0}},
            {[surge: -1.0], %{x: -1000, y: 0, z: 500, r: 0}},
            {[sway: 0.4], %{x: 0, y: 400, z: 500, r: 0}},
            {[sway: -1.0], %{x: 0, y: -1000, z: 500, r: 0}},
            {[yaw: 0.3], %{x: 0, y: 0, z: 500, r: 300}},
            # positive heave is down: below 500
            {[heave: 1.0], %{x: 0, y: 0, z: 0, r: 0}},
            {[heave: -1.0], %{x: 0, y: 0, z: 1000, r: 0}},
            {[heave: -0.25], %{x: 0, y: 0, z: 625, r: 0}},
            # surge and yaw together do not saturate each other: ArduSub mixes them
            {[surge: 1.0, yaw: 1.0, sway: 1.0], %{x: 1000, y: 1000, z: 500, r: 1000}}
          ] do
        c = Core.manual_control(demand(axes), 1.0)
        assert Map.take(c, [:x, :y, :z, :r]) == expected
        assert c.buttons == 0
      end
    end

    test "ArduSub's gain is divided out: what its mixer gets is the demand" do
      # ArduSub's channel offset is 400 µs · gain · x/1000 (z: (z − 500)/500)
      for gain <- [0.25, 0.5, 0.8, 1.0], surge <- [-0.2, 0.0, 0.1, 0.25], heave <- [-0.2, 0.2] do
        c = Core.manual_control(demand(surge: surge, heave: heave), gain)
        assert_in_delta 400 * gain * c.x / 1000, 400 * surge, 0.5
        assert_in_delta 400 * gain * (c.z - 500) / 500, -400 * heave, 0.5
      end

      # beyond ArduSub's gain the command saturates there
      assert %{x: 1000, y: -1000} = Core.manual_control(demand(surge: 0.8, sway: -0.6), 0.5)
    end

    test "a change is sent at once and restarts the period; no change sends nothing" do
      core = linked()
      {core, actions} = Core.go(core, @ahead, 600)
      assert [%{x: 500, z: 500, target: 1}] = sends(actions, :manual_control)
      assert core.next_manual_ms == 600 + 100
      {_core, actions} = Core.go(core, @ahead, 620)
      assert actions == []
    end

    test "before a vehicle is known the command is kept, not sent" do
      core = Core.new(0)
      {core, actions} = Core.go(core, @ahead, 100)
      assert actions == []
      {core, _} = Core.receive(core, heartbeat(), 200)
      {_core, actions} = Core.tick(core, 200)
      assert [%{x: 500}] = sends(actions, :manual_control)
    end

    test "neutral/2 sends neutral even when unchanged; nothing before a vehicle is known" do
      core = linked()
      {core, actions} = Core.neutral(core, 600)
      assert [%{x: 0, y: 0, z: 500, r: 0}] = sends(actions, :manual_control)
      {core, _} = Core.go(core, demand(surge: 0.5, sway: 0.5), 700)
      {_core, actions} = Core.neutral(core, 710)
      assert [%{x: 0, y: 0, z: 500}] = sends(actions, :manual_control)
      assert {_, []} = Core.neutral(Core.new(0), 100)
    end

    test "out-of-range values are clamped" do
      assert %{x: 1000, y: -1000, z: 0} =
               Core.manual_control(demand(surge: 3.0, sway: -2.0, heave: 2.0), 1.0)
    end

    test "PilotGain: the command is re-scaled and sent at once, the pilot told once per gain" do
      core = linked()
      {core, _} = Core.go(core, demand(surge: 0.25, yaw: -0.1), 600)
      assert %{x: 250, r: -100} = core.control
      assert Core.status(core).mavlink.pilot_gain == nil

      {core, actions} = Core.receive(core, named_float("PilotGain", 0.5), 650)
      assert [%{x: 500, r: -200}] = sends(actions, :manual_control)

      assert [{:log, :info, "ArduSub's joystick gain is 50%" <> _, _}] =
               for({:log, _, _, _} = log <- actions, do: log)

      assert Core.status(core).mavlink.pilot_gain == 0.5
      # the same gain again: nothing
      assert {^core, []} = Core.receive(core, named_float("PilotGain", 0.5), 700)
      # other named values and implausible gains are not the gain
      assert {^core, []} = Core.receive(core, named_float("Lights1", 0.3), 700)
      assert {^core, []} = Core.receive(core, named_float("PilotGain", 0.0), 700)
      assert {^core, []} = Core.receive(core, named_float("PilotGain", 2.0), 700)

      # a new demand is sent at the gain heard
      {_core, actions} = Core.go(core, demand(heave: 0.1), 800)
      assert [%{x: 0, z: 400}] = sends(actions, :manual_control)
    end
  end

  describe "link" do
    test "up on the vehicle's first heartbeat: requests the streams, logs armed and mode" do
      core = Core.new(0)
      {core, actions} = Core.receive(core, heartbeat(), 1000)
      assert {:link, %{up: true, reason: "heartbeat"}} in actions
      streams = sends(actions, :request_data_stream)
      assert length(streams) == 6

      assert Enum.all?(
               streams,
               &match?(%{target_system: 1, target_component: 1, start_stop: 1}, &1)
             )

      assert Enum.any?(streams, &match?(%{req_stream_id: 10, req_message_rate: 10}, &1))
      assert {:log, :info, "vehicle mode: MANUAL", %{}} in actions
      assert {:log, :info, "vehicle armed: false", %{}} in actions

      assert %{up: true, mavlink: %{armed: false, mode: "MANUAL", system_status: "active"}} =
               Core.status(core)
    end

    test "a ground station's heartbeat is not a vehicle" do
      {core, actions} = Core.receive(Core.new(0), heartbeat(type: 6, system: 254), 1000)
      assert actions == []
      refute core.up
      assert core.target == nil
    end

    test "a companion computer's or gimbal's heartbeat (autopilot invalid) is not the vehicle" do
      for {type, component} <- [{18, 191}, {26, 154}, {30, 100}] do
        hb = heartbeat(type: type, component: component)
        hb = %{hb | fields: %{hb.fields | autopilot: 8}}
        {core, actions} = Core.receive(Core.new(0), hb, 1000)
        assert actions == []
        assert core.target == nil
      end
    end

    test "the first vehicle heard is the target; another system's heartbeat is ignored" do
      core = linked()
      {core2, actions} = Core.receive(core, heartbeat(system: 2, armed: true), 700)
      assert actions == []
      assert core2 == core
    end

    test "changes of armed and mode are logged, repeated heartbeats are not" do
      core = linked()
      {core, actions} = Core.receive(core, heartbeat(), 1500)
      assert actions == []
      {core, actions} = Core.receive(core, heartbeat(armed: true), 2500)
      assert actions == [{:log, :info, "vehicle armed: true", %{}}]
      {_core, actions} = Core.receive(core, heartbeat(armed: true, mode: 2), 3500)
      assert actions == [{:log, :info, "vehicle mode: ALT_HOLD", %{}}]
    end

    test "down after link_timeout without a heartbeat; up again with the streams requested" do
      core = linked()
      {core, actions} = Core.tick(core, 3500)
      refute Enum.any?(actions, &match?({:link, _}, &1))
      {core, actions} = Core.tick(core, 3510)
      assert {:link, %{up: false, reason: "no heartbeat from the vehicle for 3.0 s"}} in actions
      refute core.up
      {_core, actions} = Core.receive(core, heartbeat(), 4000)
      assert {:link, %{up: true, reason: "heartbeat"}} in actions
      assert length(sends(actions, :request_data_stream)) == 6
    end

    test "TIMESYNC every second while up; the answer gives the round trip" do
      core = linked()
      {core, actions} = Core.tick(core, 1000)
      assert [%{tc1: 0, ts1: 1_000_000_000}] = sends(actions, :timesync)
      answer = msg(:timesync, %{tc1: 77, ts1: 1_000_000_000})
      {core, []} = Core.receive(core, answer, 1004)
      assert_in_delta Core.status(core).rtt_ms, 4.0, 1.0e-6
      # a request from the vehicle (tc1 0) or a reply to nothing we sent changes nothing
      {^core, []} = Core.receive(core, msg(:timesync, %{tc1: 0, ts1: 5}), 1100)
      {^core, []} = Core.receive(core, msg(:timesync, %{tc1: 1, ts1: 9_000_000_000}), 1100)
    end
  end

  describe "arming" do
    test "arm sends COMMAND_LONG 400 param1 1 to the vehicle; ACCEPTED replies ok" do
      core = linked()
      {core, actions} = Core.arm(core, :me, true, 1000)

      assert [%{command: 400, param1: 1.0, param2: 0.0, target_system: 1, target_component: 1}] =
               sends(actions, :command_long)

      {core, actions} = Core.receive(core, msg(:command_ack, %{command: 400, result: 0}), 1050)
      assert actions == [{:reply, :me, :ok}]
      assert core.pending == nil
    end

    test "a refusal replies with the vehicle's STATUSTEXT, else the result's name" do
      core = linked()
      {core, _} = Core.arm(core, :me, true, 1000)
      text = msg(:statustext, %{severity: 2, text: "Arm: Throttle too high"})
      {core, actions} = Core.receive(core, text, 1010)

      assert [{:log, :error, "Arm: Throttle too high", %{severity: 2, source: "vehicle"}}] =
               actions

      {core, actions} = Core.receive(core, msg(:command_ack, %{command: 400, result: 4}), 1020)
      assert actions == [{:reply, :me, {:error, "Arm: Throttle too high"}}]

      {core, _} = Core.arm(core, :me, true, 2000)
      {_core, actions} = Core.receive(core, msg(:command_ack, %{command: 400, result: 2}), 2100)
      assert actions == [{:reply, :me, {:error, "denied"}}]
    end

    test "an ACK of another command does not answer" do
      core = linked()
      {core, _} = Core.arm(core, :me, false, 1000)
      {core, actions} = Core.receive(core, msg(:command_ack, %{command: 176, result: 0}), 1100)
      assert actions == []
      assert core.pending.kind == :disarm
    end

    test "no answer within command_timeout: a clear error, and the next command may go" do
      core = linked()
      {core, _} = Core.arm(core, :me, true, 1000)
      {core, _} = Core.receive(core, heartbeat(), 2000)
      {core, actions} = Core.tick(core, 3990)
      refute Enum.any?(actions, &match?({:reply, _, _}, &1))
      {core, actions} = Core.tick(core, 4000)
      assert {:reply, :me, {:error, "no answer from the vehicle within 3.0 s"}} in actions
      {_core, actions} = Core.arm(core, :me, true, 4100)
      assert [_] = sends(actions, :command_long)
    end

    test "one command at a time; refused while the link is down" do
      core = linked()
      {core, _} = Core.arm(core, :a, true, 1000)
      {core2, actions} = Core.arm(core, :b, false, 1100)

      assert actions == [
               {:reply, :b, {:error, "a arm command is still waiting for the vehicle's answer"}}
             ]

      assert core2 == core

      {down, actions} = Core.arm(Core.new(0), :c, true, 0)

      assert [
               {:reply, :c,
                {:error, "the vehicle's link is down (no heartbeat from the vehicle yet)"}}
             ] = actions

      assert down.pending == nil
    end

    test "set_mode sends DO_SET_MODE with the custom mode; unknown modes are refused" do
      core = linked()
      {core, actions} = Core.set_mode(core, :me, "ALT_HOLD", 1000)
      assert [%{command: 176, param1: 1.0, param2: 2.0}] = sends(actions, :command_long)
      {_core, actions} = Core.receive(core, msg(:command_ack, %{command: 176, result: 0}), 1100)
      assert actions == [{:reply, :me, :ok}]
      {_core, actions} = Core.set_mode(linked(), :me, "LOITER", 1000)
      assert actions == [{:reply, :me, {:error, "unknown flight mode \"LOITER\""}}]
    end
  end

  describe "pilot loss" do
    defp armed, do: elem(Core.receive(linked(), heartbeat(armed: true), 600), 0)

    test "a pilot-loss stop disarms after disarm_delay" do
      for reason <- Core.pilot_loss_reasons() do
        core = armed() |> Core.pilot("p1") |> Core.stopped(reason, 1000)
        {core, actions} = Core.tick(core, 2990)
        assert sends(actions, :command_long) == []
        {core, actions} = Core.tick(core, 3000)
        assert [%{command: 400, param1: +0.0}] = sends(actions, :command_long)
        assert Enum.any?(actions, &match?({:log, :warning, "disarming the vehicle" <> _, _}, &1))
        assert core.disarm_at_ms == nil
      end
    end

    test "the delay is configurable" do
      core = elem(Core.receive(linked(disarm_delay_ms: 500), heartbeat(armed: true), 600), 0)
      core = Core.stopped(core, "deadman", 1000)
      {_core, actions} = Core.tick(core, 1500)
      assert [%{command: 400}] = sends(actions, :command_long)
    end

    test "a new pilot before the delay cancels it; the same pilot staying does not" do
      core = armed() |> Core.pilot("p1") |> Core.stopped("pilot_disconnected", 1000)
      core = core |> Core.pilot(nil) |> Core.pilot("p2")
      {_core, actions} = Core.tick(core, 5000)
      assert sends(actions, :command_long) == []

      # the deadman keeps the pilot: the helm broadcast after the stop names them again
      core = armed() |> Core.pilot("p1") |> Core.stopped("deadman", 1000) |> Core.pilot("p1")
      {_core, actions} = Core.tick(core, 3000)
      assert [%{command: 400}] = sends(actions, :command_long)
    end

    test "handovers, the pilot's own stop and a disarmed vehicle schedule nothing" do
      for reason <- ["control_transferred", "main_station_takeover", "pilot_stop", "whatever"] do
        assert (armed() |> Core.stopped(reason, 1000)).disarm_at_ms == nil
      end

      assert (linked() |> Core.stopped("deadman", 1000)).disarm_at_ms == nil
    end

    test "a vehicle being armed is disarmed too" do
      {core, _} = Core.arm(linked(), :me, true, 1000)
      assert Core.stopped(core, "pilot_left", 1000).disarm_at_ms == 3_000
    end

    test "nothing is sent if the vehicle disarmed meanwhile or the link is down" do
      core = armed() |> Core.stopped("deadman", 1000)
      {core2, _} = Core.receive(core, heartbeat(), 2000)
      {_core, actions} = Core.tick(core2, 3000)
      assert sends(actions, :command_long) == []
      {_core, actions} = Core.tick(%{core | up: false}, 3000)
      assert sends(actions, :command_long) == []
    end

    test "the pilot's own disarm supersedes the scheduled one" do
      core = armed() |> Core.stopped("deadman", 1000)
      {core, _} = Core.arm(core, :me, false, 1500)
      assert core.disarm_at_ms == nil
    end
  end

  describe "telemetry" do
    test "ATTITUDE makes a sample with the latest depth and battery" do
      core = linked()
      {core, []} = Core.receive(core, msg(:vfr_hud, %{alt: -2.5}), 1000)

      {core, []} =
        Core.receive(
          core,
          msg(:sys_status, %{voltage_battery: 15_900, current_battery: 123}),
          1000
        )

      attitude = %{time_boot_ms: 42_000, roll: 0.1, pitch: -0.2, yaw: -:math.pi() / 2}
      {_core, [{:sample, sample}]} = Core.receive(core, msg(:attitude, attitude), 1500)
      assert sample.t == 1.5
      assert sample.sim == nil
      assert sample.board == %{board_time: 42.0}
      m = sample.measurement
      assert m.depth == 2.5
      assert m.roll == 0.1 and m.pitch == -0.2
      assert_in_delta m.heading, 3 * :math.pi() / 2, 1.0e-9
      assert m.voltage == 15.9
      assert m.current == 1.23
    end

    test "LOCAL_POSITION_NED is the vehicle's position; with GLOBAL_POSITION_INT of the same moment, its frame's geodetic origin" do
      deg = :math.pi() / 180
      global = %{time_boot_ms: 5_000, lat: 598_000_000, lon: 107_000_000, relative_alt: -2000}
      local = %{time_boot_ms: 5_010, x: 10.0, y: -5.0, z: 2.0, vx: 0.0, vy: 0.0, vz: 0.0}
      attitude = msg(:attitude, %{time_boot_ms: 5_020, roll: 0.0, pitch: 0.0, yaw: 0.0})

      {core, []} = Core.receive(linked(), msg(:global_position_int, global), 1.0)
      {core, []} = Core.receive(core, msg(:local_position_ned, local), 1.01)
      {_core, [{:sample, s}]} = Core.receive(core, attitude, 1.02)

      assert %{x: 10.0, y: -5.0, time_boot_ms: 5_010, origin: origin} = s.board.position

      here = Neptunus.Navigation.Geo.offset(origin, 10.0, -5.0)

      assert_in_delta here.lat, 59.8 * deg, 1.0e-12
      assert_in_delta here.lon, 10.7 * deg, 1.0e-12
      assert origin.lat < 59.8 * deg and origin.lon > 10.7 * deg

      # ArduSub without an origin sends 0, 0: a position without a geodetic origin
      {core, []} =
        Core.receive(linked(), msg(:global_position_int, %{global | lat: 0, lon: 0}), 1.0)

      {core, []} = Core.receive(core, msg(:local_position_ned, local), 1.01)
      {_core, [{:sample, s}]} = Core.receive(core, attitude, 1.02)
      assert %{x: 10.0, origin: nil} = s.board.position

      # a global position of another moment is not the same frame's
      {core, []} = Core.receive(linked(), msg(:global_position_int, global), 1.0)

      {core, []} =
        Core.receive(core, msg(:local_position_ned, %{local | time_boot_ms: 9_000}), 1.01)

      {_core, [{:sample, s}]} = Core.receive(core, attitude, 1.02)
      assert %{origin: nil} = s.board.position
    end

    test "depth from GLOBAL_POSITION_INT only while no VFR_HUD came; unknown battery left out" do
      core = linked()
      {core, []} = Core.receive(core, msg(:global_position_int, %{relative_alt: -1500}), 1000)
      assert core.readings.depth == 1.5
      {core, []} = Core.receive(core, msg(:vfr_hud, %{alt: -1.0}), 1100)
      {core, []} = Core.receive(core, msg(:global_position_int, %{relative_alt: -3000}), 1200)
      assert core.readings.depth == 1.0

      {core, []} =
        Core.receive(
          core,
          msg(:sys_status, %{voltage_battery: 0xFFFF, current_battery: -1}),
          1300
        )

      {_core, [{:sample, s}]} =
        Core.receive(
          core,
          msg(:attitude, %{time_boot_ms: 0, roll: 0.0, pitch: 0.0, yaw: 0.0}),
          1400
        )

      refute Map.has_key?(s.measurement, :voltage)
      refute Map.has_key?(s.measurement, :current)
    end

    test "SERVO_OUTPUT_RAW shows as the servo outputs" do
      fields = Map.new(1..16, &{String.to_atom("servo#{&1}_raw"), 1400 + &1})
      {core, []} = Core.receive(linked(), msg(:servo_output_raw, fields), 1000)
      assert Core.status(core).mavlink.servo_us == Enum.map(1..8, &(1400 + &1))
      assert_in_delta Core.status(core).mavlink.thrusters |> hd(), -99 / 400, 0.001

      {core, []} =
        Core.receive(
          core,
          msg(:servo_output_raw, %{fields | servo1_raw: 1900, servo2_raw: 0, servo3_raw: 1100}),
          1000
        )

      assert [1.0, nil, -1.0 | _] = Core.status(core).mavlink.thrusters
    end

    test "STATUSTEXT is logged with its severity" do
      for {severity, level} <- [
            {0, :error},
            {3, :error},
            {4, :warning},
            {5, :info},
            {6, :info},
            {7, :info}
          ] do
        {_core, actions} =
          Core.receive(linked(), msg(:statustext, %{severity: severity, text: "x"}), 1000)

        assert [{:log, ^level, "x", %{severity: ^severity}}] = actions
      end
    end

    test "messages of other systems are ignored" do
      core = linked()
      assert {^core, []} = Core.receive(core, msg(:vfr_hud, %{alt: -9.0}, 7), 1000)
      fresh = Core.new(0)
      assert {^fresh, []} = Core.receive(fresh, msg(:vfr_hud, %{alt: 1.0}), 1000)
    end
  end

  describe "lights and tilt" do
    test "lights → DO_SET_SERVO on the lights' servo, 1100..1900 µs" do
      {_, [{:send, :command_long, f}]} = Core.lights(linked(), 255)
      assert %{command: 183, param1: 9.0, param2: 1900.0} = f
      {_, [{:send, :command_long, f}]} = Core.lights(linked(lights_servo: 10), 0)
      assert %{param1: 10.0, param2: 1100.0} = f
    end

    test "tilt → DO_MOUNT_CONTROL pitch in degrees, MAVLink targeting" do
      {_, [{:send, :command_long, f}]} = Core.tilt(linked(), :math.pi() / 4)
      assert %{command: 205, param7: 2.0} = f
      assert_in_delta f.param1, 45.0, 1.0e-9
    end

    test "nothing before a vehicle is known" do
      assert {_, []} = Core.lights(Core.new(0), 10)
      assert {_, []} = Core.tilt(Core.new(0), 0.1)
    end
  end

  describe "the frame: which axes the vehicle has" do
    defp frame_value(value, system \\ 1),
      do:
        msg(
          :param_value,
          %{
            param_id: "FRAME_CONFIG",
            param_value: value * 1.0,
            param_type: 2,
            param_count: 1391,
            param_index: 7
          },
          system
        )

    defp frame_request?(f),
      do:
        match?(
          %{target_system: 1, target_component: 1, param_id: "FRAME_CONFIG", param_index: -1},
          f
        )

    test "asked as the link comes up; no sway until the vehicle answers" do
      core = Core.new(0)
      assert Core.axes(core) == [:surge, :heave, :yaw]
      {core, actions} = Core.receive(core, heartbeat(), 100)
      assert [request] = sends(actions, :param_request_read)
      assert frame_request?(request)
      assert Core.axes(core) == [:surge, :heave, :yaw]
      refute Enum.any?(actions, &match?({:axes, _}, &1))
      assert %{mavlink: %{frame: nil}} = Core.status(core)
    end

    test "asked again about once a second until answered, only while the link is up" do
      core = linked()
      {core, actions} = Core.tick(core, 1000)
      assert sends(actions, :param_request_read) == []
      {core, actions} = Core.tick(core, 1400)
      assert [request] = sends(actions, :param_request_read)
      assert frame_request?(request)
      {core, actions} = Core.tick(core, 1500)
      assert sends(actions, :param_request_read) == []

      # the link goes down: nobody to ask
      {core, _} = Core.tick(core, 4000)
      refute core.up
      {_core, actions} = Core.tick(core, 6000)
      assert sends(actions, :param_request_read) == []
    end

    test "a vectored frame strafes: sway declared, said once, not asked again" do
      core = linked()
      {core, actions} = Core.receive(core, frame_value(1), 600)
      assert {:axes, [:surge, :sway, :heave, :yaw]} in actions
      assert [{:log, :info, text, %{}}] = for({:log, _, _, _} = l <- actions, do: l)
      assert text =~ "Vectored (FRAME_CONFIG 1)"
      assert %{mavlink: %{frame: "Vectored"}} = Core.status(core)
      {core, actions} = Core.tick(core, 3000)
      assert sends(actions, :param_request_read) == []

      # the same answer again changes nothing
      assert {^core, []} = Core.receive(core, frame_value(1), 3100)
    end

    test "a SimpleROV-3 has no lateral thrust: no sway (the axes do not change), and it says so" do
      core = linked()
      {core, actions} = Core.receive(core, frame_value(4), 600)
      refute Enum.any?(actions, &match?({:axes, _}, &1))
      assert [{:log, :info, text, %{}}] = actions
      assert text =~ "SimpleROV-3 (FRAME_CONFIG 4), no lateral thrust"
      assert Core.axes(core) == [:surge, :heave, :yaw]
      assert %{mavlink: %{frame: "SimpleROV-3"}} = Core.status(core)
    end

    test "every frame of ArduSub's table: sway exactly where it has lateral thrust" do
      for {value, sway?} <-
            [{0, true}, {1, true}, {2, true}, {3, true}] ++
              [{4, false}, {5, false}, {6, true}] do
        {core, _} = Core.receive(linked(), frame_value(value), 600)
        assert :sway in Core.axes(core) == sway?, "FRAME_CONFIG #{value}"
      end
    end

    test "a frame it does not know (the custom frame, or any other value): no sway, a warning" do
      for value <- [7, 8, 255, -1] do
        {core, actions} = Core.receive(linked(), frame_value(value), 600)
        assert [{:log, :warning, text, %{}}] = actions
        assert text =~ "FRAME_CONFIG #{value} is not one Neptunus knows"
        assert Core.axes(core) == [:surge, :heave, :yaw]
        assert %{mavlink: %{frame: "FRAME_CONFIG " <> _}} = Core.status(core)
      end
    end

    test "kept while the link is down, asked again when it is back; a new frame changes the axes" do
      core = linked()
      {core, _} = Core.receive(core, frame_value(1), 600)
      {core, _} = Core.tick(core, 4000)
      refute core.up
      assert :sway in Core.axes(core)
      {core, actions} = Core.receive(core, heartbeat(), 5000)
      assert [_request] = sends(actions, :param_request_read)
      assert :sway in Core.axes(core)

      # the vehicle came back as a SimpleROV-3: sway goes
      {core, actions} = Core.receive(core, frame_value(4), 5100)
      assert {:axes, [:surge, :heave, :yaw]} in actions
      assert Core.axes(core) == [:surge, :heave, :yaw]
    end

    test "other parameters, other systems' answers and a value that is no number are not the frame" do
      core = linked()
      frame = frame_value(1)
      other = %{frame | fields: %{frame.fields | param_id: "FRAME_TYPE"}}
      assert {^core, []} = Core.receive(core, other, 600)
      assert {^core, []} = Core.receive(core, frame_value(1, 2), 600)
      nan = %{frame | fields: %{frame.fields | param_value: :nan}}
      assert {^core, []} = Core.receive(core, nan, 600)
      assert Core.axes(core) == [:surge, :heave, :yaw]
    end
  end
end

defmodule Neptunus.Vehicle.Board.MAVLink.CoreModesTest do
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink.Message
  alias Neptunus.Vehicle.Board.MAVLink.Core

  defp in_mode(mode) do
    fields = %{type: 12, autopilot: 3, base_mode: 209, custom_mode: mode, system_status: 4}

    m = %Message{
      id: 0,
      name: :heartbeat,
      system: 1,
      component: 1,
      seq: 0,
      version: 2,
      fields: fields
    }

    elem(Core.receive(Core.new(0), m, 100), 0)
  end

  defp mode_sent({_core, actions}) do
    case actions do
      [{:send, :command_long, %{command: 176, param1: 1.0, param2: mode}}] -> {:mode, round(mode)}
      [{:reply, :me, reply}] -> reply
    end
  end

  @manual 19
  @stabilize 0
  @alt_hold 2

  test "depth hold → ALT_HOLD, heading hold → STABILIZE, neither → MANUAL" do
    for {from, setpoints, expected} <- [
          {@manual, %{depth: :hold, heading: :hold}, {:mode, @alt_hold}},
          {@manual, %{depth: :hold, heading: :unchanged},
           {:error, "ArduSub's depth hold (ALT_HOLD) holds the heading too"}},
          {@stabilize, %{depth: :hold, heading: :unchanged}, {:mode, @alt_hold}},
          {@manual, %{depth: :unchanged, heading: :hold}, {:mode, @stabilize}},
          {@manual, %{depth: nil, heading: :hold}, {:mode, @stabilize}},
          {@alt_hold, %{depth: nil, heading: :unchanged}, {:mode, @stabilize}},
          {@alt_hold, %{depth: :unchanged, heading: nil},
           {:error, "ArduSub's depth hold (ALT_HOLD) holds the heading too"}},
          {@alt_hold, %{depth: nil, heading: nil}, {:mode, @manual}},
          {@stabilize, %{depth: :unchanged, heading: nil}, {:mode, @manual}},
          {@manual, %{depth: 3.0, heading: :unchanged},
           {:error, "ArduSub holds the depth it has when ALT_HOLD engages: use \"hold\""}},
          {@manual, %{depth: :unchanged, heading: 1.0},
           {:error, "ArduSub holds the heading it has when STABILIZE engages: use \"hold\""}}
        ] do
      assert mode_sent(Core.autopilot(in_mode(from), :me, setpoints, 1000)) == expected,
             "from #{from} with #{inspect(setpoints)}"
    end
  end

  test "the mode's ACK answers" do
    {core, _} = Core.autopilot(in_mode(@manual), :me, %{depth: :hold, heading: :hold}, 1000)

    ack = %Message{
      id: 77,
      name: :command_ack,
      system: 1,
      component: 1,
      seq: 1,
      version: 2,
      fields: %{command: 176, result: 0}
    }

    assert {_, [{:reply, :me, :ok}]} = Core.receive(core, ack, 1100)
  end

  test "vet refuses what ArduSub cannot fly, with a reason" do
    assert {:error, "manual per-thruster mode is not available" <> _} =
             Core.vet({:set_control_mode, :manual})

    assert {:error, "manual per-thruster" <> _} =
             Core.vet({:thrust, :manual, %{port: 0.0, vertical: 0.0, starboard: 0.0}})

    assert {:error, "dp is not available" <> _} = Core.vet({:set_control_mode, :dp})
    assert {:error, _} = Core.vet({:set_laser, 3})
    assert {:error, _} = Core.vet({:autopilot, %{depth: :hold, heading: :hold}})

    for ok <- [
          {:set_control_mode, :motion},
          {:thrust, :motion, %{surge: 0.1, heave: 0.0, yaw: 0.0}},
          {:set_gain, 0.5},
          {:set_lights, 10},
          {:set_tilt, 0.1},
          {:set_run_mode, :simulator}
        ] do
      assert Core.vet(ok) == :ok
    end
  end
end

defmodule Neptunus.Vehicle.Board.MAVLink.CoreTextTest do
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink.Message
  alias Neptunus.Vehicle.Board.MAVLink.Core

  defp msg(name, fields),
    do: %Message{id: 0, name: name, system: 1, component: 1, seq: 0, version: 2, fields: fields}

  defp linked do
    hb = %{type: 12, autopilot: 3, base_mode: 81, custom_mode: 19, system_status: 3}
    elem(Core.receive(Core.new(0), msg(:heartbeat, hb), 100), 0)
  end

  test "a long STATUSTEXT in chunks is one text, and answers a waiting command" do
    {core, _} = Core.arm(linked(), :me, true, 1000)
    first = String.duplicate("a", 50)

    {core, []} =
      Core.receive(core, msg(:statustext, %{severity: 2, text: first, id: 7, chunk_seq: 0}), 1000)

    {core, [{:log, :error, text, _}]} =
      Core.receive(core, msg(:statustext, %{severity: 2, text: "bc", id: 7, chunk_seq: 1}), 1000)

    assert text == first <> "bc"
    {_core, actions} = Core.receive(core, msg(:command_ack, %{command: 400, result: 4}), 1100)
    assert actions == [{:reply, :me, {:error, first <> "bc"}}]
  end

  test "a text of exactly 50 bytes ends with an empty chunk" do
    first = String.duplicate("z", 50)

    {core, []} =
      Core.receive(
        linked(),
        msg(:statustext, %{severity: 6, text: first, id: 3, chunk_seq: 0}),
        1000
      )

    assert {_, [{:log, :info, ^first, _}]} =
             Core.receive(
               core,
               msg(:statustext, %{severity: 6, text: "", id: 3, chunk_seq: 1}),
               1000
             )
  end
end

defmodule Neptunus.Vehicle.Board.MAVLink.CorePropertiesTest do
  use ExUnit.Case, async: true

  alias Neptunus.Protocol.MAVLink, as: Codec
  alias Neptunus.Protocol.MAVLink.Message
  alias Neptunus.Test.Properties
  alias Neptunus.Vehicle.Board.MAVLink.Core

  defp unit, do: :proper_types.float(-1.0, 1.0)

  test "MANUAL_CONTROL from any demand and gain: in range, encodable, neutral only from zero" do
    gain = :proper_types.float(0.05, 1.0)
    gen = :proper_types.tuple([unit(), unit(), unit(), unit(), gain])

    Properties.check(gen, fn {x, y, z, r, g} ->
      c = Core.manual_control(%{surge: x, sway: y, heave: z, yaw: r}, g)
      fields = Map.put(c, :target, 1)
      small? = fn v, scale -> round(scale * v / g) == 0 end

      c.x in -1000..1000 and c.y in -1000..1000 and c.r in -1000..1000 and c.z in 0..1000 and
        c.buttons == 0 and
        match?(
          {:ok, _},
          Codec.encode(:manual_control, fields, %{system: 255, component: 190, seq: 0})
        ) and
        c == Core.manual_control(%{surge: 0.0, sway: 0.0, heave: 0.0, yaw: 0.0}, 1.0) ==
          (small?.(x, 1000) and small?.(y, 1000) and small?.(z, 500) and small?.(r, 1000))
    end)
  end

  test "any PARAM_VALUE: sway exactly for a known frame with lateral thrust; axes told on change" do
    frames = Core.frames()
    value = :proper_types.oneof([:proper_types.integer(-10, 300), :proper_types.float()])

    id =
      :proper_types.oneof(
        Enum.map(["FRAME_CONFIG", "FRAME_TYPE", "SYSID"], &:proper_types.exactly/1)
      )

    Properties.check(:proper_types.list(:proper_types.tuple([id, value])), fn answers ->
      core = Core.new(0)
      heartbeat = %{type: 12, autopilot: 3, base_mode: 81, custom_mode: 19, system_status: 4}
      {core, _} = Core.receive(core, from_vehicle(:heartbeat, heartbeat), 100)

      {_core, ok?} =
        Enum.reduce(answers, {core, true}, fn {param_id, v}, {core, ok?} ->
          m =
            from_vehicle(:param_value, %{
              param_id: param_id,
              param_value: v * 1.0,
              param_type: 2,
              param_count: 1,
              param_index: 0
            })

          before = Core.axes(core)
          {next, actions} = Core.receive(core, m, 200)
          told = for {:axes, axes} <- actions, do: axes
          sway? = match?({_, true}, Map.get(frames, next.frame))

          {next,
           ok? and :sway in Core.axes(next) == sway? and
             told == if(Core.axes(next) == before, do: [], else: [Core.axes(next)]) and
             (param_id == "FRAME_CONFIG" or next == core)}
        end)

      ok?
    end)
  end

  # a message from the vehicle (system 1, component 1)
  defp from_vehicle(name, fields),
    do:
      struct!(Message,
        id: 0,
        name: name,
        system: 1,
        component: 1,
        seq: 0,
        version: 2,
        fields: fields
      )

  # whatever a vehicle sends, in any order, the core never crashes and its actions are of the
  # documented shapes
  test "any sequence of vehicle messages and ticks: no crash, documented actions" do
    fields = %{
      heartbeat: fn ->
        %{
          type: Enum.random([6, 12, 2]),
          autopilot: 3,
          base_mode: Enum.random(0..255),
          custom_mode: Enum.random(0..30),
          system_status: Enum.random(0..10)
        }
      end,
      attitude: fn ->
        %{
          time_boot_ms: Enum.random(0..100_000),
          roll: :rand.uniform(),
          pitch: :rand.uniform(),
          yaw: :rand.uniform() * 8 - 4
        }
      end,
      vfr_hud: fn -> %{alt: Enum.random([-3.0, 0.0, 1.5, :nan])} end,
      sys_status: fn ->
        %{
          voltage_battery: Enum.random([0, 15_000, 0xFFFF]),
          current_battery: Enum.random([-1, 0, 250])
        }
      end,
      statustext: fn ->
        %{severity: Enum.random(0..7), text: "t", id: Enum.random([0, 1, 2]), chunk_seq: 0}
      end,
      command_ack: fn -> %{command: Enum.random([400, 176, 183]), result: Enum.random(0..6)} end,
      timesync: fn -> %{tc1: Enum.random([0, 5]), ts1: Enum.random([0, 1_000_000_000, -1])} end,
      global_position_int: fn -> %{relative_alt: Enum.random([-2000, 0, 100])} end,
      servo_output_raw: fn ->
        Map.new(1..16, &{String.to_atom("servo#{&1}_raw"), Enum.random([0, 1100, 1500, 1900])})
      end
    }

    # a message is its name and a seed for its field values (so a counterexample replays)
    message =
      :proper_types.tuple([
        :proper_types.oneof(Enum.map(Map.keys(fields), &:proper_types.exactly/1)),
        :proper_types.pos_integer()
      ])

    step =
      :proper_types.oneof([:proper_types.exactly(:tick), :proper_types.exactly(:arm), message])

    Properties.check(
      :proper_types.list(step),
      fn steps ->
        {_core, _t, ok?} =
          Enum.reduce(steps, {Core.new(0), 0, true}, fn s, {core, t, ok?} ->
            t = t + 50

            {core, actions} =
              case s do
                :tick ->
                  Core.tick(core, t)

                :arm ->
                  Core.arm(core, :me, true, t)

                {name, seed} ->
                  :rand.seed(:exsss, {seed, 7, 11})
                  system = Enum.random([1, 2])

                  m = %Message{
                    id: 0,
                    name: name,
                    system: system,
                    component: 1,
                    seq: 0,
                    version: 2,
                    fields: fields[name].()
                  }

                  Core.receive(core, m, t)
              end

            shapes? =
              Enum.all?(actions, fn
                {:send, name, f} when is_atom(name) and is_map(f) ->
                  match?({:ok, _}, Codec.encode(name, f, %{system: 255, component: 190, seq: 0}))

                {:reply, :me, :ok} ->
                  true

                {:reply, :me, {:error, r}} when is_binary(r) ->
                  true

                {:link, %{up: up, reason: r}} when is_boolean(up) and is_binary(r) ->
                  true

                {:log, level, text, %{}}
                when level in [:info, :warning, :error] and is_binary(text) ->
                  true

                {:sample, %{t: t, measurement: m, sim: nil}} when is_float(t) and is_map(m) ->
                  true

                _ ->
                  false
              end)

            {core, t, ok? and shapes?}
          end)

        ok?
      end,
      200
    )
  end
end
