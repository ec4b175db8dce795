/** The navigation panel: heading, depth, attitude, position, speed, power, telemetry age. */

import { ageText } from "../../lib/clock";
import { PLACEHOLDER, formatFixed, formatHeading } from "../../lib/units";
import { fmt, formatDeg } from "../format";
import type { OperatorState } from "../state";
import { Panel, Readout } from "./panel";

export function NavigationPanel({ s }: { s: OperatorState }): preact.JSX.Element {
  const t = s.telemetry;
  const est = t?.estimate ?? null;
  const age = ageText(s.telemetryState, s.telemetryAgeMs);
  return (
    <Panel title="Navigation" id="nav">
      <dl class="readouts">
        <Readout label="Heading" id="heading" value={t ? formatHeading(t.measurement.heading) : PLACEHOLDER} unit="°" />
        <Readout label="Depth" id="depth" value={t ? formatFixed(t.measurement.depth, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Roll" id="roll" value={formatDeg(t?.measurement.roll, true)} unit="°" />
        <Readout label="Pitch" id="pitch" value={formatDeg(t?.measurement.pitch, true)} unit="°" />
        <Readout label="Position x" id="x" value={t?.sim ? formatFixed(t.sim.x, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Position y" id="y" value={t?.sim ? formatFixed(t.sim.y, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Speed u" id="speed-u" value={t?.sim ? formatFixed(t.sim.u, 2) : PLACEHOLDER} unit="m/s" />
        <Readout label="Voltage" id="voltage" value={fmt(t?.measurement.voltage, 1)} unit="V" />
        <Readout label="Current" id="current" value={fmt(t?.measurement.current, 2)} unit="A" />
        {est && <Readout label="Est. depth rate" id="depth-rate" value={fmt(est.depth_rate, 2, true)} unit="m/s" />}
        {t?.wild_points && <Readout label="Wild points" id="wild-points" value={String(t.wild_points.total)} />}
        <div>
          <dt>Telemetry</dt>
          <dd>
            <span id="telemetry-age" data-testid="telemetry-age" data-state={s.telemetryState}>
              {age}
            </span>
          </dd>
        </div>
      </dl>
    </Panel>
  );
}
