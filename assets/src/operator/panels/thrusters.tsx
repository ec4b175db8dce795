/** The thrusters panel: each thruster's command as a bar, its value and pulse width. */

import type { Thrusters } from "../../lib/protocol";
import { formatFixed } from "../../lib/units";
import { barGeometry } from "../format";
import { Panel } from "./panel";

const THRUSTERS = ["port", "vertical", "starboard"] as const;

export function ThrusterPanel({ thrusters }: { thrusters: Thrusters | null }): preact.JSX.Element {
  return (
    <Panel title="Thrusters" id="thr">
      <ul class="thrusters">
        {THRUSTERS.map((name) => {
          const value = thrusters ? thrusters[name] : Number.NaN;
          const us = thrusters ? thrusters[`${name}_us`] : Number.NaN;
          const g = barGeometry(Number.isFinite(value) ? value : 0);
          return (
            <li key={name}>
              <span class="label">{name[0]?.toUpperCase() + name.slice(1)}</span>
              <span class="meter" aria-hidden="true">
                <span class={g.reverse ? "fill reverse" : "fill"} id={`bar-${name}`} style={{ left: `${g.left}%`, width: `${g.width}%` }} />
              </span>
              <span class="value" id={`thr-${name}`} data-testid={`thr-${name}`} data-value={String(value)} title={`${Math.round(us)} µs`}>
                {formatFixed(value, 2, true)}
              </span>
            </li>
          );
        })}
      </ul>
    </Panel>
  );
}
