import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import type { LatencySummary } from "../../src/lib/latency";
import { Heartbeat, PING_MS } from "../../src/operator/heartbeat";
import type { HeartbeatVehicle } from "../../src/operator/heartbeat";

function harness(options: { refuse?: string } = {}) {
  let latency: LatencySummary | null = null;
  let piloting = true;
  let joined = true;
  let connected = true;
  let beats = 0;
  let pings = 0;
  const refusals: string[] = [];
  const vehicle: HeartbeatVehicle = {
    get joined() {
      return joined;
    },
    heartbeat: () => {
      beats += 1;
      return options.refuse ? Promise.reject(new Error(options.refuse)) : Promise.resolve(12);
    },
  };
  const heartbeat = new Heartbeat({
    update: (patch) => void (latency = patch.latency),
    vehicle: () => vehicle,
    piloting: () => piloting,
    intervalMs: () => 100,
    ping: () => {
      if (!connected) return null;
      pings += 1;
      return Promise.resolve(30);
    },
    refused: (reason) => refusals.push(reason),
  });
  return {
    heartbeat,
    latency: () => latency,
    beats: () => beats,
    pings: () => pings,
    refusals,
    setPiloting: (p: boolean) => void (piloting = p),
    setJoined: (j: boolean) => void (joined = j),
    setConnected: (c: boolean) => void (connected = c),
  };
}

beforeEach(() => void vi.useFakeTimers());
afterEach(() => void vi.useRealTimers());

describe("Heartbeat: the pilot's", () => {
  it("beats at the server's interval while on; each reply is a round trip", async () => {
    const h = harness();
    h.heartbeat.pilot(true);
    await vi.advanceTimersByTimeAsync(350);
    expect(h.beats()).toBe(3);
    expect(h.latency()).toMatchObject({ last: 12, samples: 3 });
    h.heartbeat.pilot(false);
    await vi.advanceTimersByTimeAsync(500);
    expect(h.beats()).toBe(3);
  });

  it("turning it on twice runs one heartbeat", async () => {
    const h = harness();
    h.heartbeat.pilot(true);
    h.heartbeat.pilot(true);
    await vi.advanceTimersByTimeAsync(100);
    expect(h.beats()).toBe(1);
  });

  it("says nothing while the channel is not joined or we no longer pilot", async () => {
    const h = harness();
    h.heartbeat.pilot(true);
    h.setJoined(false);
    await vi.advanceTimersByTimeAsync(200);
    h.setJoined(true);
    h.setPiloting(false);
    await vi.advanceTimersByTimeAsync(200);
    expect(h.beats()).toBe(0);
  });

  it("a refusal is reported with the server's reason", async () => {
    const h = harness({ refuse: "not_in_control" });
    h.heartbeat.pilot(true);
    await vi.advanceTimersByTimeAsync(100);
    expect(h.refusals).toEqual(["not_in_control"]);
    expect(h.latency()).toBeNull();
  });
});

describe("Heartbeat: a watcher's round trip", () => {
  it("pings every second while we watch a connected socket, not while the pilot's heartbeat runs", async () => {
    const h = harness();
    h.heartbeat.start();
    await vi.advanceTimersByTimeAsync(2 * PING_MS);
    expect(h.pings()).toBe(2);
    expect(h.latency()).toMatchObject({ last: 30, samples: 2 });
    h.heartbeat.pilot(true);
    await vi.advanceTimersByTimeAsync(2 * PING_MS);
    expect(h.pings()).toBe(2);
    h.heartbeat.pilot(false);
    h.setConnected(false);
    await vi.advanceTimersByTimeAsync(2 * PING_MS);
    expect(h.pings()).toBe(2);
  });

  it("the round trips are forgotten when the connection drops", async () => {
    const h = harness();
    h.heartbeat.start();
    await vi.advanceTimersByTimeAsync(PING_MS);
    h.heartbeat.resetLatency();
    expect(h.latency()).toEqual({ last: null, mean: null, max: null, samples: 0 });
  });
});
