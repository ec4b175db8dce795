defmodule Neptunus.GCS.VehicleTest do
  use ExUnit.Case, async: true
  doctest Neptunus.GCS.Vehicle

  import Neptunus.Test.Properties

  alias Neptunus.GCS.{Party, Vehicle}
  alias Neptunus.Protocol.MAVLink

  @telemetry %{
    measurement: %{depth: 2.0, heading: 1.0, roll: 0.1, pitch: -0.1, voltage: 12.5, current: 3.25},
    measurement_state: %{
      depth: "valid",
      heading: "valid",
      roll: "valid",
      pitch: "valid",
      voltage: "valid",
      current: "valid"
    },
    estimate: %{
      depth: 2.0,
      depth_rate: 0.5,
      heading: 4.0,
      yaw_rate: 0.2,
      roll: 0.1,
      roll_rate: 0.0,
      pitch: -0.1,
      pitch_rate: 0.0
    },
    sim: nil,
    thrusters: %{
      port: 0.5,
      vertical: -0.25,
      starboard: 0.5,
      port_us: 1700,
      vertical_us: 1400,
      starboard_us: 1700
    },
    control: %{
      mode: "motion",
      gain: 0.5,
      lights: 100,
      tilt: :math.pi() / 8,
      autopilot: %{depth: nil, heading: 4.0}
    },
    link: %{up: true, reason: "open"}
  }

  defp vehicle(telemetry \\ @telemetry, helm \\ nil) do
    %{Vehicle.new("rov", 1, :simulated, 0) | telemetry: telemetry, helm: helm}
  end

  defp encodes?(name, fields),
    do: match?({:ok, _}, MAVLink.encode(name, fields, %{system: 1, component: 1, seq: 0}))

  test "a submarine with a generic autopilot; mode, armed and state from the vehicle" do
    hb = Vehicle.heartbeat(vehicle())
    assert %{type: 12, autopilot: 0, custom_mode: 0, system_status: 3} = hb
    # custom mode enabled, manual input enabled, not armed
    assert hb.base_mode == 65

    piloted = vehicle(@telemetry, %{pilot: %{id: "x", name: "ada"}})
    assert %{base_mode: 193, system_status: 4} = Vehicle.heartbeat(piloted)

    assert %{system_status: 1} = Vehicle.heartbeat(vehicle(nil))

    assert %{system_status: 5} =
             Vehicle.heartbeat(vehicle(%{@telemetry | link: %{up: false, reason: "hangup"}}))
  end

  test "an ArduSub vehicle: its own arming, mode and state" do
    t =
      put_in(@telemetry.link, %{
        up: true,
        reason: "heartbeat",
        mavlink: %{armed: true, mode: "ALT_HOLD", system_status: "active"}
      })

    assert %{base_mode: 193, custom_mode: 2, system_status: 4} = Vehicle.heartbeat(vehicle(t))

    t =
      put_in(t.link.mavlink, %{
        armed: false,
        mode: "MANUAL",
        system_status: "standby",
        servo_us: [1500, 1600, 0],
        loss: 0.015
      })

    v = vehicle(t, %{pilot: %{id: "x"}})
    assert %{base_mode: 65, custom_mode: 19, system_status: 3} = Vehicle.heartbeat(v)
    streamed = Vehicle.streamed(v, 1_000, 0)

    assert %{servo1_raw: 1500, servo2_raw: 1600, servo3_raw: 0, servo8_raw: 0} =
             streamed.servo_output_raw

    assert streamed.sys_status.drop_rate_comm == 150
  end

  test "the streamed messages: attitude, depth as altitude, pressure, thrusters, named values" do
    s = Vehicle.streamed(vehicle(), 1_234, 1_700_000_000_000_000)
    assert %{roll: 0.1, pitch: -0.1, yawspeed: 0.2, time_boot_ms: 1_234} = s.attitude
    assert_in_delta s.attitude.yaw, 4.0 - 2 * :math.pi(), 1.0e-12
    assert %{alt: -2.0, climb: -0.5, heading: 229, throttle: 25} = s.vfr_hud
    assert_in_delta s.scaled_pressure.press_abs, 1013.25 + 2 * 100.518, 0.01

    assert %{servo1_raw: 1700, servo2_raw: 1400, servo3_raw: 1700, servo4_raw: 0} =
             s.servo_output_raw

    assert [
             %{name: "lights", value: 100.0},
             %{name: "tilt_deg", value: tilt},
             %{name: "gain", value: 0.5}
           ] = s.named_value_float

    assert_in_delta tilt, 22.5, 1.0e-9
    assert %{voltage_battery: 12_500, current_battery: 325, battery_remaining: -1} = s.sys_status
    assert s.system_time.time_unix_usec == 1_700_000_000_000_000
    refute Map.has_key?(s, :local_position_ned)
  end

  test "what is not known: no attitude before a heading, MAVLink's unknown battery, no position" do
    t = %{
      @telemetry
      | measurement: %{
          depth: nil,
          heading: nil,
          roll: nil,
          pitch: nil,
          voltage: nil,
          current: nil
        },
        estimate: %{depth: nil, heading: nil}
    }

    s = Vehicle.streamed(vehicle(t), 0, 0)
    refute Map.has_key?(s, :attitude)
    refute Map.has_key?(s, :scaled_pressure)
    assert %{voltage_battery: 0xFFFF, current_battery: -1} = s.sys_status
    assert s.vfr_hud.alt == 0.0

    s = Vehicle.streamed(vehicle(nil), 0, 0)
    assert Map.keys(s) |> Enum.sort() == [:control_status, :heartbeat, :sys_status, :system_time]
  end

  test "sensor health follows the measurement states" do
    states = %{@telemetry.measurement_state | depth: "stale", voltage: "initialising"}
    s = Vehicle.streamed(vehicle(%{@telemetry | measurement_state: states}), 0, 0).sys_status
    assert Bitwise.band(s.onboard_control_sensors_present, 8) == 8
    assert Bitwise.band(s.onboard_control_sensors_health, 8) == 0
    assert Bitwise.band(s.onboard_control_sensors_health, 4) == 4
  end

  @position %{
    valid: true,
    reason: nil,
    frame: "usbl",
    epoch: 2,
    north: 3.0,
    east: -1.0,
    depth: 2.5,
    velocity_north: 0.25,
    velocity_east: -0.5,
    std_north: 0.3,
    std_east: 0.2,
    ellipse: %{major: 0.3, minor: 0.2, angle: 0.0},
    sources: []
  }

  @truth %{
    x: 40.0,
    y: 50.0,
    z: 2.0,
    phi: 0.0,
    theta: 0.0,
    psi: 1.0,
    u: 1.0,
    v: 0.0,
    w: 0.1,
    p: 0.0,
    q: 0.0,
    r: 0.0
  }

  describe "LOCAL_POSITION_NED" do
    test "the position filter's valid estimate, NED: x north, y east, z the depth, vz the depth rate" do
      s = Vehicle.streamed(vehicle(Map.put(@telemetry, :position, @position)), 1_500, 0)

      assert %{
               time_boot_ms: 1_500,
               x: 3.0,
               y: -1.0,
               z: 2.5,
               vx: 0.25,
               vy: -0.5,
               vz: 0.5
             } == s.local_position_ned

      assert encodes?(:local_position_ned, s.local_position_ned)
      # VFR_HUD's ground speed is the estimate's too
      assert_in_delta s.vfr_hud.groundspeed, :math.sqrt(0.25 ** 2 + 0.5 ** 2), 1.0e-12
      # a USBL's frame has no geodetic origin: no GLOBAL_POSITION_INT
      refute Map.has_key?(s, :global_position_int)
    end

    test "the depth estimate where the position has no depth; unknown velocities 0" do
      position = %{@position | depth: nil, velocity_north: nil, velocity_east: nil}
      s = Vehicle.streamed(vehicle(Map.put(@telemetry, :position, position)), 0, 0)
      assert %{z: 2.0, vx: +0.0, vy: +0.0} = s.local_position_ned
    end

    test "not sent without a valid position, whatever the simulator's truth" do
      no_position = %{
        @position
        | valid: false,
          reason: "no position source",
          frame: nil,
          north: nil,
          east: nil
      }

      untrusted = %{@position | valid: false, reason: "position uncertainty 3.4 m beyond 3.0 m"}

      for position <- [no_position, untrusted] do
        telemetry = @telemetry |> Map.put(:position, position) |> Map.put(:sim, @truth)
        refute Map.has_key?(Vehicle.streamed(vehicle(telemetry), 0, 0), :local_position_ned)
      end

      # a simulated vehicle without position sources: the truth is not its position, nor
      # its speed
      s = Vehicle.streamed(vehicle(%{@telemetry | sim: @truth}), 0, 0)
      refute Map.has_key?(s, :local_position_ned)
      assert s.vfr_hud.groundspeed == 0.0
    end

    test "GLOBAL_POSITION_INT where the frame has a geodetic origin (an ArduSub's): the origin plus the offset" do
      deg = :math.pi() / 180
      origin = %{lat: 59.8 * deg, lon: 10.7 * deg}
      position = %{@position | frame: "ardusub"} |> Map.put(:origin, origin)
      s = Vehicle.streamed(vehicle(Map.put(@telemetry, :position, position)), 1_500, 0)
      here = Neptunus.Navigation.Geo.offset(origin, 3.0, -1.0)

      assert %{
               time_boot_ms: 1_500,
               relative_alt: -2500,
               alt: -2500,
               vx: 25,
               vy: -50,
               vz: 50,
               # the heading estimate, 4 rad
               hdg: 22_918
             } = s.global_position_int

      assert s.global_position_int.lat == round(here.lat / deg * 1.0e7)
      assert s.global_position_int.lon == round(here.lon / deg * 1.0e7)
      # 3 m north of the origin: 269 degE7 of latitude (one is 1.1 cm)
      assert s.global_position_int.lat - 598_000_000 == 269
      assert encodes?(:global_position_int, s.global_position_int)
      assert %{x: 3.0, y: -1.0} = s.local_position_ned

      # no valid position: neither
      invalid = %{position | valid: false, reason: "no position measurement for a while: …"}
      s = Vehicle.streamed(vehicle(Map.put(@telemetry, :position, invalid)), 0, 0)
      refute Map.has_key?(s, :global_position_int) or Map.has_key?(s, :local_position_ned)
    end

    test "any valid estimate encodes" do
      check(
        :proper_types.tuple(List.duplicate(:proper_types.float(), 5)),
        fn {n, e, d, vn, ve} ->
          position = %{
            @position
            | north: n,
              east: e,
              depth: d,
              velocity_north: vn,
              velocity_east: ve
          }

          position = Map.put(position, :origin, %{lat: 1.0, lon: -3.0})
          s = Vehicle.streamed(vehicle(Map.put(@telemetry, :position, position)), 0, 0)

          encodes?(:local_position_ned, s.local_position_ned) and
            encodes?(:global_position_int, s.global_position_int)
        end
      )
    end
  end

  test "CONTROL_STATUS: the ground station holding the helm, 0 for a browser or nobody" do
    gcs = %{pilot: %{id: Party.id(250, "udpin0/1.2.3.4:5"), name: "qgc"}}
    assert %{sysid_in_control: 250, flags: 1} = Vehicle.control_status(vehicle(@telemetry, gcs))

    assert %{sysid_in_control: 0} =
             Vehicle.control_status(vehicle(@telemetry, %{pilot: %{id: "c-1"}}))

    assert %{sysid_in_control: 0} = Vehicle.control_status(vehicle(@telemetry, %{pilot: nil}))
  end

  test "every streamed message and AUTOPILOT_VERSION encode" do
    telemetry = Map.put(@telemetry, :position, @position)

    for {name, fields} <-
          Vehicle.streamed(vehicle(telemetry), 5_000_000_000, 1_700_000_000_000_000),
        f <- List.wrap(fields),
        do: assert(encodes?(name, f), "#{name} #{inspect(f)}")

    assert encodes?(:autopilot_version, Vehicle.autopilot_version(1, "0.1.0"))
    assert %{flight_sw_version: 0x00010200} = Vehicle.autopilot_version(1, "0.1.2")
  end

  test "long texts are chunked at character boundaries, each chunk encodable" do
    text = String.duplicate("é", 60) <> String.duplicate("x", 61)
    chunks = Vehicle.statustext(4, text, 9)
    assert Enum.map(chunks, &byte_size(&1.text)) == [50, 50, 50, 31]
    assert Enum.map(chunks, & &1.id) == [9, 9, 9, 9]

    # chunk_seq is one byte: 256 chunks at most, the rest of a longer text is not sent
    chunks = Vehicle.statustext(6, String.duplicate("é", 7000), 9)
    assert length(chunks) == 256 and List.last(chunks).chunk_seq == 255

    long = :proper_types.bind(:proper_types.list(:proper_unicode.utf8()), &Enum.join/1, false)

    check(long, fn text ->
      chunks = Vehicle.statustext(6, text, 9)
      sent = Enum.map_join(chunks, & &1.text)
      text = String.replace(text, <<0>>, "")

      # all of it, or (chunk_seq is one byte) the first 256 chunks of it
      (sent == text or (length(chunks) == 256 and String.starts_with?(text, sent))) and
        Enum.all?(chunks, &(byte_size(&1.text) <= 50 and String.valid?(&1.text))) and
        Enum.all?(chunks, &encodes?(:statustext, &1)) and
        (length(chunks) == 1 or
           Enum.map(chunks, & &1.chunk_seq) == Enum.to_list(0..(length(chunks) - 1)))
    end)
  end
end
