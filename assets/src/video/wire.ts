/**
 * The video socket's wire format (docs/API.md, "Video"), pure: the 28-byte header of every
 * binary frame and the JSON text events (`stream`, `camera`, `skipped`).
 *
 * ```
 * 0  version = 1          1  kind (1 H.264 access unit, 2 JPEG)   2  flags (bit0 keyframe,
 * bit1 first frame of a generation)   3  reserved   4  generation u32   8  sequence u32
 * 12 server arrival time, wall-clock µs u64   20 capture/render time µs u64 (0 unknown)
 * 28 payload
 * ```
 */

export const HEADER_BYTES = 28;
export const WIRE_VERSION = 1;

export type FrameKind = "h264" | "jpeg";

/** Bytes on an ordinary ArrayBuffer (what Blob, MSE and WebCodecs take). */
export type Bytes = Uint8Array<ArrayBuffer>;

export interface FrameHeader {
  readonly kind: FrameKind;
  /** an IDR access unit (H.264 keyframes carry SPS and PPS in front); every JPEG is one */
  readonly keyframe: boolean;
  /** the first frame of a new generation */
  readonly first: boolean;
  readonly generation: number;
  /** +1 per frame the camera produced: a gap is frames this viewer did not get */
  readonly sequence: number;
  /** when the server cut the frame from the camera's output (wall clock, µs since the epoch) */
  readonly serverUs: number;
  /** when the source captured or rendered it (wall clock µs); null when it does not say */
  readonly captureUs: number | null;
}

export interface EncodedFrame extends FrameHeader {
  /** the access unit (Annex B) or the JPEG image: a view into the message, not a copy */
  readonly payload: Bytes;
}

export type Parsed<T> = { readonly ok: true; readonly value: T } | { readonly ok: false; readonly reason: string };

function u64(view: DataView, offset: number): number {
  // µs since the epoch stay below 2^53 until the year 2255
  return view.getUint32(offset) * 2 ** 32 + view.getUint32(offset + 4);
}

/** One binary message: its header and payload, or why it is not a frame. */
export function parseFrame(message: ArrayBuffer | Bytes): Parsed<EncodedFrame> {
  const bytes = message instanceof Uint8Array ? message : new Uint8Array(message);
  if (bytes.byteLength < HEADER_BYTES) return { ok: false, reason: `frame of ${bytes.byteLength} bytes is shorter than its ${HEADER_BYTES}-byte header` };
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const version = view.getUint8(0);
  if (version !== WIRE_VERSION) return { ok: false, reason: `unknown frame version ${version}` };
  const kindByte = view.getUint8(1);
  const kind: FrameKind | null = kindByte === 1 ? "h264" : kindByte === 2 ? "jpeg" : null;
  if (kind === null) return { ok: false, reason: `unknown frame kind ${kindByte}` };
  const flags = view.getUint8(2);
  const captureUs = u64(view, 20);
  return {
    ok: true,
    value: {
      kind,
      keyframe: kind === "jpeg" || (flags & 1) !== 0,
      first: (flags & 2) !== 0,
      generation: view.getUint32(4),
      sequence: view.getUint32(8),
      serverUs: u64(view, 12),
      captureUs: captureUs === 0 ? null : captureUs,
      payload: bytes.subarray(HEADER_BYTES),
    },
  };
}

/** The header of a frame, for tests and stand-in servers (the inverse of parseFrame). */
export function encodeFrame(frame: Omit<EncodedFrame, "captureUs" | "payload"> & { readonly captureUs?: number | null; readonly payload: Uint8Array }): Bytes {
  const out = new Uint8Array(HEADER_BYTES + frame.payload.byteLength);
  const view = new DataView(out.buffer);
  const u64put = (offset: number, value: number): void => {
    view.setUint32(offset, Math.floor(value / 2 ** 32));
    view.setUint32(offset + 4, value % 2 ** 32);
  };
  view.setUint8(0, WIRE_VERSION);
  view.setUint8(1, frame.kind === "h264" ? 1 : 2);
  view.setUint8(2, (frame.keyframe ? 1 : 0) | (frame.first ? 2 : 0));
  view.setUint32(4, frame.generation);
  view.setUint32(8, frame.sequence);
  u64put(12, frame.serverUs);
  u64put(20, frame.captureUs ?? 0);
  out.set(frame.payload, HEADER_BYTES);
  return out;
}

export type Codec = "h264" | "mjpeg";
export type CameraState = "starting" | "running" | "restarting" | "failed" | "idle" | "none";

/** `stream`: what the camera sends now; a new `generation` means a new decoder. */
export interface StreamEvent {
  readonly event: "stream";
  readonly codec: Codec;
  readonly width: number;
  readonly height: number;
  /** the camera's configured rate, else its SPS's; 0 when it does not say (the server's null) */
  readonly fps: number;
  readonly generation: number;
  /** sim, v4l2, rtsp, testsrc, exec (only the sim camera stamps its picture) */
  readonly source: string;
  /** RFC 6381 codec string from the SPS ("avc1.42C01E"); null for MJPEG */
  readonly avc: string | null;
}

export interface CameraEvent {
  readonly event: "camera";
  readonly state: CameraState;
  readonly reason: string | null;
  readonly restarts: number;
}

/** The server dropped `frames` frames for this viewer (it skips to the next keyframe). */
export interface SkippedEvent {
  readonly event: "skipped";
  readonly frames: number;
  readonly reason: string;
}

export type VideoEvent = StreamEvent | CameraEvent | SkippedEvent;

const CAMERA_STATES: readonly CameraState[] = ["starting", "running", "restarting", "failed", "idle", "none"];
const AVC = /^avc[13]\.[0-9A-Fa-f]{6}$/;

function isRecord(v: unknown): v is Record<string, unknown> {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

function count(v: unknown): v is number {
  return typeof v === "number" && Number.isInteger(v) && v >= 0;
}

function decodeStream(v: Record<string, unknown>): Parsed<StreamEvent> {
  const { codec, width, height, fps, generation, source, avc } = v;
  if (codec !== "h264" && codec !== "mjpeg") return { ok: false, reason: `stream: unknown codec ${JSON.stringify(codec)}` };
  if (!count(width) || !count(height)) return { ok: false, reason: "stream: width and height must be whole numbers" };
  if (fps !== null && fps !== undefined && (typeof fps !== "number" || !Number.isFinite(fps) || fps < 0)) return { ok: false, reason: "stream: fps must be a number ≥ 0 or null" };
  if (!count(generation)) return { ok: false, reason: "stream: generation must be a whole number" };
  if (typeof source !== "string") return { ok: false, reason: "stream: source must be a string" };
  if (avc !== null && avc !== undefined && (typeof avc !== "string" || !AVC.test(avc))) return { ok: false, reason: `stream: avc ${JSON.stringify(avc)} is not a codec string` };
  return { ok: true, value: { event: "stream", codec, width, height, fps: typeof fps === "number" ? fps : 0, generation, source, avc: typeof avc === "string" ? avc : null } };
}

function decodeCamera(v: Record<string, unknown>): Parsed<CameraEvent> {
  const { state, reason, restarts } = v;
  const known = CAMERA_STATES.find((s) => s === state);
  if (known === undefined) return { ok: false, reason: `camera: unknown state ${JSON.stringify(state)}` };
  if (reason !== null && reason !== undefined && typeof reason !== "string") return { ok: false, reason: "camera: reason must be a string or null" };
  return { ok: true, value: { event: "camera", state: known, reason: typeof reason === "string" ? reason : null, restarts: count(restarts) ? restarts : 0 } };
}

/** One text message: an event this page knows, or why not (unknown events are reported, not fatal). */
export function parseEvent(text: string): Parsed<VideoEvent> {
  let value: unknown;
  try {
    value = JSON.parse(text);
  } catch {
    return { ok: false, reason: "text message is not JSON" };
  }
  if (!isRecord(value)) return { ok: false, reason: "text message is not a JSON object" };
  switch (value["event"]) {
    case "stream":
      return decodeStream(value);
    case "camera":
      return decodeCamera(value);
    case "skipped": {
      const { frames, reason } = value;
      if (!count(frames)) return { ok: false, reason: "skipped: frames must be a whole number" };
      return { ok: true, value: { event: "skipped", frames, reason: typeof reason === "string" ? reason : "" } };
    }
    default:
      return { ok: false, reason: `unknown event ${JSON.stringify(value["event"])}` };
  }
}

/**
 * The video socket's address on this page's server (wss on https), from its path
 * (`/video/ID/websocket`, maybe with a query): `vsn=1` and this page's current token, which
 * replaces any the path already carries (a login may have been renewed since).
 */
export function videoSocketUrl(location: { readonly protocol: string; readonly host: string }, path: string, token: string | null): string {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  const at = path.indexOf("?");
  const query = new URLSearchParams(at < 0 ? "" : path.slice(at + 1));
  query.set("vsn", "1");
  if (token !== null) query.set("token", token);
  return `${scheme}//${location.host}${at < 0 ? path : path.slice(0, at)}?${query.toString()}`;
}
