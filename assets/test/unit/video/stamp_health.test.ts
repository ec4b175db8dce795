import { describe, expect, it } from "vitest";
import { FREEZE_MIN_MS, StreamHealth, WINDOW_MS, formatBitrate, formatLatency, freezeAfterMs, quantile } from "../../../src/video/health";
import { STAMP_HEIGHT, STAMP_MODULUS, STAMP_WIDTH, drawStamp, readStamp, stampAgeMs } from "../../../src/video/stamp";

function picture(width: number, height: number, fill = 128): { data: Uint8ClampedArray; width: number; height: number } {
  return { data: new Uint8ClampedArray(width * height * 4).fill(fill), width, height };
}

describe("the render stamp in the picture's corner", () => {
  it("reads back what the renderer drew (ms modulo 2^48)", () => {
    for (const ms of [0, 1, 1_722_000_000_123, STAMP_MODULUS - 1, STAMP_MODULUS + 5]) {
      const p = picture(640, 360);
      drawStamp(p, ms);
      expect(readStamp(p)).toBe(ms % STAMP_MODULUS);
    }
  });

  it("survives what an encoder does to the blocks (noise, soft edges)", () => {
    const p = picture(STAMP_WIDTH, STAMP_HEIGHT);
    drawStamp(p, 1_722_000_000_777);
    let seed = 7;
    for (let i = 0; i < p.data.length; i++) {
      if (i % 4 === 3) continue;
      seed = (seed * 1103515245 + 12345) % 2 ** 31;
      p.data[i] = Math.max(0, Math.min(255, (p.data[i] ?? 0) + ((seed % 61) - 30)));
    }
    expect(readStamp(p)).toBe(1_722_000_000_777);
  });

  it("is no stamp when the picture has none, or a block is grey, or the second row does not mirror the first", () => {
    expect(readStamp(picture(640, 360, 0))).toBeNull();
    expect(readStamp(picture(640, 360, 255))).toBeNull();
    expect(readStamp(picture(100, 100))).toBeNull();
    const p = picture(640, 360);
    drawStamp(p, 12345);
    // block 47's twin (row 1) made equal to its code
    for (let y = 8; y < 16; y++) for (let x = 376; x < 384; x++) p.data.fill(p.data[(2 * 640 + 378) * 4] ?? 0, (y * 640 + x) * 4, (y * 640 + x) * 4 + 3);
    expect(readStamp(p)).toBeNull();
  });

  it("tells the picture's age against the server clock, across the modulus", () => {
    expect(stampAgeMs(1_722_000_000_000 % STAMP_MODULUS, 1_722_000_000_083)).toBe(83);
    expect(stampAgeMs(STAMP_MODULUS - 10, STAMP_MODULUS + 30)).toBe(40);
    // a stamp a little ahead of the estimated clock: a small negative age
    expect(stampAgeMs(1000, 995)).toBe(-5);
  });
});

describe("stream health", () => {
  it("counts pictures per second and bits per second over the window", () => {
    const h = new StreamHealth();
    h.setFps(30);
    for (let i = 0; i < 60; i++) {
      h.received(i * 33.3, 5000);
      h.displayed(i * 33.3 + 5, 40 + (i % 10), null);
    }
    const s = h.summary(60 * 33.3);
    expect(s.fps).toBeCloseTo(30, 0);
    expect(s.bitrate).toBeCloseTo((60 * 5000 * 8 * 1000) / WINDOW_MS, -3);
    expect(s.serverToDisplay.p50).toBe(44);
    expect(s.serverToDisplay.p99).toBe(49);
    expect(s.renderToDisplay).toEqual({ p50: null, p99: null, last: null });
    expect(s.freezes).toBe(0);
  });

  it("forgets what is older than the window", () => {
    const h = new StreamHealth();
    h.displayed(0, 100, 120);
    expect(h.summary(WINDOW_MS + 1).serverToDisplay.p50).toBeNull();
    expect(h.summary(WINDOW_MS + 1).fps).toBe(0);
  });

  it("counts a freeze once, whether seen while frozen or when the next picture ends it", () => {
    const h = new StreamHealth();
    h.setFps(30);
    h.displayed(0, null, null);
    h.displayed(33, null, null);
    expect(h.summary(100).frozen).toBe(false);
    const frozen = h.summary(33 + FREEZE_MIN_MS + 1);
    expect(frozen).toMatchObject({ frozen: true, freezes: 1 });
    expect(h.summary(1000).freezes).toBe(1);
    h.displayed(1000, null, null);
    expect(h.summary(1001)).toMatchObject({ frozen: false, freezes: 1 });
    // a second one, ended before a summary saw it
    h.displayed(1400, null, null);
    expect(h.summary(1401).freezes).toBe(2);
  });

  it("does not count the wait after a pause (camera restarting, new stream) as a freeze", () => {
    const h = new StreamHealth();
    h.setFps(30);
    h.displayed(0, null, null);
    h.pause();
    expect(h.summary(5000)).toMatchObject({ frozen: false, freezes: 0 });
    h.displayed(5000, null, null);
    expect(h.summary(5001).freezes).toBe(0);
  });

  it("has a freeze threshold that suits slow cameras", () => {
    expect(freezeAfterMs(30)).toBe(FREEZE_MIN_MS);
    expect(freezeAfterMs(5)).toBe(800);
    expect(freezeAfterMs(0)).toBe(4 * FREEZE_MIN_MS);
  });

  it("adds up drops and starts over on reset", () => {
    const h = new StreamHealth();
    h.drop(3);
    h.drop(0);
    h.drop(2);
    expect(h.summary(0).dropped).toBe(5);
    h.reset();
    expect(h.summary(0).dropped).toBe(0);
  });

  it("formats figures for the health line", () => {
    expect(quantile([1, 2, 3, 4], 0.5)).toBe(2);
    expect(quantile([], 0.5)).toBeNull();
    expect(formatBitrate(950)).toBe("950 bit/s");
    expect(formatBitrate(812_000)).toBe("812 kbit/s");
    expect(formatBitrate(2_340_000)).toBe("2.3 Mbit/s");
    expect(formatLatency(83.4)).toBe("83 ms");
    expect(formatLatency(null)).toBe("—");
  });
});
