/**
 * The pages' view of the Neptunus channels (`fleet`, `vehicle:<id>`), on the decoders generated
 * from the wire schema (`wire.gen.ts`, from lib/neptunus_web/wire_schema.ex: every field's type,
 * unit and meaning is there). Where a type here is the generated one it is re-exported; the
 * others are views the pages were written against: a measurement or estimate not known reads NaN
 * (the plots draw numbers), a manual command is `manual` beside a null motion `command`, a serial
 * link's details are grouped under `link.board`, and a snapshot from a server without `helm` or
 * `session` reads them null.
 *
 * Units are SI throughout (m, m/s, rad, rad/s); degrees exist only in the view (see units.ts).
 */

import * as wire from "./wire.gen";
import { isRecord } from "./wire_runtime";

export { isRecord };

export type SimState = wire.SimState;
/** A motion command; `sway` only from a vehicle that has it (absent or null: none). */
export type MotionCommand = Omit<wire.MotionCommand, "sway"> & { readonly sway?: number | null };
export type ThrusterOutputs = wire.ThrusterOutputs;
export type Thrusters = wire.Thrusters;
export type ControlMode = wire.ControlMode;
export type RunMode = wire.RunMode;
export type MeasurementState = wire.MeasurementState;
export type MeasurementStates = wire.MeasurementStates;
export type Role = wire.Role;
export type AuthMode = wire.Session["mode"];
export type Party = wire.Party;
export type HelmPilot = wire.HelmPilot;
export type HelmStateName = wire.HelmState;
export type Helm = wire.Helm;
export type Session = wire.Session;
export type Pilot = wire.Pilot;
export type CameraInfo = wire.CameraInfo;
export type RecordingStatus = wire.RecordingStatus;
export type CameraStatus = wire.CameraStatus;
export type VehicleSettings = wire.VehicleSettings;
export type PositionStatus = wire.PositionStatus;
export type PositionSource = wire.PositionSource;
export type PositionEllipse = wire.PositionEllipse;
export type DpStatus = wire.DpStatus;
export type Mission = wire.Mission;
export type MissionState = wire.MissionState;
export type MissionReply = wire.MissionReply;
export type Waypoint = wire.Waypoint;
export type WaypointIn = wire.WaypointIn;

export const CONTROL_MODES: readonly ControlMode[] = wire.CONTROL_MODE_VALUES;
export const RUN_MODES: readonly RunMode[] = wire.RUN_MODE_VALUES;

export interface VehicleInfo {
  readonly id: string;
  readonly board: string;
  /** the node of the fleet it runs on (servers of a fleet say) */
  readonly node?: string;
  /** "up", or "unreachable" while its node is cut off from the server's */
  readonly status?: string;
  /** the fleet's directory (topic `fleet`) says these; absent from a snapshot or an older server */
  readonly detail?: FleetDetail;
  /**
   * the body-frame axes it can be commanded in (a snapshot says; absent from the directory or
   * an older server: surge, heave, yaw)
   */
  readonly axes?: readonly wire.Axis[];
}

/** What the fleet's directory says of a vehicle (nulls: unknown, or its node is cut off). */
export interface FleetDetail {
  /** the helm's state ("free", "held", …) */
  readonly helm: string | null;
  /** the pilot's name; null: nobody */
  readonly pilot: string | null;
  /** the board link (null before the first telemetry) */
  readonly link: wire.LinkSummary | null;
  /** m, positive down */
  readonly depth: number | null;
  /** rad */
  readonly heading: number | null;
  /** whether its recorder records */
  readonly recording: boolean;
}

/** Sensor readings (`wire.Measurement`), NaN for a value not known (initialising). */
export type Measurement = { readonly [K in keyof wire.Measurement]: number };

/** Autopilot setpoints: depth (m) and heading (rad), null when that autopilot is off. */
export interface AutopilotSetpoints {
  readonly depth: number | null;
  readonly heading: number | null;
}

/** The control settings (`wire.ControlSettings`); fields a server does not send read null. */
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
  /** the mission in dp (its waypoints come with the `mission` event); absent or null: none */
  readonly mission?: MissionState | null;
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
  /** DP: its target, phase and a mission's guidance (absent outside dp) */
  readonly position?: DpStatus;
}

/** The navigation filter's depth and heading estimate (NaN for a value not known). */
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

/**
 * A mavlink vehicle's armed state and modes (`wire.MavlinkStatus`, docs/MAVLINK.md), and its
 * frame once the vehicle told it (its `FRAME_CONFIG`: whether it sways).
 */
export type MavlinkStatus = Pick<wire.MavlinkStatus, "armed" | "mode" | "system_status"> & { readonly frame?: string };

/** The board link's liveness fields (`wire.LinkStatus`), from a board on a serial link. */
export interface BoardLinkDetails {
  readonly rtt_ms: number | null;
  readonly pong_age_ms: number | null;
  readonly board_deadman_armed: boolean | null;
  readonly firmware: string;
  readonly detected_firmware: string | null;
  readonly firmware_mismatch: boolean;
  readonly commands_sent: number | null;
  readonly commands_confirmed: number | null;
  /** whether the board confirmed (echoed) every setting sent to it; null: not reported */
  readonly board_settings: "confirmed" | "pending" | "failed" | null;
  /** the settings it has not confirmed: mtrmod1, mtrmod2 (motor modifiers), lights, laser, tilt */
  readonly board_settings_pending: readonly string[];
  /** why a setting failed (past the bound of writes), else null */
  readonly board_settings_reason: string | null;
  /** thrust other than neutral is held (sent as neutral) until the motor modifiers are confirmed */
  readonly thrust_held: boolean;
}

export interface WildPoints {
  readonly total: number;
  readonly by_field: Readonly<Record<string, number>>;
}

/**
 * The camera address an `<img>` can load: our own server's stream (a path) needs the login
 * token in the query, since an image request carries no Authorization header. Other sites'
 * addresses are left alone (the token is never sent elsewhere).
 */
export function cameraWithToken(camera: CameraInfo | null, token: string | null): CameraInfo | null {
  if (camera === null || token === null) return camera;
  return { ...camera, video: withToken(camera.video, token), url: camera.url === null ? null : withToken(camera.url, token) };
}

/** `url` with `token` added, when it is our own server's (a path); another server's as it is. */
function withToken(url: string, token: string): string {
  if (!ownPath(url)) return url;
  const separator = url.includes("?") ? "&" : "?";
  return `${url}${separator}token=${encodeURIComponent(token)}`;
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
  /** the position estimate and its sources (absent from an older server) */
  readonly position?: PositionStatus;
  /**
   * the body-frame axes the pilot may command now (absent from an older server, or before
   * control's first report): they follow the vehicle, e.g. an ArduSub's once its frame is known
   */
  readonly axes?: readonly string[];
  /** the payload as received (plots derive their series from it) */
  readonly raw: Readonly<Record<string, unknown>>;
}

/** What the new pilot picks up (pick-up procedure). */
export interface ControlState extends ControlSettings {
  readonly command: MotionCommand | null;
}

/** `control_granted` and the `granted` reply of `request_control` / `take_control`. */
export interface Grant extends Omit<wire.Grant, "control"> {
  readonly control: ControlState;
}

export type ControlReply =
  | { readonly status: "granted"; readonly grant: Grant }
  | wire.Pending
  | wire.Takeover;

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
  /** the mission in dp with its waypoints (absent or null: none) */
  readonly mission?: Mission | null;
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
// Decoders: the generated ones, or the views above built from them.

type Json = Record<string, unknown>;

export const decodeMotionCommand = wire.decodeMotionCommand;
export const decodeThrusters = wire.decodeThrusters;
export const decodeThrusterOutputs = wire.decodeThrusterOutputs;
export const decodeMeasurementStates = wire.decodeMeasurementStates;
export const decodeRecordingStatus = wire.decodeRecordingStatus;
export const decodeCameraStatus = wire.decodeCameraStatus;
export const decodeVehicleSettings = wire.decodeVehicleSettings;
export const decodeParty = wire.decodeParty;
export const decodeSession = wire.decodeSession;

/** A value not known (null) as NaN, for views that draw numbers. */
function orNaN(value: number | null): number {
  return value ?? Number.NaN;
}

function controlSettings(c: wire.ControlSettings): ControlSettings {
  const { mode, gain, lights, laser, tilt, run_mode, autopilot, dp_holds, mission } = c;
  return {
    mode,
    gain,
    lights,
    laser,
    tilt,
    run_mode,
    autopilot: autopilot && { depth: autopilot.depth, heading: autopilot.heading },
    ...(dp_holds ? { dp_holds } : {}),
    ...(mission ? { mission } : {}),
  };
}

function controlState(c: wire.ControlState): ControlState {
  return { ...controlSettings(c), command: motionOnly(c.command) };
}

function motionOnly(command: wire.PilotCommand | null): MotionCommand | null {
  return command !== null && "surge" in command ? withSway(command) : null;
}

/** A motion command with `sway` only when the vehicle's command has one (no `sway: null`). */
function withSway(command: wire.MotionCommand): MotionCommand {
  const { surge, heave, yaw, sway } = command;
  return sway === null ? { surge, heave, yaw } : { surge, heave, yaw, sway };
}

function autopilotLoop(loop: wire.AutopilotLoop | null): AutopilotLoop | null {
  if (loop === null) return null;
  const { setpoint, output, waiting, reference } = loop;
  return { setpoint, output, waiting, ...(reference !== null ? { reference } : {}) };
}

function autopilotStatus(s: wire.AutopilotStatus): AutopilotStatus {
  return { depth: autopilotLoop(s.depth), heading: autopilotLoop(s.heading), ...(s.position ? { position: s.position } : {}) };
}

function linkStatus(l: wire.LinkStatus): LinkStatus {
  const board: BoardLinkDetails | null =
    l.firmware === null
      ? null
      : {
          rtt_ms: l.rtt_ms,
          pong_age_ms: l.pong_age_ms,
          board_deadman_armed: l.board_deadman_armed,
          firmware: l.firmware,
          detected_firmware: l.detected_firmware,
          firmware_mismatch: l.firmware_mismatch === true,
          commands_sent: l.commands_sent,
          commands_confirmed: l.commands_confirmed,
          board_settings: l.board_settings,
          board_settings_pending: l.board_settings_pending ?? [],
          board_settings_reason: l.board_settings_reason,
          thrust_held: l.thrust_held === true,
        };
  const mavlink = l.mavlink && mavlinkStatus(l.mavlink);
  return { up: l.up, reason: l.reason, ...(board ? { board } : {}), ...(mavlink ? { mavlink } : {}) };
}

function mavlinkStatus(m: wire.MavlinkStatus): MavlinkStatus {
  return { armed: m.armed, mode: m.mode, system_status: m.system_status, ...(m.frame !== null ? { frame: m.frame } : {}) };
}

/** Control settings (telemetry's `control`, or a control state); null unless it has a mode. */
export function decodeControlSettings(value: unknown): ControlSettings | null {
  const c = wire.decodeControlSettings(value);
  return c && controlSettings(c);
}

export function decodeAutopilotStatus(value: unknown): AutopilotStatus | null {
  const s = wire.decodeAutopilotStatus(value);
  return s && autopilotStatus(s);
}

export function decodeLinkStatus(value: unknown): LinkStatus | null {
  const l = wire.decodeLinkStatus(value);
  return l && linkStatus(l);
}

export function decodeMavlinkStatus(value: unknown): MavlinkStatus | null {
  const m = wire.decodeMavlinkStatus(value);
  return m && mavlinkStatus(m);
}

export function decodeWildPoints(value: unknown): WildPoints | null {
  const w = wire.decodeWildPoints(value);
  return w && { total: w.total, by_field: w.by_field ?? {} };
}

/** Telemetry (`wire.Telemetry`, see there what it needs), in the view above. */
export function decodeTelemetry(value: unknown): Telemetry | null {
  const t = wire.decodeTelemetry(value);
  if (t === null || !isRecord(value)) return null;
  const m = t.measurement;
  const e = t.estimate;
  const command = motionOnly(t.command);
  return {
    t: t.t,
    sent_at: t.sent_at,
    measurement: {
      depth: orNaN(m.depth),
      heading: orNaN(m.heading),
      roll: orNaN(m.roll),
      pitch: orNaN(m.pitch),
      voltage: orNaN(m.voltage),
      current: orNaN(m.current),
    },
    measurement_state: t.measurement_state,
    sim: t.sim,
    command,
    manual: command === null && "port" in t.command ? t.command : null,
    thrusters: t.thrusters,
    control: t.control && controlSettings(t.control),
    autopilot: t.autopilot && autopilotStatus(t.autopilot),
    estimate: e && {
      depth: orNaN(e.depth),
      depth_rate: orNaN(e.depth_rate),
      heading: orNaN(e.heading),
      yaw_rate: orNaN(e.yaw_rate),
    },
    link: t.link && linkStatus(t.link),
    wild_points: t.wild_points && { total: t.wild_points.total, by_field: t.wild_points.by_field ?? {} },
    recording: t.recording,
    camera_status: t.camera,
    ...(t.position ? { position: t.position } : {}),
    ...(t.axes ? { axes: t.axes } : {}),
    raw: value,
  };
}

/**
 * The camera of the snapshot: `camera: {codec, video, url}` — this server's video socket (a path:
 * the page never opens another host's socket with its token) and, for an MJPEG camera, the `<img>`
 * stream (http(s) or a path).
 */
export function decodeCamera(snapshot: Record<string, unknown>): CameraInfo | null {
  const camera = wire.decodeCameraInfo(snapshot["camera"]);
  if (camera === null || !ownPath(camera.video) || (camera.url !== null && !safeUrl(camera.url))) return null;
  return camera;
}

/** A path on this server (not another host's address, not a protocol-relative one). */
function ownPath(url: string): boolean {
  return url.startsWith("/") && !url.startsWith("//");
}

/** A URL a page may load: http(s) or a path on this server (never `javascript:` and the like). */
function safeUrl(url: string): boolean {
  return /^(https?:\/\/|\/)/.test(url);
}

/** A vehicle of the fleet's directory, or of a snapshot (`wire.FleetVehicle`). */
export function decodeVehicleInfo(value: unknown): VehicleInfo | null {
  const v = wire.decodeFleetVehicle(value);
  if (v === null || !isRecord(value)) return null;
  const detail = decodeFleetDetail(value);
  const axes = decodeAxes(value["axes"]);
  return {
    id: v.id,
    board: v.board,
    ...(axes ? { axes } : {}),
    ...(v.node !== null ? { node: v.node } : {}),
    ...(v.status !== null ? { status: v.status } : {}),
    ...(detail ? { detail } : {}),
  };
}

/** A list of body-frame axes (a snapshot's `vehicle.axes`), or null when it is not one. */
function decodeAxes(value: unknown): readonly wire.Axis[] | null {
  if (!Array.isArray(value)) return null;
  const axes = value.map(wire.decodeAxis);
  return axes.every((a): a is wire.Axis => a !== null) ? axes : null;
}

const FLEET_DETAIL_KEYS = ["helm", "pilot", "link", "depth", "heading", "recording"];

/**
 * The directory's fields of a fleet entry (`helm`, `pilot`, `link`, `depth`, `heading`,
 * `recording`), or null when it has none of them (a snapshot's vehicle, an older server).
 */
export function decodeFleetDetail(value: Json): FleetDetail | null {
  if (!FLEET_DETAIL_KEYS.some((k) => k in value)) return null;
  const v = wire.decodeFleetVehicle(value);
  return v && { helm: v.helm, pilot: v.pilot, link: v.link, depth: v.depth, heading: v.heading, recording: v.recording === true };
}

/** `null` and a missing pilot both mean "nobody"; anything else malformed is `undefined`. */
export function decodePilot(value: unknown): Pilot | null | undefined {
  if (value === null || value === undefined) return null;
  return wire.decodePilot(value) ?? undefined;
}

export function decodeFleetReply(value: unknown): FleetReply | null {
  if (!isRecord(value) || !Array.isArray(value["vehicles"])) return null;
  const vehicles = value["vehicles"].map(decodeVehicleInfo);
  return vehicles.every((v): v is VehicleInfo => v !== null) ? { vehicles } : null;
}

/** Absent or null: null; else what `decode` makes of it (undefined: it does not decode). */
function absentOr<T>(value: unknown, decode: (value: unknown) => T | null): T | null | undefined {
  return value === undefined || value === null ? null : (decode(value) ?? undefined);
}

export function decodeVehicleSnapshot(value: unknown): VehicleSnapshot | null {
  if (!isRecord(value)) return null;
  const vehicle = decodeVehicleInfo(value["vehicle"]);
  const telemetry = absentOr(value["telemetry"], decodeTelemetry);
  const pilot = decodePilot(value["pilot"]);
  const helm = absentOr(value["helm"], decodeHelm);
  const session = absentOr(value["session"], decodeSession);
  if (!vehicle || telemetry === undefined || pilot === undefined || helm === undefined || session === undefined) return null;
  const control = decodeControlSettings(value["control"]);
  const settings = decodeVehicleSettings(value["settings"]);
  const mission = wire.decodeMission(value["mission"]);
  return {
    vehicle,
    telemetry,
    pilot,
    helm,
    session,
    control,
    camera: decodeCamera(value),
    ...(settings ? { settings } : {}),
    ...(mission ? { mission } : {}),
  };
}

/** The helm; a helm piloted by nobody (but free) is malformed. */
export function decodeHelm(value: unknown): Helm | null {
  const helm = wire.decodeHelm(value);
  return helm && (helm.pilot !== null || helm.state === "free") ? helm : null;
}

export function decodeGrant(value: unknown): Grant | null {
  const g = wire.decodeGrant(value);
  return g && { ...g, control: controlState(g.control) };
}

export function decodeControlReply(value: unknown): ControlReply | null {
  const reply = wire.decodeControlReply(value);
  if (reply?.status !== "granted") return reply;
  const grant = decodeGrant(reply.grant);
  return grant && { status: "granted", grant };
}

/** `thrust` and `stop` replies; the pulse widths, when the server sends them, are dropped. */
export function decodeThrustReply(value: unknown): ThrustReply | null {
  if (!isRecord(value)) return null;
  const pilot = wire.decodePilotCommand(value["command"]);
  const command = pilot !== null && "surge" in pilot ? withSway(pilot) : pilot;
  const thrusters = wire.decodeThrusterOutputs(value["thrusters"]);
  return command && thrusters ? { command, thrusters } : null;
}

/** The `ok` reply of the settings commands: `{control: C}`. */
export function decodeControlUpdate(value: unknown): ControlSettings | null {
  const update = wire.decodeControlUpdate(value);
  return update && controlSettings(update.control);
}

/** Reply to `clock`: `{now}`, the server's wall clock in ms since the epoch. */
export function decodeClock(value: unknown): number | null {
  return wire.decodeClockReply(value)?.now ?? null;
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
