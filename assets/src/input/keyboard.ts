/**
 * Keyboard input (thesis table 7.1). Keys are identified by `KeyboardEvent.code`, the physical
 * key, so the WASD block stays where it is on AZERTY, Dvorak and other layouts.
 *
 * Motion mode              Manual mode
 *   W  + surge               W  vertical thruster up
 *   S  − surge               S  vertical thruster down
 *   Q  + heave               Q  port thruster forward
 *   E  − heave               A  port thruster backward
 *   D  + yaw                 E  starboard thruster forward
 *   A  − yaw                 D  starboard thruster backward
 *   C  + sway (starboard)
 *   Z  − sway (port)         — sway only on a vehicle that has it (an ArduSub that strafes)
 *
 * An axis is the sum of its held keys, so opposing keys held together cancel to 0.
 */

import { manualDemand, motionDemand } from "./demand";
import type { StickMode, ThrustDemand } from "./demand";

export type MotionAxis = "surge" | "heave" | "yaw";
export type Thruster = "port" | "vertical" | "starboard";

export interface MotionAxes {
  readonly surge: number;
  readonly heave: number;
  readonly yaw: number;
  /** to starboard; absent: 0 (a vehicle without sway never gets it) */
  readonly sway?: number;
}

export interface ThrusterCommands {
  readonly port: number;
  readonly vertical: number;
  readonly starboard: number;
}

export interface Binding<T extends string> {
  readonly target: T;
  readonly sign: 1 | -1;
}

export const NEUTRAL_AXES: MotionAxes = Object.freeze({ surge: 0, heave: 0, yaw: 0 });
export const NEUTRAL_THRUSTERS: ThrusterCommands = Object.freeze({
  port: 0,
  vertical: 0,
  starboard: 0,
});

/** Table 7.1, column "Command (motion)". */
export const MOTION_KEYMAP: Readonly<Record<string, Binding<MotionAxis>>> = Object.freeze({
  KeyW: { target: "surge", sign: 1 },
  KeyS: { target: "surge", sign: -1 },
  KeyQ: { target: "heave", sign: 1 },
  KeyE: { target: "heave", sign: -1 },
  KeyD: { target: "yaw", sign: 1 },
  KeyA: { target: "yaw", sign: -1 },
});

/** Table 7.1, column "Command (manual)". */
export const MANUAL_KEYMAP: Readonly<Record<string, Binding<Thruster>>> = Object.freeze({
  KeyW: { target: "vertical", sign: 1 },
  KeyS: { target: "vertical", sign: -1 },
  KeyQ: { target: "port", sign: 1 },
  KeyA: { target: "port", sign: -1 },
  KeyE: { target: "starboard", sign: 1 },
  KeyD: { target: "starboard", sign: -1 },
});

function lookup<T extends string>(
  map: Readonly<Record<string, Binding<T>>>,
  code: string,
): Binding<T> | undefined {
  return Object.prototype.hasOwnProperty.call(map, code) ? map[code] : undefined;
}

/** Sway, below the yaw keys: a vehicle that can sway (not in table 7.1, which has none). */
export const SWAY_KEYMAP: Readonly<Record<string, Binding<"sway">>> = Object.freeze({
  KeyC: { target: "sway", sign: 1 },
  KeyZ: { target: "sway", sign: -1 },
});

/** The sway a key drives (`SWAY_KEYMAP`), or `undefined`. */
export function keyToSway(code: string): Binding<"sway"> | undefined {
  return lookup(SWAY_KEYMAP, code);
}

/** Sway of a set of held keys, -1, 0 or 1. */
export function swayFromKeys(held: ReadonlySet<string>): number {
  let sway = 0;
  for (const code of held) sway += keyToSway(code)?.sign ?? 0;
  return sway;
}

/** The motion axis a key drives, or `undefined` for keys we do not use. */
export function keyToAxis(code: string): Binding<MotionAxis> | undefined {
  return lookup(MOTION_KEYMAP, code);
}

/** The thruster a key drives in manual mode, or `undefined`. */
export function keyToThruster(code: string): Binding<Thruster> | undefined {
  return lookup(MANUAL_KEYMAP, code);
}

/** Absolute motion axes for a set of held keys (codes); unknown codes are ignored. */
export function axesFromKeys(held: ReadonlySet<string>): MotionAxes {
  const axes = { surge: 0, heave: 0, yaw: 0 };
  for (const code of held) {
    const binding = keyToAxis(code);
    if (binding) axes[binding.target] += binding.sign;
  }
  return axes;
}

/** Thruster commands (manual mode) for a set of held keys. */
export function thrustersFromKeys(held: ReadonlySet<string>): ThrusterCommands {
  const out = { port: 0, vertical: 0, starboard: 0 };
  for (const code of held) {
    const binding = keyToThruster(code);
    if (binding) out[binding.target] += binding.sign;
  }
  return out;
}

export function axesEqual(a: MotionAxes, b: MotionAxes): boolean {
  return a.surge === b.surge && a.heave === b.heave && a.yaw === b.yaw;
}

export function isNeutral(a: MotionAxes): boolean {
  return axesEqual(a, NEUTRAL_AXES);
}

const NON_TEXT_INPUT_TYPES = new Set([
  "button",
  "checkbox",
  "color",
  "file",
  "image",
  "radio",
  "range",
  "reset",
  "submit",
]);

/** True for an element that takes typed text (so W/A/S/D there are letters, not commands). */
export function isEditableTarget(target: unknown): boolean {
  if (typeof target !== "object" || target === null) return false;
  const el = target as { tagName?: unknown; type?: unknown; isContentEditable?: unknown };
  if (el.isContentEditable === true) return true;
  const tag = typeof el.tagName === "string" ? el.tagName.toUpperCase() : "";
  if (tag === "TEXTAREA" || tag === "SELECT") return true;
  if (tag === "INPUT") {
    const type = typeof el.type === "string" ? el.type.toLowerCase() : "text";
    return !NON_TEXT_INPUT_TYPES.has(type);
  }
  return false;
}

/** The part of a KeyboardEvent we look at (plain objects in tests). */
export interface KeyEventLike {
  readonly code: string;
  readonly repeat?: boolean;
  readonly ctrlKey?: boolean;
  readonly metaKey?: boolean;
  readonly altKey?: boolean;
  readonly target?: EventTarget | null | object;
  preventDefault?(): void;
}

export interface KeyboardInputOptions {
  /**
   * Called with the held table keys whenever that set changes (press, release; not on
   * `reset`); `keyboardDemand` turns them into the demand of the control mode in force (the
   * same keys drive the motion axes or single thrusters).
   */
  readonly onHeld: (held: ReadonlySet<string>) => void;
  /**
   * Called when held keys were dropped without key-up events (window blur, page hidden,
   * `reset()`), with why. No key is held afterwards; `onHeld` is not called for this.
   */
  readonly onReset?: (reason: string) => void;
  /** The vehicle can sway: Z and C are keys of ours too (default: they are not). */
  readonly sway?: () => boolean;
}

function isKeyEventLike(event: Event): event is Event & KeyEventLike {
  return typeof (event as Event & { code?: unknown }).code === "string";
}

/** Minimal event source: a Window or any EventTarget (Node's in tests). */
export interface KeySource {
  addEventListener(type: string, listener: (event: Event) => void): void;
  removeEventListener(type: string, listener: (event: Event) => void): void;
}

/**
 * Tracks held motion keys and reports the held set when it changes. Ignores auto-repeat,
 * keys typed into text fields and shortcuts with Ctrl/Alt/Meta; a key-up always releases.
 */
export class KeyboardInput {
  private readonly held = new Set<string>();
  private readonly options: KeyboardInputOptions;

  constructor(options: KeyboardInputOptions) {
    this.options = options;
  }

  /** The motion axes of the held keys (table 7.1's motion column). */
  get current(): MotionAxes {
    return axesFromKeys(this.held);
  }

  /** Codes of the motion keys currently held. */
  get heldKeys(): ReadonlySet<string> {
    return this.held;
  }

  /** Returns true when the event was ours (a motion key, or a sway key on a vehicle that sways). */
  handleKeyDown(event: KeyEventLike): boolean {
    const sway = this.options.sway ? this.options.sway() : false;
    if (!keyToAxis(event.code) && !(sway && keyToSway(event.code))) return false;
    if (event.ctrlKey === true || event.metaKey === true || event.altKey === true) return false;
    if (isEditableTarget(event.target)) return false;
    event.preventDefault?.();
    if (event.repeat === true || this.held.has(event.code)) return true;
    this.held.add(event.code);
    this.update();
    return true;
  }

  handleKeyUp(event: KeyEventLike): boolean {
    if (!this.held.delete(event.code)) return false;
    event.preventDefault?.();
    this.update();
    return true;
  }

  /**
   * Forgets every held key (their key-ups may never come) and reports `onReset(reason)`
   * unless `notify` is false (e.g. when the server has already stopped the vehicle and a held
   * key must be pressed again to count). Returns whether any key was held.
   */
  reset(reason: string, notify = true): boolean {
    const wasHeld = this.held.size > 0;
    this.held.clear();
    if (notify) this.options.onReset?.(reason);
    return wasHeld;
  }

  /**
   * Listens for keydown/keyup and blur on `source` (normally `window`). Returns a function that
   * removes the listeners.
   */
  attach(source: KeySource): () => void {
    const down = (e: Event): void => {
      if (isKeyEventLike(e)) this.handleKeyDown(e);
    };
    const up = (e: Event): void => {
      if (isKeyEventLike(e)) this.handleKeyUp(e);
    };
    const blur = (): void => {
      this.reset("window lost focus");
    };
    source.addEventListener("keydown", down);
    source.addEventListener("keyup", up);
    source.addEventListener("blur", blur);
    return () => {
      source.removeEventListener("keydown", down);
      source.removeEventListener("keyup", up);
      source.removeEventListener("blur", blur);
    };
  }

  private update(): void {
    this.options.onHeld(new Set(this.held));
  }
}

/**
 * The demand of the held keys in control mode `mode`: table 7.1's motion column (axes, and
 * sway from Z/C when the vehicle `sway`s) or its manual column (thrusters). Values are
 * absolute: -1, 0 or 1 per axis.
 */
export function keyboardDemand(held: ReadonlySet<string>, mode: StickMode, sway = false): ThrustDemand {
  if (mode === "motion") {
    const a = axesFromKeys(held);
    return motionDemand(a.surge, a.heave, a.yaw, sway ? swayFromKeys(held) : 0);
  }
  const t = thrustersFromKeys(held);
  return manualDemand(t.port, t.vertical, t.starboard);
}

/** Every key of table 7.1 (the same six in both columns). */
export const TABLE_KEYS: ReadonlySet<string> = new Set([
  ...Object.keys(MOTION_KEYMAP),
  ...Object.keys(MANUAL_KEYMAP),
]);
