/** The command panel: the motion command (or manual thrusters) in force, and the control mode. */

import { PLACEHOLDER, formatFixed } from "../../lib/units";
import { fmt } from "../format";
import type { OperatorState } from "../state";
import { Panel, Readout } from "./panel";

export function CommandPanel({ s }: { s: OperatorState }): preact.JSX.Element {
  const t = s.telemetry;
  const cmd = t?.command ?? null;
  const manual = t?.manual ?? null;
  return (
    <Panel title="Command" id="cmd">
      <dl class="readouts">
        <Readout label="Surge" id="cmd-surge" value={cmd ? formatFixed(cmd.surge, 2, true) : PLACEHOLDER} />
        <Readout label="Heave" id="cmd-heave" value={cmd ? formatFixed(cmd.heave, 2, true) : PLACEHOLDER} />
        <Readout label="Yaw" id="cmd-yaw" value={cmd ? formatFixed(cmd.yaw, 2, true) : PLACEHOLDER} />
        {manual && <Readout label="Manual" id="cmd-manual" value={`P ${fmt(manual.port, 2, true)} V ${fmt(manual.vertical, 2, true)} S ${fmt(manual.starboard, 2, true)}`} />}
        <Readout label="Mode" id="control-mode" value={s.control?.mode ?? "motion"} />
      </dl>
    </Panel>
  );
}
