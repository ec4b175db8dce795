/**
 * The operator's preferences, kept in localStorage: the camera image rotation per vehicle
 * (the thesis' camera was mounted rotated), the input mode, and the gamepad's deadband and
 * expo. Every read is validated; bad or missing values give the defaults.
 */

import { DEFAULT_GAMEPAD_OPTIONS } from "../input/gamepad";
import type { GamepadOptions } from "../input/gamepad";
import { isInputMode } from "../input/demand";
import type { InputMode } from "../input/demand";

export type Rotation = 0 | 90 | 180 | 270;
export const ROTATIONS: readonly Rotation[] = [0, 90, 180, 270];

/** What we use of `Storage` (a Map-backed stand-in in tests). */
export interface KeyValueStore {
  getItem(key: string): string | null;
  setItem(key: string, value: string): void;
}

/** This browser's localStorage, or null where the page may not use it (storage disabled, private mode). */
export function browserStorage(): Storage | null {
  try {
    return window.localStorage;
  } catch {
    return null;
  }
}

const rotationKey = (vehicle: string): string => `neptunus.camera.rotation.${vehicle}`;
const INPUT_KEY = "neptunus.input.mode";
const GAMEPAD_KEY = "neptunus.input.gamepad";

function safeGet(store: KeyValueStore | null, key: string): string | null {
  try {
    return store?.getItem(key) ?? null;
  } catch {
    return null; // storage disabled (private mode)
  }
}

function safeSet(store: KeyValueStore | null, key: string, value: string): void {
  try {
    store?.setItem(key, value);
  } catch {
    // not kept: fine
  }
}

export function parseRotation(value: unknown): Rotation {
  const n = typeof value === "string" ? Number(value) : value;
  return ROTATIONS.find((r) => r === n) ?? 0;
}

export function loadRotation(store: KeyValueStore | null, vehicle: string): Rotation {
  return parseRotation(safeGet(store, rotationKey(vehicle)));
}

export function saveRotation(store: KeyValueStore | null, vehicle: string, rotation: Rotation): void {
  safeSet(store, rotationKey(vehicle), String(rotation));
}

/** Touch on touch-first devices, else the keyboard (the thesis' default). */
export function defaultInputMode(touchFirst: boolean): InputMode {
  return touchFirst ? "touch" : "keyboard";
}

export function loadInputMode(store: KeyValueStore | null, touchFirst: boolean): InputMode {
  const v = safeGet(store, INPUT_KEY);
  return isInputMode(v) ? v : defaultInputMode(touchFirst);
}

export function saveInputMode(store: KeyValueStore | null, mode: InputMode): void {
  safeSet(store, INPUT_KEY, mode);
}

/** Deadband in [0, 0.5], expo in [0, 1]; anything else gives the default. */
export function parseGamepadOptions(text: string | null): GamepadOptions {
  if (text === null) return DEFAULT_GAMEPAD_OPTIONS;
  try {
    const v: unknown = JSON.parse(text);
    if (typeof v !== "object" || v === null) return DEFAULT_GAMEPAD_OPTIONS;
    const o = v as { deadband?: unknown; expo?: unknown };
    const deadband = typeof o.deadband === "number" && o.deadband >= 0 && o.deadband <= 0.5 ? o.deadband : DEFAULT_GAMEPAD_OPTIONS.deadband;
    const expo = typeof o.expo === "number" && o.expo >= 0 && o.expo <= 1 ? o.expo : DEFAULT_GAMEPAD_OPTIONS.expo;
    return { deadband, expo };
  } catch {
    return DEFAULT_GAMEPAD_OPTIONS;
  }
}

export function loadGamepadOptions(store: KeyValueStore | null): GamepadOptions {
  return parseGamepadOptions(safeGet(store, GAMEPAD_KEY));
}

export function saveGamepadOptions(store: KeyValueStore | null, options: GamepadOptions): void {
  safeSet(store, GAMEPAD_KEY, JSON.stringify(options));
}
