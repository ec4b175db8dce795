/**
 * The operator page's connection, once the page knows who we are (`PageSession`): opens the
 * socket (with our token; in local mode named `?name=`, else the server names us
 * `guest-XXXX`), picks the vehicle — `?vehicle=ID`, else the first of the fleet that can be
 * reached, asked again every 2 s until there is one — follows the fleet for the picker and
 * the overview, and joins the vehicle's channel with the page's handlers. The phoenix client
 * reconnects on its own; the connection's status (and since when it was lost) is the page's.
 * A join the server refuses (unknown vehicle, bad reply) is not retried.
 */

import { firstVehicle } from "../lib/first_vehicle";
import { reasonOf } from "../lib/errors";
import type { AuthMode } from "../lib/protocol";
import { CommandError } from "../lib/vehicle_client";
import type { ConnectionStatus, FleetHandlers, NeptunusClient, NeptunusClientOptions, VehicleChannel, VehicleHandlers } from "../lib/vehicle_client";
import { withReachability } from "./fleet";
import type { MessageKind } from "./reactions";
import { withStatus } from "./state";
import type { OperatorState } from "./state";

/** How long to wait before asking an empty or unreachable fleet again (ms). */
export const RETRY_MS = 2000;
const VEHICLE_ID = /^[A-Za-z0-9_.-]{1,64}$/;

type ConnectionFields = "status" | "disconnectedAt" | "fleet";

export interface ConnectionHost {
  readonly get: () => Pick<OperatorState, ConnectionFields>;
  readonly update: (patch: Partial<Pick<OperatorState, ConnectionFields>>) => void;
  readonly showMessage: (text: string, kind: MessageKind, source: string | null) => void;
  readonly clearMessage: (source: string) => void;
  /** a refused upgrade (expired or revoked token) looks like a network error: ask the session */
  readonly recheck: () => void;
  /** a socket for these options (the page's: `new NeptunusClient`) */
  readonly client: (options: NeptunusClientOptions) => NeptunusClient;
  /** the vehicle `id` is about to be joined */
  readonly opening: (id: string) => void;
  /** what the page does with the vehicle's events (the status is the page's first) */
  readonly events: VehicleHandlers;
  /** monotonic clock, ms */
  readonly nowMs: () => number;
}

/** Who we are, as the session says. */
export interface Identity {
  readonly mode: AuthMode;
  readonly token: string | null;
}

export { firstVehicle };

/** `?name=`, else none: the server then names us `guest-XXXX`. */
export function displayName(params: URLSearchParams): string | undefined {
  const name = (params.get("name") ?? "").trim().slice(0, 40);
  return name === "" ? undefined : name;
}

export class OperatorConnection {
  private readonly host: ConnectionHost;
  private readonly params: URLSearchParams;
  private socket: NeptunusClient | null = null;
  private channel: VehicleChannel | null = null;

  constructor(host: ConnectionHost, params: URLSearchParams) {
    this.host = host;
    this.params = params;
  }

  /** The socket, once opened. */
  get client(): NeptunusClient | null {
    return this.socket;
  }

  /** The vehicle's channel, once chosen. */
  get vehicle(): VehicleChannel | null {
    return this.channel;
  }

  /** Opens the socket, picks the vehicle and joins it (resolves once it is being joined). */
  async open(identity: Identity): Promise<void> {
    const host = this.host;
    const name = displayName(this.params);
    const client = host.client({
      ...(identity.mode === "local" && name !== undefined ? { name } : {}),
      ...(identity.token !== null ? { token: identity.token } : {}),
    });
    this.socket = client;
    client.socket.onClose(() => {
      if (!this.channel) this.setStatus("disconnected");
    });
    client.socket.onOpen(() => {
      if (!this.channel) this.setStatus("connecting");
    });
    client.socket.onError(() => host.recheck());
    client.connect();
    const id = await this.choose(client);
    if (id !== null) this.join(client, id);
  }

  private setStatus(status: ConnectionStatus): void {
    this.host.update(withStatus(this.host.get(), status, this.host.nowMs()));
  }

  /** The vehicle to open; null when the address names one that cannot be. */
  private async choose(client: NeptunusClient): Promise<string | null> {
    const host = this.host;
    const requested = this.params.get("vehicle");
    if (requested !== null) {
      // the picker's list; the requested vehicle opens whatever it says
      client.fleet(undefined, this.fleetHandlers()).then(
        (fleet) => host.update({ fleet: fleet.vehicles }),
        () => undefined,
      );
      if (VEHICLE_ID.test(requested)) return requested;
      host.showMessage(`Invalid vehicle id in the address: "${requested}"`, "error", null);
      return null;
    }
    for (;;) {
      try {
        const fleet = await client.fleet(undefined, this.fleetHandlers());
        const first = firstVehicle(fleet.vehicles);
        host.update({ fleet: fleet.vehicles });
        if (first) {
          host.clearMessage("fleet");
          return first.id;
        }
        host.showMessage("The server has no vehicles.", "warn", "fleet");
      } catch (err) {
        host.showMessage(`Cannot list vehicles: ${reasonOf(err)}`, "warn", "fleet");
      }
      await new Promise((resolve) => setTimeout(resolve, RETRY_MS));
    }
  }

  /** The fleet overview follows the directory's updates. */
  private fleetHandlers(): FleetHandlers {
    const host = this.host;
    return {
      vehicles: (vehicles) => host.update({ fleet: vehicles }),
      reachability: (id, reachable) => host.update({ fleet: withReachability(host.get().fleet, id, reachable) }),
      protocolError: (what, payload) => console.warn(`neptunus: unexpected fleet ${what} payload`, payload),
    };
  }

  private join(client: NeptunusClient, id: string): void {
    const host = this.host;
    host.opening(id);
    const vehicle = client.vehicle(id, {
      ...host.events,
      status: (status) => {
        this.setStatus(status);
        host.events.status?.(status);
      },
    });
    this.channel = vehicle;
    this.setStatus(vehicle.status);
    vehicle.join().catch((err: unknown) => {
      host.showMessage(`Cannot join vehicle ${id}: ${reasonOf(err)}`, "error", "join");
      if (err instanceof CommandError && err.kind !== "timeout") {
        // Refused (unknown vehicle, bad reply): the client would retry forever; stop asking.
        void vehicle.leave().then(() => this.setStatus("disconnected"));
      }
    });
  }
}
