/**
 * The developer page's autopilot tuning, pure parts: the gains form (text fields → a
 * validated tuning), the server's replies (`get_tuning`, `step_response`, `set_tuning`), and
 * the step-response preview's polylines. The server validates again; the page only saves a
 * round trip and says what is wrong next to the field.
 */

import * as wire from "../lib/wire.gen";

export type Axis = "depth" | "heading";
export type GainKey = "kp" | "ki" | "kd";
export const AXES: readonly Axis[] = ["depth", "heading"];
export const GAIN_KEYS: readonly GainKey[] = ["kp", "ki", "kd"];

export type Gains = Readonly<Record<GainKey, number>>;
export type AxisGains = Readonly<Record<Axis, Gains>>;

export interface TuningInfo {
  readonly gains: AxisGains;
  readonly defaults: AxisGains;
  readonly ranges: Readonly<Record<GainKey, readonly [number, number]>>;
  readonly model: string;
}

/** The `step_response` reply (`wire.StepResponse`). */
export type StepResponse = wire.StepResponse;

const isNum = (v: number | null): v is number => v !== null;

/** `[min, max]`, or null when it is not a pair. */
function pair(range: readonly number[]): readonly [number, number] | null {
  const [lo, hi] = range;
  return range.length === 2 && lo !== undefined && hi !== undefined ? [lo, hi] : null;
}

/** The `get_tuning` reply, or null. */
export function decodeTuningInfo(v: unknown): TuningInfo | null {
  const info = wire.decodeTuningInfo(v);
  if (!info) return null;
  const kp = pair(info.ranges.kp);
  const ki = pair(info.ranges.ki);
  const kd = pair(info.ranges.kd);
  return kp && ki && kd ? { gains: info.gains, defaults: info.defaults, ranges: { kp, ki, kd }, model: info.model } : null;
}

/** The `set_tuning` reply's gains in force, or null. */
export function decodeSetTuning(v: unknown): AxisGains | null {
  return wire.decodeTuningReply(v)?.tuning ?? null;
}

/** The `step_response` reply, or null (also when its curves are not of one length). */
export function decodeStepResponse(v: unknown): StepResponse | null {
  const r = wire.decodeStepResponse(v);
  return r && r.value.length === r.t.length ? r : null;
}

export type GainsForm = Readonly<Record<Axis, Readonly<Record<GainKey, string>>>>;

export function formOf(gains: AxisGains): GainsForm {
  const axis = (g: Gains): Readonly<Record<GainKey, string>> => ({ kp: String(g.kp), ki: String(g.ki), kd: String(g.kd) });
  return { depth: axis(gains.depth), heading: axis(gains.heading) };
}

/**
 * The form as a tuning (every gain of both axes), or the first error naming the field
 * (`depth.kp must be a number in [0, 20]`).
 */
export function parseForm(form: GainsForm, ranges: TuningInfo["ranges"]): { ok: true; gains: AxisGains } | { ok: false; error: string } {
  const out: Record<string, Record<string, number>> = {};
  for (const axis of AXES) {
    out[axis] = {};
    for (const key of GAIN_KEYS) {
      const text = form[axis][key].trim();
      const x = Number(text);
      const [lo, hi] = ranges[key];
      if (text === "" || !Number.isFinite(x) || x < lo || x > hi) {
        return { ok: false, error: `${axis}.${key} must be a number in [${lo}, ${hi}]` };
      }
      (out[axis] as Record<string, number>)[key] = x;
    }
  }
  return { ok: true, gains: out as unknown as AxisGains };
}

/** The step shown for an axis: 1 m of depth, 90° of heading. */
export const PREVIEW_STEP: Readonly<Record<Axis, number>> = { depth: 1.0, heading: Math.PI / 2 };

export interface Polylines {
  readonly value: string;
  readonly reference: string;
  readonly setpoint: string;
  /** y range shown (m or rad) */
  readonly min: number;
  readonly max: number;
}

/**
 * SVG polyline points of the step response in a `width` × `height` box (y up), the value,
 * the reference and the setpoint on one scale.
 */
export function polylines(r: StepResponse, width: number, height: number): Polylines {
  const ys = [...r.value, ...r.reference.filter(isNum), ...r.setpoint.filter(isNum)];
  let min = Math.min(...ys);
  let max = Math.max(...ys);
  if (!(max > min)) {
    min -= 0.5;
    max += 0.5;
  }
  const t0 = r.t[0] ?? 0;
  const t1 = r.t[r.t.length - 1] ?? 1;
  const x = (t: number): number => ((t - t0) / (t1 - t0 || 1)) * width;
  const y = (v: number): number => height - ((v - min) / (max - min)) * height;
  const line = (vs: readonly (number | null)[]): string =>
    vs
      .map((v, i) => (v === null ? null : `${x(r.t[i] ?? 0).toFixed(1)},${y(v).toFixed(1)}`))
      .filter((p): p is string => p !== null)
      .join(" ");
  return { value: line(r.value), reference: line(r.reference), setpoint: line(r.setpoint), min, max };
}

/** The step response's figures, for the pilot: "overshoot 0.6 cm, within ±5 cm after 4.7 s". */
export function figures(r: StepResponse): string {
  const deg = (rad: number): number => (rad * 180) / Math.PI;
  const over = r.axis === "depth" ? `${(r.overshoot * 100).toFixed(1)} cm` : `${deg(r.overshoot).toFixed(1)}°`;
  const band = r.axis === "depth" ? `±${Math.round(r.band * 100)} cm` : `±${Math.round(deg(r.band))}°`;
  const settle = r.settle === null ? `never within ${band} in ${(r.t[r.t.length - 1] ?? 0).toFixed(0)} s` : `within ${band} after ${r.settle.toFixed(1)} s`;
  return `overshoot ${over}, ${settle}`;
}
