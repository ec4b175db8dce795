defmodule NeptunusWeb.WireSchema do
  @moduledoc """
  The payloads of the channels (`vehicle:<id>`, `fleet`, `log:<id>`), written once: every
  event the server sends, every command a client sends and its reply, every field with its
  type, unit, whether it may be null or absent, and what it means.

  Everything else is derived from it (`mix neptunus.gen.wire` writes the derived copies, and
  `test/neptunus_web/wire_schema_test.exs` fails when one is out of date):

    * `assets/src/lib/wire.gen.ts` — TypeScript types and decoders
      (`NeptunusWeb.WireSchema.TypeScript`);
    * the tables of docs/API.md between `<!-- wire:begin NAME -->` and `<!-- wire:end NAME -->`
      (`NeptunusWeb.WireSchema.Docs`);
    * the conformance tests: the server's real payloads (a running simulated, SITL and
      MAVLink vehicle's) and the JS fake server's are checked against it
      (`NeptunusWeb.WireSchema.Check`).

  ## Types

  A type is `:number` (a finite JSON number), `:integer`, `:string`, `:boolean`, the name of
  a type defined here (an atom), `{:enum, values}` (strings or
  integers), `{:list, type}`, `{:map, type}` (an object whose keys are data, e.g. counts by
  field), `{:one_of, [type]}` (the first that fits) or `{:or_null, type}` (for list elements).

  A definition is `{:object, doc, fields}` (or `{:object, doc, fields, opts}` with
  `extends: name` — that object's fields first — and `open: true` — fields not named here
  are allowed), `{:enum, values, doc}` or `{:one_of, types, doc}`. A field is `name: type` or `name: {type, opts}`:

    * `doc:` what it means; `unit:` its unit (SI: m, m/s, rad, rad/s, V, A, s; `ms`, `µs`;
      `ms since the epoch` for wall-clock times);
    * `null: true` — the server may send `null` ("not known": an initialising measurement,
      a disengaged autopilot);
    * `optional: true` — the server may leave the field out (a field of some boards only);
    * `essential: true` — a page cannot use the object without it.

  ## Decoding: one treatment of missing, null and malformed

  The generated decoders read a payload as follows. A field that is absent, null or of the
  wrong type is **not known**: it reads `null` (never `undefined`, never NaN) — unless it is
  `essential`, in which case only what the schema allows (null for a `null: true` field,
  absence for an `optional: true` one) reads null, and anything else makes the whole object
  undecodable (`null`). So one malformed part of telemetry (the link, say) reads as not
  known while the rest is shown, and a helm without an epoch is refused. In a `{:map, t}`,
  an entry that is not a `t` is left out; a `{:list, t}` with an element that is not a `t`
  does not decode. Fields not named in the schema are ignored by the decoders; the
  conformance check (`NeptunusWeb.WireSchema.Check`) refuses them, so a field the server
  starts sending cannot go undocumented.

  ## How to add a telemetry field (or any payload field)

  Add it to its object below (type, unit, `null`/`optional`, `doc`), build it on the server,
  run `mix neptunus.gen.wire`, use the generated type and decoder in the page, and commit
  the three together. docs/ARCHITECTURE.md has the recipe, and one for a command.
  """

  @typedoc "A type expression (see the moduledoc)."
  @type type ::
          :number
          | :integer
          | :string
          | :boolean
          | atom()
          | {:enum, [String.t() | integer()]}
          | {:list, type()}
          | {:map, type()}
          | {:one_of, [type()]}
          | {:or_null, type()}

  @typedoc "A field, normalised: its name, type and options."
  @type field :: %{
          name: atom(),
          type: type(),
          doc: String.t(),
          unit: String.t() | nil,
          null: boolean(),
          optional: boolean(),
          essential: boolean()
        }

  @typedoc "A named definition, normalised."
  @type definition ::
          %{
            kind: :object,
            name: atom(),
            doc: String.t(),
            fields: [field()],
            open: boolean(),
            extends: atom() | nil
          }
          | %{kind: :enum, name: atom(), doc: String.t(), values: [String.t() | integer()]}
          | %{kind: :union, name: atom(), doc: String.t(), types: [type()]}

  @typedoc """
  A message on a topic: a server event (`payload`), a client command (`payload` and the
  `reply` of an `ok`; an `error` reply is always `{"reason": string}`) or a join reply.
  `group` places a command in the docs' tables; `who` may send it; `errors` its error
  reasons, for the docs.
  """
  @type message :: %{
          required(:topic) => String.t(),
          required(:name) => String.t(),
          required(:payload) => type(),
          required(:doc) => String.t(),
          optional(:reply) => type(),
          optional(:group) => atom(),
          optional(:who) => String.t(),
          optional(:errors) => String.t(),
          optional(:to) => String.t()
        }

  @primitives [:number, :integer, :string, :boolean]

  # ---------------------------------------------------------------------------------------
  # Payload types, in the order the docs list them.

  @types [
    # --- telemetry ---------------------------------------------------------------------------
    telemetry:
      {:object,
       "The `telemetry` broadcast on `vehicle:<id>`: the vehicle's latest state, 20 Hz (a stable shape; later versions add fields).",
       [
         t: {:number, unit: "s", essential: true, doc: "the vehicle's clock"},
         sent_at:
           {:number,
            unit: "ms since the epoch",
            essential: true,
            doc: "the server's wall clock at broadcast (latency measurement only)"},
         measurement:
           {:measurement,
            essential: true, doc: "what navigation accepted of the board's readings"},
         measurement_state: {:measurement_states, doc: "whether each measurement can be trusted"},
         estimate: {:estimate, doc: "the navigation filter's estimate"},
         wild_points: {:wild_points, doc: "readings rejected since navigation started"},
         position:
           {:position_status,
            doc:
              "where the vehicle is: the position filter's estimate from its position sources (DVL, USBL), with its uncertainty, or why there is none"},
         sim:
           {:sim_state,
            null: true, essential: true, doc: "the simulator's true state; null on a real board"},
         command: {:pilot_command, essential: true, doc: "the pilot's command"},
         thrusters:
           {:thrusters,
            essential: true, doc: "what goes to the board (pilot and autopilots together)"},
         control:
           {:control_settings,
            null: true,
            doc:
              "the control state without command and thrusters (null before control's first report)"},
         autopilot: {:autopilot_status, doc: "each engaged autopilot's state"},
         axes:
           {{:list, :axis},
            null: true,
            doc:
              "the body-frame axes the pilot may command now, which the pages offer: the vehicle's as its board declares them (an ArduSub vehicle's once its frame is known: docs/MAVLINK.md), surge, heave and yaw in run mode simulator; null before control's first report"},
         link: {:link_status, doc: "the board link's state, as in the `link` event"},
         recording:
           {:recording_status,
            optional: true, doc: "the vehicle's recorder (absent until it reported)"},
         camera:
           {:camera_status,
            optional: true, doc: "the camera program (a vehicle with a camera only)"}
       ]},
    measurement:
      {:object,
       "Sensor readings that passed the wild-point tests; a field is null while its state is `initialising`.",
       [
         depth: {:number, unit: "m", null: true, doc: "positive down"},
         heading: {:number, unit: "rad", null: true, doc: "[0, 2π)"},
         roll: {:number, unit: "rad", null: true, doc: "positive starboard down"},
         pitch: {:number, unit: "rad", null: true, doc: "positive bow up"},
         voltage: {:number, unit: "V", null: true, doc: "the battery's"},
         current: {:number, unit: "A", null: true, doc: "drawn from the battery"}
       ]},
    measurement_states:
      {:object, "Each measurement's state.",
       [
         depth: {:measurement_state, essential: true},
         heading: {:measurement_state, essential: true},
         roll: {:measurement_state, essential: true},
         pitch: {:measurement_state, essential: true},
         voltage: {:measurement_state, essential: true},
         current: {:measurement_state, essential: true}
       ]},
    measurement_state:
      {:enum, ~w(initialising valid stale),
       "`initialising`: no valid reading since the server started, the link came up or the " <>
         "board reset (the value is null); `valid`; `stale`: no plausible reading for 2 s " <>
         "(the last value is kept)."},
    estimate:
      {:object,
       "The Kalman filter's estimate; a pair is null until its measurement is valid and while it is stale.",
       [
         depth: {:number, unit: "m", null: true, doc: "positive down"},
         depth_rate: {:number, unit: "m/s", null: true, doc: "positive down"},
         heading: {:number, unit: "rad", null: true, doc: "[0, 2π)"},
         yaw_rate: {:number, unit: "rad/s", null: true},
         roll: {:number, unit: "rad", null: true, doc: "positive starboard down"},
         roll_rate: {:number, unit: "rad/s", null: true},
         pitch: {:number, unit: "rad", null: true, doc: "positive bow up"},
         pitch_rate: {:number, unit: "rad/s", null: true}
       ]},
    wild_points:
      {:object, "Readings rejected since navigation started (a repeated reading counts once).",
       [
         total: {:integer, essential: true},
         by_field: {{:map, :integer}, doc: "by measurement"},
         by_reason:
           {{:map, :integer},
            doc: "by reason: `out_of_range`, `not_a_number`, `rate_of_change`, `innovation`"},
         reacquired:
           {:integer,
            doc: "times rejected readings that agreed with each other were taken as the truth"}
       ]},
    position_status:
      {:object,
       "The position estimate (north/east, NED, m) and its sources. Without a valid position, DP holds depth and heading only.",
       [
         valid: {:boolean, essential: true, doc: "position hold and missions may use it"},
         reason: {:string, null: true, doc: "why it is not valid (per source); null while valid"},
         frame:
           {{:enum, ~w(local usbl ardusub)},
            null: true,
            doc:
              "whose origin: `local` dead reckoning from where the DVL started, `usbl` the topside's, `ardusub` the vehicle's own; null without an estimate"},
         epoch:
           {:integer,
            doc: "changes when the frame does (targets are moved by the shift, or dropped)"},
         north: {:number, unit: "m", null: true},
         east: {:number, unit: "m", null: true},
         depth: {:number, unit: "m", null: true, doc: "the depth estimate"},
         velocity_north: {:number, unit: "m/s", null: true},
         velocity_east: {:number, unit: "m/s", null: true},
         std_north: {:number, unit: "m", null: true, doc: "1 σ"},
         std_east: {:number, unit: "m", null: true, doc: "1 σ"},
         ellipse:
           {:position_ellipse,
            null: true, doc: "the 1-σ uncertainty ellipse; null without an estimate"},
         origin:
           {:geo_point,
            null: true,
            doc:
              "the frame's geodetic origin where it is known: an ArduSub vehicle's own (`ardusub` frame), from its GLOBAL_POSITION_INT and LOCAL_POSITION_NED; null otherwise (a DVL's and a USBL's frames have none)"},
         sources: {{:list, :position_source}, doc: "each position source's state"}
       ]},
    geo_point:
      {:object, "A point on the Earth (WGS 84).",
       [
         lat: {:number, unit: "rad", essential: true, doc: "latitude, north positive"},
         lon: {:number, unit: "rad", essential: true, doc: "longitude, east positive"}
       ]},
    position_ellipse:
      {:object, "A 1-σ uncertainty ellipse.",
       [
         major: {:number, unit: "m", essential: true, doc: "the larger semi-axis"},
         minor: {:number, unit: "m", essential: true, doc: "the smaller semi-axis"},
         angle:
           {:number,
            unit: "rad",
            essential: true,
            doc: "the larger axis' direction, from north towards east"}
       ]},
    position_source:
      {:object, "One position source and what navigation made of its reports.",
       [
         name: {:string, essential: true, doc: "`dvl`, `usbl`, `ardusub`"},
         kind:
           {{:enum, ~w(velocity fix)},
            null: true,
            doc:
              "what it measures: velocity (a DVL) or position (a USBL fix); null before its first report"},
         state:
           {{:enum, ~w(valid invalid waiting)},
            essential: true, doc: "`valid`: a usable report lately; `waiting`: nothing heard yet"},
         reason: {:string, null: true, doc: "why it is not valid; null while valid"},
         connected: {:boolean, doc: "its link is up"},
         reports: {:integer, doc: "readings received"},
         accepted: {:integer, doc: "readings the filter took"},
         rejected:
           {{:map, :integer},
            doc:
              "by reason: `no_lock`, `water_track`, `out_of_range`, `no_heading`, `invalid_fix`, `innovation`, `too_old`, `frame`"},
         garbage: {:integer, doc: "reports that could not be read"},
         disconnects: {:integer, doc: "times its link went down"},
         reacquired:
           {:integer, doc: "times rejected readings that agreed were taken as the truth"},
         altitude: {:number, unit: "m", null: true, doc: "a DVL's altitude above the bottom"},
         fom: {:number, unit: "m/s", null: true, doc: "a DVL's figure of merit"},
         std: {:number, unit: "m", null: true, doc: "a fix's standard deviation"},
         innovation:
           {{:list, :number},
            null: true,
            doc:
              "the last innovation: m/s in the vehicle frame (x, y) for a DVL, m (north, east) for a fix"},
         dead_reckoning:
           {:dead_reckoning,
            null: true, doc: "a DVL's own integrated position (shown, not fused)"}
       ]},
    dead_reckoning:
      {:object, "A DVL's dead reckoning, in its own frame.",
       [
         x: {:number, unit: "m", essential: true},
         y: {:number, unit: "m", essential: true},
         z: {:number, unit: "m", essential: true},
         std: {:number, unit: "m", essential: true}
       ]},
    sim_state:
      {:object, "The simulator's true 6-DOF state (Fossen notation, NED: z is depth).",
       [
         x: {:number, unit: "m", essential: true, doc: "north"},
         y: {:number, unit: "m", essential: true, doc: "east"},
         z: {:number, unit: "m", essential: true, doc: "down (depth)"},
         phi: {:number, unit: "rad", essential: true, doc: "roll"},
         theta: {:number, unit: "rad", essential: true, doc: "pitch"},
         psi: {:number, unit: "rad", essential: true, doc: "yaw, [-π, π)"},
         u: {:number, unit: "m/s", essential: true, doc: "surge velocity"},
         v: {:number, unit: "m/s", essential: true, doc: "sway velocity"},
         w: {:number, unit: "m/s", essential: true, doc: "heave velocity"},
         p: {:number, unit: "rad/s", essential: true, doc: "roll rate"},
         q: {:number, unit: "rad/s", essential: true, doc: "pitch rate"},
         r: {:number, unit: "rad/s", essential: true, doc: "yaw rate"}
       ]},
    pilot_command:
      {:one_of, [:motion_command, :thruster_outputs],
       "The pilot's command in the control mode's terms: motion `{surge, heave, yaw}` (and `sway` on a vehicle that has it), manual `{port, vertical, starboard}`."},
    motion_command:
      {:object, "A motion command: each axis in [-1, 1].",
       [
         surge: {:number, essential: true, doc: "forward"},
         heave: {:number, essential: true, doc: "down"},
         yaw: {:number, essential: true, doc: "to starboard"},
         sway: {:number, optional: true, doc: "to starboard; only when the pilot sent it"}
       ]},
    thruster_outputs:
      {:object,
       "Thruster values in [-1, 1] (positive pushes the vehicle forward for port and starboard, down for vertical).",
       [
         port: {:number, essential: true},
         vertical: {:number, essential: true},
         starboard: {:number, essential: true}
       ]},
    thrusters:
      {:object, "Thruster values and the PWM pulse widths that go to the ESCs.",
       [
         port_us: {:integer, unit: "µs", essential: true, doc: "1000..2000, 1500 neutral"},
         vertical_us: {:integer, unit: "µs", essential: true},
         starboard_us: {:integer, unit: "µs", essential: true}
       ], extends: :thruster_outputs},
    control_settings:
      {:object, "The control state C without command and thrusters (telemetry's `control`).",
       [
         mode: {:control_mode, essential: true},
         gain: {:number, doc: "[0, 1]: scales the pilot's axes (motion) or thrusters (manual)"},
         lights: {:integer, doc: "0..255"},
         laser: {:integer, doc: "0..255"},
         tilt: {:number, unit: "rad", doc: "camera tilt, [-π/4, π/4]"},
         run_mode: :run_mode,
         dp_holds:
           {{:list, {:enum, ~w(depth heading position)}},
            null: true,
            doc:
              "in dp, what DP holds (without a position source: depth and heading); null outside dp"},
         autopilot: {:autopilot_setpoints, doc: "the engaged autopilots' setpoints"},
         mission:
           {:mission_state,
            null: true, doc: "the mission in dp (its waypoints come in the `mission` event)"}
       ]},
    mission_state:
      {:object, "A mission's progress.",
       [
         id: {:integer, essential: true, doc: "a new one for each mission started"},
         state: {{:enum, ~w(running paused done)}, essential: true},
         leg: {:integer, essential: true, doc: "the waypoint steered to, 1-based"},
         count: {:integer, essential: true, doc: "waypoints"}
       ]},
    mission:
      {:object, "A mission with its waypoints (the `mission` event, the join snapshot).",
       [
         id: {:integer, essential: true},
         state: {{:enum, ~w(running paused done)}, essential: true},
         leg: {:integer, essential: true, doc: "the waypoint steered to, 1-based"},
         waypoints: {{:list, :waypoint}, essential: true}
       ]},
    waypoint:
      {:object, "A mission's waypoint (in the position's frame).",
       [
         north: {:number, unit: "m", essential: true},
         east: {:number, unit: "m", essential: true},
         depth: {:number, unit: "m", essential: true},
         heading:
           {:number,
            unit: "rad", null: true, essential: true, doc: "to hold there; null: the guidance's"},
         speed: {:number, unit: "m/s", essential: true},
         radius: {:number, unit: "m", essential: true, doc: "reached within it"}
       ]},
    control_state:
      {:object,
       "The control state C: command replies, the join snapshot, every grant (telemetry has it without command and thrusters).",
       [
         command: :pilot_command,
         thrusters: {:thrusters, doc: "the output, with pulse widths"}
       ], extends: :control_settings},
    control_mode:
      {:enum, ~w(motion manual dp),
       "`motion`: surge, heave, yaw; `manual`: each thruster; `dp`: position hold."},
    run_mode:
      {:enum, ~w(normal simulator),
       "`normal` flies the configured board; `simulator` a simulator in its place."},
    autopilot_setpoints:
      {:object, "The engaged autopilots' setpoints (null: disengaged).",
       [
         depth: {:number, unit: "m", null: true},
         heading: {:number, unit: "rad", null: true, doc: "[0, 2π)"},
         position: {:dp_target, null: true, doc: "DP's target (null unless in dp)"}
       ]},
    dp_target:
      {:object, "DP's target position.",
       [
         x: {:number, unit: "m", essential: true, doc: "north"},
         y: {:number, unit: "m", essential: true, doc: "east"}
       ]},
    autopilot_status:
      {:object, "Each autopilot's state in telemetry (null: disengaged).",
       [
         depth: {:autopilot_loop, null: true},
         heading: {:autopilot_loop, null: true},
         position: {:dp_status, null: true, doc: "in dp"}
       ]},
    autopilot_loop:
      {:object, "One autopilot loop (depth: m, m/s, heave; heading: rad, rad/s, yaw).",
       [
         setpoint: {:number, essential: true, doc: "m or rad"},
         reference:
           {:number,
            doc:
              "what it tracks on the way to the setpoint (rate- and acceleration-limited), m or rad"},
         reference_rate: {:number, doc: "the reference's rate, m/s or rad/s"},
         output:
           {:number,
            essential: true,
            doc: "its command in [-1, 1]: heave (positive down) or yaw (positive to starboard)"},
         overridden: {:boolean, doc: "the pilot overrides it (its output is 0 then)"},
         waiting:
           {:string,
            null: true,
            doc: "why it gives no output for want of a measurement; null while it acts"}
       ]},
    dp_status:
      {:object, "DP: position hold and missions.",
       [
         x: {:number, unit: "m", null: true, doc: "the target held, north; null: none"},
         y: {:number, unit: "m", null: true, doc: "the target held, east; null: none"},
         heading: {:number, unit: "rad", doc: "the heading held now"},
         phase:
           {{:enum, ~w(hold return mission waiting)},
            doc:
              "`hold` at the target, `return` towards it (a three-thruster vehicle beyond its radius), `mission` steering a leg, `waiting` for a valid position"},
         distance:
           {:number, unit: "m", null: true, doc: "to the target, or to the waypoint steered to"},
         output: {:number, doc: "surge demanded, [-1, 1]"},
         sway: {:number, doc: "sway demanded, [-1, 1] (0 on a vehicle without sway)"},
         waiting:
           {:string, null: true, doc: "why there is no horizontal demand; null while acting"},
         mission: {:mission_guidance, null: true, doc: "during a mission"}
       ]},
    mission_guidance:
      {:object, "A mission's guidance (line of sight).",
       [
         id: {:integer, essential: true},
         state: {{:enum, ~w(running paused done)}, essential: true},
         leg: {:integer, essential: true, doc: "the waypoint steered to, 1-based"},
         cross_track:
           {:number, unit: "m", null: true, doc: "off the line, positive to its starboard"},
         along: {:number, unit: "m", null: true, doc: "along the leg from its start"},
         course: {:number, unit: "rad", null: true, doc: "the course steered"},
         speed: {:number, unit: "m/s", null: true, doc: "the speed asked"}
       ]},
    link_status:
      {:object,
       "The board link (the `link` event, telemetry's `link`). The fields after `reason` come from a serial board link (updated every second) or, `rtt_ms` and `mavlink`, from a mavlink vehicle.",
       [
         up: {:boolean, essential: true},
         reason:
           {:string,
            doc:
              "`open`, `hangup: …`, `cannot open …`; `no link` (the built-in simulator); `heartbeat` (mavlink)"},
         rtt_ms:
           {:number,
            unit: "ms",
            optional: true,
            null: true,
            doc: "the last ping → pong round trip (mavlink: TIMESYNC); null before the first"},
         pong_age_ms:
           {:integer,
            unit: "ms", optional: true, null: true, doc: "how long ago the last pong came"},
         board_uptime_ms:
           {:integer, unit: "ms", optional: true, null: true, doc: "from the board's millis"},
         board_deadman_armed:
           {:boolean,
            optional: true,
            null: true,
            doc: "the board's own deadman arms 180 s after it boots; null: not known yet"},
         firmware: {:string, optional: true, doc: "the configured firmware line"},
         detected_firmware:
           {:string,
            optional: true,
            null: true,
            doc: "the one the board's output shows (null until it shows)"},
         firmware_mismatch: {:boolean, optional: true},
         commands_sent: {:integer, optional: true, doc: "commands written"},
         commands_confirmed: {:integer, optional: true, doc: "commands the board echoed"},
         board_settings:
           {{:enum, ~w(confirmed pending failed)},
            optional: true,
            doc:
              "`confirmed`: the board echoed every setting it was sent (motor modifiers, lights, laser, tilt); `pending`; `failed`: one was not echoed after 8 writes (see docs/OPENROV.md, Settings)"},
         board_settings_pending:
           {{:list, {:enum, ~w(mtrmod1 mtrmod2 lights laser tilt)}},
            optional: true, doc: "the settings not confirmed yet"},
         board_settings_reason:
           {:string, optional: true, null: true, doc: "why a setting failed; null: none did"},
         thrust_held:
           {:boolean,
            optional: true,
            doc:
              "thrust other than neutral is held (the board gets neutral) until the motor modifiers are confirmed"},
         mavlink: {:mavlink_status, optional: true, doc: "a mavlink vehicle's state"}
       ]},
    mavlink_status:
      {:object, "A mavlink (ArduSub) vehicle's state (docs/MAVLINK.md).",
       [
         armed: {:boolean, essential: true},
         mode:
           {:string,
            null: true,
            doc:
              "ArduSub's flight mode (`MANUAL`, `ALT_HOLD`, …); null before its first heartbeat"},
         system_status: {:string, null: true},
         target: {{:list, :integer}, null: true, doc: "[system, component]"},
         servo_us: {{:list, :integer}, unit: "µs", doc: "SERVO_OUTPUT_RAW 1..8"},
         thrusters:
           {{:list, {:or_null, :number}},
            doc: "each output as a thruster value, (µs − 1500)/400; null: not driven"},
         control: {:manual_control, doc: "the MANUAL_CONTROL being sent"},
         disarm_pending: {:boolean, doc: "a disarm after pilot loss is pending"},
         pilot_gain:
           {:number,
            null: true,
            doc:
              "ArduSub's joystick gain (its `PilotGain`), divided out of MANUAL_CONTROL so that only ours applies; null until the vehicle sends it"},
         frame:
           {:string,
            null: true,
            doc:
              "the vehicle's frame, from its `FRAME_CONFIG` (`Vectored`, `SimpleROV-3`, …; `FRAME_CONFIG n` for one Neptunus does not know): it decides whether the vehicle has sway; null until the vehicle answered"},
         frames_received: :integer,
         frames_lost: {:integer, doc: "from the vehicle's sequence numbers"},
         loss: {:number, doc: "frames lost / (received + lost)"}
       ]},
    manual_control:
      {:object, "MAVLink MANUAL_CONTROL.",
       [
         x: {:integer, doc: "-1000..1000"},
         y: {:integer, doc: "-1000..1000"},
         z: {:integer, doc: "0..1000, 500 neutral"},
         r: {:integer, doc: "-1000..1000"},
         buttons: {:integer, doc: "bit mask"}
       ]},
    recording_status:
      {:object, "The vehicle's recorder.",
       [
         on: {:boolean, essential: true, doc: "it writes"},
         error:
           {:string, null: true, doc: "why it stopped; null: it is on, or off by configuration"}
       ]},
    camera_status:
      {:object, "The camera (updated every second).",
       [
         running: {:boolean, essential: true},
         fps: {:number, essential: true, doc: "frames in the last second"},
         error: {:string, null: true, doc: "why it is not running"},
         state:
           {{:enum, ~w(starting running restarting failed idle none)},
            doc:
              "as the video socket's `camera` message: `idle` is a `sim` camera nobody watches (it renders only while someone does)"},
         restarts: {:integer, doc: "times the camera program was started again"},
         codec:
           {{:enum, ~w(h264 mjpeg)},
            null: true, doc: "the current stream's; null before its first picture"},
         width: {:integer, null: true, doc: "the current stream's picture width, pixels"},
         height: {:integer, null: true, doc: "the current stream's picture height, pixels"}
       ]},

    # --- helm ------------------------------------------------------------------------------
    helm:
      {:object,
       "The helm: who pilots, who asks, the countdowns (`helm` event, the snapshot's `helm`).",
       [
         state: {:helm_state, essential: true},
         epoch:
           {:integer,
            essential: true,
            doc: "the stamp `thrust` must carry; changes on every grant and every deadman stop"},
         pilot: {:helm_pilot, null: true, essential: true},
         request: {:helm_request, null: true, essential: true},
         takeover: {:helm_takeover, null: true, essential: true},
         deadman_ms: {:integer, unit: "ms", essential: true},
         heartbeat_ms: {:integer, unit: "ms", essential: true},
         request_timeout_ms: {:integer, unit: "ms", essential: true},
         takeover_ms: {:integer, unit: "ms", essential: true}
       ]},
    helm_state: {:enum, ~w(free piloted requested takeover), "The helm's state."},
    party:
      {:object, "One connection of one user, as the helm names it.",
       [
         id: {:string, essential: true, doc: "the connection's id (its snapshot's `session.id`)"},
         name: {:string, essential: true},
         role: {:role, essential: true}
       ]},
    role: {:enum, ~w(pilot observer main_station), "A user's role."},
    helm_pilot:
      {:object, "The pilot.",
       [since: {:integer, unit: "ms since the epoch", null: true, doc: "when it got the helm"}],
       extends: :party},
    helm_request:
      {:object, "A pending request for control.",
       [
         from: {:party, essential: true},
         remaining_ms: {:integer, unit: "ms", essential: true, doc: "time left when sent"}
       ]},
    helm_takeover:
      {:object, "The main station's takeover countdown.",
       [
         by: {:party, essential: true},
         countdown_ms: {:integer, unit: "ms", essential: true, doc: "time left when sent"}
       ]},
    grant:
      {:object, "What the new pilot picks up (`control_granted`, a `granted` reply).",
       [
         epoch: {:integer, essential: true, doc: "the stamp for `thrust`"},
         pilot: {:helm_pilot, essential: true},
         control: {:control_state, essential: true, doc: "the control state to pick up"},
         deadman_ms: {:integer, unit: "ms", essential: true},
         heartbeat_ms: {:integer, unit: "ms", essential: true}
       ]},
    session:
      {:object, "Who this connection is.",
       [
         id: {:string, essential: true, doc: "this connection's id"},
         name: {:string, essential: true},
         role: {:role, essential: true},
         mode: {{:enum, ~w(local secure)}, essential: true, doc: "the server's security mode"}
       ]},

    # --- join replies ------------------------------------------------------------------------
    vehicle_snapshot:
      {:object, "The join reply of `vehicle:<id>`: the vehicle's state.",
       [
         vehicle: {:vehicle_info, essential: true},
         telemetry:
           {:telemetry, null: true, essential: true, doc: "null before the first sample"},
         pilot: {:pilot, null: true, essential: true, doc: "null: nobody pilots"},
         helm: {:helm, essential: true},
         control: {:control_state, essential: true},
         mission:
           {:mission, null: true, doc: "the mission in dp, with its waypoints; null: none"},
         camera: {:camera_info, null: true, doc: "null: the vehicle has no camera"},
         settings: {:vehicle_settings, doc: "the vehicle's settings every page applies"},
         session: {:session, essential: true}
       ]},
    vehicle_info:
      {:object, "A vehicle in the snapshot.",
       [
         id: {:string, essential: true},
         board: {:string, essential: true, doc: "`simulated`, `uart`, `sitl`, `mavlink`"},
         node: {:string, doc: "the node of the fleet it runs on"},
         axes:
           {{:list, :axis},
            doc:
              "the body-frame axes the vehicle can be commanded in (its board's, when the page joined): the pilot's inputs offer these; the three-thruster vehicle has `surge`, `heave`, `yaw`; a simulated `neptunus-sway` (a lateral thruster) and an ArduSub vehicle whose frame strafes `sway` too (an ArduSub's are known once its frame is: telemetry's `axes` follow them)"},
         autopilots:
           {{:enum, ~w(neptunus vehicle)},
            doc:
              "whose depth and heading hold `autopilot` drives: Neptunus' own, or the vehicle's flight modes (ArduSub)"}
       ]},
    axis:
      {:enum, ~w(surge sway heave yaw roll pitch),
       "A body-frame axis: surge forward, sway to starboard, heave down, yaw bow to starboard, roll, pitch."},
    pilot: {:object, "Who pilots.", [name: {:string, essential: true}]},
    camera_info:
      {:object, "Where the camera can be watched (see [Video](#video)).",
       [
         codec:
           {{:enum, ~w(h264 mjpeg)},
            essential: true, doc: "the camera's codec (configured or probed)"},
         video:
           {:string,
            essential: true,
            doc: "the video WebSocket's path (pages add `?token=…` in secure mode)"},
         url:
           {:string,
            null: true,
            doc:
              "the MJPEG stream for `<img>`, only for an MJPEG camera (pages add `?token=…` in secure mode)"}
       ]},
    snapshot:
      {:object, "A snapshot: the camera's picture saved as a JPEG next to the recordings.",
       [
         vehicle: {:string, essential: true},
         name: {:string, essential: true, doc: "the file's name (vehicle, time, depth, heading)"},
         bytes: {:integer, doc: "the file's size"},
         taken_at: {:number, unit: "ms since the epoch", doc: "when it was taken"},
         depth:
           {:number, null: true, unit: "m", doc: "the vehicle's depth then; null: not known"},
         heading:
           {:number, null: true, unit: "rad", doc: "the vehicle's heading then; null: not known"},
         width:
           {:integer, optional: true, doc: "pixels (only in the answer to the snapshot itself)"},
         height:
           {:integer, optional: true, doc: "pixels (only in the answer to the snapshot itself)"},
         url: {:string, essential: true, doc: "where to download it (`GET`)"},
         node: {:string, doc: "the node of the fleet that keeps it"}
       ]},
    snapshot_result:
      {:object, "A snapshot's outcome (the event `snapshot`, to the connection that asked).",
       [
         ok: {:boolean, essential: true},
         snapshot: {:snapshot, optional: true, doc: "the saved snapshot (`ok: true`)"},
         reason: {:string, optional: true, doc: "why not (`ok: false`)"}
       ]},
    accepted:
      {:object, "Accepted; the outcome follows as an event.",
       [status: {{:enum, ~w(pending)}, essential: true}]},
    vehicle_settings:
      {:object, "A vehicle's settings every page applies (stored on the server).",
       [
         camera_rotation:
           {{:enum, [0, 90, 180, 270]},
            unit: "°", essential: true, doc: "how the camera is mounted, clockwise"}
       ]},
    fleet_reply:
      {:object, "Every vehicle of the fleet (all nodes').",
       [vehicles: {{:list, :fleet_vehicle}, essential: true}]},
    fleet_vehicle:
      {:object,
       "A vehicle of the fleet's directory (as in `/api/health`); of an unreachable node's vehicle only `id`, `board`, `node` and `status` are known.",
       [
         id: {:string, essential: true},
         board: {:string, essential: true},
         node: {:string, doc: "the node it runs on"},
         status: {{:enum, ~w(up unreachable)}, doc: "`unreachable`: its node is cut off"},
         helm: {:helm_state, null: true, doc: "the helm's state"},
         pilot: {:string, null: true, doc: "the pilot's name; null: nobody"},
         link: {:link_summary, null: true, doc: "null before the first telemetry"},
         depth: {:number, unit: "m", null: true, doc: "measured (rounded to cm in `vehicles`)"},
         heading:
           {:number, unit: "rad", null: true, doc: "measured (rounded to mrad in `vehicles`)"},
         recording: {:boolean, doc: "its recorder records"}
       ]},
    link_summary:
      {:object, "The board link, in short.", [up: {:boolean, essential: true}, reason: :string]},
    log_join: {:object, "The join reply of `log:<id>`.", [vehicle: {:string, essential: true}]},

    # --- events ------------------------------------------------------------------------------
    reason:
      {:object, "Why (a reason a person can read, or one of the documented words).",
       [reason: {:string, essential: true}]},
    control_lost:
      {:object, "Why this connection lost control.",
       [
         reason:
           {{:enum,
             ~w(released control_transferred main_station_takeover pilot_left pilot_disconnected pilot_unreachable)},
            essential: true}
       ]},
    request_denied:
      {:object, "Why a request for control was denied.",
       [reason: {{:enum, ~w(denied request_timeout main_station_takeover)}, essential: true}]},
    control_request: {:object, "Someone asks for control.", [from: {:party, essential: true}]},
    vehicle_answer:
      {:object, "A mavlink vehicle's late answer.",
       [
         command: {{:enum, ~w(arm disarm autopilot position_source)}, essential: true},
         ok: {:boolean, essential: true},
         reason: {:string, optional: true, doc: "why not (`ok: false`)"}
       ]},
    board_event:
      {:object,
       "The board restarted (its uptime went backwards, or it printed its start-up line `boot:1;`), or its deadman tripped and was cleared (the link sent its whole state again); or thrust is held at neutral until the board confirms its motor modifiers.",
       [
         event: {{:enum, ~w(reset deadman_recovery thrust_held)}, essential: true},
         reason: :string
       ]},
    firmware_event:
      {:object, "The board's output shows another firmware line than configured.",
       [
         configured: {:string, essential: true},
         detected: {:string, essential: true}
       ]},
    recording_stopped:
      {:object, "The recorder stopped: the disk refused.",
       [
         recording: {:boolean, essential: true, doc: "false"},
         error: {:string, essential: true}
       ]},
    unreachable:
      {:object, "A vehicle's node was cut off.",
       [
         id: {:string, essential: true},
         node: {:string, essential: true},
         reason: {{:enum, ["node_unreachable"]}, essential: true}
       ]},
    reachable:
      {:object, "A vehicle's node is back.",
       [id: {:string, essential: true}, node: {:string, essential: true}]},
    presence_diff:
      {:object, "Phoenix Presence: who joined and left, keyed by user name.",
       [
         joins: {{:map, :presence}, essential: true},
         leaves: {{:map, :presence}, essential: true}
       ]},
    presence:
      {:object, "One user's connections.", [metas: {{:list, :presence_meta}, essential: true}]},
    presence_meta:
      {:object, "One connection of a user.",
       [
         phx_ref: {:string, essential: true, doc: "tells metas apart"},
         name: :string,
         role: :role,
         pilot: {:boolean, doc: "this connection pilots"},
         since: {:integer, unit: "ms since the epoch", doc: "when it joined"},
         online_at: {:integer, unit: "ms since the epoch"},
         conn: {:string, doc: "its connection id"},
         node: {:string, doc: "the node it is connected to"}
       ]},
    log_entry:
      {:object, "A developer logger entry; each category adds its own fields.",
       [
         category:
           {:string,
            essential: true, doc: "`safety`, `errors`, `recording`, `autopilot`, `vehicle`, …"},
         level: {{:enum, ~w(info warning error)}, essential: true},
         message: {:string, essential: true},
         at: {:integer, unit: "ms since the epoch", essential: true}
       ], open: true},

    # --- commands and replies --------------------------------------------------------------
    empty: {:object, "Nothing.", []},
    thrust:
      {:one_of, [:thrust_motion, :thrust_manual],
       "A thrust in the control mode's terms, stamped with the grant's epoch."},
    thrust_motion:
      {:object, "A motion-mode thrust: absolute axis values, not key presses.",
       [
         mode: {{:enum, ["motion"]}, essential: true},
         surge: {:number, essential: true, doc: "[-1, 1]"},
         heave: {:number, essential: true, doc: "[-1, 1]"},
         yaw: {:number, essential: true, doc: "[-1, 1]"},
         sway:
           {:number,
            optional: true,
            doc: "[-1, 1], to starboard: a vehicle with `sway` in its axes; elsewhere only 0"},
         epoch: {:integer, essential: true, doc: "the stamp from the grant"}
       ]},
    thrust_manual:
      {:object, "A manual-mode thrust: each thruster.",
       [
         mode: {{:enum, ["manual"]}, essential: true},
         port: {:number, essential: true, doc: "[-1, 1]"},
         vertical: {:number, essential: true, doc: "[-1, 1]"},
         starboard: {:number, essential: true, doc: "[-1, 1]"},
         epoch: {:integer, essential: true, doc: "the stamp from the grant"}
       ]},
    thrust_reply:
      {:object, "The command in force and the thrusters.",
       [
         command: {:pilot_command, essential: true},
         thrusters: {:thrusters, essential: true},
         control: :control_state
       ]},
    stop:
      {:object, "A stop.",
       [
         reason:
           {:string, optional: true, doc: "1..100 bytes, shown to everyone; default `pilot_stop`"}
       ]},
    clock_reply:
      {:object, "The server's wall clock (the clock of telemetry's `sent_at`).",
       [now: {:number, unit: "ms since the epoch", essential: true, doc: "µs resolution"}]},
    control_reply:
      {:one_of, [:granted, :pending, :takeover],
       "Control is granted, pending the pilot's answer, or taken after a countdown."},
    granted:
      {:object, "Control is granted.",
       [status: {{:enum, ["granted"]}, essential: true}, grant: {:grant, essential: true}]},
    pending:
      {:object, "The pilot has been asked.",
       [
         status: {{:enum, ["pending"]}, essential: true},
         timeout_ms:
           {:integer, unit: "ms", essential: true, doc: "how long the pilot has to answer"}
       ]},
    takeover:
      {:object, "The main station takes control after a countdown.",
       [
         status: {{:enum, ["takeover"]}, essential: true},
         countdown_ms: {:integer, unit: "ms", essential: true, doc: "when control moves"}
       ]},
    answer: {:object, "The pilot's answer to a request.", [accept: {:boolean, essential: true}]},
    helm_reply: {:object, "The helm after the command.", [helm: {:helm, essential: true}]},
    control_mode_change: {:object, "A control mode.", [mode: {:control_mode, essential: true}]},
    run_mode_change: {:object, "A run mode.", [mode: {:run_mode, essential: true}]},
    set_number: {:object, "A value.", [value: {:number, essential: true}]},
    set_level: {:object, "A level.", [value: {:integer, essential: true, doc: "0..255"}]},
    control_update:
      {:object, "The control state after the command.",
       [control: {:control_state, essential: true}]},
    autopilot_command:
      {:object,
       "Per key: a number engages that autopilot at that setpoint (or changes it), `\"hold\"` at the current estimate, null disengages it; an absent key changes nothing.",
       [
         depth:
           {{:one_of, [:number, {:enum, ["hold"]}]},
            unit: "m", optional: true, null: true, doc: "[0, 200]"},
         heading:
           {{:one_of, [:number, {:enum, ["hold"]}]},
            unit: "rad", optional: true, null: true, doc: "[-2π, 2π], wrapped to [0, 2π)"}
       ]},
    mission_event:
      {:object, "The mission now.",
       [mission: {:mission, null: true, essential: true, doc: "null: none"}]},
    mission_command:
      {:object,
       "A mission command: `start` or `plan` with `waypoints` or a `survey`; `pause`, `resume`, `abort` alone.",
       [
         action: {{:enum, ~w(start plan pause resume abort)}, essential: true},
         waypoints:
           {{:list, :waypoint_in}, optional: true, doc: "1..100, in the position's frame"},
         survey: {:survey, optional: true, doc: "a lawnmower survey to make the waypoints"}
       ]},
    waypoint_in:
      {:object, "A waypoint to fly to.",
       [
         north: {:number, unit: "m", essential: true},
         east: {:number, unit: "m", essential: true},
         depth: {:number, unit: "m", essential: true, doc: "[0, 200]"},
         heading:
           {:number,
            unit: "rad",
            optional: true,
            null: true,
            doc: "[-2π, 2π]; null or absent: the guidance's"},
         speed: {:number, unit: "m/s", optional: true, doc: "[0.05, 1], default 0.3"},
         radius:
           {:number, unit: "m", optional: true, doc: "acceptance radius [0.2, 20], default 0.5"}
       ]},
    survey:
      {:object,
       "A lawnmower survey: lines `length` m long in the direction `heading`, `spacing` m apart, covering `width` m to starboard of the first, which starts at (north, east).",
       [
         north: {:number, unit: "m", essential: true},
         east: {:number, unit: "m", essential: true},
         heading: {:number, unit: "rad", essential: true, doc: "the lines' direction"},
         length: {:number, unit: "m", essential: true, doc: "[1, 1000]"},
         width: {:number, unit: "m", essential: true, doc: "[0, 1000]"},
         spacing: {:number, unit: "m", essential: true, doc: "[0.5, 100]"},
         depth: {:number, unit: "m", essential: true},
         speed: {:number, unit: "m/s", optional: true},
         radius: {:number, unit: "m", optional: true}
       ]},
    mission_reply:
      {:object, "The control state and the mission after the command.",
       [
         control: {:control_state, essential: true},
         mission: {:mission, null: true, essential: true, doc: "null: no mission"},
         waypoints:
           {{:list, :waypoint},
            optional: true, doc: "`plan` only: the waypoints the mission would fly"}
       ]},
    position_source_command:
      {:object, "A command for a position source's device.",
       [
         source: {:string, essential: true, doc: "`dvl`"},
         command: {{:enum, ~w(reset_dead_reckoning calibrate_gyro)}, essential: true}
       ]},
    vehicle_request:
      {:object,
       "A device's answer within 200 ms (`ok`), or still awaited (`pending`: it follows as `vehicle_answer`): a mavlink vehicle's, a position source's.",
       [
         status: {{:enum, ~w(ok pending)}, essential: true},
         control: {:control_state, essential: true}
       ]},
    sim_set:
      {:object, "Simulator settings to change (at least one).",
       [
         paused: {:boolean, optional: true, doc: "freeze or resume simulated time"},
         current:
           {{:list, :number},
            unit: "m/s", optional: true, doc: "water current [n, e, d], each in [-5, 5]"},
         tether_length:
           {:number,
            unit: "m", optional: true, doc: "deployed tether, 0..1000; 0 removes its drag"}
       ]},
    sim_reply: {:object, "The simulator's settings.", [sim: {:sim_status, essential: true}]},
    sim_status:
      {:object, "The simulator's settings.",
       [
         vehicle: {:string, doc: "its parameter set"},
         t: {:number, unit: "s"},
         dt: {:number, unit: "s"},
         current: {{:list, :number}, unit: "m/s", doc: "[n, e, d]"},
         tether_length: {:number, unit: "m"},
         noise: {:boolean, doc: "realistic sensors"},
         seed: :integer,
         paused: :boolean
       ]},
    pid_gains:
      {:object, "A PID loop's gains.",
       [
         kp: {:number, essential: true},
         ki: {:number, essential: true},
         kd: {:number, essential: true}
       ]},
    tuning_gains:
      {:object, "The depth and heading autopilots' gains.",
       [depth: {:pid_gains, essential: true}, heading: {:pid_gains, essential: true}]},
    pid_gains_change:
      {:object, "Gains to change.",
       [
         kp: {:number, optional: true, doc: "[0, 20]"},
         ki: {:number, optional: true, doc: "[0, 5]"},
         kd: {:number, optional: true, doc: "[0, 20]"}
       ]},
    tuning_change:
      {:object, "Gains to change, per autopilot.",
       [
         depth: {:pid_gains_change, optional: true},
         heading: {:pid_gains_change, optional: true}
       ]},
    tuning_info:
      {:object,
       "The gains in force, the defaults, their ranges and the simulator model a step runs on.",
       [
         gains: {:tuning_gains, essential: true},
         defaults: {:tuning_gains, essential: true},
         ranges: {:tuning_ranges, essential: true},
         model: {:string, essential: true}
       ]},
    tuning_ranges:
      {:object, "Each gain's range, `[min, max]`.",
       [
         kp: {{:list, :number}, essential: true, doc: "[0, 20]"},
         ki: {{:list, :number}, essential: true, doc: "[0, 5]"},
         kd: {{:list, :number}, essential: true, doc: "[0, 20]"}
       ]},
    step_request:
      {:object, "A step to try on the vehicle's simulator model.",
       [
         axis: {{:enum, ~w(depth heading)}, essential: true},
         step: {:number, essential: true, doc: "m or rad, at most 10 m or 3 rad"},
         gains: {:tuning_change, optional: true, doc: "proposed gains, over those in force"}
       ]},
    step_response:
      {:object, "A step response, every 0.1 s for 20 s.",
       [
         axis: {{:enum, ~w(depth heading)}, essential: true},
         step: {:number, essential: true},
         target: {:number, essential: true},
         band: {:number, essential: true, doc: "5 cm or 2°"},
         t: {{:list, :number}, unit: "s", essential: true},
         setpoint:
           {{:list, {:or_null, :number}}, essential: true, doc: "null while no autopilot holds"},
         reference:
           {{:list, {:or_null, :number}}, essential: true, doc: "null while no autopilot holds"},
         value: {{:list, :number}, essential: true, doc: "the true depth or heading"},
         output: {{:list, :number}, essential: true, doc: "the axis' thruster command"},
         overshoot: {:number, essential: true, doc: "past the target, m or rad"},
         settle:
           {:number,
            unit: "s",
            null: true,
            essential: true,
            doc: "to stay within `band`; null: it does not settle"}
       ]},
    tuning_reply: {:object, "The gains in force.", [tuning: {:tuning_gains, essential: true}]},
    camera_rotation:
      {:object, "The camera rotation.",
       [value: {{:enum, [0, 90, 180, 270]}, unit: "°", essential: true, doc: "clockwise"}]}
  ]

  # ---------------------------------------------------------------------------------------
  # Messages

  @vehicle_events [
    %{
      name: "telemetry",
      payload: :telemetry,
      doc:
        "20 Hz; while someone pilots: the pilot's connection first, observers in slices every 2 ms, all within 25 ms"
    },
    %{
      name: "mission",
      payload: :mission_event,
      doc:
        "the mission started, changed (a waypoint reached, paused, resumed, moved with the position's frame) or ended (`mission: null`)"
    },
    %{
      name: "helm",
      payload: :helm,
      doc: "every change of the helm: state, pilot, request, takeover countdown, epoch"
    },
    %{
      name: "stopped",
      payload: :reason,
      doc:
        "thrusters were driven neutral, for safety or by request (reasons: [Safety stops](#safety-stops))"
    },
    %{
      name: "vehicle_settings",
      payload: :vehicle_settings,
      doc: "the vehicle's settings changed (`set_camera_rotation`)"
    },
    %{
      name: "link",
      payload: :link_status,
      doc:
        "the board link of a `uart` or `sitl` vehicle came up or went down (`{up, reason}`, see [Board link](#board-link)); on a `mavlink` vehicle its heartbeat came (`heartbeat`) or stopped (`no heartbeat from the vehicle for 3.0 s`)"
    },
    %{
      name: "snapshot",
      payload: :snapshot_result,
      to: "one connection",
      doc: "the outcome of this connection's `snapshot` command"
    },
    %{
      name: "vehicle_answer",
      payload: :vehicle_answer,
      to: "one connection",
      doc:
        "a `mavlink` vehicle's late answer to its `arm`, `disarm` or `autopilot`, or a position source's to `position_source`, whose reply was `pending` (see [ArduSub vehicles](#ardusub), [docs/POSITION.md](POSITION.md))"
    },
    %{
      name: "board",
      payload: :board_event,
      doc:
        "the board restarted, or its own deadman tripped and was cleared: the link sent its whole state again (see [Board link](#board-link))"
    },
    %{
      name: "firmware",
      payload: :firmware_event,
      doc:
        "the board's output shows another firmware line than configured (once per link process; see [docs/OPENROV.md](OPENROV.md))"
    },
    %{
      name: "recording",
      payload: :recording_stopped,
      doc: "the recorder stopped because the disk refused (a `log` entry says why)"
    },
    %{
      name: "presence_state",
      payload: {:map, :presence},
      to: "one connection",
      doc: "Phoenix Presence, after each join and when the server's presence process restarted"
    },
    %{
      name: "presence_diff",
      payload: :presence_diff,
      doc:
        "Phoenix Presence: on every join and leave, and when a grant or a loss of control re-announces a meta"
    },
    %{
      name: "control_request",
      payload: :control_request,
      to: "the pilot",
      doc: "`from` asks for control; answer with `answer_request`"
    },
    %{name: "control_granted", payload: :grant, to: "the new pilot", doc: "control is yours"},
    %{name: "control_lost", payload: :control_lost, to: "the old pilot", doc: "control is gone"},
    %{
      name: "request_denied",
      payload: :request_denied,
      to: "the requester",
      doc: "the request was denied, timed out or overtaken by the main station"
    },
    %{
      name: "unreachable",
      payload: :unreachable,
      doc:
        "the vehicle's node is cut off (or went down): telemetry stops, commands answer `vehicle_unreachable`; a pilot connected here has lost control and gets `control_lost` `pilot_unreachable` (the vehicle's node stopped it for that reason; see [A fleet](#a-fleet))"
    },
    %{
      name: "reachable",
      payload: :reachable,
      doc:
        "the vehicle's node is back: telemetry resumes, a `helm` with the helm's state follows (what it broadcast while apart never came); nobody is in control until a `request_control`"
    }
  ]

  @pilot "the pilot"
  @tuner "the user who pilots (from any of their connections) or the main station"

  @vehicle_commands [
    # the helm and the pilot's commands
    %{
      group: :helm,
      name: "thrust",
      payload: :thrust,
      reply: :thrust_reply,
      who: @pilot,
      doc:
        "`mode` must be the control mode; `epoch` the stamp from the grant (see [Helm](#helm)). Motion mode uses the thesis' allocation (eq. 9.3) with gain k (default 0.5): `port = sat(k(X + M))`, `vertical = sat(kZ)`, `starboard = sat(k(X − M))`; a vehicle that allocates itself (ArduSub) gets the body-frame demand k·(surge, sway, heave, yaw) instead (docs/MAVLINK.md). `sway` only on a vehicle with `sway` in its axes (the snapshot's `vehicle.axes`): elsewhere `this vehicle has no sway …`",
      errors:
        "`stale_command`, `missing field: epoch`, `thrust mode manual does not match control mode motion`, `surge must be a number in [-1, 1], got …`, see [Error reasons](#error-reasons)"
    },
    %{
      group: :helm,
      name: "stop",
      payload: :stop,
      reply: :thrust_reply,
      who: @pilot,
      doc:
        "neutral, autopilots disengaged; broadcasts `stopped` with the reason (the operator page sends `window lost focus`, `page hidden`, `page closed`); no stamp needed"
    },
    %{
      group: :helm,
      name: "heartbeat",
      payload: :empty,
      reply: :empty,
      who: @pilot,
      doc: "feeds the deadman: the pilot sends it every `heartbeat_ms` (100 ms)"
    },
    %{
      group: :helm,
      name: "clock",
      payload: :empty,
      reply: :clock_reply,
      who: "anyone joined",
      doc:
        "the server's wall clock: a page estimates its offset from the round trip (`assets/src/lib/clock.ts`) and so knows how old each telemetry frame is on arrival"
    },
    %{
      group: :helm,
      name: "request_control",
      payload: :empty,
      reply: :control_reply,
      who: "pilots and the main station",
      doc: "granted at once on a free helm, else pending the pilot's answer (see [Helm](#helm))",
      errors: "`busy`, `forbidden` (observers)"
    },
    %{
      group: :helm,
      name: "answer_request",
      payload: :answer,
      reply: :helm_reply,
      who: @pilot,
      doc: "accept → control moves; deny → the requester gets `request_denied`",
      errors: "`no_request`, `accept must be true or false`"
    },
    %{
      group: :helm,
      name: "take_control",
      payload: :empty,
      reply: :control_reply,
      who: "the main station",
      doc: "`takeover` with a countdown; on a free helm `granted`",
      errors: "`forbidden`, `busy`"
    },
    %{
      group: :helm,
      name: "release_control",
      payload: :empty,
      reply: :helm_reply,
      who: "the pilot, a requester or the main station",
      doc: "stops the vehicle and frees the helm (or withdraws a request, cancels a takeover)"
    },

    # control (Neptunus.Vehicle.Control)
    %{
      group: :control,
      name: "set_control_mode",
      payload: :control_mode_change,
      reply: :control_update,
      who: @pilot,
      doc:
        "`motion`, `manual` or `dp`; a change stops the thrusters first (`stopped` `control_mode_changed`); the same mode again does nothing. `manual` disengages the autopilots (thesis §7.1). `dp` holds the current position, and depth and heading (engaged at their current values unless already engaged); without a position source it holds depth and heading only and says so (`control.dp_holds`). Back to `motion` from `dp`: DP ends, the depth and heading autopilots keep holding",
      errors:
        "`mode must be one of \"dp\", \"manual\", \"motion\", got …`, `dp needs a current estimate of depth and heading (no board samples)`, `dp needs depth hold: depth is initialising (…)`"
    },
    %{
      group: :control,
      name: "set_gain",
      payload: :set_number,
      reply: :control_update,
      who: @pilot,
      doc:
        "k in [0, 1]: the gain that scales the pilot's axes (motion) or thrusters (manual); the command in force is re-applied at once",
      errors: "`value must be a number in [0, 1], got …`"
    },
    %{
      group: :control,
      name: "set_lights",
      payload: :set_level,
      reply: :control_update,
      who: @pilot,
      doc:
        "an integer 0..255, set on the board at once (no \"resend the last thrust\": thesis §13.1)",
      errors: "`value must be an integer in [0, 255], got …`"
    },
    %{
      group: :control,
      name: "set_laser",
      payload: :set_level,
      reply: :control_update,
      who: @pilot,
      doc: "an integer 0..255, as `set_lights`",
      errors: "`value must be an integer in [0, 255], got …`"
    },
    %{
      group: :control,
      name: "set_tilt",
      payload: :set_number,
      reply: :control_update,
      who: @pilot,
      doc:
        "rad in [−π/4, π/4] (±0.7854): camera tilt, set at once (servo 1000..2000 µs, 1500 level)",
      errors: "`value must be a number in [-0.7854, 0.7854] (rad, ±45°), got …`"
    },
    %{
      group: :control,
      name: "autopilot",
      payload: :autopilot_command,
      reply: {:one_of, [:control_update, :vehicle_request]},
      who: @pilot,
      doc:
        "per key: a number engages that autopilot at that setpoint, or changes its setpoint (depth in [0, 200] m; heading in [−2π, 2π] rad, wrapped to [0, 2π)); `\"hold\"` engages it at the current estimated value; `null` disengages it; an absent key changes nothing. On a `mavlink` vehicle it sets the flight mode and replies as `arm` (see [ArduSub vehicles](#ardusub))",
      errors:
        "`autopilot needs depth and/or heading (…)`, `depth must be a depth in [0, 200] m, \"hold\" or null, got …`, `heading must be a heading in [-6.2832, 6.2832] rad, \"hold\" or null, got …` (degrees by mistake are caught), `no current estimate of depth and heading (no board samples): cannot engage`, `depth hold: depth is initialising (the board's depth sensor has not given consistent readings yet)` (and `heading hold: heading is initialising (the board's compass …)`, `… is stale (…)`, also for `dp needs …`), `autopilots are not available in manual mode: switch to motion or dp`, `dp holds depth and heading: switch to motion to release them`"
    },
    %{
      group: :control,
      name: "set_run_mode",
      payload: :run_mode_change,
      reply: :control_update,
      who: @pilot,
      doc:
        "`normal` or `simulator`, see *Run mode* below; a change stops the thrusters first (`stopped` `run_mode_changed`) and disengages the autopilots",
      errors:
        "`mode must be one of \"normal\", \"simulator\", got …`, `run mode simulator needs a vehicle with a real board: this one is simulated (its normal run mode is the simulator)`"
    },
    %{
      group: :control,
      name: "mission",
      payload: :mission_command,
      reply: :mission_reply,
      who: @pilot,
      doc:
        "in `dp` with a valid position: `start` flies the waypoints (or the survey's) with line-of-sight guidance from where the vehicle is; `plan` only checks them and answers the waypoints (a survey's, to show or edit); `pause` holds position, `resume` goes on with the leg, `abort` ends it and holds position (depth and heading without a position). A running mission sets depth and heading (`autopilot` is refused until it is paused or ended). Every stop ends it: a handover holds position, any other stop ends dp (see [Safety stops](#safety-stops))",
      errors:
        "`missions run in control mode dp: switch to dp first`, `a mission needs a valid position: …`, `a mission needs at least one waypoint`, `a mission has at most 100 waypoints, got …`, `waypoints[2].speed must be a number in [0.05, 1], got …`, `waypoint 3 is 250.0 m away: beyond the 200 m a mission may reach`, `waypoint 2 is 150.0 m deep: beyond this vehicle's 100 m`, `waypoints 1 and 2 are the same point`, `the survey makes 120 waypoints, at most 100: …`, `the mission is paused: nothing to pause`, `no mission to abort`"
    },
    %{
      group: :control,
      name: "position_source",
      payload: :position_source_command,
      reply: :vehicle_request,
      who: @pilot,
      doc:
        "a command for a DVL: `reset_dead_reckoning` (its own dead reckoning starts again at zero), `calibrate_gyro` (keep the vehicle still; up to 15 s). Answered `pending`, the DVL's answer follows as `vehicle_answer`",
      errors:
        "`no position source usbl on this vehicle`, `position source usbl takes no commands`, `command must be \"reset_dead_reckoning\" or \"calibrate_gyro\", got …`; in `vehicle_answer`: `DVL not connected (…)`, `the DVL refused calibrate_gyro: …`, `no response from the DVL in 20 s`"
    },

    # tuning and the vehicle's settings
    %{
      group: :tuning,
      name: "get_tuning",
      payload: :empty,
      reply: :tuning_info,
      who: "anyone",
      doc: "the gains in force, the defaults, their ranges and the model a step runs on"
    },
    %{
      group: :tuning,
      name: "step_response",
      payload: :step_request,
      reply: :step_response,
      who: @tuner,
      doc:
        "runs the step headless on the vehicle's simulator model with the gains in force and the proposed ones over them; changes nothing on the vehicle",
      errors:
        "`step must be a non-zero number in [-10.0, 10.0], got 0`, `depth.kp must be a number in [0, 20], got 30`"
    },
    %{
      group: :tuning,
      name: "set_tuning",
      payload: :tuning_change,
      reply: :tuning_reply,
      who: @tuner,
      doc: "applies the gains at once, bumplessly, and stores them for the vehicle",
      errors: "`depth.kp must be a number in [0, 20], got 30`, `unknown field: tuning.surge`"
    },
    %{
      group: :tuning,
      name: "set_camera_rotation",
      payload: :camera_rotation,
      reply: :vehicle_settings,
      who: @tuner,
      doc: "the camera image rotation every page applies; broadcast as `vehicle_settings`",
      errors: "`value must be one of 0, 90, 180, 270 (degrees), got 45`"
    },

    # The camera
    %{
      group: :camera,
      name: "snapshot",
      payload: :empty,
      reply: :accepted,
      who: "anyone joined",
      doc:
        "saves the camera's current picture (see [Snapshots](#snapshots)); the outcome follows as the event `snapshot` to this connection",
      errors:
        "as the event's `reason`: `vehicle … has no camera`, `the camera is starting: no picture yet`, `recording is off on this server: …`"
    },

    # ArduSub vehicles
    %{
      group: :ardusub,
      name: "arm",
      payload: :empty,
      reply: :vehicle_request,
      who: @pilot,
      doc: "arms a `mavlink` vehicle",
      errors:
        "the vehicle's refusal — the STATUSTEXT it sent with it, e.g. `PreArm: Must assign a disarm or arm_toggle button or disarm aux function`, else `failed`, `denied`, …; `the vehicle's link is down (…)`; `a arm command is still waiting for the vehicle's answer`; `no answer from the vehicle within 3.0 s` (as `vehicle_answer`); on other boards `this vehicle's board has no arming (only mavlink vehicles arm)`"
    },
    %{
      group: :ardusub,
      name: "disarm",
      payload: :empty,
      reply: :vehicle_request,
      who: @pilot,
      doc: "disarms a `mavlink` vehicle",
      errors: "as `arm`"
    },

    # the built-in simulator
    %{
      group: :sim,
      name: "sim_reset",
      payload: :empty,
      reply: :sim_reply,
      who: @pilot,
      doc:
        "the vehicle is back at its start, at rest; the thrusters are stopped first (`stopped` with reason `sim_reset`). Current and tether length set since are kept",
      errors: "`unknown field: seed (no fields expected)`"
    },
    %{
      group: :sim,
      name: "sim_set",
      payload: :sim_set,
      reply: :sim_reply,
      who: @pilot,
      doc:
        "changes the simulator's settings (telemetry keeps coming while paused, with the same `t`)",
      errors:
        "`sim_set needs at least one of: current, paused, tether_length`, `current[0] must be a number in [-5, 5], got 7`, `paused must be true or false, got \"yes\"`, `tether_length must be a number in [0, 1000], got -1`"
    }
  ]

  @fleet_events [
    %{
      name: "vehicles",
      payload: :fleet_reply,
      doc:
        "the list whenever it changed, at most once a second (depth rounded to cm, heading to mrad)"
    },
    %{
      name: "unreachable",
      payload: :unreachable,
      doc: "at once, for every vehicle of another node that is cut off"
    },
    %{name: "reachable", payload: :reachable, doc: "at once, when it is back"}
  ]

  @joins [
    %{topic: "vehicle", name: "phx_join", payload: :vehicle_snapshot, doc: "the vehicle's state"},
    %{topic: "fleet", name: "phx_join", payload: :fleet_reply, doc: "every vehicle of the fleet"},
    %{topic: "log", name: "phx_join", payload: :log_join, doc: "the vehicle"}
  ]

  @log_events [
    %{name: "log", payload: :log_entry, doc: "every entry the vehicle's processes publish"}
  ]

  # ---------------------------------------------------------------------------------------
  # Access

  @doc "Every named definition, normalised, in the schema's order."
  @spec definitions() :: [definition()]
  def definitions do
    Enum.map(@types, fn {name, definition} -> normalise(name, definition) end)
  end

  @doc "The definition named `name`; raises for an unknown name."
  @spec definition(atom()) :: definition()
  def definition(name) do
    case List.keyfind(@types, name, 0) do
      {^name, definition} -> normalise(name, definition)
      nil -> raise ArgumentError, "no wire type #{inspect(name)}"
    end
  end

  @doc "Whether `type` is one of the primitive types (not a name defined here)."
  @spec primitive?(type()) :: boolean()
  def primitive?(type), do: type in @primitives

  @doc """
  The server's events (`topic`: `"vehicle"` for `vehicle:<id>`, `"fleet"`, `"log"` for
  `log:<id>`).
  """
  @spec events() :: [message()]
  def events do
    Enum.map(@vehicle_events, &Map.put(&1, :topic, "vehicle")) ++
      Enum.map(@fleet_events, &Map.put(&1, :topic, "fleet")) ++
      Enum.map(@log_events, &Map.put(&1, :topic, "log"))
  end

  @doc "The clients' commands on `vehicle:<id>`, with their replies."
  @spec commands() :: [message()]
  def commands, do: Enum.map(@vehicle_commands, &Map.put(&1, :topic, "vehicle"))

  @doc "The join replies of each topic."
  @spec joins() :: [message()]
  def joins, do: @joins

  @doc "The event `name` on `topic`'s payload type; raises for an unknown event."
  @spec event!(String.t(), String.t()) :: type()
  def event!(topic, name), do: find!(events(), topic, name).payload

  @doc "The command `name` on `topic`: `%{payload, reply, …}`; raises for an unknown one."
  @spec command!(String.t(), String.t()) :: message()
  def command!(topic, name), do: find!(commands(), topic, name)

  defp find!(messages, topic, name) do
    Enum.find(messages, &(&1.topic == topic and &1.name == name)) ||
      raise ArgumentError, "no #{name} on #{topic} in the wire schema"
  end

  # ---------------------------------------------------------------------------------------
  # Normalisation

  defp normalise(name, {:enum, values, doc}),
    do: %{kind: :enum, name: name, doc: doc, values: values}

  defp normalise(name, {:one_of, types, doc}),
    do: %{kind: :union, name: name, doc: doc, types: types}

  defp normalise(name, {:object, doc, fields}), do: normalise(name, {:object, doc, fields, []})

  defp normalise(name, {:object, doc, fields, opts}) do
    inherited =
      case Keyword.fetch(opts, :extends) do
        {:ok, parent} -> definition(parent).fields
        :error -> []
      end

    %{
      kind: :object,
      name: name,
      doc: doc,
      fields: inherited ++ Enum.map(fields, &field/1),
      open: Keyword.get(opts, :open, false),
      extends: Keyword.get(opts, :extends)
    }
  end

  defp field({name, {type, [{_, _} | _] = opts}}) do
    %{
      name: name,
      type: type,
      doc: Keyword.get(opts, :doc, ""),
      unit: Keyword.get(opts, :unit),
      null: Keyword.get(opts, :null, false),
      optional: Keyword.get(opts, :optional, false),
      essential: Keyword.get(opts, :essential, false)
    }
  end

  defp field({name, type}), do: field({name, {type, [doc: ""]}})
end
