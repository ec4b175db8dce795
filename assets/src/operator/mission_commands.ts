/**
 * The pilot's missions, from the map: the waypoints planned by click or touch (kept in the
 * page's `plan` until sent), `start` (one waypoint: go there and hold it), `pause`, `resume`
 * and `abort`. The server checks every waypoint and says why it refuses one; the mission it
 * flies comes back in the reply and, for everyone, as the `mission` event (`received`).
 */

import { reasonOf } from "../lib/errors";
import type { Mission } from "../lib/protocol";
import type { VehicleChannel, WaypointOut } from "../lib/vehicle_client";
import { MAX_WAYPOINTS, planDepth, planWaypoints } from "./map";
import type { MapPoint } from "./map";
import type { MessageKind } from "./reactions";
import type { OperatorState } from "./state";

export type MissionVehicle = Pick<VehicleChannel, "mission">;

export interface MissionCommandsHost {
  readonly get: () => OperatorState;
  readonly update: (patch: Partial<OperatorState>) => void;
  /** the vehicle's channel, once opened */
  readonly vehicle: () => MissionVehicle | null;
  readonly showMessage: (text: string, kind: MessageKind, source: string) => void;
  readonly clearMessage: (source: string) => void;
}

export class MissionCommands {
  private readonly host: MissionCommandsHost;

  constructor(host: MissionCommandsHost) {
    this.host = host;
  }

  /** Adds a point to the plan (up to the server's limit). */
  add(point: MapPoint): void {
    const plan = this.host.get().plan;
    if (plan.length >= MAX_WAYPOINTS) {
      this.host.showMessage(`A mission has at most ${MAX_WAYPOINTS} waypoints.`, "warn", "mission");
      return;
    }
    this.host.update({ plan: [...plan, point] });
  }

  /** Takes the last planned point off. */
  undo(): void {
    this.host.update({ plan: this.host.get().plan.slice(0, -1) });
  }

  clear(): void {
    this.host.update({ plan: [] });
  }

  /** Flies the plan at the depth held now (a single point: go there and hold it). */
  start(): void {
    const s = this.host.get();
    const depth = planDepth(s.telemetry?.control?.autopilot?.depth ?? s.control?.autopilot?.depth, s.telemetry?.estimate?.depth);
    if (s.plan.length === 0) {
      this.host.showMessage("Plan a waypoint first: click or tap the map.", "warn", "mission");
      return;
    }
    if (depth === null) {
      this.host.showMessage("Mission refused: no depth to fly at yet.", "error", "mission");
      return;
    }
    this.send("start", planWaypoints(s.plan, depth));
  }

  pause(): void {
    this.send("pause");
  }

  resume(): void {
    this.send("resume");
  }

  abort(): void {
    this.send("abort");
  }

  /** The `mission` event (or a snapshot's mission): the mission now, null when none. */
  received(mission: Mission | null): void {
    this.host.update({ mission });
  }

  private send(action: "start" | "pause" | "resume" | "abort", waypoints?: readonly WaypointOut[]): void {
    const vehicle = this.host.vehicle();
    if (vehicle === null) return;
    vehicle.mission(action, waypoints).then(
      (reply) => {
        this.host.update(action === "start" ? { mission: reply.mission, plan: [] } : { mission: reply.mission });
        this.host.clearMessage("mission");
      },
      (err: unknown) => this.host.showMessage(`Mission ${action} refused: ${reasonOf(err)}`, "error", "mission"),
    );
  }
}
