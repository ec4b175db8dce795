/**
 * The operator page's heartbeat and round-trip latency. While we pilot, the pilot's `heartbeat`
 * every `heartbeat_ms` (the server's deadman); a refusal goes to the reactions (which stop it on
 * `not_in_control`). While we watch, the socket's own ping every second. Either reply is a
 * round trip for the HUD's latency (lib/latency.ts), forgotten when the connection drops. The
 * reactions (reactions.ts) switch the pilot's heartbeat on and off (`heartbeat` effect).
 */

import { reasonOf } from "../lib/errors";
import { LatencyTracker } from "../lib/latency";
import type { OperatorState } from "./state";

/** How often a watcher measures the round trip (ms). */
export const PING_MS = 1000;

/** The pilot's heartbeat (a `VehicleChannel` has it): resolves with the round trip in ms. */
export interface HeartbeatVehicle {
  readonly joined: boolean;
  heartbeat(): Promise<number>;
}

export interface HeartbeatHost {
  readonly update: (patch: Pick<OperatorState, "latency">) => void;
  /** the vehicle's channel, once opened */
  readonly vehicle: () => HeartbeatVehicle | null;
  /** we pilot now (the helm as seen) */
  readonly piloting: () => boolean;
  /** the pilot's heartbeat interval the server asks for (ms) */
  readonly intervalMs: () => number;
  /** the socket's ping (round trip in ms), or null while it is not connected */
  readonly ping: () => Promise<number> | null;
  /** the server refused a heartbeat, for `reason` */
  readonly refused: (reason: string) => void;
}

export class Heartbeat {
  private readonly host: HeartbeatHost;
  private readonly latency = new LatencyTracker();
  private beat: ReturnType<typeof setInterval> | null = null;
  private watch: ReturnType<typeof setInterval> | null = null;

  constructor(host: HeartbeatHost) {
    this.host = host;
  }

  /** Starts measuring the round trip while we watch (once, when the page starts). */
  start(): void {
    if (this.watch === null) this.watch = setInterval(() => this.pingIfWatching(), PING_MS);
  }

  /** The pilot's heartbeat on (at the interval the server asks for) or off. */
  pilot(on: boolean): void {
    if (!on) {
      if (this.beat !== null) clearInterval(this.beat);
      this.beat = null;
      return;
    }
    if (this.beat !== null) return;
    this.beat = setInterval(() => {
      const vehicle = this.host.vehicle();
      if (!vehicle || !vehicle.joined || !this.host.piloting()) return;
      vehicle.heartbeat().then(
        (rtt) => this.add(rtt),
        (err: unknown) => this.host.refused(reasonOf(err)),
      );
    }, this.host.intervalMs());
  }

  /** Forgets the round trips measured so far (the connection dropped). */
  resetLatency(): void {
    this.latency.reset();
    this.host.update({ latency: this.latency.summary });
  }

  private pingIfWatching(): void {
    if (this.beat !== null) return;
    this.host.ping()?.then(
      (rtt) => this.add(rtt),
      () => undefined,
    );
  }

  private add(rtt: number): void {
    this.latency.add(rtt);
    this.host.update({ latency: this.latency.summary });
  }
}
