import { describe, expect, it } from "vitest";
import { ClockOffset, TelemetryClock, ageOnArrival, telemetryAge, STALE_AFTER_MS, ageText, freshness } from "../../src/lib/clock";

describe("the server's clock against this one", () => {
  it("has no offset before the first reading", () => {
    const c = new ClockOffset();
    expect(c.offsetMs).toBeNull();
    expect(c.uncertaintyMs).toBeNull();
  });

  it("takes the middle of the round trip: server 5 s ahead, 40 ms round trip", () => {
    const c = new ClockOffset();
    c.add({ sentAt: 1_000, serverNow: 6_020, receivedAt: 1_040 });
    expect(c.offsetMs).toBe(5_000);
    expect(c.uncertaintyMs).toBe(20);
  });

  it("trusts the quickest round trip of the recent readings", () => {
    const c = new ClockOffset(3);
    // a reply held up 1.3 s behind telemetry on a slow link (the request went fast)
    c.add({ sentAt: 10_000, serverNow: 15_020, receivedAt: 11_340 });
    c.add({ sentAt: 20_000, serverNow: 25_010, receivedAt: 20_020 }); // quick: offset 5 000
    c.add({ sentAt: 30_000, serverNow: 35_020, receivedAt: 31_300 });
    expect(c.offsetMs).toBe(5_000);
    // the quick one leaves the window of 3: the best of the slow ones (1.3 s) is off by 630 ms
    c.add({ sentAt: 40_000, serverNow: 45_020, receivedAt: 41_320 });
    c.add({ sentAt: 50_000, serverNow: 55_020, receivedAt: 51_330 });
    expect(c.offsetMs).toBe(4_370);
    expect(c.uncertaintyMs).toBe(650);
  });

  it("ignores impossible readings and forgets on reset", () => {
    const c = new ClockOffset();
    c.add({ sentAt: 100, serverNow: 50, receivedAt: 90 }); // reply before request
    c.add({ sentAt: Number.NaN, serverNow: 50, receivedAt: 90 });
    c.add({ sentAt: 0, serverNow: Number.POSITIVE_INFINITY, receivedAt: 10 });
    expect(c.offsetMs).toBeNull();
    c.add({ sentAt: 0, serverNow: -995, receivedAt: 10 }); // server 1 s behind
    expect(c.offsetMs).toBe(-1_000);
    c.reset();
    expect(c.offsetMs).toBeNull();
  });
});

describe("how old telemetry is", () => {
  it("on arrival: received + offset − sent_at, never below zero, unknown without an offset", () => {
    // server 5 s ahead; the frame was stamped 1.3 s before it arrived
    expect(ageOnArrival(106_000, 102_300, 5_000)).toBe(1_300);
    expect(ageOnArrival(107_400, 102_300, 5_000)).toBe(0); // looks early: the offset's own error
    expect(ageOnArrival(106_000, 102_300, null)).toBeNull();
    expect(ageOnArrival(Number.NaN, 102_300, 5_000)).toBeNull();
  });

  it("now: time since the newest frame arrived plus its age on arrival", () => {
    expect(telemetryAge(10_250, 10_000, 1_300)).toBe(1_550); // a slow link
    expect(telemetryAge(12_000, 10_000, null)).toBe(2_000); // silence, offset unknown
    expect(telemetryAge(9_990, 10_000, 0)).toBe(0);
  });
});

describe("freshness and ageText (both pages)", () => {
  it("live within STALE_AFTER_MS (age shown as 0), stale beyond it with the age to 0.1 s", () => {
    expect(freshness(0)).toEqual({ telemetryState: "live", telemetryAgeMs: 0 });
    expect(freshness(STALE_AFTER_MS)).toEqual({ telemetryState: "live", telemetryAgeMs: 0 });
    expect(freshness(STALE_AFTER_MS + 1)).toEqual({ telemetryState: "stale", telemetryAgeMs: 1000 });
    expect(freshness(2345)).toEqual({ telemetryState: "stale", telemetryAgeMs: 2300 });
  });

  it("says none yet, live, or stale with seconds", () => {
    expect(ageText("none", 0)).toBe("none yet");
    expect(ageText("live", 0)).toBe("live");
    expect(ageText("stale", 2300)).toBe("stale (2.3 s)");
  });
});

describe("TelemetryClock: the pages' telemetry age", () => {
  const source = (joined: boolean, serverNow: number) => {
    let asked = 0;
    return {
      get asked() {
        return asked;
      },
      joined,
      clock: () => {
        asked += 1;
        return Promise.resolve({ sentAt: 1_000, serverNow, receivedAt: 1_040 });
      },
    };
  };

  it("says nothing before the first frame, and reads the clock only once a vehicle is joined", () => {
    const none = new TelemetryClock(() => null);
    expect(none.tick(0)).toBeNull();
    const left = source(false, 0);
    new TelemetryClock(() => left).tick(0);
    expect(left.asked).toBe(0);
  });

  it("reads the server's clock while its offset is unknown, one request at a time", async () => {
    const s = source(true, 6_020);
    const c = new TelemetryClock(() => s);
    c.tick(0);
    c.tick(250);
    expect(s.asked).toBe(1);
    await Promise.resolve();
    expect(c.offset.offsetMs).toBe(5_000);
    c.tick(500);
    expect(s.asked).toBe(1);
  });

  it("a frame that was already old on arrival is stale; a silent link goes stale with time", async () => {
    const s = source(true, 6_020);
    const c = new TelemetryClock(() => s);
    c.read();
    await Promise.resolve();
    // server 5 s ahead: stamped 4 000 by the server, arriving at our 1 000 (its 6 000): 2 s old
    expect(c.received(4_000, 100, 1_000)).toEqual({ telemetryState: "stale", telemetryAgeMs: 2_000 });
    expect(c.received(6_000, 200, 1_000)).toEqual({ telemetryState: "live", telemetryAgeMs: 0 });
    expect(c.tick(900)).toBeNull();
    expect(c.tick(1_300)).toEqual({ telemetryState: "stale", telemetryAgeMs: 1_100 });
  });
});
