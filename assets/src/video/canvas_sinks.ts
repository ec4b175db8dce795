/**
 * The decode paths that paint a canvas: H.264 with WebCodecs' VideoDecoder (secure contexts:
 * https or localhost), and JPEG images (MJPEG cameras) with createImageBitmap. Both keep only
 * the newest decoded picture and paint it on the next animation frame: a page never shows an
 * old picture while a newer one waits.
 */

import type { DecoderConfig } from "./core";
import { codecString, parameterSets, splitNals } from "./h264";
import type { DecodePath, Sink, SinkEvents } from "./sink";
import { STAMP_HEIGHT, STAMP_WIDTH, readStamp } from "./stamp";
import type { EncodedFrame, FrameHeader } from "./wire";

/** Reads the render stamp from the top-left corner of a picture (a small canvas of its own). */
export class StampReader {
  private readonly ctx: CanvasRenderingContext2D | null;

  constructor() {
    const canvas = document.createElement("canvas");
    canvas.width = STAMP_WIDTH;
    canvas.height = STAMP_HEIGHT;
    this.ctx = canvas.getContext("2d", { willReadFrequently: true });
  }

  read(source: CanvasImageSource, width: number, height: number): number | null {
    const ctx = this.ctx;
    if (ctx === null || width < STAMP_WIDTH || height < STAMP_HEIGHT) return null;
    ctx.drawImage(source, 0, 0, STAMP_WIDTH, STAMP_HEIGHT, 0, 0, STAMP_WIDTH, STAMP_HEIGHT);
    return readStamp(ctx.getImageData(0, 0, STAMP_WIDTH, STAMP_HEIGHT));
  }
}

interface Picture {
  readonly image: VideoFrame | ImageBitmap;
  readonly width: number;
  readonly height: number;
  readonly frame: FrameHeader;
}

/** The canvas, the newest picture waiting for the next animation frame, and the painting. */
class CanvasPainter {
  readonly canvas: HTMLCanvasElement;
  private readonly ctx: CanvasRenderingContext2D | null;
  private pending: Picture | null = null;
  private raf: number | null = null;
  private readonly stamps = new StampReader();
  readStamps = false;

  constructor(private readonly events: SinkEvents) {
    this.canvas = document.createElement("canvas");
    this.canvas.className = "video-picture";
    this.ctx = this.canvas.getContext("2d", { alpha: false });
  }

  /** A new picture: it replaces any that was not painted yet. */
  show(picture: Picture): void {
    if (this.pending !== null) {
      this.pending.image.close();
      this.events.superseded(1);
    }
    this.pending = picture;
    if (this.raf === null) this.raf = requestAnimationFrame(() => this.paint());
  }

  private paint(): void {
    this.raf = null;
    const p = this.pending;
    this.pending = null;
    if (p === null || this.ctx === null) return;
    if (this.canvas.width !== p.width || this.canvas.height !== p.height) {
      this.canvas.width = p.width;
      this.canvas.height = p.height;
    }
    this.ctx.drawImage(p.image, 0, 0, p.width, p.height);
    const stamp = this.readStamps ? this.stamps.read(p.image, p.width, p.height) : null;
    p.image.close();
    this.events.displayed(p.frame, performance.now(), stamp);
  }

  /** Drops the waiting picture (the canvas keeps the last one painted). */
  clear(): void {
    if (this.raf !== null) cancelAnimationFrame(this.raf);
    this.raf = null;
    this.pending?.image.close();
    this.pending = null;
  }
}

/** Whether this page can decode H.264 with WebCodecs (a secure context that has VideoDecoder). */
export function hasWebCodecs(): boolean {
  return typeof window !== "undefined" && window.isSecureContext && typeof VideoDecoder === "function";
}

/** What both canvas paths share: the painter, the element, the stamps; no buffer to lag in. */
abstract class CanvasSink {
  protected readonly painter: CanvasPainter;

  constructor(protected readonly events: SinkEvents) {
    this.painter = new CanvasPainter(events);
  }

  get element(): HTMLElement {
    return this.painter.canvas;
  }

  get readStamps(): boolean {
    return this.painter.readStamps;
  }

  set readStamps(on: boolean) {
    this.painter.readStamps = on;
  }

  lagMs(): null {
    return null;
  }
}

export class WebCodecsSink extends CanvasSink implements Sink {
  readonly path: DecodePath = "webcodecs";
  private decoder: VideoDecoder | null = null;
  /** the frames in the decoder, by timestamp (µs): their headers come back with the pictures */
  private readonly inFlight = new Map<number, FrameHeader>();
  private lastTimestamp = 0;

  configure(config: DecoderConfig, keyframe: EncodedFrame): void {
    this.reset();
    const codec = config.avc ?? codecString(parameterSets(splitNals(keyframe.payload)).sps ?? new Uint8Array()) ?? null;
    if (codec === null) {
      this.events.error("the keyframe has no SPS to read the codec from");
      return;
    }
    const decoder = new VideoDecoder({
      output: (picture) => this.output(decoder, picture),
      error: (err) => this.failed(decoder, err.message),
    });
    try {
      // no description: the access units are Annex B, with SPS and PPS in each keyframe
      decoder.configure({ codec, optimizeForLatency: true, ...(config.width > 0 ? { codedWidth: config.width, codedHeight: config.height } : {}) });
    } catch (err) {
      this.events.error(`cannot configure ${codec}: ${err instanceof Error ? err.message : String(err)}`);
      return;
    }
    this.decoder = decoder;
  }

  decode(frame: EncodedFrame): void {
    const decoder = this.decoder;
    if (decoder === null || decoder.state !== "configured") return;
    // timestamps must grow; the server's arrival time does, one µs more at least
    const timestamp = Math.max(frame.serverUs, this.lastTimestamp + 1);
    this.lastTimestamp = timestamp;
    this.inFlight.set(timestamp, frame);
    try {
      decoder.decode(new EncodedVideoChunk({ type: frame.keyframe ? "key" : "delta", timestamp, data: frame.payload }));
    } catch (err) {
      this.failed(decoder, err instanceof Error ? err.message : String(err));
    }
  }

  private output(decoder: VideoDecoder, picture: VideoFrame): void {
    const frame = this.inFlight.get(picture.timestamp);
    if (decoder !== this.decoder || frame === undefined) {
      picture.close();
      return;
    }
    // pictures come out in order: whatever was given before this one is done
    for (const t of this.inFlight.keys()) {
      if (t > picture.timestamp) break;
      this.inFlight.delete(t);
    }
    this.events.decoded();
    this.painter.show({ image: picture, width: picture.displayWidth, height: picture.displayHeight, frame });
  }

  private failed(decoder: VideoDecoder, reason: string): void {
    if (decoder !== this.decoder) return;
    this.drop();
    this.events.error(reason);
  }

  backlog(): number {
    return this.decoder?.decodeQueueSize ?? 0;
  }

  private drop(): void {
    const decoder = this.decoder;
    this.decoder = null;
    this.inFlight.clear();
    if (decoder !== null && decoder.state !== "closed") decoder.close();
  }

  reset(): void {
    this.drop();
    this.painter.clear();
  }

  close(): void {
    this.reset();
  }
}

/** MJPEG: each frame is a JPEG image, decoded off the main thread by createImageBitmap. */
export class JpegSink extends CanvasSink implements Sink {
  readonly path: DecodePath = "jpeg";
  private decoding = 0;
  /** bumped by reset: images decoded for an older stream are thrown away */
  private epoch = 0;

  configure(): void {
    this.reset();
  }

  decode(frame: EncodedFrame): void {
    const epoch = this.epoch;
    this.decoding += 1;
    createImageBitmap(new Blob([frame.payload], { type: "image/jpeg" })).then(
      (image) => {
        this.decoding -= 1;
        if (epoch !== this.epoch) {
          image.close();
          return;
        }
        this.events.decoded();
        this.painter.show({ image, width: image.width, height: image.height, frame });
      },
      (err: unknown) => {
        this.decoding -= 1;
        if (epoch === this.epoch) this.events.error(`JPEG image not decoded: ${err instanceof Error ? err.message : String(err)}`);
      },
    );
  }

  backlog(): number {
    return this.decoding;
  }

  reset(): void {
    this.epoch += 1;
    this.painter.clear();
  }

  close(): void {
    this.reset();
  }
}
