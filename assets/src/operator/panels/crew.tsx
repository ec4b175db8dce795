/** The crew panel: who is connected to this vehicle, the pilot marked. */

import type { OperatorState } from "../state";
import { Panel } from "./panel";

export function CrewPanel({ s }: { s: OperatorState }): preact.JSX.Element {
  return (
    <Panel title="Crew" id="crew">
      <ul class="crew-list" data-testid="crew-list">
        {s.presence.map((e) => (
          <li key={e.key} data-pilot={e.pilot}>
            <span class="crew-mark" aria-hidden="true">{e.pilot ? "● " : "○ "}</span>
            {e.name}
            {e.role ? <small> {e.role.replace("_", " ")}</small> : null}
            {e.connections > 1 ? <small> ×{e.connections}</small> : null}
          </li>
        ))}
      </ul>
    </Panel>
  );
}
