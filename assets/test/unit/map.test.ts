import { describe, expect, it } from "vitest";
import type { Mission, MissionReply, PositionStatus } from "../../src/lib/protocol";
import type { WaypointOut } from "../../src/lib/vehicle_client";
import {
  NO_TRACK,
  TRACK_MAX,
  ellipseOnScreen,
  fitView,
  fromScreen,
  gridLines,
  niceStep,
  planDepth,
  planWaypoints,
  pointsOnMap,
  positionText,
  sourceText,
  toScreen,
  withTrackPoint,
} from "../../src/operator/map";
import { MissionCommands } from "../../src/operator/mission_commands";
import type { MissionVehicle } from "../../src/operator/mission_commands";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";
import { telemetry } from "./telemetry_fixtures";

function position(extra: Partial<PositionStatus> = {}): PositionStatus {
  return {
    valid: true,
    reason: null,
    frame: "usbl",
    epoch: 1,
    north: 3,
    east: -2,
    depth: 4,
    velocity_north: 0,
    velocity_east: 0,
    std_north: 0.2,
    std_east: 0.1,
    ellipse: { major: 0.2, minor: 0.1, angle: 0 },
    origin: null,
    sources: [],
    ...extra,
  };
}

describe("the track", () => {
  it("takes valid positions that moved, starts again in a new frame, keeps the newest TRACK_MAX", () => {
    let track = withTrackPoint(NO_TRACK, position());
    expect(track).toEqual({ epoch: 1, points: [{ north: 3, east: -2 }] });
    expect(withTrackPoint(track, position({ north: 3.01 }))).toBe(track);
    expect(withTrackPoint(track, position({ valid: false, north: 9 }))).toBe(track);
    expect(withTrackPoint(track, undefined)).toBe(track);
    track = withTrackPoint(track, position({ north: 3.5 }));
    expect(track.points).toHaveLength(2);
    expect(withTrackPoint(track, position({ epoch: 2, north: 0, east: 0 }))).toEqual({ epoch: 2, points: [{ north: 0, east: 0 }] });
    for (let i = 0; i < TRACK_MAX + 10; i++) track = withTrackPoint(track, position({ north: i }));
    expect(track.points).toHaveLength(TRACK_MAX);
    expect(track.points[track.points.length - 1]).toEqual({ north: TRACK_MAX + 9, east: -2 });
  });
});

describe("the view", () => {
  it("nice steps are 1, 2, 5 × 10^k", () => {
    expect([0.3, 1, 1.5, 3, 7, 12, 60].map(niceStep)).toEqual([0.5, 1, 2, 5, 10, 20, 100]);
  });

  it("holds every point, north up and east right, and converts both ways", () => {
    const points = [
      { north: 0, east: 0 },
      { north: 12, east: -3 },
      { north: -4, east: 20 },
    ];
    const view = fitView(points, 480, 300);
    for (const p of points) {
      const { x, y } = toScreen(view, p);
      expect(x).toBeGreaterThanOrEqual(0);
      expect(x).toBeLessThanOrEqual(480);
      expect(y).toBeGreaterThanOrEqual(0);
      expect(y).toBeLessThanOrEqual(300);
      const back = fromScreen(view, x, y);
      expect(back.north).toBeCloseTo(p.north, 9);
      expect(back.east).toBeCloseTo(p.east, 9);
    }
    const a = toScreen(view, { north: 1, east: 0 });
    const b = toScreen(view, { north: 0, east: 1 });
    const o = toScreen(view, { north: 0, east: 0 });
    expect(a.y).toBeLessThan(o.y);
    expect(b.x).toBeGreaterThan(o.x);
    expect(gridLines(view).north.length).toBeGreaterThan(2);
  });

  it("stands still while the vehicle moves a little, and is at least 10 m across with nothing on it", () => {
    const v1 = fitView([{ north: 0.6, east: 0.5 }], 480, 300);
    const v2 = fitView([{ north: 0.9, east: 0.2 }], 480, 300);
    expect(v2).toEqual(v1);
    expect(300 / fitView([], 480, 300).scale).toBeGreaterThanOrEqual(10);
  });

  it("draws the 1-σ ellipse with its major axis where the angle points", () => {
    const view = fitView([{ north: 0, east: 0 }], 400, 400);
    const north = ellipseOnScreen(view, position({ north: 0, east: 0, ellipse: { major: 2, minor: 1, angle: 0 } }));
    expect(north?.rx).toBeCloseTo(2 * view.scale, 9);
    expect(north?.ry).toBeCloseTo(view.scale, 9);
    // along north: the screen's x axis turned -90° (up)
    expect(north?.rotate).toBeCloseTo(-90, 9);
    expect(ellipseOnScreen(view, position({ north: 0, east: 0, ellipse: { major: 2, minor: 1, angle: Math.PI / 2 } }))?.rotate).toBeCloseTo(0, 9);
    expect(ellipseOnScreen(view, position({ ellipse: null }))).toBeNull();
  });

  it("holds the track, the vehicle, DP's target, the mission and the plan", () => {
    const mission: Mission = {
      id: 1,
      state: "running",
      leg: 1,
      waypoints: [{ north: 5, east: 5, depth: 2, heading: null, speed: 0.3, radius: 0.5 }],
    };
    const pts = pointsOnMap({ epoch: 1, points: [{ north: 0, east: 0 }] }, position(), null, mission, [{ north: 9, east: 9 }]);
    expect(pts).toEqual([
      { north: 0, east: 0 },
      { north: 3, east: -2 },
      mission.waypoints[0],
      { north: 9, east: 9 },
    ]);
  });
});

describe("what the pilot reads", () => {
  it("a valid position with its uncertainty, or honestly why there is none", () => {
    expect(positionText(position())).toEqual({ valid: true, text: "N 3.00 m, E -2.00 m ± 0.20 m (usbl frame)" });
    expect(positionText(position({ valid: false, reason: "no position source" }))).toEqual({ valid: false, text: "No position: no position source" });
    expect(positionText(undefined).valid).toBe(false);
  });

  it("a source: its state, measurements, and the reason it is not valid", () => {
    const src = {
      name: "dvl",
      kind: "velocity" as const,
      state: "invalid" as const,
      reason: "no bottom lock",
      connected: true,
      reports: 10,
      accepted: 4,
      rejected: { no_lock: 6 },
      garbage: 1,
      disconnects: 0,
      reacquired: 0,
      altitude: 12.34,
      fom: 0.1,
      std: null,
      innovation: null,
      dead_reckoning: null,
    };
    expect(sourceText(src)).toBe("dvl: invalid (altitude 12.3 m, 1 unreadable, 6 rejected) — no bottom lock");
    expect(sourceText({ ...src, state: "valid", reason: null, garbage: 0, rejected: {}, altitude: -1 })).toBe("dvl: valid");
  });

  it("telemetry's position and DP status decode into the page's view", () => {
    const t = telemetry({
      position: position(),
      autopilot: { depth: null, heading: null, position: { x: 1, y: 2, heading: 0, phase: "hold", distance: 0.3, output: 0, sway: 0, waiting: null, mission: null } },
    });
    expect(t?.position?.north).toBe(3);
    expect(t?.autopilot?.position?.phase).toBe("hold");
  });
});

describe("planning", () => {
  it("waypoints at the depth held (else the estimate), rounded", () => {
    expect(planWaypoints([{ north: 1.234, east: -5.678 }], 2.04)).toEqual([{ north: 1.23, east: -5.68, depth: 2 }]);
    expect(planDepth(3, 1)).toBe(3);
    expect(planDepth(null, 1.5)).toBe(1.5);
    expect(planDepth(undefined, Number.NaN)).toBeNull();
  });
});

describe("MissionCommands", () => {
  function harness(refuse: string | null = null) {
    let state: OperatorState = initialState("keyboard", { deadband: 0.1, expo: 0 });
    const sent: { action: string; waypoints?: readonly WaypointOut[] }[] = [];
    const messages: { text: string; kind: string }[] = [];
    const mission: Mission = { id: 3, state: "running", leg: 1, waypoints: [{ north: 1, east: 2, depth: 2, heading: null, speed: 0.3, radius: 0.5 }] };
    const vehicle: MissionVehicle = {
      mission: (action, waypoints) => {
        sent.push(waypoints === undefined ? { action } : { action, waypoints });
        if (refuse !== null) return Promise.reject(new Error(refuse));
        const reply: MissionReply = { control: { mode: "dp" } as MissionReply["control"], mission: action === "abort" ? null : mission, waypoints: null };
        return Promise.resolve(reply);
      },
    };
    const missions = new MissionCommands({
      get: () => state,
      update: (patch) => (state = { ...state, ...patch }),
      vehicle: () => vehicle,
      showMessage: (text, kind) => messages.push({ text, kind }),
      clearMessage: () => undefined,
    });
    const withDepth = (depth: number): void => {
      state = { ...state, control: { mode: "dp", gain: null, lights: null, laser: null, tilt: null, run_mode: null, autopilot: { depth, heading: 0 } } };
    };
    return { missions, sent, messages, get: () => state, withDepth, settled: (): Promise<void> => new Promise((r) => setTimeout(r, 0)) };
  }

  it("plans by adding, undoing and clearing; starts the plan at the depth held and forgets it", async () => {
    const h = harness();
    h.missions.add({ north: 1, east: 2 });
    h.missions.add({ north: 3, east: 4 });
    h.missions.add({ north: 5, east: 6 });
    h.missions.undo();
    expect(h.get().plan).toEqual([
      { north: 1, east: 2 },
      { north: 3, east: 4 },
    ]);
    h.withDepth(2.5);
    h.missions.start();
    await h.settled();
    expect(h.sent).toEqual([
      {
        action: "start",
        waypoints: [
          { north: 1, east: 2, depth: 2.5 },
          { north: 3, east: 4, depth: 2.5 },
        ],
      },
    ]);
    expect(h.get().plan).toEqual([]);
    expect(h.get().mission?.id).toBe(3);
    h.missions.abort();
    await h.settled();
    expect(h.sent[1]).toEqual({ action: "abort" });
    expect(h.get().mission).toBeNull();
  });

  it("nothing to start, or no depth: says so and sends nothing", () => {
    const h = harness();
    h.missions.start();
    h.missions.add({ north: 1, east: 1 });
    h.missions.start();
    expect(h.sent).toEqual([]);
    expect(h.messages.map((m) => m.kind)).toEqual(["warn", "error"]);
  });

  it("a refusal is shown with the server's reason, and the plan is kept", async () => {
    const h = harness("a mission needs a valid position: no position source");
    h.withDepth(2);
    h.missions.add({ north: 1, east: 1 });
    h.missions.start();
    await h.settled();
    expect(h.messages).toEqual([{ text: "Mission start refused: a mission needs a valid position: no position source", kind: "error" }]);
    expect(h.get().plan).toHaveLength(1);
    h.missions.clear();
    expect(h.get().plan).toEqual([]);
  });

  it("the mission event replaces the page's mission", () => {
    const h = harness();
    h.missions.received(null);
    expect(h.get().mission).toBeNull();
  });
});
