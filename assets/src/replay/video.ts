/**
 * The replay's picture: the recorded frames of a time window (`GET /api/recordings/…/video`),
 * drawn on a canvas — JPEG images decoded one by one, H.264 through the browser's WebCodecs
 * decoder from the keyframe before the frame asked for (forward from the frame decoded last
 * while playing). Only the newest frame asked for is decoded to a picture; frames asked for
 * while one decodes wait, so a slow decoder skips pictures and never falls behind.
 *
 * A decoded picture waits until the page's animation frame puts it on the canvas
 * (`present()`), in the same step as the cursor and the HUD it goes with (sync.ts decides
 * which position they show). The canvas says which frame it shows: `data-frame-us` (its
 * recorded time, µs) and `data-frame-index` (its index in the loaded window), for the page's
 * tests.
 */

import { indexAt, parseVideoFrames } from "./core";
import type { RecordedFrame } from "./core";
import { NO_FOOTAGE } from "./sync";
import type { Footage } from "./sync";

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

/** A decoded picture waiting for the animation frame that puts it on the canvas. */
interface Picture {
  readonly index: number;
  readonly us: number;
  readonly image: VideoFrame | ImageBitmap;
  readonly width: number;
  readonly height: number;
}

export class ReplayVideo {
  private window: VideoWindow | null = null;
  private loading: Promise<void> | null = null;
  /** the window whose fetch failed last: not fetched again until the position leaves it */
  private failed: { readonly fromMs: number; readonly toMs: number } | null = null;
  private wanted = -1;
  /** the frame decoded last (index in the window), -1 after a new window */
  private decoded = -1;
  private busy = false;
  private ready: Picture | null = null;
  /** the frame on the canvas (µs), null before the first */
  private shownUs: number | null = null;
  private decoder: VideoDecoder | null = null;
  /** the last frame given to the H.264 decoder (index in the window), -1 after a reset */
  private fed = -1;
  private generation = -1;
  /** why the frames around the position cannot be fetched, or the last frame asked for decoded */
  private loadProblem: string | null = null;
  private decodeProblem: string | null = null;

  constructor(
    private readonly canvas: HTMLCanvasElement,
    private readonly url: (fromMs: number, toMs: number) => string,
    private readonly headers: Record<string, string>,
    private readonly bounds: { readonly start: number; readonly end: number },
    private readonly onChange: () => void,
  ) {}

  /** Why the picture cannot be shown (null: it can). */
  get problem(): string | null {
    return this.loadProblem ?? this.decodeProblem;
  }

  /** The frames loaded now, as sync.ts reads them (none while the picture cannot be shown). */
  get footage(): Footage {
    if (this.problem !== null) return NO_FOOTAGE;
    const w = this.window;
    return w === null ? { kind: "loading" } : { kind: "frames", fromMs: w.fromMs, toMs: w.toMs, times: w.times };
  }

  /** Decodes the frame at `posMs` (the last at or before it), loading its window first when needed. */
  want(posMs: number): void {
    const w = this.window;
    if (w === null || posMs < w.fromMs || (posMs > w.toMs - MARGIN_MS && w.toMs < this.bounds.end)) {
      this.load(posMs);
      if (w === null || posMs < w.fromMs || posMs > w.toMs) return;
    }
    // before the first frame, the first picture; µs rounded as frame steps set them
    const index = Math.max(0, indexAt(w.times, Math.round(posMs * 1000)));
    if (w.frames.length === 0 || index === this.wanted) return;
    this.wanted = index;
    // a picture decoded for a later position (before a seek back or a pause) is not shown
    if (this.ready !== null && this.ready.us > (w.times[index] ?? Infinity)) {
      this.ready.image.close();
      this.ready = null;
    }
    if (!this.busy) void this.decodeWanted();
  }

  /**
   * Puts the newest decoded picture on the canvas, if one waits; the time (µs) of the frame
   * the canvas shows, null before the first.
   */
  present(): number | null {
    const p = this.ready;
    if (p !== null) {
      this.ready = null;
      if (this.canvas.width !== p.width || this.canvas.height !== p.height) {
        this.canvas.width = p.width;
        this.canvas.height = p.height;
      }
      this.canvas.getContext("2d")?.drawImage(p.image, 0, 0, p.width, p.height);
      p.image.close();
      this.shownUs = p.us;
      this.canvas.dataset["frameUs"] = String(p.us);
      this.canvas.dataset["frameIndex"] = String(p.index);
    }
    return this.shownUs;
  }

  private load(posMs: number): void {
    if (this.loading !== null) return;
    const fromMs = Math.max(this.bounds.start, Math.floor(posMs) - 1_000);
    const toMs = Math.min(this.bounds.end + 1, fromMs + WINDOW_MS);
    const f = this.failed;
    if (f !== null && posMs >= f.fromMs && posMs <= f.toMs) return;
    this.loading = (async () => {
      try {
        const response = await fetch(this.url(fromMs, toMs), { headers: this.headers, cache: "no-store" });
        if (!response.ok) throw new Error(`video: HTTP ${response.status}`);
        const frames = parseVideoFrames(await response.arrayBuffer());
        // the reply starts at the keyframe before `from`: the window covers from there
        const first = frames[0];
        const times = Float64Array.from(frames, (fr) => fr.atUs);
        this.window = { fromMs: first !== undefined ? Math.min(fromMs, first.atUs / 1000) : fromMs, toMs, frames, times };
        this.wanted = -1;
        this.decoded = -1;
        this.resetDecoder();
        this.failed = null;
        this.loadProblem = null;
      } catch (err) {
        this.failed = { fromMs, toMs };
        this.loadProblem = err instanceof Error ? err.message : String(err);
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

  private offer(picture: Picture): void {
    this.ready?.image.close();
    this.ready = picture;
  }

  private async decodeWanted(): Promise<void> {
    this.busy = true;
    try {
      while (this.window !== null && this.wanted >= 0 && this.wanted !== this.decoded) {
        const w = this.window;
        const target = this.wanted;
        const frame = w.frames[target];
        if (frame === undefined) break;
        const image = frame.codec === "jpeg" ? await createImageBitmap(new Blob([frame.payload], { type: "image/jpeg" })) : await this.decodeH264(w, target);
        // a new window came meanwhile (its frames are asked for again), or an earlier frame is
        // wanted now (a seek back, a pause): this picture would be shown in the wrong place
        if (this.window !== w || this.wanted < target) {
          if (this.window === w) this.decoded = target;
          image.close();
          continue;
        }
        this.decoded = target;
        const width = image instanceof ImageBitmap ? image.width : image.displayWidth;
        const height = image instanceof ImageBitmap ? image.height : image.displayHeight;
        this.offer({ index: target, us: frame.atUs, image, width, height });
        if (this.decodeProblem !== null) {
          this.decodeProblem = null;
          this.onChange();
        }
      }
    } catch (err) {
      this.decodeProblem = err instanceof Error ? err.message : String(err);
      this.resetDecoder();
      this.onChange();
    } finally {
      this.busy = false;
    }
  }

  /** Decodes up to frame `target`: its picture. */
  private async decodeH264(w: VideoWindow, target: number): Promise<VideoFrame> {
    if (typeof VideoDecoder === "undefined") throw new Error("this browser cannot decode H.264 (no WebCodecs)");
    const frame = w.frames[target];
    if (frame === undefined) throw new Error(`no frame ${target} in the window`);
    // forward from the frame fed last when it is the same stream and not far; else from the keyframe before
    let from = this.fed + 1;
    if (this.decoder === null || this.fed < 0 || target <= this.fed || target - this.fed > 90 || frame.generation !== this.generation) {
      let key = target;
      while (key > 0 && !(w.frames[key]?.keyframe ?? false)) key--;
      const keyframe = w.frames[key];
      if (keyframe === undefined || !keyframe.keyframe) throw new Error("the recording has no keyframe before this frame: it cannot be decoded");
      this.resetDecoder();
      await this.configure(keyframe);
      from = key;
    }
    const decoder = this.decoder;
    if (decoder === null) throw new Error("the H.264 decoder closed");
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
    this.onOutput = null;
    const picture: VideoFrame | null = last;
    if (picture === null) throw new Error(`the H.264 decoder gave no picture for the frame at ${frame.atUs} µs`);
    return picture;
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
        this.decodeProblem = `video decoder: ${e.message}`;
        this.onChange();
      },
    });
    this.decoder.configure(config);
    this.generation = keyframe.generation;
  }

  close(): void {
    this.ready?.image.close();
    this.ready = null;
    this.resetDecoder();
  }
}
