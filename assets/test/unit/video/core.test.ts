import { describe, expect, it } from "vitest";
import { FLUSH_BACKLOG, INITIAL_CORE, MAX_BACKLOG, MAX_JPEG_BACKLOG, step } from "../../../src/video/core";
import type { CoreAction, CoreInput, CoreState } from "../../../src/video/core";
import { LATE_MS, Lateness, RESET_MS, WINDOW_MS } from "../../../src/video/lateness";
import { liveEdge, JUMP_S, KEEP_S, TRIM_AFTER_S } from "../../../src/video/live_edge";
import { choosePath } from "../../../src/video/sink";
import type { FrameHeader, StreamEvent } from "../../../src/video/wire";

const STREAM: StreamEvent = { event: "stream", codec: "h264", width: 640, height: 360, fps: 30, generation: 1, source: "sim", avc: "avc1.42C01E" };
const CONFIG = { codec: "h264", generation: 1, avc: "avc1.42C01E", width: 640, height: 360, fps: 30 };

function frame(sequence: number, keyframe = false, generation = 1, kind: "h264" | "jpeg" = "h264"): FrameHeader {
  return { kind, keyframe, first: false, generation, sequence, serverUs: sequence * 33_333, captureUs: null };
}

function run(inputs: readonly CoreInput[], from: CoreState = INITIAL_CORE): { state: CoreState; actions: CoreAction[][] } {
  let state = from;
  const actions: CoreAction[][] = [];
  for (const input of inputs) {
    const r = step(state, input);
    state = r.state;
    actions.push([...r.actions]);
  }
  return { state, actions };
}

const streamed = run([{ type: "open" }, { type: "event", event: STREAM }]).state;
const playing = run([{ type: "frame", frame: frame(10, true), backlog: 0, lateMs: 0 }], streamed).state;

describe("starting a stream", () => {
  it("drops frames before the stream event and delta frames before the first keyframe", () => {
    expect(step(INITIAL_CORE, { type: "frame", frame: frame(1, true), backlog: 0, lateMs: 0 }).actions).toEqual([{ type: "drop", frames: 1, why: "no_stream" }]);
    const r = run([{ type: "frame", frame: frame(7), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(8), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(9, true), backlog: 0, lateMs: 0 }], streamed);
    expect(r.actions).toEqual([
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "configure", config: CONFIG }, { type: "decode" }],
    ]);
    expect(r.state).toMatchObject({ awaitingKey: false, lastSequence: 9, configured: CONFIG });
  });

  it("decodes the frames that follow the keyframe", () => {
    expect(step(playing, { type: "frame", frame: frame(11), backlog: 1, lateMs: 0 }).actions).toEqual([{ type: "decode" }]);
  });

  it("does nothing for the same stream said again", () => {
    expect(step(playing, { type: "event", event: STREAM })).toEqual({ state: playing, actions: [] });
  });
});

describe("a new stream, a decoder error, a closed socket: the decoder starts over at a keyframe", () => {
  it("resets on a new generation and waits for its keyframe; old frames are stale", () => {
    const next: StreamEvent = { ...STREAM, generation: 2, width: 1280, height: 720 };
    const r = run(
      [
        { type: "event", event: next },
        { type: "frame", frame: frame(11, false, 1), backlog: 0, lateMs: 0 },
        { type: "frame", frame: frame(1, false, 2), backlog: 0, lateMs: 0 },
        { type: "frame", frame: frame(2, true, 2), backlog: 0, lateMs: 0 },
      ],
      playing,
    );
    expect(r.actions).toEqual([
      [{ type: "reset", reason: "new stream (generation 2)" }, { type: "pause" }],
      [{ type: "drop", frames: 1, why: "stale" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "configure", config: { ...CONFIG, generation: 2, width: 1280, height: 720 } }, { type: "decode" }],
    ]);
  });

  it("resets on a new size in the same generation", () => {
    expect(step(playing, { type: "event", event: { ...STREAM, width: 320, height: 180 } }).actions[0]).toMatchObject({ type: "reset" });
  });

  it("takes a frame of a newer generation than it was told as that stream's start", () => {
    const r = step(playing, { type: "frame", frame: frame(1, true, 5), backlog: 0, lateMs: 0 });
    expect(r.actions).toEqual([
      { type: "reset", reason: "new generation 5" },
      { type: "pause" },
      { type: "configure", config: { ...CONFIG, generation: 5, avc: null } },
      { type: "decode" },
    ]);
  });

  it("after a decoder error, asks for a keyframe and waits for it", () => {
    const r = run([{ type: "decoder_error", reason: "bad slice" }, { type: "frame", frame: frame(11), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(12, true), backlog: 0, lateMs: 0 }], playing);
    expect(r.actions).toEqual([
      [{ type: "reset", reason: "decoder error: bad slice" }, { type: "pause" }, { type: "request_keyframe" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "configure", config: CONFIG }, { type: "decode" }],
    ]);
  });

  it("forgets the stream when the socket closes, starts clean when it opens", () => {
    const closed = step(playing, { type: "closed" });
    expect(closed.actions).toEqual([{ type: "reset", reason: "socket closed" }, { type: "pause" }]);
    expect(closed.state).toMatchObject({ stream: null, configured: null, awaitingKey: true });
    expect(step(closed.state, { type: "open" }).state).toEqual(INITIAL_CORE);
  });

  it("pauses the health figures while the camera is not running", () => {
    expect(step(playing, { type: "event", event: { event: "camera", state: "restarting", reason: "exit 1", restarts: 1 } }).actions).toEqual([{ type: "pause" }]);
    expect(step(playing, { type: "event", event: { event: "camera", state: "running", reason: null, restarts: 1 } }).actions).toEqual([]);
  });
});

describe("the live edge", () => {
  it("counts a gap in the sequence as lost and waits for the next keyframe", () => {
    const r = run([{ type: "frame", frame: frame(14), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(15), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(16, true), backlog: 0, lateMs: 0 }], playing);
    expect(r.actions).toEqual([
      [{ type: "drop", frames: 3, why: "lost" }, { type: "drop", frames: 1, why: "await_key" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "decode" }],
    ]);
  });

  it("notes the server's skip and waits for the keyframe it skips to", () => {
    const r = run([{ type: "event", event: { event: "skipped", frames: 20, reason: "slow_viewer" } }, { type: "frame", frame: frame(31, true), backlog: 0, lateMs: 0 }], playing);
    expect(r.actions).toEqual([[{ type: "skipped", frames: 20 }], [{ type: "drop", frames: 20, why: "lost" }, { type: "decode" }]]);
  });

  it("drops to the next keyframe when the decoder is behind; the keyframe joins the queue", () => {
    const r = run(
      [
        { type: "frame", frame: frame(11), backlog: MAX_BACKLOG, lateMs: 0 },
        { type: "frame", frame: frame(12), backlog: MAX_BACKLOG + 1, lateMs: 0 },
        { type: "frame", frame: frame(13), backlog: 0, lateMs: 0 },
        { type: "frame", frame: frame(14, true), backlog: MAX_BACKLOG + 2, lateMs: 0 },
        { type: "frame", frame: frame(15), backlog: 0, lateMs: 0 },
      ],
      playing,
    );
    expect(r.actions).toEqual([
      [{ type: "decode" }],
      [{ type: "drop", frames: 1, why: "behind" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "decode" }],
      [{ type: "decode" }],
    ]);
  });

  it("flushes a decoder far behind at a keyframe (never at every keyframe of a merely slow one)", () => {
    expect(step(playing, { type: "frame", frame: frame(11, true), backlog: FLUSH_BACKLOG, lateMs: 0 }).actions).toEqual([{ type: "decode" }]);
    expect(step(playing, { type: "frame", frame: frame(11, true), backlog: FLUSH_BACKLOG + 1, lateMs: 0 }).actions).toEqual([
      { type: "drop", frames: FLUSH_BACKLOG + 1, why: "behind" },
      { type: "reset", reason: "behind: flushed at a keyframe" },
      { type: "configure", config: CONFIG },
      { type: "decode" },
    ]);
  });

  it("drops frames that waited in the page, keyframes too, and goes on at a fresh keyframe", () => {
    const r = run(
      [
        { type: "frame", frame: frame(11), backlog: 0, lateMs: LATE_MS + 1 },
        { type: "frame", frame: frame(12, true), backlog: 0, lateMs: 5000 },
        { type: "frame", frame: frame(13), backlog: 0, lateMs: 0 },
        { type: "frame", frame: frame(14, true), backlog: 0, lateMs: LATE_MS },
      ],
      playing,
    );
    expect(r.actions).toEqual([
      [{ type: "drop", frames: 1, why: "late" }],
      [{ type: "drop", frames: 1, why: "late" }],
      [{ type: "drop", frames: 1, why: "await_key" }],
      [{ type: "decode" }],
    ]);
  });

  it("drops duplicate and reordered frames", () => {
    expect(step(playing, { type: "frame", frame: frame(10), backlog: 0, lateMs: 0 }).actions).toEqual([{ type: "drop", frames: 1, why: "stale" }]);
  });

  it("drops frames that are not of the stream's codec", () => {
    expect(step(playing, { type: "frame", frame: frame(11, true, 1, "jpeg"), backlog: 0, lateMs: 0 }).actions).toEqual([{ type: "drop", frames: 1, why: "kind" }]);
  });
});

describe("MJPEG", () => {
  const mjpeg = run([{ type: "event", event: { ...STREAM, codec: "mjpeg", avc: null } }], INITIAL_CORE).state;

  it("decodes every image; gaps cost nothing more than the images missed", () => {
    const r = run([{ type: "frame", frame: frame(1, true, 1, "jpeg"), backlog: 0, lateMs: 0 }, { type: "frame", frame: frame(4, true, 1, "jpeg"), backlog: 0, lateMs: 0 }], mjpeg);
    expect(r.actions).toEqual([
      [{ type: "configure", config: { ...CONFIG, codec: "mjpeg", avc: null } }, { type: "decode" }],
      [{ type: "drop", frames: 2, why: "lost" }, { type: "decode" }],
    ]);
  });

  it("drops an image while the page is still decoding earlier ones", () => {
    const started = step(mjpeg, { type: "frame", frame: frame(1, true, 1, "jpeg"), backlog: 0, lateMs: 0 }).state;
    expect(step(started, { type: "frame", frame: frame(2, true, 1, "jpeg"), backlog: MAX_JPEG_BACKLOG, lateMs: 0 }).actions).toEqual([{ type: "drop", frames: 1, why: "behind" }]);
  });
});

describe("how late a frame reaches the page", () => {
  // server and page clocks 5 s apart, a link of 40 ms: local − server = 5 040 ms when on time
  const OFFSET = 5040;

  it("is nothing on a steady link, however slow or however far the clocks are apart", () => {
    const l = new Lateness();
    for (let i = 0; i < 100; i++) expect(l.observe(1_000_000 + i * 33 + OFFSET, 1_000_000 + i * 33)).toBe(0);
    const slow = new Lateness();
    for (let i = 0; i < 100; i++) expect(slow.observe(i * 33 + 2500, i * 33)).toBe(0);
  });

  it("is the wait above the link's floor: a busy page finds old frames", () => {
    const l = new Lateness();
    l.observe(1000 + OFFSET, 1000);
    l.observe(1033 + OFFSET + 10, 1033); // a little jitter
    // the page was busy for 2 s: the frame stamped 1066 is handled at 3100
    expect(l.observe(3100 + OFFSET, 1066)).toBe(2034);
    // and it catches up: the next one is on time again
    expect(l.observe(3110 + OFFSET, 3110)).toBe(0);
  });

  it("forgets a floor older than its window", () => {
    const l = new Lateness();
    l.observe(0 + OFFSET, 0); // a quick one long ago
    for (let t = 1000; t <= WINDOW_MS + 2000; t += 1000) l.observe(t + OFFSET + 300, t);
    // the floor is now the link's 300 ms more
    expect(l.observe(WINDOW_MS + 3000 + OFFSET + 300, WINDOW_MS + 3000)).toBe(0);
  });

  it("takes a new floor when frames stay late for RESET_MS (a clock was set): never late for ever", () => {
    const l = new Lateness();
    for (let t = 0; t < 1000; t += 100) l.observe(t + OFFSET, t);
    // the server's clock steps back 10 s: every frame now looks 10 s late
    let last = -1;
    for (let t = 1000; t <= 1000 + RESET_MS + 200; t += 100) last = l.observe(t + OFFSET, t - 10_000);
    expect(last).toBe(0);
    expect(l.observe(1000 + RESET_MS + 300 + OFFSET, 1000 + RESET_MS + 300 - 10_000)).toBe(0);
    expect(LATE_MS).toBeLessThan(RESET_MS);
  });
});

describe("MSE's live edge", () => {
  const frameS = 1 / 30;

  it("plays at normal speed within two frames of the newest", () => {
    expect(liveEdge({ start: 0, end: 1 }, 1 - 1.5 * frameS, frameS)).toEqual({ seekTo: null, rate: 1, trimTo: null, skipped: 0 });
  });

  it("plays faster while it lags a few frames, at most 25 %", () => {
    expect(liveEdge({ start: 0, end: 1 }, 1 - 4 * frameS, frameS).rate).toBe(1.1);
    expect(liveEdge({ start: 0, end: 1 }, 1 - 0.29, frameS).rate).toBe(1.25);
  });

  it("jumps to the newest frame past JUMP_S, counting the frames jumped over", () => {
    const d = liveEdge({ start: 0, end: 2 }, 2 - JUMP_S - 0.1, frameS);
    expect(d.seekTo).toBeCloseTo(2 - frameS / 2);
    expect(d.skipped).toBe(11);
    expect(d.rate).toBe(1);
  });

  it("moves a playhead that is before the buffer into it", () => {
    expect(liveEdge({ start: 5, end: 5.05 }, 0, frameS)).toMatchObject({ seekTo: 5.05 - frameS / 2, skipped: 0 });
  });

  it("trims the buffer behind the playhead", () => {
    expect(liveEdge({ start: 0, end: TRIM_AFTER_S + 1 }, TRIM_AFTER_S + 1 - frameS, frameS).trimTo).toBeCloseTo(TRIM_AFTER_S + 1 - frameS - KEEP_S);
    expect(liveEdge({ start: 0, end: 3 }, 3, frameS).trimTo).toBeNull();
  });

  it("does nothing without a buffer", () => {
    expect(liveEdge(null, 0, frameS)).toEqual({ seekTo: null, rate: 1, trimTo: null, skipped: 0 });
  });
});

describe("the decode path", () => {
  const both = { webcodecs: true, mse: true };
  it("is WebCodecs where the page has it, else MSE; MJPEG is always JPEG", () => {
    expect(choosePath("h264", null, both)).toBe("webcodecs");
    expect(choosePath("h264", null, { webcodecs: false, mse: true })).toBe("mse");
    expect(choosePath("h264", null, { webcodecs: false, mse: false })).toBeNull();
    expect(choosePath("mjpeg", "mse", both)).toBe("jpeg");
  });

  it("is the forced one when this page can run it", () => {
    expect(choosePath("h264", "mse", both)).toBe("mse");
    expect(choosePath("h264", "webcodecs", { webcodecs: false, mse: true })).toBe("mse");
    expect(choosePath("h264", "mse", { webcodecs: true, mse: false })).toBe("webcodecs");
  });
});
