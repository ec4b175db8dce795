/**
 * Where decoded pictures go: the common face of the three decode paths (WebCodecs and JPEG
 * paint a canvas, Media Source Extensions play a <video>), and what each reports back.
 */

import type { DecoderConfig } from "./core";
import type { EncodedFrame, FrameHeader } from "./wire";

export type DecodePath = "webcodecs" | "mse" | "jpeg";

export interface SinkEvents {
  /** a picture was decoded (not yet shown) */
  decoded(): void;
  /**
   * A picture reached the screen: its frame, when (performance.now() clock, ms) and, when
   * the picture carries one, the render stamp read from its corner (ms modulo 2^48).
   */
  displayed(frame: FrameHeader, atMs: number, stamp: number | null): void;
  /** pictures decoded but replaced by a newer one before they were shown */
  superseded(frames: number): void;
  /** the decoder failed; the sink has already let go of it */
  error(reason: string): void;
}

export interface Sink {
  readonly path: DecodePath;
  /** the element that shows the pictures (canvas or video) */
  readonly element: HTMLElement;
  /** set up for a stream; `keyframe` is the frame the stream starts with */
  configure(config: DecoderConfig, keyframe: EncodedFrame): void;
  decode(frame: EncodedFrame): void;
  /** forget everything decoded or queued (a new configure follows before any decode) */
  reset(): void;
  /** frames given but not decoded yet */
  backlog(): number;
  /** how far the picture shown is behind the newest frame received (ms), where the path keeps a buffer */
  lagMs(): number | null;
  /** read the render stamp of each picture (the sim camera's) */
  readStamps: boolean;
  close(): void;
}

/** Chooses the decode path: `forced` when it can run here, else WebCodecs where available, else MSE. */
export function choosePath(
  codec: "h264" | "mjpeg",
  forced: DecodePath | null,
  env: { readonly webcodecs: boolean; readonly mse: boolean },
): DecodePath | null {
  if (codec === "mjpeg") return "jpeg";
  if (forced === "webcodecs" && env.webcodecs) return "webcodecs";
  if (forced === "mse" && env.mse) return "mse";
  if (env.webcodecs) return "webcodecs";
  if (env.mse) return "mse";
  return null;
}
