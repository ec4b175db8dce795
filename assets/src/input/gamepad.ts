/**
 * Gamepad input (thesis table 7.2), read by polling `navigator.getGamepads()` on animation
 * frames — never from button/axis events, whose order caused the thesis' gamepad.js bug.
 *
 * Standard mapping (W3C Gamepad "standard" layout, XBOX and PlayStation pads alike):
 *   axes[0] left stick X, axes[1] left stick Y (up is −1), axes[2] right stick X,
 *   axes[3] right stick Y (up is −1); buttons[6] LT, buttons[7] RT (analog `value` in [0, 1]).
 *
 *                    motion            manual              range
 *   right stick Y    surge (up: +)     starboard (up: +)   [-1, 1]
 *   left stick Y     heave (up: −, ascend)  port (up: +)   [-1, 1]
 *   right stick X    yaw (right: +)    —                   [-1, 1]
 *   LT               —                 vertical −          [0, 1]
 *   RT               —                 vertical +          [0, 1]
 *
 * A vehicle that can sway (ArduSub) is flown in motion mode with the layout its pilots know
 * (QGroundControl's and BlueOS' defaults): left stick Y heave (up: ascend), left stick X yaw,
 * right stick Y surge, right stick X sway (right: to starboard).
 *
 * Every axis goes through a deadband (default 0.1, rescaled so the output starts at 0 at the
 * edge of the band) and an expo curve (default 0: linear). After a reset (safety stop, loss
 * of control) the pad is disarmed until every input is back in its deadband, so a stick held
 * over from before the stop cannot move the vehicle.
 *
 * Buttons (buttons.ts): the poller hands each press to `onPress` — once per press, again
 * every `repeatMs` while a button whose action repeats is held — and after a reset or a new
 * pad, a button held from before does nothing until released.
 */

import { ButtonRepeater, pressedButtons } from "./buttons";
import { clampAxis, demandEqual, isNeutralDemand, manualDemand, motionDemand, neutralDemand } from "./demand";
import type { StickMode, ThrustDemand } from "./demand";

export interface GamepadOptions {
  /** in [0, 1): inputs with |v| ≤ deadband read 0 */
  readonly deadband: number;
  /** in [0, 1]: 0 linear, 1 cubic */
  readonly expo: number;
}

export const DEFAULT_GAMEPAD_OPTIONS: GamepadOptions = Object.freeze({ deadband: 0.1, expo: 0 });

/** What we read of a Gamepad (plain objects in tests). */
export interface PadSnapshot {
  readonly axes: readonly number[];
  readonly buttons: readonly { readonly value: number; readonly pressed: boolean }[];
}

export const AXIS = { leftX: 0, leftY: 1, rightX: 2, rightY: 3 } as const;
export const BUTTON = { lt: 6, rt: 7 } as const;

/**
 * Deadband with rescaling: |v| ≤ d gives 0; beyond it the output grows linearly from 0 to ±1,
 * so there is no jump at the edge of the band. Input is clamped to [-1, 1]; NaN gives 0.
 */
export function deadband(value: number, band: number): number {
  const v = clampAxis(value);
  const d = Math.min(Math.max(band, 0), 0.99);
  const m = Math.abs(v);
  if (m <= d) return 0;
  return (Math.sign(v) * (m - d)) / (1 - d);
}

/** Expo curve (1 − e)·v + e·v³: fine control near the centre, full range at the ends. */
export function expo(value: number, e: number): number {
  const v = clampAxis(value);
  const k = Math.min(Math.max(e, 0), 1);
  return (1 - k) * v + k * v * v * v;
}

/** Deadband, then expo. */
export function shape(value: number, options: GamepadOptions): number {
  return expo(deadband(value, options.deadband), options.expo);
}

function axis(pad: PadSnapshot, index: number): number {
  const v = pad.axes[index];
  return typeof v === "number" && Number.isFinite(v) ? v : 0;
}

function trigger(pad: PadSnapshot, index: number): number {
  const b = pad.buttons[index];
  if (!b) return 0;
  const v = Number.isFinite(b.value) ? b.value : b.pressed ? 1 : 0;
  return Math.min(1, Math.max(0, v));
}

/**
 * Table 7.2: the demand of one gamepad reading in control mode `mode` (with `sway`, a vehicle
 * that can sway: the ArduSub layout in motion mode, see the module's comment).
 */
export function gamepadDemand(
  pad: PadSnapshot,
  mode: StickMode,
  options: GamepadOptions = DEFAULT_GAMEPAD_OPTIONS,
  sway = false,
): ThrustDemand {
  const ly = shape(axis(pad, AXIS.leftY), options);
  const rx = shape(axis(pad, AXIS.rightX), options);
  const ry = shape(axis(pad, AXIS.rightY), options);
  if (mode === "motion" && sway) {
    return motionDemand(-ry, ly, shape(axis(pad, AXIS.leftX), options), rx);
  }
  if (mode === "motion") {
    return motionDemand(-ry, ly, rx);
  }
  const lt = shape(trigger(pad, BUTTON.lt), options);
  const rt = shape(trigger(pad, BUTTON.rt), options);
  return manualDemand(-ly, rt - lt, -ry);
}

/** True when every input table 7.2 uses (and the left stick's X, with `sway`) is inside its deadband. */
export function padAtRest(pad: PadSnapshot, options: GamepadOptions = DEFAULT_GAMEPAD_OPTIONS, sway = false): boolean {
  const inputs = [
    sway ? axis(pad, AXIS.leftX) : 0,
    axis(pad, AXIS.leftY),
    axis(pad, AXIS.rightX),
    axis(pad, AXIS.rightY),
    trigger(pad, BUTTON.lt),
    trigger(pad, BUTTON.rt),
  ];
  return inputs.every((v) => deadband(v, options.deadband) === 0);
}

/**
 * The first connected pad, preferring one with the standard mapping; null if none.
 * `navigator.getGamepads()` returns an array with null holes.
 */
export function pickGamepad<T extends PadSnapshot & { readonly connected: boolean; readonly mapping: string }>(
  pads: readonly (T | null)[],
): T | null {
  const connected = pads.filter((p): p is T => p !== null && p.connected);
  return connected.find((p) => p.mapping === "standard") ?? connected[0] ?? null;
}

/**
 * The pure state of the gamepad reader: disarmed after a reset until the pad rests.
 * `step` returns the demand to use (neutral while disarmed).
 */
export class GamepadArming {
  private armed = true;

  get isArmed(): boolean {
    return this.armed;
  }

  disarm(): void {
    this.armed = false;
  }

  step(pad: PadSnapshot, mode: StickMode, options: GamepadOptions = DEFAULT_GAMEPAD_OPTIONS, sway = false): ThrustDemand {
    if (!this.armed) {
      if (!padAtRest(pad, options, sway)) return neutralDemand(mode);
      this.armed = true;
    }
    return gamepadDemand(pad, mode, options, sway);
  }
}

export interface GamepadSource {
  getGamepads(): readonly (Gamepad | null)[];
}

export interface GamepadPollerOptions {
  readonly source: GamepadSource;
  readonly mode: () => StickMode;
  readonly options: () => GamepadOptions;
  /** The vehicle can sway: the ArduSub layout (default: it cannot). */
  readonly sway?: () => boolean;
  /** A new demand (only on change). */
  readonly onDemand: (demand: ThrustDemand) => void;
  /** The pad that is read, or null (for the view). */
  readonly onPad: (pad: { readonly id: string; readonly armed: boolean } | null) => void;
  /** A button press that acts now (its index), edge-triggered and repeat-limited. */
  readonly onPress?: (button: number) => void;
  /** Whether a held `button` repeats (default: none does). */
  readonly repeats?: (button: number) => boolean;
  /** The repeat interval of held buttons (ms; default 250). */
  readonly repeatMs?: () => number;
  /** Monotonic clock (ms; default `performance.now`). */
  readonly nowMs?: () => number;
  readonly requestFrame?: (cb: () => void) => number;
  readonly cancelFrame?: (handle: number) => void;
}

/** Polls the pads on every animation frame while started. */
export class GamepadPoller {
  private readonly o: GamepadPollerOptions;
  private readonly arming = new GamepadArming();
  private readonly buttons = new ButtonRepeater();
  private frame: number | null = null;
  private last: ThrustDemand | null = null;
  private lastPad: string | null = null;
  private lastArmed = true;

  constructor(options: GamepadPollerOptions) {
    this.o = options;
  }

  start(): void {
    if (this.frame !== null) return;
    const request = this.o.requestFrame ?? ((cb: () => void) => window.requestAnimationFrame(cb));
    const loop = (): void => {
      this.poll();
      this.frame = request(loop);
    };
    this.frame = request(loop);
  }

  stop(): void {
    if (this.frame === null) return;
    (this.o.cancelFrame ?? ((h: number) => window.cancelAnimationFrame(h)))(this.frame);
    this.frame = null;
  }

  /** Forget the last demand and require the pad to rest before it counts again. */
  reset(): void {
    this.arming.disarm();
    this.buttons.reset();
    this.last = null;
  }

  /** One poll (public for tests). */
  poll(): void {
    let pads: readonly (Gamepad | null)[] = [];
    try {
      pads = this.o.source.getGamepads();
    } catch {
      pads = [];
    }
    const pad = pickGamepad(Array.from(pads));
    const mode = this.o.mode();
    const id = pad ? pad.id : null;
    if (id !== this.lastPad) this.buttons.reset();
    if (id !== this.lastPad || this.arming.isArmed !== this.lastArmed) {
      this.lastPad = id;
      this.lastArmed = this.arming.isArmed;
      this.o.onPad(id === null ? null : { id, armed: this.arming.isArmed });
    }
    const sway = this.o.sway ? this.o.sway() : false;
    const demand = pad ? this.arming.step(pad, mode, this.o.options(), sway) : neutralDemand(mode);
    if (this.arming.isArmed !== this.lastArmed) {
      this.lastArmed = this.arming.isArmed;
      this.o.onPad(id === null ? null : { id, armed: this.arming.isArmed });
    }
    this.pollButtons(pad);
    const prev = this.last;
    if (prev !== null && demandEqual(prev, demand)) return;
    if (prev === null && isNeutralDemand(demand)) {
      // nothing to say until the pad moves
      this.last = demand;
      return;
    }
    this.last = demand;
    this.o.onDemand(demand);
  }

  private pollButtons(pad: PadSnapshot | null): void {
    const onPress = this.o.onPress;
    if (!onPress) return;
    const now = (this.o.nowMs ?? (() => performance.now()))();
    const repeats = this.o.repeats ?? (() => false);
    const repeatMs = this.o.repeatMs ? this.o.repeatMs() : 250;
    for (const button of this.buttons.step(pad ? pressedButtons(pad.buttons) : [], now, repeats, repeatMs)) onPress(button);
  }
}
