/**
 * Wire types of the Neptunus channels (`fleet`, `vehicle:<id>`) and decoders that turn the
 * untyped JSON the phoenix client hands us into these types, or `null` when the shape is wrong.
 *
 * Units are SI throughout (m, m/s, rad, rad/s); degrees exist only in the view (see units.ts).
 */

export interface VehicleInfo {
  readonly id: string;
  readonly board: string;
  /** the node of the fleet it runs on (servers of a fleet say) */
  readonly node?: string;
  /** "up", or "unreachable" while its node is cut off from the server's */
  readonly status?: string;
  /** the fleet's directory (topic `fleet`) says these; absent from a snapshot or an older server */
  readonly detail?: FleetDetail;
}

/** What the fleet's directory says of a vehicle (nulls: unknown, or its node is cut off). */
export interface FleetDetail {
  /** the helm's state ("free", "held", …) */
  readonly helm: string | null;
  /** the pilot's name; null: nobody */
  readonly pilot: string | null;
  /** the board link (null before the first telemetry) */
  readonly link: { readonly up: boolean; readonly reason: string | null } | null;
  /** m, positive down */
  readonly depth: number | null;
  /** rad */
  readonly heading: number | null;
  /** whether its recorder records */
  readonly recording: boolean;
}

/** Sensor readings as the board reports them (after wild-point rejection). */
export interface Measurement {
  /** m, positive down */
  readonly depth: number;
  /** rad, [0, 2π) */
  readonly heading: number;
  /** rad */
  readonly roll: number;
  /** rad */
  readonly pitch: number;
  /** V */
  readonly voltage: number;
  /** A */
  readonly current: number;
}

/**
 * Simulated 6-DOF state (Fossen notation, NED: z is depth): position x, y, z (m), Euler angles
 * phi, theta, psi (rad), body velocities u, v, w (m/s) and p, q, r (rad/s).
 */
export interface SimState {
  readonly x: number;
  readonly y: number;
  readonly z: number;
  readonly phi: number;
  readonly theta: number;
  readonly psi: number;
  readonly u: number;
  readonly v: number;
  readonly w: number;
  readonly p: number;
  readonly q: number;
  readonly r: number;
}

/** Motion command, each axis in [-1, 1]. */
export interface MotionCommand {
  readonly surge: number;
  readonly heave: number;
  readonly yaw: number;
}

/** Thruster outputs in [-1, 1] (positive: forward for port/starboard, down for vertical). */
export interface ThrusterOutputs {
  readonly port: number;
  readonly vertical: number;
  readonly starboard: number;
}

/** Outputs and the PWM pulse widths sent to the ESCs (1000..2000 µs, 1500 neutral). */
export interface Thrusters extends ThrusterOutputs {
  readonly port_us: number;
  readonly vertical_us: number;
  readonly starboard_us: number;
}

export type ControlMode = "motion" | "manual" | "dp";
export type RunMode = "normal" | "simulator";
export const CONTROL_MODES: readonly ControlMode[] = ["motion", "manual", "dp"];
export const RUN_MODES: readonly RunMode[] = ["normal", "simulator"];

/** Autopilot setpoints: depth (m) and heading (rad), null when that autopilot is off. */
export interface AutopilotSetpoints {
  readonly depth: number | null;
  readonly heading: number | null;
}

/**
 * The control settings (`control` in telemetry, the snapshot, grants and the `ok` replies of
 * the settings commands). Fields a server does not send yet are null.
 */
export interface ControlSettings {
  readonly mode: string;
  /** [0, 1] */
  readonly gain: number | null;
  /** 0..255 */
  readonly lights: number | null;
  /** 0..255 */
  readonly laser: number | null;
  /** rad, [-π/4, π/4] */
  readonly tilt: number | null;
  readonly run_mode: string | null;
  readonly autopilot: AutopilotSetpoints | null;
  /** in control mode dp, what DP holds: `["depth", "heading", "position"]`, or without a position source `["depth", "heading"]` */
  readonly dp_holds?: readonly string[];
}

/** One autopilot loop: its setpoint (m or rad) and output. */
export interface AutopilotLoop {
  readonly setpoint: number;
  /** what the loop tracks on its way to the setpoint (rate- and acceleration-limited; m or rad) */
  readonly reference?: number;
  readonly output: number;
  /** why it gives no output now (its measurement initialising after a board reset, …); null: it acts */
  readonly waiting: string | null;
}

export interface AutopilotStatus {
  readonly depth: AutopilotLoop | null;
  readonly heading: AutopilotLoop | null;
}

/**
 * Whether a measurement can be trusted: `initialising` (no valid reading since the server
 * started, the board link came up or the board reset — the server sends no number for it),
 * `valid`, or `stale` (no plausible reading for 2 s: the last value is kept).
 */
export type MeasurementState = "initialising" | "valid" | "stale";

/** The state of each measurement (`measurement_state` in telemetry). */
export type MeasurementStates = Readonly<Record<(typeof MEASUREMENT_KEYS)[number], MeasurementState>>;

/** The navigation filter's estimate (NaN for a field the server does not send). */
export interface Estimate {
  /** m */
  readonly depth: number;
  /** m/s */
  readonly depth_rate: number;
  /** rad */
  readonly heading: number;
  /** rad/s */
  readonly yaw_rate: number;
}

/** The board link (serial boards; simulated vehicles have none). */
export interface LinkStatus {
  readonly up: boolean;
  readonly reason: string | null;
  /** what the board's replies say, from a board on a serial link (absent otherwise) */
  readonly board?: BoardLinkDetails;
  /** the vehicle's own state, from a mavlink (ArduSub) vehicle (absent otherwise) */
  readonly mavlink?: MavlinkStatus;
}

/** A mavlink vehicle's state in telemetry `link.mavlink` (docs/API.md, docs/MAVLINK.md). */
export interface MavlinkStatus {
  readonly armed: boolean;
  /** ArduSub's flight mode (`MANUAL`, `ALT_HOLD`, …); null before its first heartbeat */
  readonly mode: string | null;
  readonly system_status: string | null;
}

/** The board link's liveness fields in telemetry `link` (docs/API.md). */
export interface BoardLinkDetails {
  /** last ping → pong round trip (ms) */
  readonly rtt_ms: number | null;
  /** how long ago the last pong arrived (ms), at the server */
  readonly pong_age_ms: number | null;
  /** whether the board's own deadman is armed (its uptime past 180 s); null: not known */
  readonly board_deadman_armed: boolean | null;
  readonly firmware: string;
  readonly detected_firmware: string | null;
  readonly firmware_mismatch: boolean;
  readonly commands_sent: number | null;
  readonly commands_confirmed: number | null;
}

export interface WildPoints {
  readonly total: number;
  readonly by_field: Readonly<Record<string, number>>;
}

/** Where the vehicle's camera can be watched (from the snapshot). */
export interface CameraInfo {
  /** an address an `<img>` or `<video>` plays (this server's MJPEG stream, or another host's); null: none */
  readonly url: string | null;
  /** this server's video socket for the camera (`/video/ID/websocket`, docs/API.md "Video"); null: none */
  readonly video: string | null;
}

/**
 * The camera address an `<img>` can load: our own server's stream (a path) needs the login
 * token in the query, since an image request carries no Authorization header. Other sites'
 * addresses are left alone (the token is never sent elsewhere).
 */
export function cameraWithToken(camera: CameraInfo | null, token: string | null): CameraInfo | null {
  const url = camera?.url ?? null;
  if (camera === null || url === null || token === null || !ownPath(url)) return camera;
  const separator = url.includes("?") ? "&" : "?";
  return { ...camera, url: `${url}${separator}token=${encodeURIComponent(token)}` };
}

/** A path on this server (not another host's address, not a protocol-relative one). */
function ownPath(url: string): boolean {
  return url.startsWith("/") && !url.startsWith("//");
}

export interface Telemetry {
  /** s, vehicle monotonic clock */
  readonly t: number;
  /** ms since the Unix epoch, when the server sent the sample */
  readonly sent_at: number;
  /** sensor readings; NaN for a value the board did not give (or not valid yet) */
  readonly measurement: Measurement;
  /** each measurement's state; null when the server does not say */
  readonly measurement_state: MeasurementStates | null;
  /** the simulator's true state; `null` on a real board */
  readonly sim: SimState | null;
  /** the motion command; null when the command is not a motion command (manual mode) */
  readonly command: MotionCommand | null;
  /** the manual command, when the command names thrusters */
  readonly manual: ThrusterOutputs | null;
  readonly thrusters: Thrusters;
  readonly control: ControlSettings | null;
  readonly autopilot: AutopilotStatus | null;
  readonly estimate: Estimate | null;
  readonly link: LinkStatus | null;
  readonly wild_points: WildPoints | null;
  /** whether the server records this vehicle (null: the server does not say) */
  readonly recording: RecordingStatus | null;
  /** the vehicle's camera (null: it has none) */
  readonly camera_status: CameraStatus | null;
  /** the payload as received (plots derive their series from it) */
  readonly raw: Readonly<Record<string, unknown>>;
}

export interface Pilot {
  readonly name: string;
}

export type Role = "pilot" | "observer" | "main_station";
export type AuthMode = "local" | "secure";

/** One connection of one user, as the helm names it. */
export interface Party {
  /** connection id (the snapshot's `session.id` for this client) */
  readonly id: string;
  readonly name: string;
  readonly role: Role;
}

/** The pilot, with when it got the helm (ms since the Unix epoch). */
export interface HelmPilot extends Party {
  readonly since: number | null;
}

export type HelmStateName = "free" | "piloted" | "requested" | "takeover";

/** The `helm` event and the snapshot's `helm` (docs/API.md). */
export interface Helm {
  readonly state: HelmStateName;
  /** stamp for `thrust`; changes on every grant and every deadman stop */
  readonly epoch: number;
  readonly pilot: HelmPilot | null;
  readonly request: { readonly from: Party; readonly remaining_ms: number } | null;
  readonly takeover: { readonly by: Party; readonly countdown_ms: number } | null;
  readonly deadman_ms: number;
  readonly heartbeat_ms: number;
  readonly request_timeout_ms: number;
  readonly takeover_ms: number;
}

/** What the new pilot picks up (pick-up procedure). */
export interface ControlState extends ControlSettings {
  readonly command: MotionCommand | null;
}

/** `control_granted` and the `granted` reply of `request_control` / `take_control`. */
export interface Grant {
  readonly epoch: number;
  readonly pilot: HelmPilot;
  readonly control: ControlState;
  readonly deadman_ms: number;
  readonly heartbeat_ms: number;
}

/** Who this connection is (snapshot `session`). */
export interface Session {
  readonly id: string;
  readonly name: string;
  readonly role: Role;
  readonly mode: AuthMode;
}

export type ControlReply =
  | { readonly status: "granted"; readonly grant: Grant }
  | { readonly status: "pending"; readonly timeout_ms: number }
  | { readonly status: "takeover"; readonly countdown_ms: number };

export interface FleetReply {
  readonly vehicles: readonly VehicleInfo[];
}

/** Join reply of `vehicle:<id>`. `helm` and `session` are null from servers without them. */
export interface VehicleSnapshot {
  readonly vehicle: VehicleInfo;
  readonly telemetry: Telemetry | null;
  readonly pilot: Pilot | null;
  readonly helm: Helm | null;
  readonly session: Session | null;
  readonly control: ControlSettings | null;
  /** null: the vehicle has no camera (or the server does not say) */
  readonly camera: CameraInfo | null;
  /** the vehicle's view settings (absent from an older server) */
  readonly settings?: VehicleSettings;
}

/** A vehicle's settings every page applies (`settings` in the snapshot, `vehicle_settings`). */
export interface VehicleSettings {
  /** the camera image rotation, degrees clockwise: 0, 90, 180 or 270 */
  readonly camera_rotation: number;
}

/** `vehicle_settings` (and the snapshot's `settings`), or null. */
export function decodeVehicleSettings(value: unknown): VehicleSettings | null {
  if (!isRecord(value)) return null;
  const r = value["camera_rotation"];
  return r === 0 || r === 90 || r === 180 || r === 270 ? { camera_rotation: r } : null;
}

/** Reply to a `thrust` or `stop` push (outputs only; the pulse widths come with telemetry). */
export interface ThrustReply {
  /** Motion mode echoes `{surge, heave, yaw}`; manual mode `{port, vertical, starboard}`. */
  readonly command: MotionCommand | ThrusterOutputs;
  readonly thrusters: ThrusterOutputs;
}

/** One entry of the Presence list (one key, possibly several connections). */
export interface PresenceEntry {
  readonly key: string;
  /** display name from the first meta that has one, else the key */
  readonly name: string;
  readonly connections: number;
  /** role from the first meta that has one */
  readonly role: string | null;
  /** one of its connections pilots */
  readonly pilot: boolean;
}

// ---------------------------------------------------------------------------------------------
// Decoders

type Json = Record<string, unknown>;

export function isRecord(value: unknown): value is Json {
  return typeof value === "object" && value !== null && !Array.isArray(value);
}

function isFiniteNumber(value: unknown): value is number {
  return typeof value === "number" && Number.isFinite(value);
}

/** Picks the named finite-number fields from `value`; `null` if any is missing or not a number. */
function numbers<K extends string>(
  value: unknown,
  keys: readonly K[],
): { readonly [P in K]: number } | null {
  if (!isRecord(value)) return null;
  const out: Partial<Record<K, number>> = {};
  for (const key of keys) {
    const v = value[key];
    if (!isFiniteNumber(v)) return null;
    out[key] = v;
  }
  return out as { [P in K]: number };
}

const MEASUREMENT_KEYS = ["depth", "heading", "roll", "pitch", "voltage", "current"] as const;
const SIM_KEYS = ["x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r"] as const;
const COMMAND_KEYS = ["surge", "heave", "yaw"] as const;
const OUTPUT_KEYS = ["port", "vertical", "starboard"] as const;
const THRUSTER_KEYS = [
  "port",
  "vertical",
  "starboard",
  "port_us",
  "vertical_us",
  "starboard_us",
] as const;

export function decodeMotionCommand(value: unknown): MotionCommand | null {
  return numbers(value, COMMAND_KEYS);
}

export function decodeThrusters(value: unknown): Thrusters | null {
  return numbers(value, THRUSTER_KEYS);
}

export function decodeThrusterOutputs(value: unknown): ThrusterOutputs | null {
  return numbers(value, OUTPUT_KEYS);
}

/** Like `numbers`, but a missing or null field reads NaN ("not known"); null if not a record. */
function lenientNumbers<K extends string>(
  value: unknown,
  keys: readonly K[],
): { readonly [P in K]: number } | null {
  if (!isRecord(value)) return null;
  const out: Partial<Record<K, number>> = {};
  for (const key of keys) {
    const v = value[key];
    out[key] = isFiniteNumber(v) ? v : Number.NaN;
  }
  return out as { [P in K]: number };
}

const ESTIMATE_KEYS = ["depth", "depth_rate", "heading", "yaw_rate"] as const;

function numberOrNull(value: unknown): number | null {
  return isFiniteNumber(value) ? value : null;
}

/** Control settings; null unless it has at least a string `mode`. */
export function decodeControlSettings(value: unknown): ControlSettings | null {
  if (!isRecord(value) || typeof value["mode"] !== "string") return null;
  const ap = value["autopilot"];
  const autopilot = isRecord(ap)
    ? { depth: numberOrNull(ap["depth"]), heading: numberOrNull(ap["heading"]) }
    : null;
  const runMode = value["run_mode"];
  const dpHolds: unknown = value["dp_holds"];
  return {
    mode: value["mode"],
    gain: numberOrNull(value["gain"]),
    lights: numberOrNull(value["lights"]),
    laser: numberOrNull(value["laser"]),
    tilt: numberOrNull(value["tilt"]),
    run_mode: typeof runMode === "string" ? runMode : null,
    autopilot,
    ...(Array.isArray(dpHolds) ? { dp_holds: dpHolds.filter((x): x is string => typeof x === "string") } : {}),
  };
}

function decodeLoop(value: unknown): AutopilotLoop | null {
  const loop = numbers(value, ["setpoint", "output"] as const);
  if (!loop || !isRecord(value)) return null;
  const waiting = value["waiting"];
  const reference = value["reference"];
  return {
    setpoint: loop.setpoint,
    output: loop.output,
    waiting: typeof waiting === "string" ? waiting : null,
    ...(typeof reference === "number" && Number.isFinite(reference) ? { reference } : {}),
  };
}

export function decodeAutopilotStatus(value: unknown): AutopilotStatus | null {
  if (!isRecord(value)) return null;
  return { depth: decodeLoop(value["depth"]), heading: decodeLoop(value["heading"]) };
}

export function decodeLinkStatus(value: unknown): LinkStatus | null {
  if (!isRecord(value) || typeof value["up"] !== "boolean") return null;
  const reason = value["reason"];
  const board = decodeBoardLinkDetails(value);
  const mavlink = decodeMavlinkStatus(value["mavlink"]);
  return {
    up: value["up"],
    reason: typeof reason === "string" ? reason : null,
    ...(board ? { board } : {}),
    ...(mavlink ? { mavlink } : {}),
  };
}

export function decodeMavlinkStatus(value: unknown): MavlinkStatus | null {
  if (!isRecord(value) || typeof value["armed"] !== "boolean") return null;
  const mode = value["mode"];
  const status = value["system_status"];
  return {
    armed: value["armed"],
    mode: typeof mode === "string" ? mode : null,
    system_status: typeof status === "string" ? status : null,
  };
}

function decodeBoardLinkDetails(value: Record<string, unknown>): BoardLinkDetails | null {
  const firmware = value["firmware"];
  if (typeof firmware !== "string") return null;
  const num = (v: unknown): number | null => (typeof v === "number" && Number.isFinite(v) ? v : null);
  const armed = value["board_deadman_armed"];
  const detected = value["detected_firmware"];
  return {
    rtt_ms: num(value["rtt_ms"]),
    pong_age_ms: num(value["pong_age_ms"]),
    board_deadman_armed: typeof armed === "boolean" ? armed : null,
    firmware,
    detected_firmware: typeof detected === "string" ? detected : null,
    firmware_mismatch: value["firmware_mismatch"] === true,
    commands_sent: num(value["commands_sent"]),
    commands_confirmed: num(value["commands_confirmed"]),
  };
}

export interface RecordingStatus {
  readonly on: boolean;
  /** why recording stopped (null: it is on, or off by configuration) */
  readonly error: string | null;
}

export interface CameraStatus {
  readonly running: boolean;
  readonly fps: number;
  readonly error: string | null;
}

export function decodeRecordingStatus(value: unknown): RecordingStatus | null {
  if (!isRecord(value) || typeof value["on"] !== "boolean") return null;
  const error = value["error"];
  return { on: value["on"], error: typeof error === "string" ? error : null };
}

export function decodeCameraStatus(value: unknown): CameraStatus | null {
  if (!isRecord(value) || typeof value["running"] !== "boolean" || !isFiniteNumber(value["fps"])) return null;
  const error = value["error"];
  return { running: value["running"], fps: value["fps"], error: typeof error === "string" ? error : null };
}

const MEASUREMENT_STATES: readonly string[] = ["initialising", "valid", "stale"];

function isMeasurementState(value: unknown): value is MeasurementState {
  return typeof value === "string" && MEASUREMENT_STATES.includes(value);
}

/** Each measurement's state; null unless every measurement has a known one. */
export function decodeMeasurementStates(value: unknown): MeasurementStates | null {
  if (!isRecord(value)) return null;
  const out: Partial<Record<(typeof MEASUREMENT_KEYS)[number], MeasurementState>> = {};
  for (const key of MEASUREMENT_KEYS) {
    const state = value[key];
    if (!isMeasurementState(state)) return null;
    out[key] = state;
  }
  return out as MeasurementStates;
}

export function decodeWildPoints(value: unknown): WildPoints | null {
  if (!isRecord(value) || !isFiniteNumber(value["total"])) return null;
  const byField: Record<string, number> = {};
  const raw = value["by_field"];
  if (isRecord(raw)) for (const [k, v] of Object.entries(raw)) if (isFiniteNumber(v)) byField[k] = v;
  return { total: value["total"], by_field: byField };
}

/**
 * Telemetry. Required: `t`, `sent_at`, a `measurement` object (fields the board did not give
 * read NaN), `sim` (object or null), `thrusters`. The command is a motion command or names
 * thrusters (manual mode). The fields later servers add (`control`, `autopilot`, `estimate`,
 * `link`, `wild_points`, `measurement_state`) are null when absent or malformed.
 */
export function decodeTelemetry(value: unknown): Telemetry | null {
  if (!isRecord(value)) return null;
  const { t, sent_at } = value;
  if (!isFiniteNumber(t) || !isFiniteNumber(sent_at)) return null;
  const measurement = lenientNumbers(value["measurement"], MEASUREMENT_KEYS);
  const rawSim = value["sim"];
  const sim = rawSim === null ? null : numbers(rawSim, SIM_KEYS);
  const command = decodeMotionCommand(value["command"]);
  const manual = command ? null : decodeThrusterOutputs(value["command"]);
  const thrusters = decodeThrusters(value["thrusters"]);
  if (!measurement || !thrusters || (!command && !manual)) return null;
  if (sim === null && rawSim !== null) return null;
  const estimate = lenientNumbers(value["estimate"], ESTIMATE_KEYS);
  return {
    t,
    sent_at,
    measurement,
    measurement_state: decodeMeasurementStates(value["measurement_state"]),
    sim,
    command,
    manual,
    thrusters,
    control: decodeControlSettings(value["control"]),
    autopilot: decodeAutopilotStatus(value["autopilot"]),
    estimate,
    link: decodeLinkStatus(value["link"]),
    wild_points: decodeWildPoints(value["wild_points"]),
    recording: decodeRecordingStatus(value["recording"]),
    camera_status: decodeCameraStatus(value["camera"]),
    raw: value,
  };
}

/**
 * The camera: `camera: {video, url}` in the snapshot (this server's video socket and, for an
 * MJPEG camera, its `<img>` stream), `camera: {url}` or a bare URL, else `vehicle.camera_url`.
 */
export function decodeCamera(snapshot: Record<string, unknown>): CameraInfo | null {
  const camera = snapshot["camera"];
  const vehicle = snapshot["vehicle"];
  const video = isRecord(camera) && typeof camera["video"] === "string" && ownPath(camera["video"]) ? camera["video"] : null;
  const candidates = [
    isRecord(camera) ? camera["url"] : camera,
    isRecord(vehicle) ? vehicle["camera_url"] : undefined,
    isRecord(vehicle) ? vehicle["video_url"] : undefined,
  ];
  for (const url of candidates) {
    if (typeof url === "string" && /^(https?:\/\/|\/)/.test(url)) return { url, video };
  }
  return video !== null ? { url: null, video } : null;
}

export function decodeVehicleInfo(value: unknown): VehicleInfo | null {
  if (!isRecord(value)) return null;
  const { id, board, node, status } = value;
  if (typeof id !== "string" || typeof board !== "string") return null;
  const detail = decodeFleetDetail(value);
  return {
    id,
    board,
    ...(typeof node === "string" ? { node } : {}),
    ...(typeof status === "string" ? { status } : {}),
    ...(detail ? { detail } : {}),
  };
}

function finiteOrNull(value: unknown): number | null {
  return typeof value === "number" && Number.isFinite(value) ? value : null;
}

function stringOrNull(value: unknown): string | null {
  return typeof value === "string" ? value : null;
}

/**
 * The directory's fields of a fleet entry (`helm`, `pilot`, `link`, `depth`, `heading`,
 * `recording`), or null when it has none of them (a snapshot's vehicle, an older server).
 * A malformed field reads as unknown (null).
 */
export function decodeFleetDetail(value: Json): FleetDetail | null {
  const keys = ["helm", "pilot", "link", "depth", "heading", "recording"];
  if (!keys.some((k) => k in value)) return null;
  const link = value["link"];
  return {
    helm: stringOrNull(value["helm"]),
    pilot: stringOrNull(value["pilot"]),
    link: isRecord(link) && typeof link["up"] === "boolean" ? { up: link["up"], reason: stringOrNull(link["reason"]) } : null,
    depth: finiteOrNull(value["depth"]),
    heading: finiteOrNull(value["heading"]),
    recording: value["recording"] === true,
  };
}

/** `null` and a missing pilot both mean "nobody"; anything else malformed is `undefined`. */
export function decodePilot(value: unknown): Pilot | null | undefined {
  if (value === null || value === undefined) return null;
  if (isRecord(value) && typeof value["name"] === "string") return { name: value["name"] };
  return undefined;
}

export function decodeFleetReply(value: unknown): FleetReply | null {
  if (!isRecord(value) || !Array.isArray(value["vehicles"])) return null;
  const vehicles: VehicleInfo[] = [];
  for (const v of value["vehicles"]) {
    const info = decodeVehicleInfo(v);
    if (!info) return null;
    vehicles.push(info);
  }
  return { vehicles };
}

export function decodeVehicleSnapshot(value: unknown): VehicleSnapshot | null {
  if (!isRecord(value)) return null;
  const vehicle = decodeVehicleInfo(value["vehicle"]);
  const raw = value["telemetry"];
  const telemetry = raw === null || raw === undefined ? null : decodeTelemetry(raw);
  const pilot = decodePilot(value["pilot"]);
  if (!vehicle || pilot === undefined) return null;
  if (telemetry === null && raw !== null && raw !== undefined) return null;
  const rawHelm = value["helm"];
  const helm = rawHelm === undefined ? null : decodeHelm(rawHelm);
  if (helm === null && rawHelm !== undefined) return null;
  const rawSession = value["session"];
  const session = rawSession === undefined ? null : decodeSession(rawSession);
  if (session === null && rawSession !== undefined) return null;
  const control = decodeControlSettings(value["control"]);
  const settings = decodeVehicleSettings(value["settings"]);
  return { vehicle, telemetry, pilot, helm, session, control, camera: decodeCamera(value), ...(settings ? { settings } : {}) };
}

const ROLES: readonly string[] = ["pilot", "observer", "main_station"];
const HELM_STATES: readonly string[] = ["free", "piloted", "requested", "takeover"];

function isRole(value: unknown): value is Role {
  return typeof value === "string" && ROLES.includes(value);
}

export function decodeParty(value: unknown): Party | null {
  if (!isRecord(value)) return null;
  const { id, name, role } = value;
  if (typeof id !== "string" || typeof name !== "string" || !isRole(role)) return null;
  return { id, name, role };
}

function decodeHelmPilot(value: unknown): HelmPilot | null {
  const party = decodeParty(value);
  if (!party || !isRecord(value)) return null;
  const since = value["since"];
  return { ...party, since: isFiniteNumber(since) ? since : null };
}

export function decodeHelm(value: unknown): Helm | null {
  if (!isRecord(value)) return null;
  const state = value["state"];
  if (typeof state !== "string" || !HELM_STATES.includes(state)) return null;
  const times = numbers(value, [
    "epoch",
    "deadman_ms",
    "heartbeat_ms",
    "request_timeout_ms",
    "takeover_ms",
  ] as const);
  if (!times) return null;

  const rawPilot = value["pilot"];
  const pilot = rawPilot === null ? null : decodeHelmPilot(rawPilot);
  if (pilot === null && (rawPilot !== null || state !== "free")) return null;

  let request: Helm["request"] = null;
  const rawRequest = value["request"];
  if (rawRequest !== null && rawRequest !== undefined) {
    const from = isRecord(rawRequest) ? decodeParty(rawRequest["from"]) : null;
    const remaining = isRecord(rawRequest) ? rawRequest["remaining_ms"] : undefined;
    if (!from || !isFiniteNumber(remaining)) return null;
    request = { from, remaining_ms: remaining };
  }

  let takeover: Helm["takeover"] = null;
  const rawTakeover = value["takeover"];
  if (rawTakeover !== null && rawTakeover !== undefined) {
    const by = isRecord(rawTakeover) ? decodeParty(rawTakeover["by"]) : null;
    const countdown = isRecord(rawTakeover) ? rawTakeover["countdown_ms"] : undefined;
    if (!by || !isFiniteNumber(countdown)) return null;
    takeover = { by, countdown_ms: countdown };
  }

  return { state: state as HelmStateName, ...times, pilot, request, takeover };
}

export function decodeGrant(value: unknown): Grant | null {
  if (!isRecord(value)) return null;
  const times = numbers(value, ["epoch", "deadman_ms", "heartbeat_ms"] as const);
  const pilot = decodeHelmPilot(value["pilot"]);
  const control = value["control"];
  const settings = decodeControlSettings(control);
  if (!times || !pilot || !settings || !isRecord(control)) return null;
  const command = decodeMotionCommand(control["command"]);
  return { ...times, pilot, control: { ...settings, command } };
}

export function decodeSession(value: unknown): Session | null {
  if (!isRecord(value)) return null;
  const { id, name, role, mode } = value;
  if (typeof id !== "string" || typeof name !== "string" || !isRole(role)) return null;
  if (mode !== "local" && mode !== "secure") return null;
  return { id, name, role, mode };
}

export function decodeControlReply(value: unknown): ControlReply | null {
  if (!isRecord(value)) return null;
  switch (value["status"]) {
    case "granted": {
      const grant = decodeGrant(value["grant"]);
      return grant ? { status: "granted", grant } : null;
    }
    case "pending": {
      const t = value["timeout_ms"];
      return isFiniteNumber(t) ? { status: "pending", timeout_ms: t } : null;
    }
    case "takeover": {
      const t = value["countdown_ms"];
      return isFiniteNumber(t) ? { status: "takeover", countdown_ms: t } : null;
    }
    default:
      return null;
  }
}

export function decodeThrustReply(value: unknown): ThrustReply | null {
  if (!isRecord(value)) return null;
  const command = decodeMotionCommand(value["command"]) ?? decodeThrusterOutputs(value["command"]);
  const thrusters = decodeThrusterOutputs(value["thrusters"]);
  return command && thrusters ? { command, thrusters } : null;
}

/** The `ok` reply of the settings commands: `{control: C}`. */
export function decodeControlUpdate(value: unknown): ControlSettings | null {
  return isRecord(value) ? decodeControlSettings(value["control"]) : null;
}

/** Reply to `clock`: `{now}`, the server's wall clock in ms since the epoch. */
export function decodeClock(value: unknown): number | null {
  return isRecord(value) && isFiniteNumber(value["now"]) ? value["now"] : null;
}

/** Readable reason from an error reply `{reason}`; falls back to the JSON of the reply. */
export function errorReason(value: unknown): string {
  if (isRecord(value) && typeof value["reason"] === "string" && value["reason"] !== "") {
    return value["reason"];
  }
  if (value === undefined) return "unknown error";
  try {
    return JSON.stringify(value);
  } catch {
    return String(value);
  }
}

/** One Presence list entry from the `(key, {metas})` pair that phoenix' Presence hands out. */
export function presenceEntry(key: string, presence: unknown): PresenceEntry {
  const metas = isRecord(presence) && Array.isArray(presence["metas"]) ? presence["metas"] : [];
  let name: string | null = null;
  let role: string | null = null;
  let pilot = false;
  for (const meta of metas) {
    if (!isRecord(meta)) continue;
    if (name === null && typeof meta["name"] === "string" && meta["name"] !== "") {
      name = meta["name"];
    }
    if (role === null && typeof meta["role"] === "string") role = meta["role"];
    if (meta["pilot"] === true) pilot = true;
  }
  return { key, name: name ?? key, connections: Math.max(1, metas.length), role, pilot };
}
