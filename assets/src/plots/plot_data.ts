/**
 * What one plot of the developer page draws (pure): the recording's times and, for each
 * series, its values as plotted — degrees for angles, and an angle that wraps as one
 * continuous line (`SeriesRecorder.line`), so a steady heading near north is a line and a
 * turn through north does not jump by a whole turn. The legend reads such an angle back
 * within its turn (a heading of 361° reads 1°), and so does the axis when every series of
 * the plot reads in the same turn.
 */

import type uPlot from "uplot";
import type { SeriesRecorder } from "./recorder";
import { displayValue, intoTurn, turnStart } from "./series";

export function plotData(recorder: SeriesRecorder, series: readonly string[]): uPlot.AlignedData {
  return [recorder.times(), ...series.map((k) => recorder.line(k, (v) => displayValue(k, v)))];
}

/** How `path`'s plotted value reads in the legend. */
export function legendValue(path: string, value: number): number {
  const start = turnStart(path);
  return start === null ? value : intoTurn(value, start);
}

/**
 * The y axis' labels at `splits` (plotted values): within the turn when every one of `series`
 * is an angle read in the same turn and the axis spans less than a turn (so the labels still
 * rise); else as plotted.
 */
export function axisLabels(series: readonly string[], splits: readonly number[]): number[] {
  const starts = new Set(series.map(turnStart));
  const [start] = starts;
  const span = splits.length === 0 ? 0 : Math.max(...splits) - Math.min(...splits);
  if (starts.size !== 1 || start === undefined || start === null || span >= 360) return [...splits];
  return splits.map((v) => intoTurn(v, start));
}
