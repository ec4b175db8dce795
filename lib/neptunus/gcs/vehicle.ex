defmodule Neptunus.GCS.Vehicle do
  @moduledoc """
  What one vehicle says as a MAVLink system (pure): its messages built from what the node
  knows of it — the latest `telemetry` broadcast, the `helm`, the board — as the fields
  `Neptunus.Protocol.MAVLink.encode/4` takes. `Neptunus.GCS.Source` builds them once per tick
  and encodes each once for every ground station.

  A vehicle (`t:t/0`) is `%{id, sysid, board, boot_ms, telemetry, helm}`: `telemetry` the
  latest payload (nil before the first), `helm` the latest `helm` broadcast (nil until known).

  ## Identity

  Every vehicle is a submarine (`MAV_TYPE_SUBMARINE`, 12) with a generic autopilot
  (`MAV_AUTOPILOT_GENERIC`, 0) on component 1 (`MAV_COMP_ID_AUTOPILOT1`): the autopilot a
  ground station talks to is Neptunus — its helm, its parameters, its modes — also for an
  ArduSub vehicle, whose own autopilot sits behind the `mavlink` board (docs/MAVLINK.md says
  why). `custom_mode` is `Neptunus.GCS.Modes`'; `base_mode` has CUSTOM_MODE_ENABLED (1),
  MANUAL_INPUT_ENABLED (64) and SAFETY_ARMED (128) while armed: an ArduSub vehicle's own
  arming, or, on a board without arming, while someone holds the helm (only then do the
  thrusters answer). `system_status` (MAV_STATE): BOOT before the first telemetry, CRITICAL
  while the board link is down, ACTIVE while armed, STANDBY otherwise (an ArduSub vehicle's
  own state when it reports one).

  ## Messages

    * SYS_STATUS — sensors present, enabled and healthy (IMU and compass: attitude and
      heading; absolute pressure: depth; battery: voltage; motor outputs; AHRS: the
      estimate), each healthy while its measurement is `valid`; battery volts (mV) and amps
      (cA), unknown as MAVLink says (UINT16_MAX, −1); `drop_rate_comm` a mavlink vehicle's
      link loss (c%).
    * ATTITUDE — roll, pitch, yaw (heading in [−π, π)) and their rates from the estimate
      (measurements where the estimate has none; 0 where neither is known); not sent before
      the heading is known.
    * VFR_HUD — heading (deg), altitude = −depth (m), climb = −depth rate (m/s), throttle =
      |vertical thrust| (%), ground speed the valid position's horizontal speed (m/s; 0
      without one).
    * SCALED_PRESSURE — absolute pressure from depth (sea water: 1013.25 hPa + 1025 kg/m³ ·
      g · depth), temperature 0 (no sensor reports it).
    * SERVO_OUTPUT_RAW — the thrusters' PWM (µs) in `go()` order (port, vertical,
      starboard); an ArduSub vehicle's own outputs 1..8.
    * NAMED_VALUE_FLOAT — `lights` (0..255), `tilt_deg` (camera tilt, degrees), `gain`
      (0..1).
    * SYSTEM_TIME — the node's wall clock and the time since the vehicle's source started.
    * LOCAL_POSITION_NED — while the vehicle has a valid position (`position/1`: the
      position filter's estimate from its DVL, USBL or ArduSub position, telemetry's
      `position`): x north, y east, z down (the depth), vx, vy the estimate's velocity, vz
      the depth rate; in the estimate's frame (`local`: from where the DVL started, `usbl`:
      the topside's, `ardusub`: the vehicle's own), whose origin may move (a frame change:
      docs/POSITION.md). Never the simulator's truth: a ground station sees what Neptunus
      knows.
    * GLOBAL_POSITION_INT — as LOCAL_POSITION_NED, while the estimate's frame has a known
      geodetic origin (telemetry's `position.origin`: an ArduSub vehicle's own frame): its
      latitude and longitude (degE7) from the origin and the offset (`Neptunus.Navigation.Geo`),
      `relative_alt` and `alt` −depth (mm; the surface taken as sea level), velocities (cm/s),
      `hdg` the heading (cdeg, UINT16_MAX unknown). A DVL's and a USBL's frames have no
      geodetic origin: no GLOBAL_POSITION_INT for them (docs/MAVLINK.md).
    * CONTROL_STATUS — who flies: `sysid_in_control` the system id of the ground station
      holding the helm (0 when none does: a free helm, or a browser pilot), flags
      GCS_CONTROL_STATUS_FLAGS_SYSTEM_MANAGER (1).
    * AUTOPILOT_VERSION — on request: capabilities MAVLINK2, PARAM_FLOAT, COMMAND_INT,
      PARAM_ENCODE_C_CAST and COMPONENT_ACCEPTS_GCS_CONTROL; the node's version.
  """

  alias Neptunus.GCS.{Modes, Party}
  alias Neptunus.Navigation.Geo

  @component 1
  @mav_type_submarine 12
  @mav_autopilot_generic 0

  # MAV_MODE_FLAG
  @custom_mode_enabled 1
  @manual_input_enabled 64
  @safety_armed 128

  # MAV_STATE
  @boot 1
  @standby 3
  @active 4
  @critical 5
  @states ~w(uninit boot calibrating standby active critical emergency poweroff flight_termination)

  # MAV_SYS_STATUS_SENSOR
  @gyro 1
  @accel 2
  @mag 4
  @pressure 8
  @motors 32_768
  @ahrs 2_097_152
  @battery 33_554_432

  # MAV_PROTOCOL_CAPABILITY
  @capabilities Bitwise.bor(
                  Bitwise.bor(2, 8),
                  Bitwise.bor(8192, Bitwise.bor(131_072, 524_288))
                )

  # SYS_STATUS while nothing is known (no telemetry yet): no sensors, voltage and current
  # unknown (UINT16_MAX, -1); what telemetry tells replaces its fields
  @unknown_sys_status %{
    onboard_control_sensors_present: 0,
    onboard_control_sensors_enabled: 0,
    onboard_control_sensors_health: 0,
    load: 0,
    voltage_battery: 0xFFFF,
    current_battery: -1,
    battery_remaining: -1,
    drop_rate_comm: 0,
    errors_comm: 0,
    errors_count1: 0,
    errors_count2: 0,
    errors_count3: 0,
    errors_count4: 0
  }

  @surface_hpa 1013.25
  # hPa per metre of sea water (1025 kg/m³ · 9.80665 m/s² / 100 Pa/hPa)
  @hpa_per_m 1025 * 9.80665 / 100

  @type t :: %{
          required(:id) => String.t(),
          required(:sysid) => 1..255,
          required(:board) => atom(),
          required(:boot_ms) => integer(),
          required(:telemetry) => map() | nil,
          required(:helm) => map() | nil,
          optional(atom()) => term()
        }

  @typedoc "A message to encode: its name and fields."
  @type message :: {atom(), map()}

  @doc "The component id every vehicle speaks from (the autopilot's, 1)."
  @spec component() :: 1
  def component, do: @component

  @doc "A vehicle as its source starts: nothing known yet."
  @spec new(String.t(), 1..255, atom(), integer()) :: t()
  def new(id, sysid, board, now_ms),
    do: %{id: id, sysid: sysid, board: board, boot_ms: now_ms, telemetry: nil, helm: nil}

  @doc """
  The messages the vehicle streams at `now_ms` (monotonic) and `wall_us` (Unix µs), by
  message name: each one `{name, fields}` — NAMED_VALUE_FLOAT a list of three — leaving out
  those it cannot say yet (ATTITUDE before the heading is known, LOCAL_POSITION_NED without a
  position).
  """
  @spec streamed(t(), integer(), integer()) :: %{atom() => map() | [map()]}
  def streamed(vehicle, now_ms, wall_us) do
    boot = boot_ms(vehicle, now_ms)
    t = vehicle.telemetry

    %{
      heartbeat: heartbeat(vehicle),
      sys_status: sys_status(vehicle),
      control_status: control_status(vehicle),
      system_time: %{time_unix_usec: max(wall_us, 0), time_boot_ms: boot}
    }
    |> put_some(:attitude, t && attitude(t, boot))
    |> put_some(:vfr_hud, t && vfr_hud(t))
    |> put_some(:scaled_pressure, t && scaled_pressure(t, boot))
    |> put_some(:servo_output_raw, t && servo_output_raw(t, boot))
    |> put_some(:named_value_float, t && named_values(t, boot))
    |> put_some(:local_position_ned, t && local_position(t, boot))
    |> put_some(:global_position_int, t && global_position(t, boot))
  end

  defp put_some(map, _key, nil), do: map
  defp put_some(map, key, value), do: Map.put(map, key, value)

  defp boot_ms(vehicle, now_ms), do: rem(max(now_ms - vehicle.boot_ms, 0), 0x1_0000_0000)

  @doc "HEARTBEAT (see the moduledoc)."
  @spec heartbeat(t()) :: map()
  def heartbeat(vehicle) do
    t = vehicle.telemetry
    armed = armed?(vehicle)

    %{
      type: @mav_type_submarine,
      autopilot: @mav_autopilot_generic,
      base_mode:
        Bitwise.bor(
          Bitwise.bor(@custom_mode_enabled, @manual_input_enabled),
          if(armed, do: @safety_armed, else: 0)
        ),
      custom_mode: custom_mode(vehicle),
      system_status: system_status(t, armed)
    }
  end

  @doc "The flight mode number (`Neptunus.GCS.Modes`)."
  @spec custom_mode(t()) :: non_neg_integer()
  def custom_mode(%{telemetry: t}) do
    Modes.current(t && t[:control], t && get_in(t, [:link, :mavlink, :mode]))
  end

  @doc """
  Whether the vehicle is armed: an ArduSub vehicle's own arming; on a board without arming,
  whether someone holds the helm.
  """
  @spec armed?(t()) :: boolean()
  def armed?(%{telemetry: t, helm: helm}) do
    case t && get_in(t, [:link, :mavlink]) do
      %{armed: armed} -> armed == true
      _ -> match?(%{pilot: %{}}, helm)
    end
  end

  defp system_status(nil, _armed), do: @boot

  defp system_status(t, armed) do
    own = get_in(t, [:link, :mavlink, :system_status])

    cond do
      is_binary(own) and own in @states -> Enum.find_index(@states, &(&1 == own))
      get_in(t, [:link, :up]) == false -> @critical
      armed -> @active
      true -> @standby
    end
  end

  @doc "CONTROL_STATUS: the system id of the ground station holding the helm (0: none)."
  @spec control_status(t()) :: map()
  def control_status(%{helm: helm}) do
    pilot_sysid =
      case helm do
        %{pilot: %{id: id}} -> Party.sysid(id) || 0
        _ -> 0
      end

    %{sysid_in_control: pilot_sysid, flags: 1}
  end

  defp sys_status(%{telemetry: nil}), do: @unknown_sys_status

  defp sys_status(%{telemetry: t}) do
    m = t[:measurement] || %{}
    states = t[:measurement_state] || %{}
    valid? = fn field -> states[field] == "valid" end

    sensors = [
      {Bitwise.bor(@gyro, @accel), m[:roll] != nil or m[:pitch] != nil,
       valid?.(:roll) or valid?.(:pitch)},
      {@mag, m[:heading] != nil or valid?.(:heading), valid?.(:heading)},
      {@pressure, m[:depth] != nil or valid?.(:depth), valid?.(:depth)},
      {@battery, m[:voltage] != nil, valid?.(:voltage)},
      {@motors, true, get_in(t, [:link, :up]) != false},
      {@ahrs, get_in(t, [:estimate, :heading]) != nil, get_in(t, [:estimate, :heading]) != nil}
    ]

    present = for {bit, true, _} <- sensors, reduce: 0, do: (acc -> Bitwise.bor(acc, bit))
    healthy = for {bit, true, true} <- sensors, reduce: 0, do: (acc -> Bitwise.bor(acc, bit))
    loss = get_in(t, [:link, :mavlink, :loss])

    %{
      @unknown_sys_status
      | onboard_control_sensors_present: present,
        onboard_control_sensors_enabled: present,
        onboard_control_sensors_health: healthy,
        voltage_battery: scaled(m[:voltage], 1000, 0, 0xFFFE, 0xFFFF),
        current_battery: scaled(m[:current], 100, -1, 0x7FFF, -1),
        drop_rate_comm: if(is_number(loss), do: round(min(max(loss, 0), 1) * 10_000), else: 0)
    }
  end

  defp scaled(value, factor, lo, hi, _unknown) when is_number(value),
    do: round(value * factor) |> max(lo) |> min(hi)

  defp scaled(_value, _factor, _lo, _hi, unknown), do: unknown

  defp attitude(t, boot) do
    case angle(t, :heading) do
      nil ->
        nil

      heading ->
        %{
          time_boot_ms: boot,
          roll: angle(t, :roll) || 0.0,
          pitch: angle(t, :pitch) || 0.0,
          yaw: wrap_pi(heading),
          rollspeed: number(get_in(t, [:estimate, :roll_rate])),
          pitchspeed: number(get_in(t, [:estimate, :pitch_rate])),
          yawspeed: number(get_in(t, [:estimate, :yaw_rate]))
        }
    end
  end

  defp vfr_hud(t) do
    depth = depth(t)
    vertical = get_in(t, [:thrusters, :vertical])

    %{
      airspeed: 0.0,
      groundspeed:
        case position(t) do
          nil -> 0.0
          p -> :math.sqrt(p.velocity_north * p.velocity_north + p.velocity_east * p.velocity_east)
        end,
      heading:
        case angle(t, :heading) do
          nil -> 0
          h -> rem(round(h * 180 / :math.pi()), 360) |> Kernel.+(360) |> rem(360)
        end,
      throttle: if(is_number(vertical), do: min(round(abs(vertical) * 100), 100), else: 0),
      alt: if(depth, do: -depth, else: 0.0),
      climb: -number(get_in(t, [:estimate, :depth_rate]))
    }
  end

  defp scaled_pressure(t, boot) do
    case depth(t) do
      nil ->
        nil

      depth ->
        %{
          time_boot_ms: boot,
          press_abs: @surface_hpa + @hpa_per_m * depth,
          press_diff: 0.0,
          temperature: 0
        }
    end
  end

  defp servo_output_raw(t, boot) do
    outputs =
      case get_in(t, [:link, :mavlink, :servo_us]) do
        [_ | _] = us ->
          us

        _ ->
          thrusters = t[:thrusters] || %{}
          for key <- [:port_us, :vertical_us, :starboard_us], do: thrusters[key] || 0
      end

    outputs = outputs |> Enum.map(&pwm/1) |> Enum.take(8)
    padded = outputs ++ List.duplicate(0, 8 - length(outputs))

    for({us, i} <- Enum.with_index(padded, 1), into: %{}, do: {:"servo#{i}_raw", us})
    |> Map.merge(%{time_usec: rem(boot * 1000, 0x1_0000_0000), port: 0})
  end

  defp pwm(us) when is_integer(us) and us in 0..0xFFFF, do: us
  defp pwm(_), do: 0

  defp named_values(t, boot) do
    case t[:control] do
      %{gain: gain, lights: lights, tilt: tilt} ->
        [
          %{time_boot_ms: boot, name: "lights", value: lights * 1.0},
          %{time_boot_ms: boot, name: "tilt_deg", value: tilt * 180 / :math.pi()},
          %{time_boot_ms: boot, name: "gain", value: gain * 1.0}
        ]

      _ ->
        nil
    end
  end

  defp local_position(t, boot) do
    case position(t) do
      nil ->
        nil

      p ->
        %{
          time_boot_ms: boot,
          x: p.north,
          y: p.east,
          z: p.depth,
          vx: p.velocity_north,
          vy: p.velocity_east,
          vz: p.depth_rate
        }
    end
  end

  defp global_position(t, boot) do
    with %{} = p <- position(t),
         %{lat: lat0, lon: lon0} when is_number(lat0) and is_number(lon0) <-
           get_in(t, [:position, :origin]) do
      %{lat: lat, lon: lon} = Geo.offset(%{lat: lat0, lon: lon0}, p.north, p.east)

      %{
        time_boot_ms: boot,
        lat: int(lat * 180 / :math.pi() * 1.0e7, 0x7FFF_FFFF),
        lon: int(lon * 180 / :math.pi() * 1.0e7, 0x7FFF_FFFF),
        alt: int(-p.depth * 1000, 0x7FFF_FFFF),
        relative_alt: int(-p.depth * 1000, 0x7FFF_FFFF),
        vx: int(p.velocity_north * 100, 0x7FFF),
        vy: int(p.velocity_east * 100, 0x7FFF),
        vz: int(p.depth_rate * 100, 0x7FFF),
        hdg:
          case angle(t, :heading) do
            nil -> 0xFFFF
            h -> rem(rem(round(h * 18_000 / :math.pi()), 36_000) + 36_000, 36_000)
          end
      }
    else
      _ -> nil
    end
  end

  # a signed integer field of at most `max`
  defp int(value, max), do: value |> round() |> max(-max) |> min(max)

  @doc """
  The vehicle's position in its telemetry, NED: `%{north, east, depth, velocity_north,
  velocity_east, depth_rate}` (m, m/s; velocities 0.0 where the estimate has none, depth the
  position's, else the depth estimate's, else 0.0), or nil while the position filter has no
  valid position — an estimate navigation does not trust (too uncertain, its sources silent)
  is not a position.

      iex> Neptunus.GCS.Vehicle.position(%{position: %{valid: true, north: 1.0, east: 2, depth: 3.0,
      ...>   velocity_north: 0.5, velocity_east: nil}, estimate: %{depth_rate: 0.1}})
      %{north: 1.0, east: 2.0, depth: 3.0, velocity_north: 0.5, velocity_east: 0.0, depth_rate: 0.1}
      iex> Neptunus.GCS.Vehicle.position(%{position: %{valid: false, north: 1.0, east: 2.0}})
      nil
      iex> Neptunus.GCS.Vehicle.position(%{sim: %{x: 1.0, y: 2.0}})
      nil
  """
  @spec position(map()) :: map() | nil
  def position(%{position: %{valid: true, north: north, east: east} = p} = t)
      when is_number(north) and is_number(east) do
    %{
      north: north * 1.0,
      east: east * 1.0,
      depth: if(is_number(p[:depth]), do: p.depth * 1.0, else: depth(t) || 0.0),
      velocity_north: number(p[:velocity_north]),
      velocity_east: number(p[:velocity_east]),
      depth_rate: number(get_in(t, [:estimate, :depth_rate]))
    }
  end

  def position(_telemetry), do: nil

  @doc "AUTOPILOT_VERSION of vehicle `sysid` with the node's version `\"X.Y.Z\"`."
  @spec autopilot_version(1..255, String.t()) :: map()
  def autopilot_version(sysid, version) do
    [major, minor, patch] =
      case version |> String.split(["."]) |> Enum.map(&Integer.parse/1) do
        [{a, _}, {b, _}, {c, _} | _] -> [a, b, c]
        _ -> [0, 0, 0]
      end

    %{
      capabilities: @capabilities,
      # major.minor.patch and FIRMWARE_VERSION_TYPE_DEV (0)
      flight_sw_version:
        Bitwise.bor(
          Bitwise.bor(Bitwise.bsl(min(major, 255), 24), Bitwise.bsl(min(minor, 255), 16)),
          Bitwise.bsl(min(patch, 255), 8)
        ),
      middleware_sw_version: 0,
      os_sw_version: 0,
      board_version: 0,
      flight_custom_version: List.duplicate(0, 8),
      middleware_custom_version: List.duplicate(0, 8),
      os_custom_version: List.duplicate(0, 8),
      vendor_id: 0,
      product_id: 0,
      uid: sysid
    }
  end

  defp depth(t) do
    case get_in(t, [:estimate, :depth]) || get_in(t, [:measurement, :depth]) do
      d when is_number(d) -> d * 1.0
      _ -> nil
    end
  end

  defp angle(t, key) do
    case get_in(t, [:estimate, key]) || get_in(t, [:measurement, key]) do
      a when is_number(a) -> a * 1.0
      _ -> nil
    end
  end

  defp number(x) when is_number(x), do: x * 1.0
  defp number(_), do: 0.0

  defp wrap_pi(a) do
    two_pi = 2 * :math.pi()
    a = :math.fmod(a + :math.pi(), two_pi)
    if a < 0, do: a + two_pi - :math.pi(), else: a - :math.pi()
  end

  @doc """
  STATUSTEXT messages for a text at a MAV_SEVERITY (0 emergency … 7 debug): at most 50
  bytes each, cut at UTF-8 character boundaries; a longer text in chunks sharing a
  non-zero `id` with `chunk_seq` 0, 1, … (MAVLink 2's chunked STATUSTEXT). `chunk_seq` is
  one byte: a text longer than 256 chunks (about 12 KB) is cut after the 256th.

      iex> [one] = Neptunus.GCS.Vehicle.statustext(4, "stopped: deadman", 7)
      iex> one
      %{severity: 4, text: "stopped: deadman", id: 0, chunk_seq: 0}
  """
  @spec statustext(0..7, String.t(), 1..0xFFFF) :: [map()]
  def statustext(severity, text, id) do
    # a STATUSTEXT's text has no NUL (it ends the string)
    text = String.replace(text, <<0>>, "")

    case chunks(text, []) do
      [one] ->
        [%{severity: severity, text: one, id: 0, chunk_seq: 0}]

      many ->
        many
        |> Enum.take(256)
        |> Enum.with_index()
        |> Enum.map(fn {chunk, i} -> %{severity: severity, text: chunk, id: id, chunk_seq: i} end)
    end
  end

  defp chunks(text, acc) when byte_size(text) <= 50, do: Enum.reverse([text | acc])

  defp chunks(text, acc) do
    cut = cut_at(text, 50)
    <<chunk::binary-size(cut), rest::binary>> = text
    chunks(rest, [chunk | acc])
  end

  # the largest cut ≤ n that does not split a UTF-8 character (a continuation byte 10xxxxxx)
  defp cut_at(text, n) do
    case :binary.at(text, n) do
      byte when Bitwise.band(byte, 0xC0) == 0x80 and n > 1 -> cut_at(text, n - 1)
      _ -> n
    end
  end
end
