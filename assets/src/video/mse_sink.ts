/**
 * H.264 through Media Source Extensions (where WebCodecs is missing: plain http on a tether
 * LAN): each access unit becomes one fragmented-MP4 segment (fmp4.ts) appended to a
 * SourceBuffer of a muted <video>. The live edge is kept by `liveEdge` (live_edge.ts): the
 * video plays a little faster when it lags, jumps to the newest frame when it lags far, and
 * the buffer behind the playhead is trimmed — it never grows.
 */

import type { DecoderConfig } from "./core";
import { TIMESCALE, initSegment, mediaSegment } from "./fmp4";
import { avcDecoderConfig, codecString, lengthPrefixed, parameterSets, parseSps, splitNals } from "./h264";
import { StampReader } from "./canvas_sinks";
import { liveEdge } from "./live_edge";
import type { DecodePath, Sink, SinkEvents } from "./sink";
import type { EncodedFrame, FrameHeader } from "./wire";

/** Whether this page has Media Source Extensions for H.264. */
export function hasMse(): boolean {
  return typeof MediaSource === "function" && MediaSource.isTypeSupported('video/mp4; codecs="avc1.42E01E"');
}

interface Session {
  readonly source: MediaSource;
  readonly url: string;
  buffer: SourceBuffer | null;
  readonly queue: Uint8Array<ArrayBuffer>[];
  /** the frame of each segment appended, by its decode time (ticks) */
  readonly frames: Map<number, FrameHeader>;
  nextDecodeTime: number;
  sequence: number;
  readonly duration: number;
}

export class MseSink implements Sink {
  readonly path: DecodePath = "mse";
  readonly video: HTMLVideoElement;
  private session: Session | null = null;
  private readonly stamps = new StampReader();
  private presented = 0;
  readStamps = false;

  constructor(private readonly events: SinkEvents) {
    const video = document.createElement("video");
    video.className = "video-picture";
    video.muted = true;
    video.autoplay = true;
    video.playsInline = true;
    video.disablePictureInPicture = true;
    video.addEventListener("error", () => {
      if (this.session !== null) this.failed(`the video element failed: ${video.error?.message || `code ${video.error?.code ?? "?"}`}`);
    });
    this.video = video;
    this.watchFrames();
  }

  get element(): HTMLElement {
    return this.video;
  }

  configure(config: DecoderConfig, keyframe: EncodedFrame): void {
    this.reset();
    const { sps, pps } = parameterSets(splitNals(keyframe.payload));
    if (sps === null || pps.length === 0) {
      this.events.error("the keyframe carries no SPS/PPS");
      return;
    }
    const parsed = parseSps(sps);
    const codec = codecString(sps) ?? config.avc;
    const width = parsed?.width ?? config.width;
    const height = parsed?.height ?? config.height;
    if (codec === null || width <= 0 || height <= 0) {
      this.events.error("cannot read the picture size from the SPS");
      return;
    }
    const mime = `video/mp4; codecs="${codec}"`;
    if (!MediaSource.isTypeSupported(mime)) {
      this.events.error(`this browser cannot play ${mime}`);
      return;
    }
    const source = new MediaSource();
    const fps = config.fps > 0 ? config.fps : 30;
    const session: Session = {
      source,
      url: URL.createObjectURL(source),
      buffer: null,
      queue: [initSegment({ width, height, avcC: avcDecoderConfig(sps, pps, parsed) })],
      frames: new Map(),
      nextDecodeTime: 0,
      sequence: 1,
      duration: Math.round(TIMESCALE / fps),
    };
    this.session = session;
    source.addEventListener("sourceopen", () => {
      if (this.session !== session) return;
      try {
        const buffer = source.addSourceBuffer(mime);
        buffer.mode = "segments";
        buffer.addEventListener("updateend", () => this.pump(session));
        buffer.addEventListener("error", () => this.failed("the SourceBuffer failed"));
        session.buffer = buffer;
        source.duration = Number.POSITIVE_INFINITY;
        this.pump(session);
      } catch (err) {
        this.failed(`cannot play ${mime}: ${err instanceof Error ? err.message : String(err)}`);
      }
    });
    this.video.src = session.url;
  }

  decode(frame: EncodedFrame): void {
    const session = this.session;
    if (session === null) return;
    const decodeTime = session.nextDecodeTime;
    session.nextDecodeTime += session.duration;
    session.frames.set(decodeTime, frame);
    session.queue.push(mediaSegment({ sequence: session.sequence++, decodeTime, duration: session.duration, keyframe: frame.keyframe, data: lengthPrefixed(splitNals(frame.payload)) }));
    this.pump(session);
  }

  /** Appends the next segment when the buffer is free; keeps the live edge. */
  private pump(session: Session): void {
    const buffer = session.buffer;
    if (this.session !== session || buffer === null || buffer.updating) return;
    const video = this.video;
    const ranges = buffer.buffered;
    const range = ranges.length > 0 ? { start: ranges.start(0), end: ranges.end(ranges.length - 1) } : null;
    const edge = liveEdge(range, video.currentTime, session.duration / TIMESCALE);
    if (edge.seekTo !== null) {
      video.currentTime = edge.seekTo;
      if (edge.skipped > 0) this.events.superseded(edge.skipped);
    }
    if (video.playbackRate !== edge.rate) video.playbackRate = edge.rate;
    try {
      if (edge.trimTo !== null && range !== null) {
        buffer.remove(range.start, edge.trimTo);
        return; // updateend pumps again
      }
      const next = session.queue.shift();
      if (next === undefined) return;
      buffer.appendBuffer(next);
    } catch (err) {
      this.failed(`append failed: ${err instanceof Error ? err.message : String(err)}`);
      return;
    }
    if (video.paused) video.play().catch(() => undefined);
  }

  /** Every picture the video presents: its frame, its display time, its stamp. */
  private watchFrames(): void {
    const video = this.video;
    const onFrame = (_now: number, meta: VideoFrameCallbackMetadata): void => {
      video.requestVideoFrameCallback(onFrame);
      const session = this.session;
      if (session === null) return;
      const shown = meta.presentedFrames - this.presented;
      this.presented = meta.presentedFrames;
      if (shown > 1) this.events.superseded(shown - 1);
      const ticks = Math.round(meta.mediaTime * TIMESCALE);
      const frame = session.frames.get(ticks);
      if (frame === undefined) return;
      // frames at or before this one are done with
      for (const t of session.frames.keys()) {
        if (t > ticks) break;
        session.frames.delete(t);
      }
      this.events.decoded();
      const stamp = this.readStamps ? this.stamps.read(video, meta.width, meta.height) : null;
      this.events.displayed(frame, meta.expectedDisplayTime, stamp);
    };
    video.requestVideoFrameCallback(onFrame);
  }

  backlog(): number {
    return this.session?.queue.length ?? 0;
  }

  lagMs(): number | null {
    const ranges = this.session?.buffer?.buffered;
    if (ranges === undefined || ranges.length === 0) return null;
    return (ranges.end(ranges.length - 1) - this.video.currentTime) * 1000;
  }

  private failed(reason: string): void {
    this.reset();
    this.events.error(reason);
  }

  reset(): void {
    const session = this.session;
    this.session = null;
    if (session === null) return;
    this.video.removeAttribute("src");
    this.video.load();
    URL.revokeObjectURL(session.url);
  }

  close(): void {
    this.reset();
  }
}
