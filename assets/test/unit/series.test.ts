import { describe, expect, it } from "vitest";
import {
  breakWraps,
  displayValue,
  isWrappedAngle,
  flattenNumeric,
  isAngle,
  seriesGroup,
  seriesLabel,
  seriesUnit,
  sortSeries,
} from "../../src/plots/series";

const telemetry = {
  t: 12.5,
  sent_at: 1795000000123,
  measurement: { depth: 1, heading: 0.5, roll: 0, pitch: 0, voltage: 12.5, current: 0.3 },
  sim: { x: 1, y: 2, z: 1, phi: 0, theta: 0, psi: 0.5, u: 0.1, v: 0, w: 0, p: 0, q: 0, r: 0.01 },
  command: { surge: 0.5, heave: 0, yaw: 0 },
  thrusters: { port: 0.25, vertical: 0, starboard: 0.25, port_us: 1625, vertical_us: 1500, starboard_us: 1625 },
  control: { mode: "motion", gain: 0.5, autopilot: { depth: null, heading: 1.2 } },
  autopilot: { depth: null, heading: { setpoint: 1.2, output: 0.1 } },
  estimate: { depth: 1, depth_rate: 0, heading: 0.5, yaw_rate: 0.01 },
  wild_points: { total: 3, by_field: { hdgd: 2, deap: 1 } },
  link: { up: true, reason: "open" },
};

describe("flattenNumeric: series from the payload", () => {
  it("takes every numeric and boolean leaf by path, but not sent_at (the x axis) or strings/nulls", () => {
    const f = flattenNumeric(telemetry);
    expect(f.get("t")).toBe(12.5);
    expect(f.has("sent_at")).toBe(false);
    expect(f.get("measurement.depth")).toBe(1);
    expect(f.get("thrusters.port_us")).toBe(1625);
    expect(f.get("control.gain")).toBe(0.5);
    expect(f.get("control.autopilot.heading")).toBe(1.2);
    expect(f.has("control.autopilot.depth")).toBe(false);
    expect(f.has("control.mode")).toBe(false);
    expect(f.get("autopilot.heading.output")).toBe(0.1);
    expect(f.get("estimate.yaw_rate")).toBe(0.01);
    expect(f.get("wild_points.by_field.hdgd")).toBe(2);
    expect(f.get("link.up")).toBe(1);
    expect(f.has("link.reason")).toBe(false);
    // thesis table 7.3 is all there
    for (const key of ["measurement.roll", "measurement.pitch", "measurement.heading", "measurement.voltage", "measurement.current",
      "command.surge", "command.heave", "command.yaw", "thrusters.starboard", "thrusters.vertical",
      "estimate.heading", "estimate.depth", "sim.x", "sim.y", "sim.z", "sim.psi", "sim.u", "sim.w", "sim.r"]) {
      expect(f.has(key), key).toBe(true);
    }
  });

  it("ignores arrays and non-finite numbers", () => {
    const f = flattenNumeric({ a: [1, 2], b: Number.NaN, c: Infinity, d: { e: 1 } });
    expect([...f.keys()]).toEqual(["d.e"]);
  });
});

describe("series metadata", () => {
  it("groups by table 7.3 column", () => {
    expect(seriesGroup("measurement.depth")).toBe("Measurement");
    expect(seriesGroup("command.yaw")).toBe("Command");
    expect(seriesGroup("estimate.heading")).toBe("Estimated state");
    expect(seriesGroup("sim.psi")).toBe("Simulated state");
    expect(seriesGroup("thrusters.port")).toBe("Thrusters");
    expect(seriesGroup("t")).toBe("Other");
  });

  it("plots angles in degrees, with units in the label", () => {
    expect(isAngle("measurement.heading")).toBe(true);
    expect(isAngle("sim.psi")).toBe(true);
    expect(isAngle("autopilot.heading.setpoint")).toBe(true);
    expect(isAngle("autopilot.heading.output")).toBe(false);
    expect(isAngle("command.yaw")).toBe(false);
    expect(displayValue("measurement.heading", Math.PI)).toBeCloseTo(180);
    expect(displayValue("sim.r", Math.PI)).toBeCloseTo(180);
    expect(displayValue("measurement.depth", 2)).toBe(2);
    expect(seriesUnit("sim.r")).toBe("deg/s");
    expect(seriesUnit("measurement.depth")).toBe("m");
    expect(seriesUnit("sim.u")).toBe("m/s");
    expect(seriesUnit("thrusters.port_us")).toBe("µs");
    expect(seriesUnit("measurement.voltage")).toBe("V");
    expect(seriesUnit("measurement.current")).toBe("A");
    expect(seriesLabel("measurement.roll")).toBe("measurement.roll [deg]");
    expect(seriesLabel("command.surge")).toBe("command.surge");
  });

  it("sorts by group, table 7.3's rows first, then the payload order", () => {
    expect(
      sortSeries(["t", "sim.q", "sim.x", "command.heave", "measurement.heading", "command.surge", "measurement.depth", "measurement.extra", "sim.p"]),
    ).toEqual(["measurement.depth", "measurement.heading", "measurement.extra", "command.surge", "command.heave", "sim.x", "sim.q", "sim.p", "t"]);
  });
});

describe("wrapped angles break at north instead of crossing the plot", () => {
  it("knows which series wrap", () => {
    for (const p of ["measurement.heading", "estimate.heading", "sim.psi", "sim.phi", "autopilot.heading.setpoint"])
      expect(isWrappedAngle(p)).toBe(true);
    for (const p of ["measurement.roll", "sim.theta", "sim.r", "estimate.yaw_rate", "command.yaw", "measurement.depth"])
      expect(isWrappedAngle(p)).toBe(false);
  });

  it("puts a gap where consecutive samples jump by more than half a turn", () => {
    expect(breakWraps([350, 355, 359, 2, 6, 10])).toEqual([350, 355, 359, null, 6, 10]);
    expect(breakWraps([10, 3, 358, 351])).toEqual([10, 3, null, 351]);
    expect(breakWraps([-175, -179, 179, 175])).toEqual([-175, -179, null, 175]);
  });

  it("keeps smooth turns, steps up to half a turn, and existing gaps", () => {
    expect(breakWraps([0, 90, 180, 270])).toEqual([0, 90, 180, 270]);
    expect(breakWraps([0, 180, 0])).toEqual([0, 180, 0]);
    // a jump measured across a missing sample still breaks
    expect(breakWraps([358, null, 3, 8])).toEqual([358, null, null, 8]);
    expect(breakWraps([null, 5, 6])).toEqual([null, 5, 6]);
    expect(breakWraps([])).toEqual([]);
  });
});
