import { describe, expect, it } from "vitest";
import { axisLabels, legendValue, plotData } from "../../src/plots/plot_data";
import { SeriesRecorder } from "../../src/plots/recorder";
import { flattenNumeric, wrapPeriod } from "../../src/plots/series";

const rad = (d: number): number => (d * Math.PI) / 180;

/** The developer page's recording of telemetry whose heading sits near north, jittering across it. */
function nearNorth(): SeriesRecorder {
  const r = new SeriesRecorder(100, wrapPeriod);
  const headings = [359.6, 0.3, 359.8, 0.1, 359.5, 0.4, 359.9, 0.2];
  headings.forEach((h, i) =>
    r.add(i * 0.05, flattenNumeric({ measurement: { heading: rad(h), depth: 1 }, sim: { psi: rad(h > 180 ? h - 360 : h) } })),
  );
  return r;
}

describe("plotData: what a developer plot draws", () => {
  it("a steady heading near north is a line (within a degree), not a square wave between 0° and 360°", () => {
    const [, heading, depth] = plotData(nearNorth(), ["measurement.heading", "measurement.depth"]);
    const values = (heading ?? []).filter((v): v is number => typeof v === "number");
    expect(values).toHaveLength(8);
    expect(Math.max(...values) - Math.min(...values)).toBeLessThan(1);
    expect(values[0]).toBeCloseTo(359.6);
    expect(depth).toEqual([1, 1, 1, 1, 1, 1, 1, 1]);
  });

  it("the times are the samples'", () => {
    const [times] = plotData(nearNorth(), []);
    expect(times).toHaveLength(8);
    expect(times[1]).toBeCloseTo(0.05);
  });

  it("the legend reads the heading within its turn; other series as plotted", () => {
    expect(legendValue("measurement.heading", 360.3)).toBeCloseTo(0.3);
    expect(legendValue("measurement.heading", -0.5)).toBeCloseTo(359.5);
    expect(legendValue("sim.psi", 181)).toBeCloseTo(-179);
    expect(legendValue("measurement.depth", 361)).toBe(361);
  });

  it("the axis reads within the turn when every series agrees and it spans less than a turn", () => {
    expect(axisLabels(["measurement.heading", "estimate.heading"], [358, 360, 362])).toEqual([358, 0, 2]);
    expect(axisLabels(["sim.psi"], [170, 180, 190])).toEqual([170, -180, -170]);
    // a plot that mixes headings and depths, or headings and psi, reads as plotted
    expect(axisLabels(["measurement.heading", "measurement.depth"], [358, 360, 362])).toEqual([358, 360, 362]);
    expect(axisLabels(["measurement.heading", "sim.psi"], [358, 360, 362])).toEqual([358, 360, 362]);
    // several turns in view: the labels must still rise
    expect(axisLabels(["measurement.heading"], [0, 200, 400, 600])).toEqual([0, 200, 400, 600]);
    expect(axisLabels([], [1, 2])).toEqual([1, 2]);
  });
});
