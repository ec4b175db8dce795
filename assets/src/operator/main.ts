/**
 * Operator page: connects to the server, joins the vehicle's channel, shows its telemetry and
 * drives it from the keyboard (thesis table 7.1, motion mode).
 *
 * Safety: every change of the held keys sends the absolute axes (releasing all keys sends
 * zeros); losing window focus or hiding the page sends `stop`.
 *
 * Query parameters: `vehicle` (default: the first vehicle of the fleet), `name` (display name
 * in presence; without it the server picks `guest-XXXX`).
 */

import { KeyboardInput } from "../input/keyboard";
import type { MotionAxes } from "../input/keyboard";
import type { Pilot, Telemetry } from "../lib/protocol";
import { CommandError, NeptunusClient } from "../lib/vehicle_client";
import type { VehicleChannel } from "../lib/vehicle_client";
import { OperatorView } from "./view";

const STALE_AFTER_MS = 1000;
const FLEET_RETRY_MS = 2000;
const VEHICLE_ID = /^[A-Za-z0-9_.-]{1,64}$/;

function reasonOf(err: unknown): string {
  if (err instanceof CommandError) return err.reason;
  if (err instanceof Error) return err.message;
  return String(err);
}

function sleep(ms: number): Promise<void> {
  return new Promise((resolve) => setTimeout(resolve, ms));
}

/** `?name=`, else none: the server then names us `guest-XXXX`. */
function displayName(params: URLSearchParams): string | undefined {
  const name = (params.get("name") ?? "").trim().slice(0, 40);
  return name === "" ? undefined : name;
}

class OperatorPage {
  private readonly view: OperatorView;
  private readonly client: NeptunusClient;
  private readonly params: URLSearchParams;
  private readonly keyboard: KeyboardInput;
  private vehicle: VehicleChannel | null = null;
  private pilot: Pilot | null = null;
  private lastTelemetryAt: number | null = null;
  /** We have sent a thrust command that was not refused: blur/hidden must send `stop`. */
  private mayBePilot = false;

  constructor(doc: Document, params: URLSearchParams) {
    this.view = new OperatorView(doc);
    this.params = params;
    const name = displayName(params);
    this.client = new NeptunusClient(name === undefined ? {} : { name });
    this.keyboard = new KeyboardInput({
      onChange: (axes) => this.sendThrust(axes),
      onReset: (reason) => this.safetyStop(reason),
    });
  }

  start(): void {
    this.view.setStatus("connecting");
    this.keyboard.attach(window);
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "hidden") this.keyboard.reset("page hidden");
    });
    window.addEventListener("pagehide", () => this.keyboard.reset("page closed"));
    window.setInterval(() => this.checkTelemetryAge(), 250);
    this.client.socket.onClose(() => {
      if (!this.vehicle) this.view.setStatus("disconnected");
    });
    this.client.socket.onOpen(() => {
      if (!this.vehicle) this.view.setStatus("connecting");
    });
    this.client.connect();
    void this.chooseVehicle().then((id) => this.openVehicle(id));
  }

  private async chooseVehicle(): Promise<string> {
    const requested = this.params.get("vehicle");
    if (requested !== null) {
      if (VEHICLE_ID.test(requested)) return requested;
      this.view.showMessage(`Invalid vehicle id in the address: "${requested}"`, "error");
      return new Promise<string>(() => undefined); // nothing to connect to
    }
    for (;;) {
      try {
        const fleet = await this.client.fleet();
        const first = fleet.vehicles[0];
        if (first) {
          this.view.clearMessage("fleet");
          return first.id;
        }
        this.view.showMessage("The server has no vehicles.", "warn", "fleet");
      } catch (err) {
        this.view.showMessage(`Cannot list vehicles: ${reasonOf(err)}`, "warn", "fleet");
      }
      await sleep(FLEET_RETRY_MS);
    }
  }

  private openVehicle(id: string): void {
    this.view.setVehicle(id);
    const vehicle = this.client.vehicle(id, {
      snapshot: (snapshot) => {
        this.setPilot(snapshot.pilot);
        if (snapshot.telemetry) this.onTelemetry(snapshot.telemetry);
        this.view.clearMessage("join");
      },
      telemetry: (t) => this.onTelemetry(t),
      pilot: (p) => this.setPilot(p),
      stopped: (reason) => this.view.showMessage(`Vehicle stopped: ${reason}`, "info", "command"),
      presence: (entries) => this.view.setPresence(entries),
      status: (status) => {
        this.view.setStatus(status);
        if (status !== "connected") {
          // Key-ups may be lost and the server stops the vehicle when our socket closes;
          // the operator presses again once we are back.
          this.keyboard.reset("connection lost");
          this.mayBePilot = false;
        }
      },
      protocolError: (what, payload) => {
        console.warn(`neptunus: unexpected ${what} payload`, payload);
      },
    });
    this.vehicle = vehicle;
    this.view.setStatus(vehicle.status);
    vehicle.join().catch((err: unknown) => {
      this.view.showMessage(`Cannot join vehicle ${id}: ${reasonOf(err)}`, "error", "join");
      if (err instanceof CommandError && err.kind !== "timeout") {
        // Refused (unknown vehicle, bad reply): the client would retry forever; stop asking.
        void vehicle.leave().then(() => this.view.setStatus("disconnected"));
      }
    });
  }

  private onTelemetry(t: Telemetry): void {
    this.lastTelemetryAt = performance.now();
    this.view.showTelemetry(t);
    this.view.setTelemetryState("live");
  }

  private checkTelemetryAge(): void {
    if (this.lastTelemetryAt === null) return;
    const age = performance.now() - this.lastTelemetryAt;
    if (age > STALE_AFTER_MS) this.view.setTelemetryState("stale", age);
  }

  private setPilot(pilot: Pilot | null): void {
    this.pilot = pilot;
    this.view.setPilot(pilot);
    if (pilot === null) this.mayBePilot = false;
  }

  private sendThrust(axes: MotionAxes): void {
    const vehicle = this.vehicle;
    if (!vehicle || !vehicle.joined) {
      this.view.showMessage("Not connected: command not sent.", "warn", "command");
      return;
    }
    this.mayBePilot = true;
    vehicle.thrust(axes).then(
      () => this.view.clearMessage("command"),
      (err: unknown) => this.commandFailed("Thrust", err),
    );
  }

  private safetyStop(reason: string): void {
    const vehicle = this.vehicle;
    if (!vehicle || !vehicle.joined || !this.mayBePilot) return;
    vehicle.stop(reason).then(
      () => this.view.showMessage(`Stopped: ${reason}.`, "info", "command"),
      (err: unknown) => this.commandFailed("Stop", err),
    );
  }

  private commandFailed(what: string, err: unknown): void {
    const reason = reasonOf(err);
    if (reason === "not_in_control") {
      this.mayBePilot = false;
      const who = this.pilot ? ` (pilot: ${this.pilot.name})` : "";
      this.view.showMessage(`${what} refused: not_in_control${who}`, "error", "command");
    } else {
      this.view.showMessage(`${what} refused: ${reason}`, "error", "command");
    }
  }
}

function main(): void {
  const page = new OperatorPage(document, new URLSearchParams(window.location.search));
  page.start();
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
