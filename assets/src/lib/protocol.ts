/**
 * Wire types of the Neptunus channels (`fleet`, `vehicle:<id>`) and decoders that turn the
 * untyped JSON the phoenix client hands us into these types, or `null` when the shape is wrong.
 *
 * Units are SI throughout (m, m/s, rad, rad/s); degrees exist only in the view (see units.ts).
 */

export interface VehicleInfo {
  readonly id: string;
  readonly board: string;
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

export interface Telemetry {
  /** s, vehicle monotonic clock */
  readonly t: number;
  /** ms since the Unix epoch, when the server sent the sample */
  readonly sent_at: number;
  readonly measurement: Measurement;
  /** the simulator's true state; `null` on a real board */
  readonly sim: SimState | null;
  readonly command: MotionCommand;
  readonly thrusters: Thrusters;
}

export interface Pilot {
  readonly name: string;
}

export interface FleetReply {
  readonly vehicles: readonly VehicleInfo[];
}

/** Join reply of `vehicle:<id>`. */
export interface VehicleSnapshot {
  readonly vehicle: VehicleInfo;
  readonly telemetry: Telemetry | null;
  readonly pilot: Pilot | null;
}

/** Reply to a `thrust` or `stop` push (outputs only; the pulse widths come with telemetry). */
export interface ThrustReply {
  readonly command: MotionCommand;
  readonly thrusters: ThrusterOutputs;
}

/** One entry of the Presence list (one key, possibly several connections). */
export interface PresenceEntry {
  readonly key: string;
  /** display name from the first meta that has one, else the key */
  readonly name: string;
  readonly connections: number;
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

export function decodeTelemetry(value: unknown): Telemetry | null {
  if (!isRecord(value)) return null;
  const { t, sent_at } = value;
  if (!isFiniteNumber(t) || !isFiniteNumber(sent_at)) return null;
  const measurement = numbers(value["measurement"], MEASUREMENT_KEYS);
  const rawSim = value["sim"];
  const sim = rawSim === null ? null : numbers(rawSim, SIM_KEYS);
  const command = decodeMotionCommand(value["command"]);
  const thrusters = decodeThrusters(value["thrusters"]);
  if (!measurement || !command || !thrusters) return null;
  if (sim === null && rawSim !== null) return null;
  return { t, sent_at, measurement, sim, command, thrusters };
}

export function decodeVehicleInfo(value: unknown): VehicleInfo | null {
  if (!isRecord(value)) return null;
  const { id, board } = value;
  if (typeof id !== "string" || typeof board !== "string") return null;
  return { id, board };
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
  return { vehicle, telemetry, pilot };
}

export function decodeThrustReply(value: unknown): ThrustReply | null {
  if (!isRecord(value)) return null;
  const command = decodeMotionCommand(value["command"]);
  const thrusters = decodeThrusterOutputs(value["thrusters"]);
  return command && thrusters ? { command, thrusters } : null;
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
  let name = key;
  for (const meta of metas) {
    if (isRecord(meta) && typeof meta["name"] === "string" && meta["name"] !== "") {
      name = meta["name"];
      break;
    }
  }
  return { key, name, connections: Math.max(1, metas.length) };
}
