/**
 * How the replay keeps its picture and its numbers together (pure): `react(state, event,
 * footage)` for what the pilot and the picture do, `display(state, now, footage)` for what
 * one animation frame shows. The page feeds it its clicks, keys and drags, the animation
 * frames, and the frame the picture has just put on the canvas; it draws the plots' cursor
 * and the HUD at `display().pos`, asks the video for the frame at `display().want`, and marks
 * the picture as not yet the one at the cursor while `display().stale`.
 *
 * ## Rules
 *
 * - **A position change holds the clock until its picture is shown.** A seek (drag, plot,
 *   keys, an event, Home/End), a frame step, a pause, playing again from the end and the
 *   dive's end reached all *hold* the position: the cursor, the HUD and the plots stand at
 *   it, and the clock does not run, until the picture on the canvas is the frame at that
 *   position. Then the clock resumes from the held position (playing, when it played).
 *   While held, the picture is marked stale (it is still the previous frame).
 * - **While the clock runs, the numbers never run ahead of the picture**: the cursor stops
 *   just before the frame after the one shown, so the cursor's time is always within the
 *   frame on the canvas. The clock itself keeps time (the video decodes up to it, and a slow
 *   decoder skips pictures): the picture and the numbers jump together rather than drift.
 * - **Paused, the picture is exactly the frame at the cursor**: a pause holds until it is, and
 *   a picture asked for before the pause that comes after it holds again.
 * - Nothing to wait for means no hold: a dive without video, a picture that cannot be shown
 *   (the video's problem is on the page), or a position where the recording has no frames.
 *
 * The state counts the holds begun and settled: the page shows both (`data-holds`,
 * `data-settled`), so that its tests wait for a seek's picture without timing.
 *
 * Positions are the dive's clock (ms since the epoch); frames' times are µs; `now` is the
 * page's monotonic clock (ms).
 */

import { frameStep, indexAt, newClock, pause, play, positionAt, seek, setRate, stepRate, tick } from "./core";
import type { Rate, ReplayClock } from "./core";

/** The recorded frames the picture can show now. */
export type Footage =
  /** no picture to wait for: the dive has no video, or it cannot be shown */
  | { readonly kind: "none" }
  /** the first frames are being fetched */
  | { readonly kind: "loading" }
  /** the frames fetched: their window (ms, both ends included) and each frame's time (µs, ascending) */
  | { readonly kind: "frames"; readonly fromMs: number; readonly toMs: number; readonly times: ArrayLike<number> };

export const NO_FOOTAGE: Footage = { kind: "none" };

export interface SyncState {
  readonly clock: ReplayClock;
  /** the position held until the picture shows its frame; null while the clock runs freely */
  readonly hold: number | null;
  /** the frame on the canvas (its time, µs); null before the first */
  readonly shownUs: number | null;
  /** holds begun, and the last one settled (equal when none waits) */
  readonly holds: number;
  readonly settled: number;
}

export type SyncEvent =
  /** an animation frame */
  | { readonly type: "tick"; readonly now: number }
  /** the picture put the frame of `us` on the canvas */
  | { readonly type: "picture"; readonly us: number; readonly now: number }
  | { readonly type: "seek"; readonly pos: number; readonly now: number }
  /** seek by `ms` from the position shown */
  | { readonly type: "seekBy"; readonly ms: number; readonly now: number }
  /** one frame on (1) or back (-1), pausing */
  | { readonly type: "step"; readonly dir: 1 | -1; readonly now: number }
  | { readonly type: "toggle"; readonly now: number }
  | { readonly type: "rate"; readonly rate: Rate; readonly now: number }
  | { readonly type: "stepRate"; readonly dir: 1 | -1; readonly now: number };

/** What one animation frame shows. */
export interface Display {
  /** the position of the cursor, the HUD and the plots (ms) */
  readonly pos: number;
  /** the position whose frame the picture should show (or decode towards) */
  readonly want: number;
  /** the picture is not yet the frame at `pos` (a hold waits for it) */
  readonly stale: boolean;
}

/** What a held position waits for: nothing, frames being fetched, or the frame of `us`. */
export type Target = { readonly kind: "free" } | { readonly kind: "loading" } | { readonly kind: "frame"; readonly us: number };

/** The frame shown at `pos`: the last at or before it (the first, before the first). */
export function target(footage: Footage, pos: number): Target {
  switch (footage.kind) {
    case "none":
      return { kind: "free" };
    case "loading":
      return { kind: "loading" };
    case "frames": {
      if (pos < footage.fromMs || pos > footage.toMs) return { kind: "loading" };
      if (footage.times.length === 0) return { kind: "free" };
      // µs rounded, as frame steps set positions to a frame's time / 1000
      const us = footage.times[Math.max(0, indexAt(footage.times, Math.round(pos * 1000)))];
      return us !== undefined ? { kind: "frame", us } : { kind: "free" };
    }
  }
}

/** A new replay of the dive from `start` to `end`: paused at its start, waiting for its first picture. */
export function newSync(start: number, end: number, now: number, footage: Footage): SyncState {
  return settleIfShown({ clock: newClock(start, end, now), hold: start, shownUs: null, holds: 1, settled: 0 }, now, footage);
}

function clamp(c: ReplayClock, pos: number): number {
  return Math.min(c.end, Math.max(c.start, pos));
}

/** Holds `pos` (the clock set there, playing or not as `clock` says) until its picture shows. */
function holdAt(s: SyncState, clock: ReplayClock, pos: number, now: number, footage: Footage): SyncState {
  const at = clamp(clock, pos);
  return settleIfShown({ ...s, clock: seek(clock, at, now), hold: at, holds: s.holds + 1 }, now, footage);
}

/** Lets the clock run again from the held position when the picture shows its frame (or nothing is to wait for). */
function settleIfShown(s: SyncState, now: number, footage: Footage): SyncState {
  if (s.hold === null) return s;
  const t = target(footage, s.hold);
  const shown = t.kind === "free" || (t.kind === "frame" && t.us === s.shownUs);
  return shown ? { ...s, clock: seek(s.clock, s.hold, now), hold: null, settled: s.holds } : s;
}

/** The time (ms) the cursor may reach while the clock runs: just before the frame after the one shown. */
function runLimit(s: SyncState, footage: Footage): number {
  if (footage.kind !== "frames" || s.shownUs === null) return Infinity;
  const { times } = footage;
  const next = times[indexAt(times, s.shownUs) + 1];
  // 1 µs before the next frame: the cursor's frame is still the one shown
  if (next !== undefined) return (next - 1) / 1000;
  // the window's last frame: no frame follows it up to the window's end; past it, unknown yet
  return footage.toMs >= s.clock.end ? Infinity : footage.toMs;
}

export function display(s: SyncState, now: number, footage: Footage): Display {
  if (s.hold !== null) {
    const t = target(footage, s.hold);
    return { pos: s.hold, want: s.hold, stale: !(t.kind === "free" || (t.kind === "frame" && t.us === s.shownUs)) };
  }
  const clockPos = positionAt(s.clock, now);
  if (!s.clock.playing) return { pos: clockPos, want: clockPos, stale: false };
  return { pos: Math.min(clockPos, Math.max(s.clock.start, runLimit(s, footage))), want: clockPos, stale: false };
}

export function react(s: SyncState, e: SyncEvent, footage: Footage): SyncState {
  switch (e.type) {
    case "tick": {
      if (s.hold !== null) return settleIfShown(s, e.now, footage);
      const ticked = tick(s.clock, e.now);
      // the dive's end reached: paused there, held until its picture shows
      return ticked === s.clock ? s : holdAt(s, ticked, ticked.anchorPos, e.now, footage);
    }
    case "picture": {
      const shown = { ...s, shownUs: e.us };
      if (shown.hold !== null || shown.clock.playing) return settleIfShown(shown, e.now, footage);
      // paused, a picture asked for before the pause (not the frame at the cursor): held again until it is
      const t = target(footage, shown.clock.anchorPos);
      return t.kind === "frame" && t.us !== e.us ? holdAt(shown, shown.clock, shown.clock.anchorPos, e.now, footage) : shown;
    }
    case "seek":
      return holdAt(s, s.clock, e.pos, e.now, footage);
    case "seekBy":
      return holdAt(s, s.clock, display(s, e.now, footage).pos + e.ms, e.now, footage);
    case "step": {
      if (footage.kind !== "frames") return s;
      const to = frameStep(footage.times, display(s, e.now, footage).pos, e.dir);
      return to === null ? s : holdAt(s, pause(s.clock, e.now), to, e.now, footage);
    }
    case "toggle": {
      const pos = display(s, e.now, footage).pos;
      if (s.clock.playing) return holdAt(s, pause(s.clock, e.now), pos, e.now, footage);
      // playing at the end starts over, as players do
      const played = play(seek(s.clock, pos, e.now), e.now);
      if (s.hold !== null && played.anchorPos === s.hold) return { ...s, clock: played };
      return holdAt(s, played, played.anchorPos, e.now, footage);
    }
    case "rate":
      return { ...s, clock: setRate(s.clock, e.rate, e.now) };
    case "stepRate":
      return { ...s, clock: stepRate(s.clock, e.dir, e.now) };
  }
}
