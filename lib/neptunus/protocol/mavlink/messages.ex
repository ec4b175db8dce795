defmodule Neptunus.Protocol.MAVLink.Messages do
  @moduledoc """
  The MAVLink messages Neptunus knows, as data: each message's id, name and fields exactly as
  the published MAVLink XML declares them (`minimal.xml` for HEARTBEAT, `standard.xml` for
  AUTOPILOT_VERSION, `common.xml` for the rest, the definitions pymavlink 2.4.50 ships; and
  CONTROL_STATUS, below), and what follows from them at compile time:

    * the **wire order**: the non-extension fields stably sorted by the size of their element
      type, largest first, then the extension fields in declaration order;
    * the **CRC_EXTRA** byte, computed by the spec's rule: the X.25 checksum of the message
      name and a space, then for each non-extension field in wire order its element type, a
      space, its name and a space, and for an array its length as one byte; the byte is
      `(crc & 0xFF) ^ (crc >> 8)`;
    * the payload's **base length** (the non-extension fields: a MAVLink 1 payload) and
      **full length** (with the extensions).

  A field is `%{name: atom, type: type, length: nil | pos_integer, extension: boolean,
  c_type: String.t}`:
  `type` is the element type (`:uint8`, `:int8`, `:uint16`, `:int16`, `:uint32`, `:int32`,
  `:uint64`, `:int64`, `:float`, `:double`, `:char`) and `length` the array length (`char[N]`
  is a string of at most N bytes), `c_type` the XML's element type as the CRC_EXTRA rule
  spells it. HEARTBEAT's `mavlink_version` is declared
  `uint8_t_mavlink_version` in the XML: a `uint8_t` the sender fills with the protocol version
  (3), which the encoder does when the caller leaves it out.

  `MESSAGE_INTERVAL` (244) is the vehicle's answer to `MAV_CMD_SET_MESSAGE_INTERVAL` (511),
  which is a command sent in COMMAND_LONG, not a message of its own.

  `CONTROL_STATUS` (512) is the GCS control protocol's status message of `development.xml`
  (work in progress upstream), in the revision that defines it with `sysid_in_control` and
  `flags` and `MAV_CMD_REQUEST_OPERATOR_CONTROL` (32100) with the requester's system id,
  action, allow-takeover and request timeout (3–60 s) as params 1–4. pymavlink 2.4.50's
  `development.xml` has neither (the protocol has been reworked upstream since), so its
  CRC_EXTRA (184) is checked against the C library generated from that revision instead
  (docs/MAVLINK.md).

  Adding a message is adding its declaration below, copied from the XML; the tests check every
  CRC_EXTRA against the published value.
  """

  alias Neptunus.Protocol.MAVLink.Definition

  @type t :: Definition.t()

  # {id, NAME, fields in declaration order}; `:ext` marks where <extensions/> begins.
  @declarations [
    {0, "HEARTBEAT",
     [
       {"uint8_t", "type"},
       {"uint8_t", "autopilot"},
       {"uint8_t", "base_mode"},
       {"uint32_t", "custom_mode"},
       {"uint8_t", "system_status"},
       {"uint8_t_mavlink_version", "mavlink_version"}
     ]},
    {1, "SYS_STATUS",
     [
       {"uint32_t", "onboard_control_sensors_present"},
       {"uint32_t", "onboard_control_sensors_enabled"},
       {"uint32_t", "onboard_control_sensors_health"},
       {"uint16_t", "load"},
       {"uint16_t", "voltage_battery"},
       {"int16_t", "current_battery"},
       {"int8_t", "battery_remaining"},
       {"uint16_t", "drop_rate_comm"},
       {"uint16_t", "errors_comm"},
       {"uint16_t", "errors_count1"},
       {"uint16_t", "errors_count2"},
       {"uint16_t", "errors_count3"},
       {"uint16_t", "errors_count4"},
       :ext,
       {"uint32_t", "onboard_control_sensors_present_extended"},
       {"uint32_t", "onboard_control_sensors_enabled_extended"},
       {"uint32_t", "onboard_control_sensors_health_extended"}
     ]},
    {2, "SYSTEM_TIME",
     [
       {"uint64_t", "time_unix_usec"},
       {"uint32_t", "time_boot_ms"}
     ]},
    {11, "SET_MODE",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "base_mode"},
       {"uint32_t", "custom_mode"}
     ]},
    {20, "PARAM_REQUEST_READ",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"char[16]", "param_id"},
       {"int16_t", "param_index"}
     ]},
    {21, "PARAM_REQUEST_LIST",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"}
     ]},
    {22, "PARAM_VALUE",
     [
       {"char[16]", "param_id"},
       {"float", "param_value"},
       {"uint8_t", "param_type"},
       {"uint16_t", "param_count"},
       {"uint16_t", "param_index"}
     ]},
    {23, "PARAM_SET",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"char[16]", "param_id"},
       {"float", "param_value"},
       {"uint8_t", "param_type"}
     ]},
    {29, "SCALED_PRESSURE",
     [
       {"uint32_t", "time_boot_ms"},
       {"float", "press_abs"},
       {"float", "press_diff"},
       {"int16_t", "temperature"},
       :ext,
       {"int16_t", "temperature_press_diff"}
     ]},
    {30, "ATTITUDE",
     [
       {"uint32_t", "time_boot_ms"},
       {"float", "roll"},
       {"float", "pitch"},
       {"float", "yaw"},
       {"float", "rollspeed"},
       {"float", "pitchspeed"},
       {"float", "yawspeed"}
     ]},
    {32, "LOCAL_POSITION_NED",
     [
       {"uint32_t", "time_boot_ms"},
       {"float", "x"},
       {"float", "y"},
       {"float", "z"},
       {"float", "vx"},
       {"float", "vy"},
       {"float", "vz"}
     ]},
    {33, "GLOBAL_POSITION_INT",
     [
       {"uint32_t", "time_boot_ms"},
       {"int32_t", "lat"},
       {"int32_t", "lon"},
       {"int32_t", "alt"},
       {"int32_t", "relative_alt"},
       {"int16_t", "vx"},
       {"int16_t", "vy"},
       {"int16_t", "vz"},
       {"uint16_t", "hdg"}
     ]},
    {36, "SERVO_OUTPUT_RAW",
     [
       {"uint32_t", "time_usec"},
       {"uint8_t", "port"},
       {"uint16_t", "servo1_raw"},
       {"uint16_t", "servo2_raw"},
       {"uint16_t", "servo3_raw"},
       {"uint16_t", "servo4_raw"},
       {"uint16_t", "servo5_raw"},
       {"uint16_t", "servo6_raw"},
       {"uint16_t", "servo7_raw"},
       {"uint16_t", "servo8_raw"},
       :ext,
       {"uint16_t", "servo9_raw"},
       {"uint16_t", "servo10_raw"},
       {"uint16_t", "servo11_raw"},
       {"uint16_t", "servo12_raw"},
       {"uint16_t", "servo13_raw"},
       {"uint16_t", "servo14_raw"},
       {"uint16_t", "servo15_raw"},
       {"uint16_t", "servo16_raw"}
     ]},
    {43, "MISSION_REQUEST_LIST",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       :ext,
       {"uint8_t", "mission_type"}
     ]},
    {44, "MISSION_COUNT",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint16_t", "count"},
       :ext,
       {"uint8_t", "mission_type"}
     ]},
    {47, "MISSION_ACK",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint8_t", "type"},
       :ext,
       {"uint8_t", "mission_type"}
     ]},
    {65, "RC_CHANNELS",
     [
       {"uint32_t", "time_boot_ms"},
       {"uint8_t", "chancount"},
       {"uint16_t", "chan1_raw"},
       {"uint16_t", "chan2_raw"},
       {"uint16_t", "chan3_raw"},
       {"uint16_t", "chan4_raw"},
       {"uint16_t", "chan5_raw"},
       {"uint16_t", "chan6_raw"},
       {"uint16_t", "chan7_raw"},
       {"uint16_t", "chan8_raw"},
       {"uint16_t", "chan9_raw"},
       {"uint16_t", "chan10_raw"},
       {"uint16_t", "chan11_raw"},
       {"uint16_t", "chan12_raw"},
       {"uint16_t", "chan13_raw"},
       {"uint16_t", "chan14_raw"},
       {"uint16_t", "chan15_raw"},
       {"uint16_t", "chan16_raw"},
       {"uint16_t", "chan17_raw"},
       {"uint16_t", "chan18_raw"},
       {"uint8_t", "rssi"}
     ]},
    {66, "REQUEST_DATA_STREAM",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint8_t", "req_stream_id"},
       {"uint16_t", "req_message_rate"},
       {"uint8_t", "start_stop"}
     ]},
    {69, "MANUAL_CONTROL",
     [
       {"uint8_t", "target"},
       {"int16_t", "x"},
       {"int16_t", "y"},
       {"int16_t", "z"},
       {"int16_t", "r"},
       {"uint16_t", "buttons"},
       :ext,
       {"uint16_t", "buttons2"},
       {"uint8_t", "enabled_extensions"},
       {"int16_t", "s"},
       {"int16_t", "t"},
       {"int16_t", "aux1"},
       {"int16_t", "aux2"},
       {"int16_t", "aux3"},
       {"int16_t", "aux4"},
       {"int16_t", "aux5"},
       {"int16_t", "aux6"}
     ]},
    {70, "RC_CHANNELS_OVERRIDE",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint16_t", "chan1_raw"},
       {"uint16_t", "chan2_raw"},
       {"uint16_t", "chan3_raw"},
       {"uint16_t", "chan4_raw"},
       {"uint16_t", "chan5_raw"},
       {"uint16_t", "chan6_raw"},
       {"uint16_t", "chan7_raw"},
       {"uint16_t", "chan8_raw"},
       :ext,
       {"uint16_t", "chan9_raw"},
       {"uint16_t", "chan10_raw"},
       {"uint16_t", "chan11_raw"},
       {"uint16_t", "chan12_raw"},
       {"uint16_t", "chan13_raw"},
       {"uint16_t", "chan14_raw"},
       {"uint16_t", "chan15_raw"},
       {"uint16_t", "chan16_raw"},
       {"uint16_t", "chan17_raw"},
       {"uint16_t", "chan18_raw"}
     ]},
    {74, "VFR_HUD",
     [
       {"float", "airspeed"},
       {"float", "groundspeed"},
       {"int16_t", "heading"},
       {"uint16_t", "throttle"},
       {"float", "alt"},
       {"float", "climb"}
     ]},
    {75, "COMMAND_INT",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint8_t", "frame"},
       {"uint16_t", "command"},
       {"uint8_t", "current"},
       {"uint8_t", "autocontinue"},
       {"float", "param1"},
       {"float", "param2"},
       {"float", "param3"},
       {"float", "param4"},
       {"int32_t", "x"},
       {"int32_t", "y"},
       {"float", "z"}
     ]},
    {76, "COMMAND_LONG",
     [
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"},
       {"uint16_t", "command"},
       {"uint8_t", "confirmation"},
       {"float", "param1"},
       {"float", "param2"},
       {"float", "param3"},
       {"float", "param4"},
       {"float", "param5"},
       {"float", "param6"},
       {"float", "param7"}
     ]},
    {77, "COMMAND_ACK",
     [
       {"uint16_t", "command"},
       {"uint8_t", "result"},
       :ext,
       {"uint8_t", "progress"},
       {"int32_t", "result_param2"},
       {"uint8_t", "target_system"},
       {"uint8_t", "target_component"}
     ]},
    {111, "TIMESYNC",
     [
       {"int64_t", "tc1"},
       {"int64_t", "ts1"}
     ]},
    {137, "SCALED_PRESSURE2",
     [
       {"uint32_t", "time_boot_ms"},
       {"float", "press_abs"},
       {"float", "press_diff"},
       {"int16_t", "temperature"},
       :ext,
       {"int16_t", "temperature_press_diff"}
     ]},
    {147, "BATTERY_STATUS",
     [
       {"uint8_t", "id"},
       {"uint8_t", "battery_function"},
       {"uint8_t", "type"},
       {"int16_t", "temperature"},
       {"uint16_t[10]", "voltages"},
       {"int16_t", "current_battery"},
       {"int32_t", "current_consumed"},
       {"int32_t", "energy_consumed"},
       {"int8_t", "battery_remaining"},
       :ext,
       {"int32_t", "time_remaining"},
       {"uint8_t", "charge_state"},
       {"uint16_t[4]", "voltages_ext"},
       {"uint8_t", "mode"},
       {"uint32_t", "fault_bitmask"}
     ]},
    {148, "AUTOPILOT_VERSION",
     [
       {"uint64_t", "capabilities"},
       {"uint32_t", "flight_sw_version"},
       {"uint32_t", "middleware_sw_version"},
       {"uint32_t", "os_sw_version"},
       {"uint32_t", "board_version"},
       {"uint8_t[8]", "flight_custom_version"},
       {"uint8_t[8]", "middleware_custom_version"},
       {"uint8_t[8]", "os_custom_version"},
       {"uint16_t", "vendor_id"},
       {"uint16_t", "product_id"},
       {"uint64_t", "uid"},
       :ext,
       {"uint8_t[18]", "uid2"}
     ]},
    {244, "MESSAGE_INTERVAL",
     [
       {"uint16_t", "message_id"},
       {"int32_t", "interval_us"}
     ]},
    {251, "NAMED_VALUE_FLOAT",
     [
       {"uint32_t", "time_boot_ms"},
       {"char[10]", "name"},
       {"float", "value"}
     ]},
    {253, "STATUSTEXT",
     [
       {"uint8_t", "severity"},
       {"char[50]", "text"},
       :ext,
       {"uint16_t", "id"},
       {"uint8_t", "chunk_seq"}
     ]},
    # development.xml (work in progress there; not in the pinned pymavlink): see the moduledoc
    {512, "CONTROL_STATUS",
     [
       {"uint8_t", "sysid_in_control"},
       {"uint8_t", "flags"}
     ]}
  ]

  @messages Enum.map(@declarations, &Definition.build/1)

  @doc "Every message definition, by id."
  @spec all() :: [t()]
  def all, do: @messages

  @doc "The definition of a message by id or by name (`:heartbeat`), or `nil`."
  @spec get(non_neg_integer() | atom()) :: t() | nil
  for message <- @messages do
    def get(unquote(message.id)), do: unquote(Macro.escape(message))
    def get(unquote(message.name)), do: unquote(Macro.escape(message))
  end

  def get(_), do: nil
end
