/** Parties, helms and grants for the helm tests (helm.test.ts, reactions.test.ts, protocol.test.ts). */

import type { Grant, Helm, Party, Session } from "../../src/lib/protocol";

export const ada: Party = { id: "a", name: "ada", role: "pilot" };
export const bob: Party = { id: "b", name: "bob", role: "pilot" };
export const main: Party = { id: "m", name: "main", role: "main_station" };
export const olga: Party = { id: "o", name: "olga", role: "observer" };

export const session = (p: Party): Session => ({ ...p, mode: "secure" });

export const free: Helm = {
  state: "free",
  epoch: 0,
  pilot: null,
  request: null,
  takeover: null,
  deadman_ms: 500,
  heartbeat_ms: 100,
  request_timeout_ms: 10000,
  takeover_ms: 3000,
};

export const piloted = (p: Party, epoch = 1): Helm => ({ ...free, state: "piloted", epoch, pilot: { ...p, since: 0 } });

export const requested = (p: Party, from: Party): Helm => ({
  ...piloted(p),
  state: "requested",
  request: { from, remaining_ms: 10000 },
});

export const takeover = (p: Party, by: Party, epoch = 1): Helm => ({
  ...piloted(p, epoch),
  state: "takeover",
  takeover: { by, countdown_ms: 3000 },
});

export const grant = (p: Party, epoch: number): Grant => ({
  epoch,
  pilot: { ...p, since: 0 },
  control: { mode: "motion", gain: 0.5, lights: null, laser: null, tilt: null, run_mode: null, autopilot: null, command: { surge: 0, heave: 0, yaw: 0 } },
  deadman_ms: 500,
  heartbeat_ms: 100,
});
