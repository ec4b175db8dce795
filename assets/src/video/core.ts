/**
 * What the player does with each message of the video socket (pure):
 * `step(state, input) → {state, actions}`; the player (player.ts) carries the actions out.
 *
 * - A decoder is set up per stream generation, from a keyframe: a new `stream` (new
 *   generation, codec or size), a decoder error or a socket that opens again starts over at
 *   the next keyframe, without reloading the page.
 * - The live edge, always: a page that falls behind (its decoder holds more than
 *   MAX_BACKLOG frames) drops frames up to the next keyframe; a keyframe that finds the
 *   decoder far behind (FLUSH_BACKLOG) flushes it first. A gap in the sequence numbers (frames the server
 *   skipped for this page) also waits for a keyframe: an H.264 frame needs the ones before.
 * - A frame that waited in the page (its main thread was busy: the browser queues the socket's
 *   messages) more than LATE_MS is dropped, and the page goes on from a fresh keyframe
 *   (lateness.ts): a starved page catches up at the cost of a header's parse per frame.
 * - JPEG frames stand alone: a page behind simply drops them until it catches up.
 */

import { LATE_MS } from "./lateness";
import type { CameraEvent, Codec, FrameHeader, StreamEvent, VideoEvent } from "./wire";

/**
 * H.264 frames waiting in the decoder past which the page drops to the next keyframe: half a
 * second at 30 fps. Below it the decoder catches up by itself (a few ms a frame; only the
 * newest picture is shown) — dropping to a keyframe would freeze the picture up to a second.
 */
export const MAX_BACKLOG = 15;
/**
 * Frames waiting in the decoder at a keyframe past which it is flushed (reset) before the
 * keyframe: a decoder this far behind would show old pictures for seconds. Below it the
 * keyframe just joins the queue — a reset costs a new decoder, which a starved page cannot
 * afford every second.
 */
export const FLUSH_BACKLOG = 3 * MAX_BACKLOG;
/** JPEG images being decoded past which a new one is dropped */
export const MAX_JPEG_BACKLOG = 2;

export interface DecoderConfig {
  readonly codec: Codec;
  readonly generation: number;
  /** RFC 6381 codec string (from `stream`; null: read it from the keyframe's SPS) */
  readonly avc: string | null;
  readonly width: number;
  readonly height: number;
  /** the camera's nominal frame rate (0: unknown) */
  readonly fps: number;
}

export interface CoreState {
  readonly stream: StreamEvent | null;
  readonly camera: CameraEvent | null;
  /** what the decoder is set up for (null: nothing yet, or reset) */
  readonly configured: DecoderConfig | null;
  readonly awaitingKey: boolean;
  readonly lastSequence: number | null;
}

export const INITIAL_CORE: CoreState = { stream: null, camera: null, configured: null, awaitingKey: true, lastSequence: null };

export type CoreInput =
  | { readonly type: "open" }
  | { readonly type: "closed" }
  | { readonly type: "event"; readonly event: VideoEvent }
  /** a frame arrived while `backlog` frames wait in the decoder, `lateMs` after its time (lateness.ts) */
  | { readonly type: "frame"; readonly frame: FrameHeader; readonly backlog: number; readonly lateMs: number }
  | { readonly type: "decoder_error"; readonly reason: string };

export type DropReason = "no_stream" | "stale" | "lost" | "await_key" | "behind" | "late" | "kind";

export type CoreAction =
  /** close the decoder and forget what it holds */
  | { readonly type: "reset"; readonly reason: string }
  | { readonly type: "configure"; readonly config: DecoderConfig }
  /** decode the frame of this input */
  | { readonly type: "decode" }
  /** frames this page will never show (counted as dropped) */
  | { readonly type: "drop"; readonly frames: number; readonly why: DropReason }
  /** the server dropped frames for this page (its `skipped` event; the sequence gap counts them) */
  | { readonly type: "skipped"; readonly frames: number }
  /** ask the server to start again at the next keyframe */
  | { readonly type: "request_keyframe" }
  /** the stream stops on purpose (no freeze to count meanwhile) */
  | { readonly type: "pause" };

export interface Step {
  readonly state: CoreState;
  readonly actions: readonly CoreAction[];
}

function sameStream(a: StreamEvent, b: StreamEvent): boolean {
  return a.generation === b.generation && a.codec === b.codec && a.width === b.width && a.height === b.height && a.avc === b.avc;
}

function restart(state: CoreState, reason: string, extra: Partial<CoreState> = {}): Step {
  const actions: CoreAction[] = state.configured !== null ? [{ type: "reset", reason }, { type: "pause" }] : [{ type: "pause" }];
  return { state: { ...state, configured: null, awaitingKey: true, lastSequence: null, ...extra }, actions };
}

function onEvent(state: CoreState, event: VideoEvent): Step {
  switch (event.event) {
    case "stream": {
      if (state.stream !== null && sameStream(state.stream, event)) return { state: { ...state, stream: event }, actions: [] };
      return restart(state, `new stream (generation ${event.generation})`, { stream: event });
    }
    case "camera":
      return { state: { ...state, camera: event }, actions: event.state === "running" ? [] : [{ type: "pause" }] };
    case "skipped":
      return { state: { ...state, awaitingKey: true }, actions: [{ type: "skipped", frames: event.frames }] };
  }
}

function onFrame(state: CoreState, frame: FrameHeader, backlog: number, lateMs: number): Step {
  const stream = state.stream;
  const drop = (why: DropReason, s: CoreState = state, frames = 1): Step => ({ state: s, actions: [{ type: "drop", frames, why }] });
  if (stream === null) return drop("no_stream");
  if (frame.generation < stream.generation) return drop("stale");
  if (frame.generation > stream.generation) {
    // a frame of a stream we were not told of: take it as that stream (size from the picture)
    const next: StreamEvent = { ...stream, generation: frame.generation, avc: null };
    const restarted = restart(state, `new generation ${frame.generation}`, { stream: next });
    const again = onFrame(restarted.state, frame, 0, lateMs);
    return { state: again.state, actions: [...restarted.actions, ...again.actions] };
  }
  if ((frame.kind === "jpeg") !== (stream.codec === "mjpeg")) return drop("kind");

  const actions: CoreAction[] = [];
  let awaitingKey = state.awaitingKey;
  const last = state.lastSequence;
  if (last !== null) {
    if (frame.sequence <= last) return drop("stale");
    const gap = frame.sequence - last - 1;
    if (gap > 0) {
      actions.push({ type: "drop", frames: gap, why: "lost" });
      if (frame.kind === "h264") awaitingKey = true;
    }
  }
  const seen: CoreState = { ...state, lastSequence: frame.sequence };

  if (lateMs > LATE_MS) return { state: { ...seen, awaitingKey: true }, actions: [...actions, { type: "drop", frames: 1, why: "late" }] };

  if (frame.kind === "jpeg") {
    if (backlog >= MAX_JPEG_BACKLOG) return { state: seen, actions: [...actions, { type: "drop", frames: 1, why: "behind" }] };
    const config = configFor(stream);
    if (state.configured === null) actions.push({ type: "configure", config });
    actions.push({ type: "decode" });
    return { state: { ...seen, configured: config, awaitingKey: false }, actions };
  }

  if (!frame.keyframe) {
    if (awaitingKey || state.configured === null) return { state: { ...seen, awaitingKey: true }, actions: [...actions, { type: "drop", frames: 1, why: "await_key" }] };
    if (backlog > MAX_BACKLOG) return { state: { ...seen, awaitingKey: true }, actions: [...actions, { type: "drop", frames: 1, why: "behind" }] };
    actions.push({ type: "decode" });
    return { state: seen, actions };
  }

  // a keyframe: (re)start here if needed, or flush a decoder that is still behind
  const config = configFor(stream);
  if (state.configured === null) {
    actions.push({ type: "configure", config });
  } else if (backlog > FLUSH_BACKLOG) {
    actions.push({ type: "drop", frames: backlog, why: "behind" }, { type: "reset", reason: "behind: flushed at a keyframe" }, { type: "configure", config });
  }
  actions.push({ type: "decode" });
  return { state: { ...seen, configured: config, awaitingKey: false }, actions };
}

function configFor(stream: StreamEvent): DecoderConfig {
  return { codec: stream.codec, generation: stream.generation, avc: stream.avc, width: stream.width, height: stream.height, fps: stream.fps };
}

export function step(state: CoreState, input: CoreInput): Step {
  switch (input.type) {
    case "open":
      return { state: INITIAL_CORE, actions: [] };
    case "closed":
      return restart(state, "socket closed", { stream: null, camera: null });
    case "event":
      return onEvent(state, input.event);
    case "frame":
      return onFrame(state, input.frame, input.backlog, input.lateMs);
    case "decoder_error": {
      const r = restart(state, `decoder error: ${input.reason}`);
      return { state: r.state, actions: [...r.actions, { type: "request_keyframe" }] };
    }
  }
}
