import { describe, expect, it } from "vitest";
import {
  displayValue,
  intoTurn,
  isWrappedAngle,
  turnStart,
  unwrap,
  unwrapNext,
  wrapPeriod,
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

describe("wrapped angles are plotted as one continuous line", () => {
  it("knows which series wrap", () => {
    for (const p of ["measurement.heading", "estimate.heading", "sim.psi", "sim.phi", "autopilot.heading.setpoint"]) {
      expect(isWrappedAngle(p)).toBe(true);
      expect(wrapPeriod(p)).toBeCloseTo(2 * Math.PI);
    }
    for (const p of ["measurement.roll", "sim.theta", "sim.r", "estimate.yaw_rate", "command.yaw", "measurement.depth"]) {
      expect(isWrappedAngle(p)).toBe(false);
      expect(wrapPeriod(p)).toBeNull();
    }
  });

  it("a steady heading near north, jittering across it, is a line (no square wave between 0° and 360°)", () => {
    const near = [359.8, 0.1, 359.9, 0.2, 359.7, 0.0, 359.95];
    const line = unwrap(near, 360);
    expect(line[0]).toBe(359.8);
    const finite = line.filter((v): v is number => v !== null);
    expect(Math.max(...finite) - Math.min(...finite)).toBeCloseTo(0.5);
    // each point is its sample, moved by whole turns
    line.forEach((v, i) => expect(intoTurn(v ?? Number.NaN, 0)).toBeCloseTo(near[i] ?? Number.NaN));
  });

  it("a turn through north keeps going instead of jumping back by a turn", () => {
    expect(unwrap([350, 355, 359, 2, 6, 10], 360)).toEqual([350, 355, 359, 362, 366, 370]);
    expect(unwrap([10, 3, 358, 351], 360)).toEqual([10, 3, -2, -9]);
    expect(unwrap([-175, -179, 179, 175], 360)).toEqual([-175, -179, -181, -185]);
    // several turns, in radians
    const turns = Array.from({ length: 40 }, (_, i) => ((i * 0.5) % (2 * Math.PI)));
    const line = unwrap(turns, 2 * Math.PI);
    line.forEach((v, i) => expect(v).toBeCloseTo(i * 0.5));
  });

  it("gaps stay gaps and do not break the line; steps up to half a turn are kept", () => {
    expect(unwrap([358, null, 3, 8], 360)).toEqual([358, null, 363, 368]);
    expect(unwrap([null, 5, 6], 360)).toEqual([null, 5, 6]);
    expect(unwrap([0, 90, 180, 270], 360)).toEqual([0, 90, 180, 270]);
    expect(unwrap([], 360)).toEqual([]);
    expect(unwrapNext(null, 7, 360)).toBe(7);
    expect(unwrapNext(720, 1, 360)).toBe(721);
  });

  it("reads a plotted angle back within its turn: a heading in [0, 360), psi and phi in [-180, 180)", () => {
    expect(turnStart("measurement.heading")).toBe(0);
    expect(turnStart("autopilot.heading.setpoint")).toBe(0);
    expect(turnStart("sim.psi")).toBe(-180);
    expect(turnStart("sim.phi")).toBe(-180);
    expect(turnStart("measurement.depth")).toBeNull();
    expect(intoTurn(361, 0)).toBe(1);
    expect(intoTurn(-2, 0)).toBe(358);
    expect(intoTurn(720, 0)).toBe(0);
    expect(Object.is(intoTurn(-360, 0), 0)).toBe(true);
    expect(intoTurn(181, -180)).toBe(-179);
    expect(intoTurn(-181, -180)).toBe(179);
    expect(intoTurn(180, -180)).toBe(-180);
  });
});
