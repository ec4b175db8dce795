/**
 * Part: the vehicle's camera on the operator page — its picture played over this server's
 * video socket (the `VideoPlayer`, src/video/player.ts, which the camera area, the health line
 * and the HUD's latency show) and the pilot's snapshots (the health line's Snapshot button and
 * the gamepad's `snapshot` action).
 */

import { reasonOf } from "../lib/errors";
import type { CameraInfo } from "../lib/protocol";
import type { SnapshotInfo } from "../video/snapshots";
import type { MessageKind } from "./reactions";
import type { OperatorState } from "./state";

export interface CameraFeedHost {
  readonly get: () => Pick<OperatorState, "vehicleId" | "camera">;
  /** the player of the video socket (src/video/player.ts) */
  readonly player: { watch(path: string | null): void };
  /** asks the server to save the vehicle's current picture (`POST /api/vehicles/ID/snapshot`) */
  readonly takeSnapshot: (vehicle: string) => Promise<SnapshotInfo>;
  readonly showMessage: (text: string, kind: MessageKind, source: string) => void;
}

export class CameraFeed {
  constructor(private readonly host: CameraFeedHost) {}

  /**
   * The joined vehicle's camera, as its snapshot names it: its video socket is played (the same
   * one again changes nothing; none stops the player). The player adds the login token itself.
   */
  show(camera: CameraInfo | null): void {
    this.host.player.watch(camera?.video ?? null);
  }

  /** The camera's current picture saved on the server, next to the recordings; the outcome is said. */
  snapshot(): void {
    const { vehicleId, camera } = this.host.get();
    if (vehicleId === null || camera === null) {
      this.host.showMessage("Snapshot: this vehicle has no camera.", "warn", "snapshot");
      return;
    }
    this.host.showMessage("Taking a snapshot…", "info", "snapshot");
    this.host.takeSnapshot(vehicleId).then(
      (info) => this.host.showMessage(`Snapshot saved: ${info.name}`, "info", "snapshot"),
      (err: unknown) => this.host.showMessage(`Snapshot not saved: ${reasonOf(err)}`, "error", "snapshot"),
    );
  }
}
