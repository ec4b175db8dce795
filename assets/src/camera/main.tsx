/**
 * The camera page (`/camera.html?vehicle=ID`, default the fleet's first vehicle): the vehicle's
 * picture filling the window with its health line — for a second screen, a crew monitor or a
 * projector. It joins the vehicle as any watcher does (for the camera's address, its rotation
 * and the server's clock) and shows nothing else: no HUD, no controls, it never pilots, so it
 * costs a browser the video and little more.
 */

import { render } from "preact";
import { chooseVehicle } from "../lib/choose_vehicle";
import { TelemetryClock } from "../lib/clock";
import { reasonOf } from "../lib/errors";
import { browserStorage, parseRotation } from "../lib/prefs";
import type { Rotation } from "../lib/prefs";
import type { CameraInfo } from "../lib/protocol";
import { PageSession, browserSessionEnv } from "../lib/session";
import { Store } from "../lib/store";
import { useStore } from "../lib/use_store";
import { NeptunusClient } from "../lib/vehicle_client";
import type { ConnectionStatus, VehicleChannel } from "../lib/vehicle_client";
import { loadPathChoice } from "../video/path";
import { VideoPlayer } from "../video/player";
import { takeSnapshot } from "../video/snapshots";
import { CameraFeed } from "../operator/camera_feed";
import { VideoFeed, VideoHealthLine, VideoLatency } from "../video/view";

interface CameraPageState {
  readonly vehicleId: string | null;
  readonly camera: CameraInfo | null;
  readonly joined: boolean;
  readonly rotation: Rotation;
  readonly status: ConnectionStatus;
  readonly message: string;
}

const CLOCK_MS = 10_000;

class CameraPage {
  readonly store = new Store<CameraPageState>({ vehicleId: null, camera: null, joined: false, rotation: 0, status: "connecting", message: "" });
  readonly player: VideoPlayer;
  /** plays the joined vehicle's camera, takes snapshots (the operator page's part) */
  readonly camera: CameraFeed;
  private readonly session = new PageSession(browserSessionEnv((reason) => this.store.update({ message: reason === null ? "" : `Cannot reach the server: ${reason}` })));
  private vehicle: VehicleChannel | null = null;
  private readonly clock = new TelemetryClock(() => this.vehicle);

  constructor(private readonly params: URLSearchParams) {
    this.player = new VideoPlayer({
      token: () => this.session.token,
      serverOffsetMs: () => this.clock.offset.offsetMs,
      readClock: () => this.clock.read(),
      choice: loadPathChoice(params, browserStorage()),
    });
    this.camera = new CameraFeed({
      get: () => this.store.get(),
      player: this.player,
      takeSnapshot: (vehicle) => takeSnapshot(vehicle, this.session.token),
      showMessage: (message) => this.store.update({ message }),
    });
  }

  async start(): Promise<void> {
    window.setInterval(() => this.clock.tick(performance.now()), 250);
    window.setInterval(() => this.clock.read(), CLOCK_MS);
    const session = await this.session.authenticate();
    if (session === null) return; // leaving for the login page
    const token = this.session.token;
    const client = new NeptunusClient({ name: "camera page", ...(token !== null ? { token } : {}) });
    client.socket.onError(() => void this.session.recheck());
    client.connect();
    const id = await chooseVehicle(client, this.params.get("vehicle"), (message) => this.store.update({ message }));
    if (id === null) return;
    document.title = `Neptunus — camera — ${id}`;
    this.store.update({ vehicleId: id });
    const vehicle = client.vehicle(id, {
      snapshot: (snapshot) => {
        this.store.update({ camera: snapshot.camera, joined: true, ...(snapshot.settings ? { rotation: parseRotation(snapshot.settings.camera_rotation) } : {}) });
        this.camera.show(snapshot.camera);
      },
      vehicleSettings: (settings) => this.store.update({ rotation: parseRotation(settings.camera_rotation) }),
      status: (status) => this.store.update({ status }),
    });
    this.vehicle = vehicle;
    vehicle.join().catch((err: unknown) => this.store.update({ message: `Cannot join vehicle ${id}: ${reasonOf(err)}` }));
  }
}

function CameraView({ page }: { page: CameraPage }): preact.JSX.Element {
  const s = useStore(page.store);
  const operator = s.vehicleId === null ? "/" : `/?vehicle=${encodeURIComponent(s.vehicleId)}`;
  return (
    <div class="camera-page">
      <header class="bar">
        <h1>Neptunus</h1>
        <span class="vehicle">
          Camera of{" "}
          <strong id="vehicle-id" data-testid="vehicle-id">
            {s.vehicleId ?? "—"}
          </strong>
        </span>
        <span id="status" class="status" data-testid="status" data-state={s.status} role="status">
          {s.status === "disconnected" ? "disconnected — reconnecting" : s.status}
        </span>
        <VideoLatency player={page.player} />
        <a class="dev-link" href={operator}>
          Operator page
        </a>
      </header>
      <div class="camera" data-testid="camera" data-rotation={s.rotation} data-camera={s.camera !== null ? "on" : "none"}>
        {s.camera !== null ? (
          <VideoFeed player={page.player} rotation={s.rotation} />
        ) : (
          <div class="no-camera" data-testid="no-camera">
            <strong>{s.joined ? "No camera" : "Connecting…"}</strong>
            <span>{s.joined ? "This vehicle publishes no video stream." : ""}</span>
          </div>
        )}
      </div>
      {s.camera !== null && <VideoHealthLine player={page.player} onSnapshot={() => page.camera.snapshot()} />}
      <p id="message" class="message" data-testid="message" role="alert">
        {s.message}
      </p>
    </div>
  );
}

function main(): void {
  const root = document.getElementById("app");
  if (!root) throw new Error("camera page: #app is missing from camera.html");
  const page = new CameraPage(new URLSearchParams(window.location.search));
  render(<CameraView page={page} />, root);
  page.start().catch((err: unknown) => console.error("neptunus:", err));
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
