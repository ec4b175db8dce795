/**
 * The replay's picture: the recorded frames of a time window (`GET /api/recordings/…/video`),
 * drawn on a canvas — JPEG images decoded one by one, H.264 through the browser's WebCodecs
 * decoder from the keyframe before the frame asked for (forward from the frame shown while
 * playing). Only the newest frame asked for is drawn; frames asked for while one decodes
 * wait, so a slow decoder skips frames and never falls behind.
 *
 * The canvas says which frame it shows: `data-frame-us` (its recorded time, µs) and
 * `data-frame-index` (its index in the loaded window), for the page and its tests.
 */

import { indexAt, parseVideoFrames } from "./core";
import type { RecordedFrame } from "./core";

/** How much video one request loads from the position on (ms); a request is at most 120 s. */
const WINDOW_MS = 30_000;
/** Loaded again when the position gets this close to the window's end (ms). */
const MARGIN_MS = 5_000;

export interface VideoWindow {
  readonly fromMs: number;
  readonly toMs: number;
  readonly frames: readonly RecordedFrame[];
  /** each frame's time (µs), ascending */
  readonly times: Float64Array;
}

/** The codec string (RFC 6381) of an H.264 keyframe's SPS, e.g. "avc1.42c01e"; null without one. */
export function avcCodec(payload: Uint8Array): string | null {
  for (let i = 0; i + 7 < payload.length; i++) {
    if (payload[i] === 0 && payload[i + 1] === 0 && payload[i + 2] === 1 && ((payload[i + 3] ?? 0) & 0x1f) === 7) {
      const hex = (b: number | undefined): string => (b ?? 0).toString(16).padStart(2, "0");
      return `avc1.${hex(payload[i + 4])}${hex(payload[i + 5])}${hex(payload[i + 6])}`;
    }
  }
  return null;
}

export class ReplayVideo {
  private window: VideoWindow | null = null;
  private loading: Promise<void> | null = null;
  private wanted = -1;
  private shown = -1;
  private busy = false;
  private decoder: VideoDecoder | null = null;
  /** the last frame given to the H.264 decoder (index in the window), -1 after a reset */
  private fed = -1;
  private generation = -1;
  /** why the picture cannot be shown (null: it can) */
  problem: string | null = null;

  constructor(
    private readonly canvas: HTMLCanvasElement,
    private readonly url: (fromMs: number, toMs: number) => string,
    private readonly headers: Record<string, string>,
    private readonly bounds: { readonly start: number; readonly end: number },
    private readonly onChange: () => void,
  ) {}

  /** The frames loaded now (for frame steps), or null. */
  get loaded(): VideoWindow | null {
    return this.window;
  }

  /** Shows the frame at `posMs`, loading its window first when needed. */
  show(posMs: number): void {
    const w = this.window;
    if (w === null || posMs < w.fromMs || (posMs > w.toMs - MARGIN_MS && w.toMs < this.bounds.end)) {
      this.load(posMs);
      if (w === null || posMs < w.fromMs || posMs > w.toMs) return;
    }
    // before the first frame, the first picture; µs rounded as frame steps set them
    const index = Math.max(0, indexAt(w.times, Math.round(posMs * 1000)));
    if (w.frames.length === 0 || index === this.wanted) return;
    this.wanted = index;
    if (!this.busy) void this.drawWanted();
  }

  private load(posMs: number): void {
    if (this.loading !== null) return;
    const fromMs = Math.max(this.bounds.start, Math.floor(posMs) - 1_000);
    const toMs = Math.min(this.bounds.end + 1, fromMs + WINDOW_MS);
    this.loading = (async () => {
      try {
        const response = await fetch(this.url(fromMs, toMs), { headers: this.headers, cache: "no-store" });
        if (!response.ok) throw new Error(`video: HTTP ${response.status}`);
        const frames = parseVideoFrames(await response.arrayBuffer());
        // the reply starts at the keyframe before `from`: the window covers from there
        const first = frames[0];
        const times = Float64Array.from(frames, (f) => f.atUs);
        this.window = { fromMs: first !== undefined ? Math.min(fromMs, first.atUs / 1000) : fromMs, toMs, frames, times };
        this.wanted = -1;
        this.shown = -1;
        this.resetDecoder();
        this.problem = null;
      } catch (err) {
        this.problem = err instanceof Error ? err.message : String(err);
      } finally {
        this.loading = null;
        this.onChange();
      }
    })();
  }

  private resetDecoder(): void {
    if (this.decoder !== null && this.decoder.state !== "closed") this.decoder.close();
    this.decoder = null;
    this.fed = -1;
  }

  private async drawWanted(): Promise<void> {
    this.busy = true;
    try {
      while (this.window !== null && this.wanted >= 0 && this.wanted !== this.shown) {
        const target = this.wanted;
        const frame = this.window.frames[target];
        if (frame === undefined) break;
        if (frame.codec === "jpeg") await this.drawJpeg(frame);
        else await this.decodeH264(this.window, target);
        this.shown = target;
        this.canvas.dataset["frameUs"] = String(frame.atUs);
        this.canvas.dataset["frameIndex"] = String(target);
      }
    } catch (err) {
      this.problem = err instanceof Error ? err.message : String(err);
      this.resetDecoder();
      this.onChange();
    } finally {
      this.busy = false;
    }
  }

  private async drawJpeg(frame: RecordedFrame): Promise<void> {
    const bitmap = await createImageBitmap(new Blob([frame.payload], { type: "image/jpeg" }));
    this.paint(bitmap, bitmap.width, bitmap.height);
    bitmap.close();
  }

  private paint(image: CanvasImageSource, width: number, height: number): void {
    if (this.canvas.width !== width || this.canvas.height !== height) {
      this.canvas.width = width;
      this.canvas.height = height;
    }
    this.canvas.getContext("2d")?.drawImage(image, 0, 0, width, height);
  }

  /** Decodes up to frame `target` and draws it. */
  private async decodeH264(w: VideoWindow, target: number): Promise<void> {
    if (typeof VideoDecoder === "undefined") throw new Error("this browser cannot decode H.264 (no WebCodecs)");
    const frame = w.frames[target];
    if (frame === undefined) return;
    // forward from the frame fed last when it is the same stream and not far; else from the keyframe before
    let from = this.fed + 1;
    if (this.decoder === null || this.fed < 0 || target <= this.fed || target - this.fed > 90 || frame.generation !== this.generation) {
      let key = target;
      while (key > 0 && !(w.frames[key]?.keyframe ?? false)) key--;
      const keyframe = w.frames[key];
      if (keyframe === undefined || !keyframe.keyframe) return; // nothing decodable yet
      this.resetDecoder();
      await this.configure(keyframe);
      from = key;
    }
    const decoder = this.decoder;
    if (decoder === null) return;
    let last: VideoFrame | null = null;
    const done = new Promise<void>((resolve) => {
      this.onOutput = (picture) => {
        last?.close();
        last = picture;
        if (picture.timestamp === frame.atUs) resolve();
      };
    });
    for (let i = from; i <= target; i++) {
      const f = w.frames[i];
      if (f === undefined) break;
      decoder.decode(new EncodedVideoChunk({ type: f.keyframe ? "key" : "delta", timestamp: f.atUs, data: f.payload }));
      this.fed = i;
    }
    // a decoder set for latency gives each picture as it is decoded; one that holds pictures
    // back is flushed, and the next frame starts again from a keyframe (a flushed decoder
    // needs one)
    const timedOut = await Promise.race([done.then(() => false), new Promise<boolean>((r) => setTimeout(() => r(true), 250))]);
    if (timedOut) {
      await decoder.flush();
      this.fed = -1;
    }
    const picture: VideoFrame | null = last;
    if (picture !== null) {
      const p: VideoFrame = picture;
      this.paint(p, p.displayWidth, p.displayHeight);
      p.close();
    }
    this.onOutput = null;
  }

  private onOutput: ((frame: VideoFrame) => void) | null = null;

  private async configure(keyframe: RecordedFrame): Promise<void> {
    const codec = avcCodec(keyframe.payload) ?? "avc1.42e01e";
    const config: VideoDecoderConfig = { codec, optimizeForLatency: true };
    const support = await VideoDecoder.isConfigSupported(config);
    if (support.supported !== true) throw new Error(`this browser cannot decode this video (${codec})`);
    this.decoder = new VideoDecoder({
      output: (picture) => {
        if (this.onOutput !== null) this.onOutput(picture);
        else picture.close();
      },
      error: (e) => {
        this.problem = `video decoder: ${e.message}`;
        this.onChange();
      },
    });
    this.decoder.configure(config);
    this.generation = keyframe.generation;
  }

  close(): void {
    this.resetDecoder();
  }
}
