/**
 * The map panel: where the vehicle is (north up, metres in its position's frame) with its 1-σ
 * ellipse and track, DP's target, the mission's waypoints and the pilot's plan; the position
 * sources' states; and, for the pilot, a mission planned by clicking or tapping the map.
 * What it computes is map.ts (pure); what it sends goes through `c.missions`.
 */

import { formatFixed } from "../../lib/units";
import { ellipseOnScreen, fitView, fromScreen, gridLines, pointsOnMap, positionOf, positionText, sourceText, toScreen } from "../map";
import type { MapPoint, MapView } from "../map";
import { Panel } from "./panel";
import type { PanelProps } from "./panel";

/** the drawing's own size (px); the SVG scales it to the panel's width */
const WIDTH = 480;
const HEIGHT = 300;

function polyline(view: MapView, points: readonly MapPoint[]): string {
  return points
    .map((p) => toScreen(view, p))
    .map(({ x, y }) => `${x.toFixed(1)},${y.toFixed(1)}`)
    .join(" ");
}

function Vehicle({ view, at, heading }: { view: MapView; at: MapPoint; heading: number }): preact.JSX.Element {
  const { x, y } = toScreen(view, at);
  const deg = Number.isFinite(heading) ? (heading * 180) / Math.PI : 0;
  return (
    <g data-testid="map-vehicle" transform={`translate(${x.toFixed(1)} ${y.toFixed(1)}) rotate(${deg.toFixed(1)})`}>
      <path d="M 0 -10 L 6 7 L 0 3 L -6 7 Z" class="map-vehicle" />
    </g>
  );
}

export function MapPanel({ s, c }: PanelProps): preact.JSX.Element {
  const t = s.telemetry;
  const position = t?.position ?? null;
  const dp = t?.autopilot?.position ?? null;
  const here = positionOf(position);
  const view = fitView(pointsOnMap(s.track, position, dp, s.mission, s.plan), WIDTH, HEIGHT);
  const lines = gridLines(view);
  const ellipse = position ? ellipseOnScreen(view, position) : null;
  const said = positionText(position);
  const pilot = s.helm.me === "pilot" && s.status === "connected";
  const mission = s.mission;
  const running = mission?.state === "running";
  const paused = s.mission?.state === "paused";

  const onMapClick = (e: MouseEvent): void => {
    if (!pilot) return;
    const svg = e.currentTarget as SVGSVGElement;
    const box = svg.getBoundingClientRect();
    if (box.width === 0 || box.height === 0) return;
    const x = ((e.clientX - box.left) / box.width) * WIDTH;
    const y = ((e.clientY - box.top) / box.height) * HEIGHT;
    c.missions.add(fromScreen(view, x, y));
  };

  const target = dp && dp.x !== null && dp.y !== null ? toScreen(view, { north: dp.x, east: dp.y }) : null;
  const guidance = dp?.mission ?? null;

  return (
    <Panel title="Map" id="map" class="map-panel">
      <p
        class="map-position"
        data-testid="position-text"
        id="position-text"
        data-valid={String(said.valid)}
        data-north={here?.north ?? ""}
        data-east={here?.east ?? ""}
      >
        {said.text}
      </p>
      <svg
        class={`map${pilot ? " editable" : ""}`}
        data-testid="map"
        id="map"
        viewBox={`0 0 ${WIDTH} ${HEIGHT}`}
        data-centre-north={view.centre.north}
        data-centre-east={view.centre.east}
        data-scale={view.scale}
        role="img"
        aria-label={pilot ? "Map: click or tap to add a waypoint" : "Map"}
        onClick={onMapClick}
      >
        <rect x="0" y="0" width={WIDTH} height={HEIGHT} class="map-water" />
        {lines.north.map((n) => {
          const { y } = toScreen(view, { north: n, east: view.centre.east });
          return <line key={`n${n}`} x1="0" x2={WIDTH} y1={y} y2={y} class="map-grid" />;
        })}
        {lines.east.map((e) => {
          const { x } = toScreen(view, { north: view.centre.north, east: e });
          return <line key={`e${e}`} x1={x} x2={x} y1="0" y2={HEIGHT} class="map-grid" />;
        })}
        <text x="6" y={HEIGHT - 6} class="map-scale" data-testid="map-grid">
          grid {view.grid} m · N ↑
        </text>
        {s.track.points.length > 1 && (
          <polyline points={polyline(view, s.track.points)} class="map-track" data-testid="map-track" data-points={s.track.points.length} />
        )}
        {mission && (
          <g data-testid="map-mission" data-state={mission.state} data-leg={mission.leg}>
            <polyline points={polyline(view, here ? [here, ...mission.waypoints.slice(mission.leg - 1)] : mission.waypoints)} class="map-mission" />
            {mission.waypoints.map((w, i) => {
              const { x, y } = toScreen(view, w);
              return (
                <g key={`w${i}`} data-testid="map-waypoint" class={i + 1 < mission.leg ? "map-waypoint done" : "map-waypoint"}>
                  <circle cx={x} cy={y} r={Math.max(w.radius * view.scale, 4)} />
                  <text x={x + 6} y={y - 6}>
                    {i + 1}
                  </text>
                </g>
              );
            })}
          </g>
        )}
        {s.plan.length > 0 && (
          <g data-testid="map-plan">
            <polyline points={polyline(view, here ? [here, ...s.plan] : s.plan)} class="map-plan" />
            {s.plan.map((p, i) => {
              const { x, y } = toScreen(view, p);
              return (
                <g key={`p${i}`} data-testid="map-plan-point" class="map-plan-point">
                  <circle cx={x} cy={y} r="5" />
                  <text x={x + 6} y={y - 6}>
                    {i + 1}
                  </text>
                </g>
              );
            })}
          </g>
        )}
        {target && (
          <g data-testid="map-target" class="map-target">
            <line x1={target.x - 7} x2={target.x + 7} y1={target.y} y2={target.y} />
            <line x1={target.x} x2={target.x} y1={target.y - 7} y2={target.y + 7} />
          </g>
        )}
        {ellipse && (
          <ellipse
            data-testid="map-ellipse"
            class="map-ellipse"
            cx={ellipse.cx}
            cy={ellipse.cy}
            rx={Math.max(ellipse.rx, 0.5)}
            ry={Math.max(ellipse.ry, 0.5)}
            transform={`rotate(${ellipse.rotate.toFixed(1)} ${ellipse.cx.toFixed(1)} ${ellipse.cy.toFixed(1)})`}
          />
        )}
        {here && <Vehicle view={view} at={here} heading={t?.estimate?.heading ?? Number.NaN} />}
        {!said.valid && (
          <text x={WIDTH / 2} y={HEIGHT / 2} class="map-none" text-anchor="middle">
            no position
          </text>
        )}
      </svg>
      <dl class="readouts map-readouts">
        <div>
          <dt>DP</dt>
          <dd>
            <span id="dp-phase" data-testid="dp-phase">
              {dp ? dp.phase ?? "—" : "off"}
            </span>
          </dd>
        </div>
        <div>
          <dt>Distance</dt>
          <dd>
            <span id="dp-distance" data-testid="dp-distance">
              {dp?.distance != null ? formatFixed(dp.distance, 2) : "—"}
            </span>
            <span class="unit">m</span>
          </dd>
        </div>
        <div>
          <dt>Cross-track</dt>
          <dd>
            <span id="cross-track" data-testid="cross-track">
              {guidance?.cross_track != null ? formatFixed(guidance.cross_track, 2) : "—"}
            </span>
            <span class="unit">m</span>
          </dd>
        </div>
        <div>
          <dt>Mission</dt>
          <dd>
            <span id="mission-state" data-testid="mission-state" data-state={s.mission?.state ?? "none"}>
              {mission ? `${mission.state} ${mission.leg}/${mission.waypoints.length}` : "none"}
            </span>
          </dd>
        </div>
      </dl>
      <div class="map-actions">
        <button type="button" id="map-start" data-testid="map-start" disabled={!pilot || s.plan.length === 0} onClick={() => c.missions.start()}>
          {s.plan.length === 1 ? "Go there and hold" : s.plan.length === 0 ? "Start mission" : `Start mission (${s.plan.length})`}
        </button>
        <button type="button" id="map-undo" data-testid="map-undo" disabled={s.plan.length === 0} onClick={() => c.missions.undo()}>
          Undo
        </button>
        <button type="button" id="map-clear" data-testid="map-clear" disabled={s.plan.length === 0} onClick={() => c.missions.clear()}>
          Clear
        </button>
        <button type="button" id="map-pause" data-testid="map-pause" disabled={!pilot || !running} onClick={() => c.missions.pause()}>
          Pause
        </button>
        <button type="button" id="map-resume" data-testid="map-resume" disabled={!pilot || !paused} onClick={() => c.missions.resume()}>
          Resume
        </button>
        <button type="button" id="map-abort" data-testid="map-abort" disabled={!pilot || !(running || paused)} onClick={() => c.missions.abort()}>
          Abort
        </button>
      </div>
      <ul class="map-sources" data-testid="position-sources">
        {(position?.sources ?? []).map((src) => (
          <li key={src.name} data-testid={`source-${src.name}`} data-state={src.state}>
            {sourceText(src)}
          </li>
        ))}
        {position && (position.sources ?? []).length === 0 && <li data-testid="source-none">no position source configured</li>}
      </ul>
      <p class="help">{pilot ? "In DP: click or tap the map to plan waypoints at the depth held; one waypoint is go there and hold it." : "Request control to plan missions."}</p>
    </Panel>
  );
}
