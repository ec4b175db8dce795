import { describe, expect, it } from "vitest";
import {
  formatOffset,
  frameStep,
  indexAt,
  keyAction,
  newClock,
  nextEvent,
  parseVideoFrames,
  pause,
  play,
  positionAt,
  previousEvent,
  replayEvents,
  seek,
  stepRate,
  tick,
} from "../../src/replay/core";

describe("the replay clock", () => {
  it("plays at its rate from where it was, pauses there, never past the dive's ends", () => {
    let c = newClock(1_000, 11_000, 0);
    expect(positionAt(c, 500)).toBe(1_000);
    c = play(c, 100);
    expect(positionAt(c, 1_100)).toBe(2_000);
    c = stepRate(stepRate(stepRate(c, 1, 1_100), 1, 1_100), 1, 1_100); // 1 → 2 → 4 → 4
    expect(c.rate).toBe(4);
    expect(positionAt(c, 2_100)).toBe(6_000);
    c = pause(c, 2_100);
    expect(positionAt(c, 9_999)).toBe(6_000);
    c = play(c, 10_000);
    expect(positionAt(c, 20_000)).toBe(11_000);
    c = tick(c, 20_000);
    expect(c.playing).toBe(false);
    // play at the end starts over
    expect(positionAt(play(c, 0), 0)).toBe(1_000);
    expect(positionAt(seek(c, -5, 0), 0)).toBe(1_000);
    expect(positionAt(seek(c, 99_999, 0), 0)).toBe(11_000);
  });

  it("slows down to 0.25× and no further", () => {
    let c = newClock(0, 10, 0);
    for (let i = 0; i < 5; i++) c = stepRate(c, -1, 0);
    expect(c.rate).toBe(0.25);
  });

  it("changing the rate while playing keeps the position", () => {
    let c = play(newClock(0, 100_000, 0), 0);
    c = stepRate(c, 1, 1_000);
    expect(positionAt(c, 1_000)).toBe(1_000);
    expect(positionAt(c, 2_000)).toBe(3_000);
  });
});

describe("frames and events", () => {
  const frames = [1_000_000, 1_066_666, 1_133_333, 1_200_000];

  it("the frame shown is the last at or before the position", () => {
    expect(indexAt(frames, 999_999)).toBe(-1);
    expect(indexAt(frames, 1_000_000)).toBe(0);
    expect(indexAt(frames, 1_100_000)).toBe(1);
    expect(indexAt(frames, 9e9)).toBe(3);
    expect(indexAt([], 5)).toBe(-1);
  });

  it("a frame step lands on the next or previous frame's time", () => {
    expect(frameStep(frames, 1_100, 1)).toBeCloseTo(1_133.333);
    expect(frameStep(frames, 1_100, -1)).toBe(1_000);
    expect(frameStep(frames, 1_000, -1)).toBe(null);
    expect(frameStep(frames, 1_200, 1)).toBe(null);
  });

  const events = replayEvents([
    { at: 30, event: "snapshot", payload: { name: "a.jpg" } },
    { at: 10, event: "helm", payload: { state: "piloted", pilot: { name: "ada" } } },
    { at: 20, event: "stopped", payload: { reason: "deadman" } },
    { at: 25, event: "log", payload: { category: "autopilot", message: "depth hold" } },
    { at: 26, event: "log", payload: { category: "safety", message: "x" } },
    { at: 27, event: "presence_diff", payload: {} },
  ]);

  it("stops, handovers, autopilot changes, logger entries and snapshots, in time order", () => {
    expect(events.map((e) => [e.at, e.kind, e.label])).toEqual([
      [10, "handover", "helm: ada"],
      [20, "stop", "stop: deadman"],
      [25, "autopilot", "autopilot: depth hold"],
      [26, "log", "safety: x"],
      [30, "snapshot", "snapshot a.jpg"],
    ]);
  });

  it("next and previous event; previous skips the one just reached", () => {
    expect(nextEvent(events, 0)?.at).toBe(10);
    expect(nextEvent(events, 10)?.at).toBe(20);
    expect(nextEvent(events, 30)).toBe(null);
    expect(previousEvent(events, 2_000)?.at).toBe(30);
    expect(previousEvent(events, 520)?.at).toBe(10);
    expect(previousEvent(events, 200)).toBe(null);
  });
});

describe("keyboard shortcuts", () => {
  it("as video players have them", () => {
    expect(keyAction(" ")).toEqual({ type: "toggle" });
    expect(keyAction("k")).toEqual({ type: "toggle" });
    expect(keyAction("ArrowLeft")).toEqual({ type: "seekBy", ms: -5_000 });
    expect(keyAction("l")).toEqual({ type: "seekBy", ms: 10_000 });
    expect(keyAction(".")).toEqual({ type: "frame", dir: 1 });
    expect(keyAction("<")).toEqual({ type: "rate", dir: -1 });
    expect(keyAction("n")).toEqual({ type: "event", dir: 1 });
    expect(keyAction("End")).toEqual({ type: "end" });
    expect(keyAction("x")).toBe(null);
  });
});

function frameBytes(kind: number, flags: number, atUs: bigint, payload: number[]): Uint8Array {
  const out = new Uint8Array(4 + 28 + payload.length);
  const view = new DataView(out.buffer);
  view.setUint32(0, 28 + payload.length);
  view.setUint8(4, 1);
  view.setUint8(5, kind);
  view.setUint8(6, flags);
  view.setUint32(8, 7);
  view.setBigUint64(16, atUs);
  out.set(payload, 32);
  return out;
}

describe("the /video reply", () => {
  it("length-prefixed frames with their header", () => {
    const a = frameBytes(1, 1, 1_795_000_000_000_000n, [0, 0, 0, 1, 0x65]);
    const b = frameBytes(2, 0, 1_795_000_000_066_666n, [0xff, 0xd8]);
    const both = new Uint8Array(a.length + b.length);
    both.set(a);
    both.set(b, a.length);
    const frames = parseVideoFrames(both.buffer);
    expect(frames.map((f) => [f.codec, f.keyframe, f.generation, f.atUs, Array.from(f.payload)])).toEqual([
      ["h264", true, 7, 1_795_000_000_000_000, [0, 0, 0, 1, 0x65]],
      ["jpeg", false, 7, 1_795_000_000_066_666, [0xff, 0xd8]],
    ]);
    expect(parseVideoFrames(new ArrayBuffer(0))).toEqual([]);
  });

  it("a cut-off or foreign reply is refused", () => {
    const a = frameBytes(1, 1, 1n, [1, 2, 3]);
    expect(() => parseVideoFrames(a.slice(0, a.length - 1).buffer)).toThrow(/cut off/);
    expect(() => parseVideoFrames(a.slice(0, 2).buffer)).toThrow(/cut off/);
    const foreign = a.slice();
    foreign[5] = 9;
    expect(() => parseVideoFrames(foreign.buffer)).toThrow(/not a frame/);
  });
});

it("formats an offset as minutes and seconds", () => {
  expect(formatOffset(0)).toBe("0:00.0");
  expect(formatOffset(75_250)).toBe("1:15.3");
  expect(formatOffset(-5)).toBe("0:00.0");
});

it("a frame step from a frame's own time (µs / 1000, not exact in binary) finds that frame", () => {
  const times = [0, 66_666, 133_332, 1_795_000_002_066_646];
  expect(frameStep(times, 1_795_000_002_066_646 / 1000, -1)).toBe(133.332);
});
