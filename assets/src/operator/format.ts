/** Display helpers of the operator page (pure). */

import type { BoardLinkDetails, MeasurementState, VehicleInfo } from "../lib/protocol";
import { clampUnit, formatFixed, formatHeading, radToDeg } from "../lib/units";

/** Bar geometry for a value in [-1, 1] on a meter centred on zero (percent of the width). */
export function barGeometry(value: number): { left: number; width: number; reverse: boolean } {
  const v = clampUnit(value);
  const width = Math.abs(v) * 50;
  return { left: v < 0 ? 50 - width : 50, width, reverse: v < 0 };
}

/** Degrees with one decimal from radians; "—" when unknown. */
export function formatDeg(rad: number | null | undefined, signed = false): string {
  return rad === null || rad === undefined ? "—" : formatFixed(radToDeg(rad), 1, signed);
}

/** A value with `decimals`, "—" for null/undefined/NaN. */
export function fmt(value: number | null | undefined, decimals: number, signed = false): string {
  return value === null || value === undefined ? "—" : formatFixed(value, decimals, signed);
}

/** What the HUD shows for a measurement that is not valid yet: a word, never a number. */
export const INITIALISING = "initialising";

/** A measurement's unit is shown after it unless it is initialising (no number). */
export function showsUnit(state: MeasurementState | null | undefined): boolean {
  return state !== "initialising";
}

/**
 * A measurement for the HUD: "initialising" while the server says so (whatever value came
 * with it), else the value with `decimals` ("—" when unknown).
 */
export function measurementText(
  value: number | null | undefined,
  state: MeasurementState | null | undefined,
  decimals: number,
  signed = false,
): string {
  if (state === "initialising") return INITIALISING;
  return value === null || value === undefined || Number.isNaN(value) ? "—" : formatFixed(value, decimals, signed);
}

/** An angle measurement (radians) in degrees with one decimal, "initialising" while it is. */
export function measurementDeg(rad: number | null | undefined, state: MeasurementState | null | undefined, signed = false): string {
  if (state === "initialising") return INITIALISING;
  return rad === null || rad === undefined || Number.isNaN(rad) ? "—" : formatFixed(radToDeg(rad), 1, signed);
}

/** A heading measurement (radians) as the compass shows it, "initialising" while it is. */
export function measurementHeading(rad: number | null | undefined, state: MeasurementState | null | undefined): string {
  if (state === "initialising") return INITIALISING;
  return formatHeading(rad ?? Number.NaN);
}

/** Video files play in <video>; anything else (MJPEG streams, snapshots) in <img>. */
/** How long a broken camera stream waits before it is asked for again. */
export const CAMERA_RETRY_MS = 3000;

/** The feed's address for the n-th attempt (a fresh request; the first is the address itself). */
export function retryUrl(url: string, attempt: number): string {
  if (attempt <= 0) return url;
  const [path, hash] = url.split("#", 2) as [string, string | undefined];
  const separator = path.includes("?") ? "&" : "?";
  return `${path}${separator}retry=${attempt}${hash !== undefined ? `#${hash}` : ""}`;
}

export function cameraElement(url: string): "video" | "img" {
  return /\.(mp4|webm|ogv|m3u8)(\?|#|$)/i.test(url) ? "video" : "img";
}

/** "reconnecting for 12 s" style text for a connection lost `ms` ago. */
export function downFor(ms: number): string {
  const s = Math.max(0, Math.floor(ms / 1000));
  return s < 60 ? `${s} s` : `${Math.floor(s / 60)} min ${s % 60} s`;
}

/** The warning shown while the board's own deadman is not armed (its first 180 s). */
export const BOARD_DEADMAN_NOT_ARMED = "board deadman not armed: only the server's deadman protects";

/** The warning shown while thrust is held because the board has not confirmed its motor modifiers. */
export const THRUST_HELD = "board settings not confirmed: thrust held at neutral";

const SETTING_NAMES: Readonly<Record<string, string>> = {
  mtrmod1: "motor modifiers",
  mtrmod2: "motor modifiers",
  lights: "lights",
  laser: "laser",
  tilt: "tilt",
};

/** "board settings: confirmed", "board settings: pending (motor modifiers, lights)", … */
export function boardSettingsText(d: BoardLinkDetails): string | null {
  if (d.board_settings === null) return null;
  if (d.board_settings === "confirmed") return "board settings: confirmed";
  const names = [...new Set(d.board_settings_pending.map((p) => SETTING_NAMES[p] ?? p))];
  return `board settings: ${d.board_settings}${names.length > 0 ? ` (${names.join(", ")})` : ""}`;
}

/**
 * The board link's liveness for the Link box: a summary line (pong age, round trip, commands
 * the board confirmed, whether it confirmed its settings) and warnings (thrust held, a setting
 * that failed, board deadman not armed, firmware mismatch).
 */
export function boardLinkText(d: BoardLinkDetails): { summary: string; warnings: string[] } {
  const parts: string[] = [];
  parts.push(d.pong_age_ms === null ? "no pong yet" : `pong ${(d.pong_age_ms / 1000).toFixed(1)} s ago`);
  if (d.rtt_ms !== null) parts.push(`board RTT ${Math.round(d.rtt_ms)} ms`);
  if (d.commands_sent !== null && d.commands_confirmed !== null) {
    parts.push(`${d.commands_confirmed}/${d.commands_sent} confirmed`);
  }
  const settings = boardSettingsText(d);
  if (settings !== null) parts.push(settings);
  const warnings: string[] = [];
  if (d.thrust_held) warnings.push(THRUST_HELD);
  if (d.board_settings === "failed" && d.board_settings_reason !== null) warnings.push(d.board_settings_reason);
  if (d.board_deadman_armed === false) warnings.push(BOARD_DEADMAN_NOT_ARMED);
  if (d.firmware_mismatch && d.detected_firmware !== null) {
    warnings.push(`board talks ${d.detected_firmware}, configured ${d.firmware}`);
  }
  return { summary: parts.join(" · "), warnings };
}

/** The vehicle picker's label of a vehicle of the fleet: its id, its node, whether unreachable. */
export function vehicleLabel(v: VehicleInfo): string {
  const where = v.node === undefined ? "" : ` on ${v.node}`;
  return `${v.id}${where}${v.status === "unreachable" ? " (unreachable)" : ""}`;
}

/** The operator page's address for vehicle `id` (deep link `?vehicle=ID`, other parameters kept). */
export function vehicleHref(search: string, id: string): string {
  const params = new URLSearchParams(search);
  params.set("vehicle", id);
  return `?${params.toString()}`;
}

