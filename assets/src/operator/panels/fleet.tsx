/** The fleet panel (when there is more than one vehicle): every vehicle, live; a row opens it. */

import { overviewRows } from "../fleet";
import type { OperatorState } from "../state";
import { Panel } from "./panel";

/**
 * Every vehicle of the fleet with depth, heading, pilot, link, REC, node and status, live;
 * a click or a tap opens it (`?vehicle=ID`). Rows are links: big enough for a finger.
 */
export function FleetPanel({ s }: { s: OperatorState }): preact.JSX.Element {
  const rows = overviewRows(s.fleet, s.vehicleId, window.location.search);
  return (
    <Panel title="Fleet" id="fleet">
      <ul class="fleet-list" id="fleet-overview" data-testid="fleet-overview">
        {rows.map((r) => (
          <li key={r.id}>
            <a
              class="fleet-row"
              href={r.href}
              data-vehicle={r.id}
              data-status={r.status}
              aria-current={r.current ? "page" : undefined}
              title={r.summary}
            >
              <span class="fleet-name">
                <strong>{r.id}</strong> <small class="fleet-node">{r.node}</small>
                {r.rec ? (
                  <span class="fleet-rec" data-testid="fleet-rec">
                    {" "}
                    REC
                  </span>
                ) : null}
              </span>
              {r.status === "unreachable" ? (
                <span class="fleet-status" data-field="status">
                  unreachable
                </span>
              ) : (
                <span class="fleet-fields">
                  <span data-field="depth">{r.depth}</span>
                  <span data-field="heading">{r.heading}</span>
                  <span data-field="pilot">{r.pilot}</span>
                  <span data-field="link" data-up={r.linkUp === null ? undefined : String(r.linkUp)}>
                    link {r.link}
                  </span>
                </span>
              )}
            </a>
          </li>
        ))}
      </ul>
    </Panel>
  );
}
