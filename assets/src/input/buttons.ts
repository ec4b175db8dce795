/**
 * Gamepad buttons (pure): which button does what (`ButtonMapping`), when a press counts
 * (`ButtonRepeater`: one command per press, held buttons repeat no faster than the mapping's
 * `repeatMs`), and what a pressed action asks of the vehicle (`buttonCommand`).
 *
 * The mapping belongs to the pilot, not to the browser: the operator page keeps it on the
 * server (`/api/settings/gamepad.mapping`, `encodeMapping` / `parseMapping`), so it follows
 * the pilot from device to device.
 *
 * Default mapping (W3C "standard" layout; XBOX names, PlayStation in brackets):
 *
 *   B (○)            stop                 Start (Options)   request control
 *   Back (Share)     release control      Y (△)             lights on/off
 *   D-pad right/left lights up/down       RB/LB (R1/L1)     gain up/down
 *   A (×)            depth hold on/off    X (□)             heading hold on/off
 *   D-pad up/down    camera tilt up/down  L3                camera tilt centre
 *   R3               laser on/off         Home (PS)         gamepad as the input
 *   button 17 (the PlayStation pads' touchpad press)     camera snapshot
 *
 * LT and RT are left free: they are the vertical thruster in manual mode (table 7.2).
 */

import type { ControlSettings } from "../lib/protocol";

export const BUTTON_ACTIONS = [
  "stop",
  "request_control",
  "release_control",
  "lights_up",
  "lights_down",
  "lights_toggle",
  "gain_up",
  "gain_down",
  "depth_hold",
  "heading_hold",
  "tilt_up",
  "tilt_down",
  "tilt_centre",
  "laser",
  "input_gamepad",
  "snapshot",
] as const;

export type ButtonAction = (typeof BUTTON_ACTIONS)[number];

export const ACTION_LABELS: Readonly<Record<ButtonAction, string>> = {
  stop: "Stop",
  request_control: "Request control",
  release_control: "Release control",
  lights_up: "Lights up",
  lights_down: "Lights down",
  lights_toggle: "Lights on/off",
  gain_up: "Gain up",
  gain_down: "Gain down",
  depth_hold: "Depth hold on/off",
  heading_hold: "Heading hold on/off",
  tilt_up: "Camera tilt up",
  tilt_down: "Camera tilt down",
  tilt_centre: "Camera tilt centre",
  laser: "Laser on/off",
  input_gamepad: "Gamepad as input (stops first)",
  snapshot: "Camera snapshot",
};

/** Actions that repeat while their button is held (steps); the others act once per press. */
export const REPEATING: ReadonlySet<ButtonAction> = new Set<ButtonAction>(["lights_up", "lights_down", "gain_up", "gain_down", "tilt_up", "tilt_down"]);

/** Button names of the standard layout (index → name). */
export const BUTTON_NAMES: readonly string[] = [
  "A",
  "B",
  "X",
  "Y",
  "LB",
  "RB",
  "LT",
  "RT",
  "Back",
  "Start",
  "L3",
  "R3",
  "D-pad up",
  "D-pad down",
  "D-pad left",
  "D-pad right",
  "Home",
];

export function buttonName(button: number): string {
  return BUTTON_NAMES[button] ?? `Button ${button}`;
}

/** Buttons a mapping may name: 0..MAX_BUTTON. */
export const MAX_BUTTON = 31;
export const REPEAT_MS = { min: 100, max: 2000, default: 250 } as const;

export interface ButtonMapping {
  /** action → button index (an action has at most one button, a button at most one action) */
  readonly actions: Readonly<Partial<Record<ButtonAction, number>>>;
  /** a held repeating button acts again after this long (ms) */
  readonly repeatMs: number;
}

export const DEFAULT_MAPPING: ButtonMapping = Object.freeze({
  actions: Object.freeze({
    stop: 1,
    request_control: 9,
    release_control: 8,
    lights_toggle: 3,
    lights_up: 15,
    lights_down: 14,
    gain_up: 5,
    gain_down: 4,
    depth_hold: 0,
    heading_hold: 2,
    tilt_up: 12,
    tilt_down: 13,
    tilt_centre: 10,
    laser: 11,
    input_gamepad: 16,
    snapshot: 17,
  }),
  repeatMs: REPEAT_MS.default,
});

export function isButtonAction(value: unknown): value is ButtonAction {
  return typeof value === "string" && (BUTTON_ACTIONS as readonly string[]).includes(value);
}

function isButton(value: unknown): value is number {
  return typeof value === "number" && Number.isInteger(value) && value >= 0 && value <= MAX_BUTTON;
}

/** The action of `button` in `mapping`, or null. */
export function actionFor(mapping: ButtonMapping, button: number): ButtonAction | null {
  for (const action of BUTTON_ACTIONS) if (mapping.actions[action] === button) return action;
  return null;
}

/** `action` on `button`; whatever `button` did before is unassigned. */
export function assign(mapping: ButtonMapping, action: ButtonAction, button: number): ButtonMapping {
  if (!isButton(button)) return mapping;
  const actions: Partial<Record<ButtonAction, number>> = {};
  for (const a of BUTTON_ACTIONS) {
    const b = mapping.actions[a];
    if (a !== action && b !== undefined && b !== button) actions[a] = b;
  }
  actions[action] = button;
  return { ...mapping, actions };
}

/** `action` on no button. */
export function unassign(mapping: ButtonMapping, action: ButtonAction): ButtonMapping {
  const actions: Partial<Record<ButtonAction, number>> = { ...mapping.actions };
  delete actions[action];
  return { ...mapping, actions };
}

/** The repeat interval, clamped to REPEAT_MS (NaN: the default). */
export function withRepeatMs(mapping: ButtonMapping, ms: number): ButtonMapping {
  const v = Number.isFinite(ms) ? Math.round(Math.min(REPEAT_MS.max, Math.max(REPEAT_MS.min, ms))) : REPEAT_MS.default;
  return { ...mapping, repeatMs: v };
}

/** The JSON kept on the server: `{"version": 1, "actions": {action: button}, "repeat_ms": n}`. */
export function encodeMapping(mapping: ButtonMapping): { version: 1; actions: Partial<Record<ButtonAction, number>>; repeat_ms: number } {
  return { version: 1, actions: { ...mapping.actions }, repeat_ms: mapping.repeatMs };
}

/**
 * A mapping from the server's JSON, or the reason it cannot be used (all or nothing: a
 * mapping with one bad entry would silently lose a function).
 */
export function parseMapping(value: unknown): { ok: true; mapping: ButtonMapping } | { ok: false; reason: string } {
  if (typeof value !== "object" || value === null || Array.isArray(value)) return { ok: false, reason: "not an object" };
  const v = value as Record<string, unknown>;
  if (v["version"] !== 1) return { ok: false, reason: `unknown version ${JSON.stringify(v["version"])}` };
  const rawActions = v["actions"];
  if (typeof rawActions !== "object" || rawActions === null || Array.isArray(rawActions)) return { ok: false, reason: "actions is not an object" };
  const repeat = v["repeat_ms"];
  if (typeof repeat !== "number" || !Number.isInteger(repeat) || repeat < REPEAT_MS.min || repeat > REPEAT_MS.max) {
    return { ok: false, reason: `repeat_ms must be an integer in ${REPEAT_MS.min}..${REPEAT_MS.max}` };
  }
  const actions: Partial<Record<ButtonAction, number>> = {};
  const used = new Set<number>();
  for (const [action, button] of Object.entries(rawActions as Record<string, unknown>)) {
    if (!isButtonAction(action)) return { ok: false, reason: `unknown action ${JSON.stringify(action)}` };
    if (!isButton(button)) return { ok: false, reason: `${action}: button must be an integer in 0..${MAX_BUTTON}` };
    if (used.has(button)) return { ok: false, reason: `button ${button} has two actions` };
    used.add(button);
    actions[action] = button;
  }
  return { ok: true, mapping: { actions, repeatMs: repeat } };
}

/** Which buttons of a pad reading are down (`pressed`, or an analog value past half). */
export function pressedButtons(buttons: readonly { readonly value: number; readonly pressed: boolean }[]): boolean[] {
  return buttons.map((b) => b.pressed || (Number.isFinite(b.value) && b.value > 0.5));
}

interface Held {
  /** when it last acted (ms) */
  last: number;
  /** held since before a reset: it does nothing until released */
  latched: boolean;
}

/**
 * Edges and repeats of the buttons: `step` gives the buttons that act now — each on its
 * press, and a held button for which `repeats(button)` again every `repeatMs` at most. After
 * `reset` (a stop, a new pad, the page starting) buttons held at that moment do nothing
 * until released: a press is always a fresh one.
 */
export class ButtonRepeater {
  private readonly held = new Map<number, Held>();
  private primed = false;

  reset(): void {
    this.primed = false;
  }

  step(pressed: readonly boolean[], nowMs: number, repeats: (button: number) => boolean, repeatMs: number): number[] {
    const fire: number[] = [];
    if (!this.primed) {
      for (const h of this.held.values()) h.latched = true;
    }
    for (let i = 0; i < pressed.length; i++) {
      const down = pressed[i] === true;
      const h = this.held.get(i);
      if (!down) {
        this.held.delete(i);
      } else if (h === undefined) {
        this.held.set(i, { last: nowMs, latched: !this.primed });
        if (this.primed) fire.push(i);
      } else if (!h.latched && repeats(i) && nowMs - h.last >= repeatMs) {
        h.last = nowMs;
        fire.push(i);
      }
    }
    // buttons beyond this reading's length are up
    for (const i of [...this.held.keys()]) if (i >= pressed.length) this.held.delete(i);
    this.primed = true;
    return fire;
  }
}

/** What a button asks of the page or the vehicle. */
export type ButtonCommand =
  | { readonly kind: "stop" }
  | { readonly kind: "request_control" }
  | { readonly kind: "release_control" }
  | { readonly kind: "set"; readonly field: "lights" | "gain" | "laser" | "tilt"; readonly value: number }
  | { readonly kind: "autopilot"; readonly axis: "depth" | "heading"; readonly action: "hold" | "off" }
  | { readonly kind: "input_gamepad" }
  | { readonly kind: "snapshot" }
  /** nothing to do (already at the limit, no settings known yet): why */
  | { readonly kind: "none"; readonly why: string };

export const LIGHTS_STEP = 32;
export const GAIN_STEP = 0.1;
export const TILT_STEP = (5 * Math.PI) / 180;
export const TILT_MAX = Math.PI / 4;

function step(field: "lights" | "gain" | "tilt", current: number, delta: number, min: number, max: number, digits: number): ButtonCommand {
  const scale = 10 ** digits;
  // rounded for the display, then clamped again: the server refuses a value past the limit
  const value = Math.min(max, Math.max(min, Math.round((current + delta) * scale) / scale));
  if (Math.abs(value - current) < 1e-9) return { kind: "none", why: `${field} is at its ${delta > 0 ? "maximum" : "minimum"}` };
  return { kind: "set", field, value };
}

/**
 * The command of `action` given the vehicle's current settings `control` (null: not known
 * yet) and `lightsOn`, the brightness the lights come back to when toggled on.
 */
export function buttonCommand(action: ButtonAction, control: ControlSettings | null, lightsOn: number): ButtonCommand {
  switch (action) {
    case "stop":
      return { kind: "stop" };
    case "request_control":
      return { kind: "request_control" };
    case "release_control":
      return { kind: "release_control" };
    case "input_gamepad":
      return { kind: "input_gamepad" };
    case "snapshot":
      return { kind: "snapshot" };
    default:
      break;
  }
  if (control === null) return { kind: "none", why: "the vehicle's settings are not known yet" };
  switch (action) {
    case "lights_up":
      return step("lights", control.lights ?? 0, LIGHTS_STEP, 0, 255, 0);
    case "lights_down":
      return step("lights", control.lights ?? 0, -LIGHTS_STEP, 0, 255, 0);
    case "lights_toggle":
      return { kind: "set", field: "lights", value: (control.lights ?? 0) > 0 ? 0 : Math.min(255, Math.max(1, Math.round(lightsOn))) };
    case "laser":
      return { kind: "set", field: "laser", value: (control.laser ?? 0) > 0 ? 0 : 255 };
    case "gain_up":
      return step("gain", control.gain ?? 0, GAIN_STEP, 0, 1, 2);
    case "gain_down":
      return step("gain", control.gain ?? 0, -GAIN_STEP, 0, 1, 2);
    case "tilt_up":
      return step("tilt", control.tilt ?? 0, TILT_STEP, -TILT_MAX, TILT_MAX, 4);
    case "tilt_down":
      return step("tilt", control.tilt ?? 0, -TILT_STEP, -TILT_MAX, TILT_MAX, 4);
    case "tilt_centre":
      return { kind: "set", field: "tilt", value: 0 };
    case "depth_hold":
      return { kind: "autopilot", axis: "depth", action: control.autopilot?.depth == null ? "hold" : "off" };
    case "heading_hold":
      return { kind: "autopilot", axis: "heading", action: control.autopilot?.heading == null ? "hold" : "off" };
  }
}
