import { describe, expect, it } from "vitest";
import { indexAt } from "../../src/replay/core";
import { NO_FOOTAGE, display, newSync, react, target } from "../../src/replay/sync";
import type { Footage, SyncEvent, SyncState } from "../../src/replay/sync";

// a dive from 10 000 ms to 20 000 ms, its video 15 fps from 10 100 ms (frame i at 10 100 + i × 66.667 ms)
const START = 10_000;
const END = 20_000;
const FRAME_US = 1_000_000 / 15;
const TIMES = Float64Array.from({ length: 140 }, (_, i) => Math.round(10_100_000 + i * FRAME_US));
const FOOTAGE: Footage = { kind: "frames", fromMs: START, toMs: END + 1, times: TIMES };
const frameMs = (i: number): number => (TIMES[i] ?? NaN) / 1000;
/** the frame index at a position, as the picture picks it (the first before the first) */
const frameAt = (pos: number): number => Math.max(0, indexAt(TIMES, Math.round(pos * 1000)));

function run(s: SyncState, events: readonly SyncEvent[], footage: Footage = FOOTAGE): SyncState {
  return events.reduce((acc, e) => react(acc, e, footage), s);
}

/** A replay whose first picture is shown, paused at the start. */
function ready(now = 0): SyncState {
  const s = newSync(START, END, now, FOOTAGE);
  return react(s, { type: "picture", us: TIMES[0] ?? 0, now }, FOOTAGE);
}

describe("which frame a position waits for", () => {
  it("the last frame at or before it, the first before the first; nothing without video or frames", () => {
    expect(target(FOOTAGE, frameMs(5))).toEqual({ kind: "frame", us: TIMES[5] });
    expect(target(FOOTAGE, frameMs(5) + 10)).toEqual({ kind: "frame", us: TIMES[5] });
    expect(target(FOOTAGE, START)).toEqual({ kind: "frame", us: TIMES[0] });
    expect(target(NO_FOOTAGE, START)).toEqual({ kind: "free" });
    expect(target({ kind: "frames", fromMs: START, toMs: END, times: new Float64Array() }, START)).toEqual({ kind: "free" });
  });

  it("frames not fetched yet: loading (outside the window fetched, or before any)", () => {
    expect(target({ kind: "loading" }, START)).toEqual({ kind: "loading" });
    const part: Footage = { kind: "frames", fromMs: START, toMs: 12_000, times: TIMES.slice(0, 20) };
    expect(target(part, 15_000)).toEqual({ kind: "loading" });
    expect(target({ ...part, fromMs: 11_000 }, 10_500)).toEqual({ kind: "loading" });
  });
});

describe("a new replay", () => {
  it("waits at the dive's start for its first picture", () => {
    const s = newSync(START, END, 0, { kind: "loading" });
    expect(s.hold).toBe(START);
    expect(display(s, 100, { kind: "loading" })).toEqual({ pos: START, want: START, stale: true });
    const shown = react(s, { type: "picture", us: TIMES[0] ?? 0, now: 100 }, FOOTAGE);
    expect(shown.hold).toBeNull();
    expect(shown.settled).toBe(shown.holds);
    expect(display(shown, 200, FOOTAGE)).toEqual({ pos: START, want: START, stale: false });
  });

  it("without video nothing is waited for", () => {
    const s = newSync(START, END, 0, NO_FOOTAGE);
    expect(s.hold).toBeNull();
    expect(s.settled).toBe(s.holds);
    const playing = react(s, { type: "toggle", now: 0 }, NO_FOOTAGE);
    expect(display(playing, 1_000, NO_FOOTAGE).pos).toBe(START + 1_000);
  });
});

describe("a seek holds the cursor until its picture is shown", () => {
  it("paused: the cursor at the position sought, the picture stale until the frame there comes", () => {
    let s = run(ready(), [{ type: "seek", pos: frameMs(40) + 5, now: 10 }]);
    expect(s.holds).toBe(s.settled + 1);
    expect(display(s, 500, FOOTAGE)).toEqual({ pos: frameMs(40) + 5, want: frameMs(40) + 5, stale: true });
    // a picture asked for before (another frame) does not settle it
    s = run(s, [{ type: "picture", us: TIMES[3] ?? 0, now: 20 }]);
    expect(s.hold).not.toBeNull();
    s = run(s, [{ type: "picture", us: TIMES[40] ?? 0, now: 30 }]);
    expect(s.hold).toBeNull();
    expect(s.settled).toBe(s.holds);
    expect(display(s, 900, FOOTAGE)).toEqual({ pos: frameMs(40) + 5, want: frameMs(40) + 5, stale: false });
  });

  it("playing: the clock stands still until the picture is shown, then runs from the position sought", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }]);
    expect(s.clock.playing).toBe(true);
    s = run(s, [{ type: "seek", pos: 15_000, now: 100 }]);
    for (const now of [200, 900, 5_000]) {
      s = run(s, [{ type: "tick", now }]);
      expect(display(s, now, FOOTAGE).pos).toBe(15_000);
    }
    s = run(s, [{ type: "picture", us: TIMES[frameAt(15_000)] ?? 0, now: 5_000 }]);
    expect(s.hold).toBeNull();
    expect(s.clock.playing).toBe(true);
    // it runs from the position sought, at most to just before the frame after the one shown
    const d = display(s, 5_010, FOOTAGE);
    expect(d.pos).toBe(15_010);
    expect(frameAt(d.pos)).toBe(frameAt(15_000));
  });

  it("seeks past the ends are held at the ends; a seek to the frame shown settles at once", () => {
    let s = run(ready(), [{ type: "seek", pos: START - 5_000, now: 1 }]);
    expect(s.hold).toBeNull(); // the start's picture (frame 0) is the one shown
    expect(display(s, 2, FOOTAGE).pos).toBe(START);
    s = run(s, [{ type: "seek", pos: END + 5_000, now: 3 }]);
    expect(s.hold).toBe(END);
  });

  it("frames being fetched: held until the picture at the position is shown", () => {
    const part: Footage = { kind: "frames", fromMs: START, toMs: 12_000, times: TIMES.slice(0, 20) };
    let s = run(ready(), [{ type: "seek", pos: 15_000, now: 1 }], part);
    s = run(s, [{ type: "tick", now: 50 }], part);
    expect(display(s, 50, part)).toEqual({ pos: 15_000, want: 15_000, stale: true });
    s = run(s, [{ type: "tick", now: 60 }, { type: "picture", us: TIMES[frameAt(15_000)] ?? 0, now: 70 }]);
    expect(s.hold).toBeNull();
  });

  it("a picture that cannot be shown (no footage any more) lets the clock go on the next frame", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }, { type: "seek", pos: 15_000, now: 10 }]);
    expect(s.hold).toBe(15_000);
    s = run(s, [{ type: "tick", now: 20 }], NO_FOOTAGE);
    expect(s.hold).toBeNull();
    expect(display(s, 120, NO_FOOTAGE).pos).toBe(15_100);
  });
});

describe("while the clock runs, the numbers never run ahead of the picture", () => {
  it("the cursor stops just before the frame after the one shown, and goes on when the picture does", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }]);
    // the picture is still frame 0 after 500 ms (a slow decoder)
    let d = display(s, 500, FOOTAGE);
    expect(frameAt(d.pos)).toBe(0);
    expect(d.pos).toBeLessThan(frameMs(1));
    expect(d.want).toBe(START + 500); // the video decodes towards the clock
    // the picture jumps to the clock's frame: the cursor with it
    s = run(s, [{ type: "picture", us: TIMES[frameAt(START + 500)] ?? 0, now: 500 }]);
    d = display(s, 500, FOOTAGE);
    expect(d.pos).toBe(START + 500);
    expect(frameAt(d.pos)).toBe(frameAt(START + 500));
  });

  it("at every rate and any lag, the cursor's frame is the frame shown (property over a simulated picture)", () => {
    for (const rate of [0.25, 1, 4] as const) {
      for (const lagFrames of [0, 1, 3, 12]) {
        let s = run(ready(), [{ type: "rate", rate, now: 0 }, { type: "toggle", now: 0 }]);
        const asked: number[] = [];
        for (let now = 16; now < 2_000; now += 16) {
          s = run(s, [{ type: "tick", now }]);
          asked.push(display(s, now, FOOTAGE).want);
          // the picture shows what was asked `lagFrames` animation frames ago
          const old = asked[asked.length - 1 - lagFrames];
          if (old !== undefined) s = run(s, [{ type: "picture", us: TIMES[frameAt(old)] ?? 0, now }]);
          const d = display(s, now, FOOTAGE);
          expect(d.stale).toBe(false);
          expect(TIMES[frameAt(d.pos)]).toBe(s.shownUs);
        }
      }
    }
  });

  it("the window's last frame: the cursor waits at the window's end for the next window", () => {
    const part: Footage = { kind: "frames", fromMs: START, toMs: 11_000, times: TIMES.filter((t) => t <= 11_000_000) };
    const last = part.kind === "frames" ? (part.times[part.times.length - 1] ?? 0) : 0;
    let s = run(newSync(START, END, 0, part), [{ type: "picture", us: TIMES[0] ?? 0, now: 0 }, { type: "toggle", now: 0 }], part);
    s = run(s, [{ type: "picture", us: last, now: 3_000 }], part);
    expect(display(s, 3_000, part).pos).toBe(11_000);
    // the last frame of the dive's video: the telemetry goes on after it
    s = run(s, [{ type: "picture", us: TIMES[TIMES.length - 1] ?? 0, now: 3_000 }]);
    expect(display(s, 9_000, FOOTAGE).pos).toBe(START + 9_000);
  });
});

describe("paused and stepping, the picture is exactly the frame at the cursor", () => {
  it("a pause holds where the cursor is until that frame is shown", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }, { type: "picture", us: TIMES[2] ?? 0, now: 300 }]);
    const before = display(s, 400, FOOTAGE).pos; // held back by the picture (frame 2)
    s = run(s, [{ type: "toggle", now: 400 }]);
    expect(s.clock.playing).toBe(false);
    expect(s.hold).toBeNull(); // frame 2 is already the one at the cursor
    expect(display(s, 5_000, FOOTAGE).pos).toBe(before);
    expect(frameAt(before)).toBe(2);
  });

  it("a frame step pauses and holds at the next or previous frame's time", () => {
    let s = run(ready(), [{ type: "seek", pos: frameMs(30), now: 0 }, { type: "picture", us: TIMES[30] ?? 0, now: 1 }]);
    s = run(s, [{ type: "step", dir: 1, now: 2 }]);
    expect(display(s, 3, FOOTAGE)).toEqual({ pos: frameMs(31), want: frameMs(31), stale: true });
    // steps while one decodes go on from the held position
    s = run(s, [{ type: "step", dir: 1, now: 4 }]);
    expect(s.hold).toBe(frameMs(32));
    s = run(s, [{ type: "picture", us: TIMES[32] ?? 0, now: 5 }]);
    expect(s.hold).toBeNull();
    s = run(s, [{ type: "step", dir: -1, now: 6 }, { type: "step", dir: -1, now: 6 }, { type: "step", dir: -1, now: 6 }]);
    expect(s.hold).toBe(frameMs(29));
    // stepping while playing pauses
    s = run(s, [{ type: "picture", us: TIMES[29] ?? 0, now: 7 }, { type: "toggle", now: 8 }, { type: "step", dir: 1, now: 9 }]);
    expect(s.clock.playing).toBe(false);
    expect(s.hold).toBe(frameMs(30));
  });

  it("no step past the first or the last frame, nor without frames", () => {
    const s = ready();
    expect(run(s, [{ type: "step", dir: -1, now: 1 }])).toBe(s);
    expect(react(s, { type: "step", dir: 1, now: 1 }, { kind: "loading" })).toBe(s);
  });
});

describe("the other controls", () => {
  it("seekBy goes from the position shown, not from the clock running ahead of it", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }]);
    // the picture stays at frame 0: the cursor shows just before frame 1
    s = run(s, [{ type: "seekBy", ms: 5_000, now: 3_000 }]);
    expect(s.hold).toBeCloseTo(frameMs(1) + 5_000, 2);
  });

  it("the dive's end reached: paused there, held until its picture", () => {
    let s = run(ready(), [{ type: "rate", rate: 4, now: 0 }, { type: "toggle", now: 0 }, { type: "picture", us: TIMES[139] ?? 0, now: 2_000 }]);
    s = run(s, [{ type: "tick", now: 3_000 }]);
    expect(s.clock.playing).toBe(false);
    expect(display(s, 3_000, FOOTAGE).pos).toBe(END);
    expect(s.hold).toBeNull(); // the last frame is shown
    // playing at the end starts over from the start, held until the first picture
    s = run(s, [{ type: "toggle", now: 4_000 }]);
    expect(s.clock.playing).toBe(true);
    expect(s.hold).toBe(START);
    expect(display(s, 9_000, FOOTAGE).pos).toBe(START);
    s = run(s, [{ type: "picture", us: TIMES[0] ?? 0, now: 9_000 }]);
    expect(display(s, 9_010, FOOTAGE).pos).toBe(START + 40); // at 4×
  });

  it("play while a seek waits keeps the hold, and the clock plays once it settles; rates change the clock's speed", () => {
    let s = run(ready(), [{ type: "seek", pos: 12_000, now: 0 }, { type: "toggle", now: 10 }]);
    expect(s.clock.playing).toBe(true);
    expect(s.hold).toBe(12_000);
    expect(s.holds).toBe(2);
    s = run(s, [{ type: "stepRate", dir: 1, now: 20 }, { type: "picture", us: TIMES[frameAt(12_000)] ?? 0, now: 100 }]);
    expect(s.clock.rate).toBe(2);
    expect(display(s, 110, FOOTAGE).pos).toBe(12_020);
  });
});

describe("a picture asked for before a pause", () => {
  it("coming after the pause settled, holds the position again until the frame at the cursor is back", () => {
    let s = run(ready(), [{ type: "toggle", now: 0 }, { type: "picture", us: TIMES[2] ?? 0, now: 300 }, { type: "toggle", now: 400 }]);
    expect(s.hold).toBeNull();
    const pos = display(s, 400, FOOTAGE).pos;
    const holds = s.holds;
    // the decoder had been asked for frame 6 while playing
    s = run(s, [{ type: "picture", us: TIMES[6] ?? 0, now: 410 }]);
    expect(s.hold).toBe(pos);
    expect(s.holds).toBe(holds + 1);
    expect(display(s, 420, FOOTAGE)).toEqual({ pos, want: pos, stale: true });
    s = run(s, [{ type: "picture", us: TIMES[2] ?? 0, now: 430 }]);
    expect(s.hold).toBeNull();
    expect(s.settled).toBe(s.holds);
    expect(s.clock.playing).toBe(false);
  });
});
