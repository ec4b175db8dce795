/**
 * One plot of the developer page: uPlot over the recording, any set of series overlaid.
 * Time zoom: drag to select, the mouse wheel (around the cursor) or the − / + buttons; pan:
 * shift + wheel or ◀ / ▶; "Live" follows the newest data again (double-click shows all).
 * The legend shows the values under the cursor.
 */

import { useEffect, useRef, useState } from "preact/hooks";
import uPlot from "uplot";
import { LIVE_WINDOW_S, liveRange, panRange, zoomRange } from "./ranges";
import type { SeriesRecorder } from "./recorder";
import { axisLabels, legendValue, plotData } from "./plot_data";
import { GROUP_ORDER, seriesGroup, seriesLabel } from "./series";

const COLORS = ["#4fc3f7", "#ffb74d", "#66bb6a", "#ef5350", "#ba68c8", "#fff176", "#4db6ac", "#f06292", "#90a4ae", "#aed581"];
const HEIGHT = 200;

export interface PlotProps {
  readonly id: number;
  readonly series: readonly string[];
  readonly allSeries: readonly string[];
  readonly recorder: SeriesRecorder;
  readonly dataVersion: number;
  readonly onSeries: (series: readonly string[]) => void;
  readonly onRemove: () => void;
}

export function Plot(props: PlotProps): preact.JSX.Element {
  const host = useRef<HTMLDivElement>(null);
  const plot = useRef<uPlot | null>(null);
  const [follow, setFollow] = useState(true);
  const followRef = useRef(follow);
  followRef.current = follow;
  const key = props.series.join("|");

  useEffect(() => {
    const el = host.current;
    if (!el) return undefined;
    const axis: uPlot.Axis = { stroke: "#8fa9b8", grid: { stroke: "#24445a", width: 1 }, ticks: { stroke: "#24445a", width: 1 } };
    // angles that wrap are drawn as one line; the legend (and the axis, when they all agree) read them within their turn
    const yAxis: uPlot.Axis = { ...axis, size: 60, values: (_u, splits) => axisLabels(props.series, splits).map((v) => uPlot.fmtNum(v)) };
    const opts: uPlot.Options = {
      width: Math.max(200, el.clientWidth),
      height: HEIGHT,
      scales: { x: { time: true } },
      series: [
        { label: "time" },
        ...props.series.map((k, i) => ({
          label: seriesLabel(k),
          stroke: COLORS[i % COLORS.length] ?? "#fff",
          width: 1.5,
          value: (_u: uPlot, v: number | null, _s: number, idx: number | null) => (idx === null ? "--" : v === null ? "" : uPlot.fmtNum(legendValue(k, v))),
        })),
      ],
      axes: [axis, yAxis],
      cursor: { drag: { x: true, y: false, setScale: true } },
      legend: { live: true },
      hooks: {
        setSelect: [
          (u: uPlot) => {
            if (u.select.width > 0) setFollow(false);
          },
        ],
      },
    };
    const u = new uPlot(opts, plotData(props.recorder, props.series), el);
    plot.current = u;
    const setRange = (r: { min: number; max: number }): void => {
      setFollow(false);
      u.setScale("x", r);
    };
    const wheel = (e: WheelEvent): void => {
      const min = u.scales["x"]?.min;
      const max = u.scales["x"]?.max;
      if (min === undefined || max === undefined || min === null || max === null) return;
      e.preventDefault();
      if (e.shiftKey || Math.abs(e.deltaX) > Math.abs(e.deltaY)) {
        const delta = e.shiftKey ? e.deltaY : e.deltaX;
        setRange(panRange(min, max, Math.sign(delta) * 0.1));
      } else {
        const at = u.posToVal(e.offsetX, "x");
        setRange(zoomRange(min, max, at, e.deltaY < 0 ? 0.8 : 1.25));
      }
    };
    u.over.addEventListener("wheel", wheel, { passive: false });
    const resize = new ResizeObserver(() => u.setSize({ width: Math.max(200, el.clientWidth), height: HEIGHT }));
    resize.observe(el);
    return () => {
      resize.disconnect();
      u.over.removeEventListener("wheel", wheel);
      u.destroy();
      plot.current = null;
    };
    // the chart is rebuilt when its series change; data updates go through setData below
  }, [key, props.recorder]);

  useEffect(() => {
    const u = plot.current;
    if (!u) return;
    const data = plotData(props.recorder, props.series);
    u.setData(data, false);
    const range = followRef.current ? liveRange(data[0] as number[]) : null;
    if (range) u.setScale("x", range);
    else if (!followRef.current) u.redraw(false, true);
  }, [props.dataVersion, key, follow, props.recorder]);

  const act = (f: (min: number, max: number) => { min: number; max: number }): void => {
    const u = plot.current;
    const min = u?.scales["x"]?.min;
    const max = u?.scales["x"]?.max;
    if (!u || min == null || max == null) return;
    setFollow(false);
    u.setScale("x", f(min, max));
  };

  const available = props.allSeries.filter((k) => !props.series.includes(k));
  return (
    <section class="plot" data-testid="plot" data-plot-id={props.id} data-series={props.series.join(",")}>
      <div class="plot-bar">
        <ul class="chips">
          {props.series.map((k, i) => (
            <li key={k} style={{ borderColor: COLORS[i % COLORS.length] }}>
              {seriesLabel(k)}
              <button type="button" class="chip-remove" aria-label={`remove ${k}`} onClick={() => props.onSeries(props.series.filter((s) => s !== k))}>
                ×
              </button>
            </li>
          ))}
        </ul>
        <select
          class="add-series"
          aria-label="add a series"
          value=""
          onChange={(e) => {
            const v = (e.currentTarget as HTMLSelectElement).value;
            if (v !== "") props.onSeries([...props.series, v]);
          }}
        >
          <option value="">+ series…</option>
          {GROUP_ORDER.map((g) => {
            const items = available.filter((k) => seriesGroup(k) === g);
            return items.length === 0 ? null : (
              <optgroup key={g} label={g}>
                {items.map((k) => (
                  <option key={k} value={k}>
                    {seriesLabel(k)}
                  </option>
                ))}
              </optgroup>
            );
          })}
        </select>
        <span class="plot-tools">
          <button type="button" title="earlier" onClick={() => act((a, b) => panRange(a, b, -0.25))}>
            ◀
          </button>
          <button type="button" title="later" onClick={() => act((a, b) => panRange(a, b, 0.25))}>
            ▶
          </button>
          <button type="button" title="zoom out" onClick={() => act((a, b) => zoomRange(a, b, (a + b) / 2, 2))}>
            −
          </button>
          <button type="button" title="zoom in" onClick={() => act((a, b) => zoomRange(a, b, (a + b) / 2, 0.5))}>
            +
          </button>
          <button type="button" class="live" aria-pressed={follow} title={`follow the last ${LIVE_WINDOW_S} s`} onClick={() => setFollow(true)}>
            Live
          </button>
          <button type="button" class="remove-plot" data-testid="remove-plot" title="remove this plot" onClick={props.onRemove}>
            ✕
          </button>
        </span>
      </div>
      <div class="plot-host" ref={host} />
    </section>
  );
}
