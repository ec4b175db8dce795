/** The ArduSub panel: a mavlink vehicle's own state — link, armed, flight mode, frame — and, for the pilot, Arm / Disarm. */

import { PLACEHOLDER } from "../../lib/units";
import type { PanelProps } from "./panel";
import { Panel, Readout } from "./panel";

export function ArduSubPanel({ s, c }: PanelProps): preact.JSX.Element | null {
  const m = s.link?.mavlink;
  if (!s.link || !m) return null;
  const pilot = s.helm.me === "pilot";
  return (
    <Panel title="ArduSub" id="ardusub">
      <dl class="readouts">
        <Readout label="Link" id="vehicle-link" value={s.link.up ? "up" : `down${s.link.reason ? ` (${s.link.reason})` : ""}`} />
        <div>
          <dt>State</dt>
          <dd>
            <strong id="armed" data-testid="armed" data-armed={String(m.armed)}>
              {m.armed ? "ARMED" : "disarmed"}
            </strong>
          </dd>
        </div>
        <Readout label="Mode" id="vehicle-mode" value={m.mode ?? PLACEHOLDER} />
        <Readout label="Frame" id="vehicle-frame" value={m.frame ?? PLACEHOLDER} />
      </dl>
      <div class="helm-actions" hidden={!pilot}>
        <button type="button" id="arm" data-testid="arm" disabled={m.armed || !s.link.up} onClick={() => c.helm.arm(true)}>
          Arm
        </button>
        <button type="button" id="disarm" data-testid="disarm" disabled={!m.armed} onClick={() => c.helm.arm(false)}>
          Disarm
        </button>
      </div>
    </Panel>
  );
}
