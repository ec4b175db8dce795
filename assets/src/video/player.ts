/**
 * The vehicle's video on a page: the video socket (`/video/<id>/websocket`, docs/API.md
 * "Video"), the player core's decisions (core.ts) carried out on a decode path (WebCodecs,
 * MSE or JPEG), the stream's health (health.ts) and the picture's latency against the
 * server's clock. Reconnects on its own; a new stream, a decoder error or a camera restart
 * starts a new decoder, never a page reload.
 *
 * For the browser tests and the latency bench the page exposes the player's counters as
 * `window.neptunusVideo` (frames received, decoded, shown, dropped, latencies…).
 */

import { browserStorage } from "../lib/prefs";
import { Store } from "../lib/store";
import { hasWebCodecs, JpegSink, WebCodecsSink } from "./canvas_sinks";
import { INITIAL_CORE, step } from "./core";
import type { CoreAction, CoreInput, CoreState, DecoderConfig, DropReason } from "./core";
import { StreamHealth } from "./health";
import { Lateness } from "./lateness";
import type { HealthSummary } from "./health";
import { hasMse, MseSink } from "./mse_sink";
import { PATH_LABELS, forcedPath, savePathChoice } from "./path";
import type { PathChoice } from "./path";
import { choosePath } from "./sink";
import type { DecodePath, Sink, SinkEvents } from "./sink";
import { stampAgeMs } from "./stamp";
import { parseEvent, parseFrame, videoSocketUrl } from "./wire";
import type { CameraEvent, EncodedFrame, FrameHeader, StreamEvent } from "./wire";

/** reconnection delays (ms), the last repeating */
const BACKOFF_MS = [500, 1000, 2000, 5000];
/** how often the health line is refreshed (ms) */
const VIEW_MS = 250;
/** how often the server's clock is read while the video plays (ms) */
const CLOCK_MS = 2000;
/** decoder errors in a row without a picture after which a path is given up on this page */
const MAX_FAILURES = 3;

export type SocketState = "off" | "connecting" | "open" | "closed";

/** What the view shows (refreshed VIEW_MS, and at once on a change of stream or state). */
export interface VideoView {
  readonly socket: SocketState;
  /** consecutive failed attempts to open the socket */
  readonly failures: number;
  readonly path: DecodePath | null;
  readonly choice: PathChoice;
  readonly stream: StreamEvent | null;
  readonly camera: CameraEvent | null;
  readonly health: HealthSummary | null;
  /** a picture has been shown since the socket opened */
  readonly showing: boolean;
  /** why the chosen path is not the forced one, or why nothing can play */
  readonly note: string | null;
}

/** The counters the browser tests and the bench read (window.neptunusVideo). */
export interface VideoCounters {
  path: DecodePath | null;
  opens: number;
  received: number;
  keyframesReceived: number;
  /** the first frame received on each socket: a late joiner's must be a keyframe */
  firstReceived: { sequence: number; keyframe: boolean; generation: number } | null;
  /** the sequence number of the first frame decoded on each socket */
  firstDecoded: number | null;
  decoded: number;
  displayed: number;
  dropped: Record<DropReason, number>;
  /** frames the server said it skipped for this page (`skipped` events) */
  skipped: number;
  superseded: number;
  errors: number;
  lastError: string | null;
  configures: number;
  generation: number | null;
  stamps: number;
  stampMisses: number;
  /** MSE: how far the picture shown is behind the newest frame appended (ms) */
  bufferLagMs: number | null;
  /** the server's clock minus this page's (ms) the latencies were computed with */
  offsetMs: number | null;
  /** the latest latencies (ms) */
  serverToDisplay: number | null;
  renderToDisplay: number | null;
  /** every render→display sample since `samples` was emptied (the bench reads and empties it) */
  samples: number[];
}

declare global {
  interface Window {
    neptunusVideo?: VideoCounters;
  }
}

export interface PlayerOptions {
  /** the login token for the socket's address (null in local mode) */
  readonly token: () => string | null;
  /** the server's clock minus this one (ms), null while unknown (lib/clock.ts) */
  readonly serverOffsetMs: () => number | null;
  /**
   * Asks the server's clock once more (lib/clock.ts TelemetryClock.read): the latency is only
   * as good as the offset, whose best reading is the one with the quickest round trip.
   */
  readonly readClock?: () => void;
  readonly choice: PathChoice;
  /** the page's address (for the socket's host and scheme) */
  readonly location?: { readonly protocol: string; readonly host: string };
}

function newCounters(): VideoCounters {
  return {
    path: null,
    opens: 0,
    received: 0,
    keyframesReceived: 0,
    firstReceived: null,
    firstDecoded: null,
    decoded: 0,
    displayed: 0,
    dropped: { no_stream: 0, stale: 0, lost: 0, await_key: 0, behind: 0, late: 0, kind: 0 },
    skipped: 0,
    superseded: 0,
    errors: 0,
    lastError: null,
    configures: 0,
    generation: null,
    stamps: 0,
    stampMisses: 0,
    bufferLagMs: null,
    offsetMs: null,
    serverToDisplay: null,
    renderToDisplay: null,
    samples: [],
  };
}

/** Date.now() of a performance.now() reading */
function wallMs(perfMs: number): number {
  return Date.now() - (performance.now() - perfMs);
}

export class VideoPlayer {
  readonly store: Store<VideoView>;
  readonly counters: VideoCounters = newCounters();
  /** the video socket's path (`/video/ID/websocket`) */
  private path: string | null = null;
  private socket: WebSocket | null = null;
  private retry: number | null = null;
  private core: CoreState = INITIAL_CORE;
  private sink: Sink | null = null;
  private container: HTMLElement | null = null;
  private readonly health = new StreamHealth();
  private readonly lateness = new Lateness();
  private ticker: number | null = null;
  private clockTicker: number | null = null;
  private choice: PathChoice;
  /** an unopened socket's attempts since the last open */
  private failures = 0;
  /** decoder errors since the last picture shown */
  private decoderFailures = 0;
  /** paths that failed MAX_FAILURES times in a row without a picture: not chosen again */
  private readonly broken = new Set<DecodePath>();

  constructor(private readonly options: PlayerOptions) {
    this.choice = options.choice;
    this.store = new Store<VideoView>({ socket: "off", failures: 0, path: null, choice: this.choice, stream: null, camera: null, health: null, showing: false, note: null });
    if (typeof window !== "undefined") window.neptunusVideo = this.counters;
  }

  /** Watches the camera of the video socket at `path` (null: none); the same one again changes nothing. */
  watch(path: string | null): void {
    if (path === this.path) return;
    this.stop();
    this.path = path;
    if (path === null) return;
    this.ticker = window.setInterval(() => this.refresh(), VIEW_MS);
    const readClock = this.options.readClock;
    if (readClock !== undefined) this.clockTicker = window.setInterval(readClock, CLOCK_MS);
    this.connect();
  }

  stop(): void {
    this.path = null;
    if (this.retry !== null) window.clearTimeout(this.retry);
    this.retry = null;
    if (this.ticker !== null) window.clearInterval(this.ticker);
    this.ticker = null;
    if (this.clockTicker !== null) window.clearInterval(this.clockTicker);
    this.clockTicker = null;
    const socket = this.socket;
    this.socket = null;
    socket?.close(1000, "page left the vehicle");
    this.apply({ type: "closed" }, null);
    this.health.reset();
    this.store.update({ socket: "off" });
  }

  /** Shows the pictures in `container` (the view's element); null detaches. */
  attach(container: HTMLElement | null): void {
    this.container = container;
    if (container !== null && this.sink !== null) container.replaceChildren(this.sink.element);
  }

  /** Forces a decode path (or auto), kept in this browser: the decoder starts again at the next keyframe. */
  setChoice(choice: PathChoice): void {
    if (choice === this.choice) return;
    this.choice = choice;
    this.broken.clear();
    savePathChoice(browserStorage(), choice);
    this.store.update({ choice });
    this.replaceSink(null);
    this.apply({ type: "decoder_error", reason: `decode path set to ${choice}` }, null);
  }

  private connect(): void {
    const path = this.path;
    if (path === null) return;
    const url = videoSocketUrl(this.options.location ?? window.location, path, this.options.token());
    let socket: WebSocket;
    try {
      socket = new WebSocket(url);
    } catch (err) {
      this.store.update({ note: `Cannot open the video socket: ${err instanceof Error ? err.message : String(err)}` });
      return;
    }
    socket.binaryType = "arraybuffer";
    this.socket = socket;
    this.store.update({ socket: "connecting" });
    let opened = false;
    socket.onopen = () => {
      if (this.socket !== socket) return;
      opened = true;
      this.failures = 0;
      this.counters.opens += 1;
      this.counters.firstReceived = null;
      this.counters.firstDecoded = null;
      this.lateness.reset();
      this.apply({ type: "open" }, null);
      this.store.update({ socket: "open", failures: 0, showing: false });
    };
    socket.onmessage = (e: MessageEvent<unknown>) => {
      if (this.socket === socket) this.message(e.data);
    };
    socket.onclose = () => {
      if (this.socket !== socket) return;
      this.socket = null;
      if (!opened) this.failures += 1;
      this.apply({ type: "closed" }, null);
      this.store.update({ socket: "closed", failures: this.failures, showing: false });
      const delay = BACKOFF_MS[Math.min(this.failures, BACKOFF_MS.length - 1)] ?? 5000;
      this.retry = window.setTimeout(() => {
        this.retry = null;
        this.connect();
      }, delay);
    };
  }

  private message(data: unknown): void {
    if (typeof data === "string") {
      const parsed = parseEvent(data);
      if (!parsed.ok) {
        console.warn(`neptunus video: ${parsed.reason}`);
        return;
      }
      const event = parsed.value;
      this.apply({ type: "event", event }, null);
      if (event.event === "stream") {
        this.health.setFps(event.fps);
        this.store.update({ stream: event });
      } else if (event.event === "camera") {
        this.store.update({ camera: event });
      }
      return;
    }
    if (!(data instanceof ArrayBuffer)) return;
    const parsed = parseFrame(data);
    if (!parsed.ok) {
      console.warn(`neptunus video: ${parsed.reason}`);
      return;
    }
    const frame = parsed.value;
    const c = this.counters;
    c.received += 1;
    if (frame.keyframe) c.keyframesReceived += 1;
    if (c.firstReceived === null) c.firstReceived = { sequence: frame.sequence, keyframe: frame.keyframe, generation: frame.generation };
    const now = performance.now();
    this.health.received(now, data.byteLength);
    const lateMs = this.lateness.observe(performance.timeOrigin + now, frame.serverUs / 1000);
    this.apply({ type: "frame", frame, backlog: this.sink?.backlog() ?? 0, lateMs }, frame);
  }

  /** One input through the core; its actions carried out (`frame`: the frame of a frame input). */
  private apply(input: CoreInput, frame: EncodedFrame | null): void {
    const { state, actions } = step(this.core, input);
    this.core = state;
    for (const action of actions) this.perform(action, frame);
  }

  private perform(action: CoreAction, frame: EncodedFrame | null): void {
    const c = this.counters;
    switch (action.type) {
      case "reset":
        this.sink?.reset();
        return;
      case "configure":
        if (frame !== null) this.configure(action.config, frame);
        return;
      case "decode":
        if (frame === null) return;
        if (c.firstDecoded === null) c.firstDecoded = frame.sequence;
        this.sink?.decode(frame);
        return;
      case "drop":
        c.dropped[action.why] += action.frames;
        this.health.drop(action.frames);
        return;
      case "skipped":
        c.skipped += action.frames;
        return;
      case "request_keyframe":
        if (this.socket?.readyState === WebSocket.OPEN) this.socket.send(JSON.stringify({ event: "keyframe" }));
        return;
      case "pause":
        this.health.pause();
        return;
    }
  }

  private configure(config: DecoderConfig, keyframe: EncodedFrame): void {
    const env = { webcodecs: hasWebCodecs() && !this.broken.has("webcodecs"), mse: hasMse() && !this.broken.has("mse") };
    const forced = forcedPath(this.choice);
    const path = choosePath(config.codec, forced, env);
    const note =
      path === null
        ? "This browser can decode H.264 neither with WebCodecs nor with Media Source Extensions."
        : this.broken.size > 0 && config.codec === "h264"
          ? `${[...this.broken].map((p) => PATH_LABELS[p]).join(" and ")} failed on this page: playing with ${PATH_LABELS[path]}.`
          : forced !== null && config.codec === "h264" && path !== forced
            ? forced === "webcodecs"
              ? "WebCodecs needs a secure page (https or localhost): playing with MSE."
              : "This browser has no Media Source Extensions for H.264: playing with WebCodecs."
            : null;
    this.store.update({ note });
    if (path === null) return;
    if (this.sink?.path !== path) this.replaceSink(path);
    const sink = this.sink;
    if (sink === null) return;
    sink.readStamps = this.core.stream?.source === "sim";
    this.counters.configures += 1;
    this.counters.generation = config.generation;
    sink.configure(config, keyframe);
  }

  private replaceSink(path: DecodePath | null): void {
    this.sink?.close();
    this.sink = null;
    if (path !== null) {
      const events = this.sinkEvents();
      this.sink = path === "webcodecs" ? new WebCodecsSink(events) : path === "mse" ? new MseSink(events) : new JpegSink(events);
      if (this.container !== null) this.container.replaceChildren(this.sink.element);
    }
    this.counters.path = path;
    this.store.update({ path });
  }

  private sinkEvents(): SinkEvents {
    return {
      decoded: () => {
        this.counters.decoded += 1;
      },
      displayed: (frame, atMs, stamp) => this.displayed(frame, atMs, stamp),
      superseded: (frames) => {
        this.counters.superseded += frames;
        this.health.drop(frames);
      },
      error: (reason) => {
        const c = this.counters;
        c.errors += 1;
        c.lastError = reason;
        console.warn(`neptunus video: ${reason}`);
        this.decoderFailures += 1;
        const path = this.sink?.path;
        if (this.decoderFailures >= MAX_FAILURES && path !== undefined && path !== "jpeg") {
          // this browser cannot play the stream this way: the other path from the next keyframe
          this.broken.add(path);
          this.decoderFailures = 0;
          this.replaceSink(null);
        }
        this.apply({ type: "decoder_error", reason }, null);
      },
    };
  }

  private displayed(frame: FrameHeader, atMs: number, stamp: number | null): void {
    const c = this.counters;
    const offset = this.options.serverOffsetMs();
    const serverNow = offset === null ? null : wallMs(atMs) + offset;
    const serverToDisplay = serverNow === null ? null : serverNow - frame.serverUs / 1000;
    const renderToDisplay = stamp === null || serverNow === null ? null : stampAgeMs(stamp, serverNow);
    c.displayed += 1;
    this.decoderFailures = 0;
    if (stamp !== null) c.stamps += 1;
    else if (this.sink?.readStamps === true) c.stampMisses += 1;
    c.serverToDisplay = serverToDisplay;
    c.offsetMs = offset;
    c.bufferLagMs = this.sink?.lagMs() ?? null;
    c.renderToDisplay = renderToDisplay;
    if (renderToDisplay !== null && c.samples.length < 100_000) c.samples.push(renderToDisplay);
    this.health.displayed(atMs, serverToDisplay, renderToDisplay);
    if (!this.store.get().showing) this.store.update({ showing: true });
  }

  private refresh(): void {
    this.store.update({ health: this.health.summary(performance.now()) });
  }
}
