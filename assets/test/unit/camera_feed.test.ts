import { describe, expect, it } from "vitest";
import type { CameraInfo } from "../../src/lib/protocol";
import { CameraFeed } from "../../src/operator/camera_feed";
import type { SnapshotInfo } from "../../src/video/snapshots";

const h264: CameraInfo = { codec: "h264", video: "/video/rov/websocket", url: null };

function harness(state: { vehicleId: string | null; camera: CameraInfo | null }, outcome: SnapshotInfo | Error) {
  const watched: (string | null)[] = [];
  const asked: string[] = [];
  const messages: { text: string; kind: string; source: string }[] = [];
  const feed = new CameraFeed({
    get: () => state,
    player: { watch: (path) => watched.push(path) },
    takeSnapshot: (vehicle) => {
      asked.push(vehicle);
      return outcome instanceof Error ? Promise.reject(outcome) : Promise.resolve(outcome);
    },
    showMessage: (text, kind, source) => messages.push({ text, kind, source }),
  });
  return { feed, watched, asked, messages, settled: (): Promise<void> => new Promise((r) => setTimeout(r, 0)) };
}

const saved: SnapshotInfo = { vehicle: "rov", name: "rov_20261128T105000Z_d1.20_h090.jpg", bytes: 3000, takenAt: 1, depth: 1.2, heading: 1.57 };

describe("CameraFeed", () => {
  it("plays the joined vehicle's video socket, and none when it has no camera", () => {
    const h = harness({ vehicleId: "rov", camera: h264 }, saved);
    h.feed.show(h264);
    h.feed.show(null);
    expect(h.watched).toEqual(["/video/rov/websocket", null]);
  });

  it("a snapshot is asked of the server for the shown vehicle, and its name said", async () => {
    const h = harness({ vehicleId: "rov", camera: h264 }, saved);
    h.feed.snapshot();
    expect(h.messages).toEqual([{ text: "Taking a snapshot…", kind: "info", source: "snapshot" }]);
    await h.settled();
    expect(h.asked).toEqual(["rov"]);
    expect(h.messages[1]).toEqual({ text: `Snapshot saved: ${saved.name}`, kind: "info", source: "snapshot" });
  });

  it("the server's refusal is said with its reason", async () => {
    const h = harness({ vehicleId: "rov", camera: h264 }, new Error("the camera has no picture yet"));
    h.feed.snapshot();
    await h.settled();
    expect(h.messages[1]).toEqual({ text: "Snapshot not saved: the camera has no picture yet", kind: "error", source: "snapshot" });
  });

  it("no camera (or no vehicle yet): nothing is asked, the pilot is told", () => {
    for (const state of [
      { vehicleId: "rov", camera: null },
      { vehicleId: null, camera: h264 },
    ]) {
      const h = harness(state, saved);
      h.feed.snapshot();
      expect(h.asked).toEqual([]);
      expect(h.messages).toEqual([{ text: "Snapshot: this vehicle has no camera.", kind: "warn", source: "snapshot" }]);
    }
  });
});
