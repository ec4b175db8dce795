/**
 * The replay page's decisions (pure): where in the dive the replay is (a clock that plays at
 * 0.25×–4×, pauses, seeks; sync.ts holds it until the picture is shown), which recorded frame and telemetry sample show at a position, the
 * events one jumps between (stops, handovers, autopilot changes, logger entries, snapshots),
 * the keyboard shortcuts, and the frames of `GET /api/recordings/…/video` (docs/API.md).
 *
 * Positions are the dive's own clock: wall-clock ms since the epoch, as the recording's
 * entries and the video's frames carry them (frames in µs). `now` is the page's monotonic
 * clock (`performance.now()`), in ms.
 */

import type { RecordedEntry } from "../lib/recordings";

export const RATES = [0.25, 0.5, 1, 2, 4] as const;
export type Rate = (typeof RATES)[number];

export interface ReplayClock {
  readonly playing: boolean;
  readonly rate: Rate;
  /** the position when the clock was last changed, and the page's time then */
  readonly anchorPos: number;
  readonly anchorNow: number;
  /** the dive's first and last instant (ms) */
  readonly start: number;
  readonly end: number;
}

export function newClock(start: number, end: number, now: number): ReplayClock {
  return { playing: false, rate: 1, anchorPos: start, anchorNow: now, start, end: Math.max(start, end) };
}

function clamp(c: ReplayClock, pos: number): number {
  return Math.min(c.end, Math.max(c.start, pos));
}

/** The position at `now` (ms of the dive's clock), never past the dive's ends. */
export function positionAt(c: ReplayClock, now: number): number {
  if (!c.playing) return c.anchorPos;
  return clamp(c, c.anchorPos + (now - c.anchorNow) * c.rate);
}

/** The clock at `now`: paused at the end once it got there. */
export function tick(c: ReplayClock, now: number): ReplayClock {
  return c.playing && positionAt(c, now) >= c.end ? { ...c, playing: false, anchorPos: c.end, anchorNow: now } : c;
}

export function play(c: ReplayClock, now: number): ReplayClock {
  if (c.playing) return c;
  // playing at the end starts over, as players do
  const from = c.anchorPos >= c.end ? c.start : c.anchorPos;
  return { ...c, playing: true, anchorPos: from, anchorNow: now };
}

export function pause(c: ReplayClock, now: number): ReplayClock {
  return c.playing ? { ...c, playing: false, anchorPos: positionAt(c, now), anchorNow: now } : c;
}

export function seek(c: ReplayClock, pos: number, now: number): ReplayClock {
  return { ...c, anchorPos: clamp(c, pos), anchorNow: now };
}

export function setRate(c: ReplayClock, rate: Rate, now: number): ReplayClock {
  return { ...c, rate, anchorPos: positionAt(c, now), anchorNow: now };
}

/** The next faster (`dir` 1) or slower (-1) rate, within 0.25×–4×. */
export function stepRate(c: ReplayClock, dir: 1 | -1, now: number): ReplayClock {
  const i = RATES.indexOf(c.rate);
  const next = RATES[Math.min(RATES.length - 1, Math.max(0, i + dir))] ?? c.rate;
  return setRate(c, next, now);
}

/** The index of the last of `times` (ascending) at or before `t`; -1 when none is. */
export function indexAt(times: ArrayLike<number>, t: number): number {
  let lo = 0;
  let hi = times.length - 1;
  let found = -1;
  while (lo <= hi) {
    const mid = (lo + hi) >> 1;
    if ((times[mid] ?? Infinity) <= t) {
      found = mid;
      lo = mid + 1;
    } else {
      hi = mid - 1;
    }
  }
  return found;
}

/**
 * The position one frame on (`dir` 1) or back (-1) from `pos` (ms): the next frame's time,
 * or the one before the frame shown. `frameUs` are the video's frame times (µs, ascending);
 * null when there is no frame that way.
 */
export function frameStep(frameUs: ArrayLike<number>, pos: number, dir: 1 | -1): number | null {
  // µs rounded: a position set to a frame's time (µs / 1000) must find that frame again
  const shown = indexAt(frameUs, Math.round(pos * 1000));
  const target = shown + dir;
  const us = frameUs[target];
  return target >= 0 && us !== undefined ? us / 1000 : null;
}

export type EventKind = "stop" | "handover" | "autopilot" | "log" | "snapshot";

export interface ReplayEvent {
  readonly at: number;
  readonly kind: EventKind;
  readonly label: string;
}

function text(v: unknown): string {
  return typeof v === "string" ? v : "";
}

function pilotName(payload: Readonly<Record<string, unknown>>): string {
  const pilot = payload["pilot"];
  return typeof pilot === "object" && pilot !== null && "name" in pilot ? text((pilot as { name: unknown }).name) : "";
}

/** The events one jumps between, in time order, from a recording's non-telemetry entries. */
export function replayEvents(entries: readonly RecordedEntry[]): ReplayEvent[] {
  const out: ReplayEvent[] = [];
  for (const e of entries) {
    const p = e.payload;
    switch (e.event) {
      case "stopped":
        out.push({ at: e.at, kind: "stop", label: `stop: ${text(p["reason"]) || "?"}` });
        break;
      case "helm": {
        const name = pilotName(p);
        out.push({ at: e.at, kind: "handover", label: name !== "" ? `helm: ${name}` : `helm: ${text(p["state"]) || "free"}` });
        break;
      }
      case "snapshot":
        out.push({ at: e.at, kind: "snapshot", label: `snapshot ${text(p["name"])}`.trim() });
        break;
      case "log": {
        const category = text(p["category"]);
        out.push({ at: e.at, kind: category === "autopilot" ? "autopilot" : "log", label: `${category || "log"}: ${text(p["message"])}` });
        break;
      }
      default:
        break;
    }
  }
  return out.sort((a, b) => a.at - b.at);
}

/** How far back "previous event" skips the one just reached (as players restart a track). */
export const PREVIOUS_SLACK_MS = 500;

/** The first event after `pos`, or null. */
export function nextEvent(events: readonly ReplayEvent[], pos: number): ReplayEvent | null {
  return events.find((e) => e.at > pos + 0.5) ?? null;
}

/** The last event more than PREVIOUS_SLACK_MS before `pos`, or null. */
export function previousEvent(events: readonly ReplayEvent[], pos: number): ReplayEvent | null {
  let found: ReplayEvent | null = null;
  for (const e of events) {
    if (e.at < pos - PREVIOUS_SLACK_MS) found = e;
    else break;
  }
  return found;
}

export type KeyAction =
  | { readonly type: "toggle" }
  | { readonly type: "seekBy"; readonly ms: number }
  | { readonly type: "frame"; readonly dir: 1 | -1 }
  | { readonly type: "rate"; readonly dir: 1 | -1 }
  | { readonly type: "event"; readonly dir: 1 | -1 }
  | { readonly type: "home" }
  | { readonly type: "end" };

/**
 * The shortcuts, as video players have them: space or k play/pause, ← → 5 s, j l 10 s,
 * , . one frame (paused), < > (shift + , .) slower / faster, p n previous / next event,
 * Home / End the dive's ends.
 */
export function keyAction(key: string): KeyAction | null {
  switch (key) {
    case " ":
    case "k":
      return { type: "toggle" };
    case "ArrowLeft":
      return { type: "seekBy", ms: -5_000 };
    case "ArrowRight":
      return { type: "seekBy", ms: 5_000 };
    case "j":
      return { type: "seekBy", ms: -10_000 };
    case "l":
      return { type: "seekBy", ms: 10_000 };
    case ",":
      return { type: "frame", dir: -1 };
    case ".":
      return { type: "frame", dir: 1 };
    case "<":
      return { type: "rate", dir: -1 };
    case ">":
      return { type: "rate", dir: 1 };
    case "p":
      return { type: "event", dir: -1 };
    case "n":
      return { type: "event", dir: 1 };
    case "Home":
      return { type: "home" };
    case "End":
      return { type: "end" };
    default:
      return null;
  }
}

/** One frame of `GET /api/recordings/…/video`: its header's fields and its picture. */
export interface RecordedFrame {
  readonly codec: "h264" | "jpeg";
  readonly keyframe: boolean;
  readonly generation: number;
  /** arrival time, µs since the epoch (the dive's clock) */
  readonly atUs: number;
  readonly payload: Uint8Array<ArrayBuffer>;
}

const HEADER_BYTES = 28;

/**
 * The frames of a `/video` reply: each a 4-byte big-endian length, then the frame as the
 * video WebSocket sends it (28-byte header, then the picture). Throws on a malformed reply.
 */
export function parseVideoFrames(buffer: ArrayBuffer): RecordedFrame[] {
  const view = new DataView(buffer);
  const frames: RecordedFrame[] = [];
  let at = 0;
  while (at < buffer.byteLength) {
    if (at + 4 > buffer.byteLength) throw new Error("a frame's length is cut off");
    const length = view.getUint32(at);
    const start = at + 4;
    if (length < HEADER_BYTES || start + length > buffer.byteLength) throw new Error(`a frame is cut off at byte ${at}`);
    const version = view.getUint8(start);
    const kind = view.getUint8(start + 1);
    if (version !== 1 || (kind !== 1 && kind !== 2)) throw new Error(`not a frame at byte ${at} (version ${version}, kind ${kind})`);
    const flags = view.getUint8(start + 2);
    frames.push({
      codec: kind === 1 ? "h264" : "jpeg",
      keyframe: (flags & 1) === 1,
      generation: view.getUint32(start + 4),
      atUs: Number(view.getBigUint64(start + 12)),
      payload: new Uint8Array(buffer, start + HEADER_BYTES, length - HEADER_BYTES),
    });
    at = start + length;
  }
  return frames;
}

/** "12:34.5" of a position from the dive's start. */
export function formatOffset(ms: number): string {
  const clamped = Math.max(0, ms);
  const minutes = Math.floor(clamped / 60_000);
  const seconds = (clamped % 60_000) / 1000;
  return `${minutes}:${seconds.toFixed(1).padStart(4, "0")}`;
}
