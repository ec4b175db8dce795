/** Telemetry for the operator page's tests (operator_state.test.ts, map.test.ts). */

import { decodeTelemetry } from "../../src/lib/protocol";
import type { Telemetry } from "../../src/lib/protocol";

/** A decoded telemetry message of a vehicle at 1 m, heading 0.5 rad, at rest; `extra` fields added. */
export function telemetry(extra: Record<string, unknown> = {}): Telemetry {
  const t = decodeTelemetry({
    t: 1,
    sent_at: 1000,
    measurement: { depth: 1, heading: 0.5, roll: 0, pitch: 0, voltage: 12, current: 1 },
    command: { surge: 0, heave: 0, yaw: 0 },
    thrusters: { port: 0, vertical: 0, starboard: 0, port_us: 1500, vertical_us: 1500, starboard_us: 1500 },
    sim: null,
    ...extra,
  });
  if (t === null) throw new Error("test telemetry does not decode");
  return t;
}
