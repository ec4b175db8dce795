/**
 * The operator page's logic (no DOM building here: the Preact view renders `store`).
 *
 * - Connects (login in secure mode, banner in local mode), joins the vehicle, follows its
 *   telemetry, helm, presence and link; reconnects on its own (the phoenix client) and says so
 *   while disconnected.
 * - Input: keyboard (table 7.1), touch sticks, gamepad (table 7.2, polled on animation frames)
 *   and headset (heading setpoint and camera tilt). Only the selected input mode drives the
 *   vehicle; a demand is sent when it changes, as absolute values stamped with our grant's
 *   epoch (`thrust` motion or manual).
 * - Helm: request / answer / take / release; heartbeat every `heartbeat_ms` while piloting,
 *   whose replies give the round-trip latency (watchers measure it with the socket's ping).
 * - Safety: window blur, a hidden page, closing it or changing the input mode sends `stop` (and
 *   shows it); after any stop, loss of control or grant every input is forgotten — only a fresh
 *   press, touch or stick movement moves the vehicle. Safety stops and a takeover beep.
 * - Settings (control mode, run mode, autopilot, gain, lights, laser, tilt) go to the server as
 *   typed; its `error` reason is shown beside the field.
 */

import { accepts, demandEqual, stickMode } from "../input/demand";
import type { InputMode, ThrustDemand } from "../input/demand";
import { GamepadPoller } from "../input/gamepad";
import type { GamepadOptions } from "../input/gamepad";
import { startHeadPose } from "../input/head_pose";
import type { HeadPose } from "../input/head_pose";
import { HeadsetFilter, headAngles } from "../input/headset";
import type { HeadAngles, HeadReference, Quaternion } from "../input/headset";
import { KeyboardInput, keyboardDemand } from "../input/keyboard";
import { TouchTracker, touchDemand } from "../input/touch";
import type { TouchControl, TouchState } from "../input/touch";
import { beep } from "../lib/beep";
import { ClockOffset, ageOnArrival, telemetryAge } from "../lib/clock";
import { formDegrees, formValue, isSafetyStop } from "../lib/forms";
import { HelmTracker } from "../lib/helm";
import type { HelmView } from "../lib/helm";
import { LatencyTracker } from "../lib/latency";
import type { LatencySummary } from "../lib/latency";
import {
  loadGamepadOptions,
  loadInputMode,
  loadRotation,
  saveGamepadOptions,
  saveInputMode,
  saveRotation,
} from "../lib/prefs";
import type { Rotation } from "../lib/prefs";
import { cameraWithToken } from "../lib/protocol";
import type {
  AuthMode,
  CameraInfo,
  ControlMode,
  ControlSettings,
  Helm,
  LinkStatus,
  PresenceEntry,
  Role,
  RunMode,
  Telemetry,
} from "../lib/protocol";
import { AuthError, TOKEN_KEY, fetchSession, loadToken } from "../lib/session";
import type { SessionInfo } from "../lib/session";
import { Store } from "../lib/store";
import { CommandError, NeptunusClient } from "../lib/vehicle_client";
import type { ConnectionStatus, VehicleChannel } from "../lib/vehicle_client";

export type MessageKind = "info" | "warn" | "error";
export type TelemetryState = "none" | "live" | "stale";
export type FieldName =
  | "control_mode"
  | "run_mode"
  | "depth"
  | "heading"
  | "gain"
  | "lights"
  | "laser"
  | "tilt"
  | "headset";

export interface FieldStatus {
  readonly state: "busy" | "ok" | "error";
  readonly text: string;
}

export interface HeadsetState {
  readonly status: "off" | "starting" | "webxr" | "orientation" | "error";
  readonly message: string;
  readonly reference: HeadReference | null;
  readonly angles: HeadAngles | null;
  readonly lastHeading: number | null;
  readonly lastTilt: number | null;
}

export interface OperatorState {
  readonly status: ConnectionStatus;
  /** when the connection was lost (ms, performance clock), for "reconnecting for N s" */
  readonly disconnectedAt: number | null;
  readonly vehicleId: string | null;
  readonly banner: { readonly mode: AuthMode; readonly user: { readonly name: string; readonly role: Role } | null } | null;
  readonly helm: HelmView;
  readonly pilotName: string | null;
  readonly presence: readonly PresenceEntry[];
  readonly telemetry: Telemetry | null;
  readonly telemetryState: TelemetryState;
  readonly telemetryAgeMs: number;
  readonly control: ControlSettings | null;
  readonly link: LinkStatus | null;
  readonly latency: LatencySummary;
  readonly camera: CameraInfo | null;
  readonly rotation: Rotation;
  readonly inputMode: InputMode;
  readonly gamepad: { readonly id: string; readonly armed: boolean } | null;
  readonly gamepadOptions: GamepadOptions;
  readonly touch: TouchState;
  readonly headset: HeadsetState;
  /** the last demand this page sent */
  readonly sent: ThrustDemand | null;
  readonly message: { readonly text: string; readonly kind: MessageKind; readonly source: string | null };
  readonly fields: Readonly<Partial<Record<FieldName, FieldStatus>>>;
  /** the last stop the vehicle made (reason, ms since the epoch) */
  readonly lastStop: { readonly reason: string; readonly at: number } | null;
}

const STALE_AFTER_MS = 1000;
const RETRY_MS = 2000;
const SESSION_RECHECK_MS = 5000;
const PING_MS = 1000;
/** how often the page reads the server's clock (to tell how old telemetry is on arrival) */
const CLOCK_MS = 10_000;
const VEHICLE_ID = /^[A-Za-z0-9_.-]{1,64}$/;

/** The telemetry state for data `ageMs` old: stale past STALE_AFTER_MS (its age to 0.1 s), else live. */
function freshness(ageMs: number): Pick<OperatorState, "telemetryState" | "telemetryAgeMs"> {
  return ageMs > STALE_AFTER_MS
    ? { telemetryState: "stale", telemetryAgeMs: Math.round(ageMs / 100) * 100 }
    : { telemetryState: "live", telemetryAgeMs: 0 };
}

function reasonOf(err: unknown): string {
  if (err instanceof CommandError) return err.reason;
  if (err instanceof Error) return err.message;
  return String(err);
}

function sleep(ms: number): Promise<void> {
  return new Promise((resolve) => setTimeout(resolve, ms));
}

function storage(): Storage | null {
  try {
    return window.localStorage;
  } catch {
    return null;
  }
}

/** `?name=`, else none: the server then names us `guest-XXXX`. */
function displayName(params: URLSearchParams): string | undefined {
  const name = (params.get("name") ?? "").trim().slice(0, 40);
  return name === "" ? undefined : name;
}

/** Goes to the login page (and back here after it); `reason` is shown there. */
function toLogin(reason: string | null): void {
  const next = window.location.pathname + window.location.search;
  const query = new URLSearchParams({ next });
  if (reason) query.set("reason", reason);
  window.location.assign(`/login.html?${query.toString()}`);
}

function touchFirstDevice(): boolean {
  return typeof window.matchMedia === "function" && window.matchMedia("(pointer: coarse)").matches;
}

export class OperatorController {
  readonly store: Store<OperatorState>;
  private readonly params: URLSearchParams;
  private readonly helm = new HelmTracker();
  private readonly latency = new LatencyTracker();
  private readonly keyboard: KeyboardInput;
  private readonly touch = new TouchTracker();
  private readonly gamepad: GamepadPoller;
  private readonly headsetFilter = new HeadsetFilter();
  private headPose: HeadPose | null = null;
  private headsetWatchdog: number | null = null;
  private client: NeptunusClient | null = null;
  private vehicle: VehicleChannel | null = null;
  private token: string | null = null;
  private lastTelemetryAt: number | null = null;
  /** how old the newest telemetry was when it arrived (ms; null while the clock offset is unknown) */
  private lastTelemetryLate: number | null = null;
  /** the server's clock against ours: 60 readings, 10 min, the quickest round trip wins */
  private readonly clock = new ClockOffset(60);
  private clockPending = false;
  private heartbeat: number | null = null;
  private lastSessionCheck = 0;
  private warnedTakeover = false;
  private heldKeys: ReadonlySet<string> = new Set();

  constructor(params: URLSearchParams) {
    this.params = params;
    const touchFirst = touchFirstDevice();
    this.store = new Store<OperatorState>({
      status: "connecting",
      disconnectedAt: null,
      vehicleId: null,
      banner: null,
      helm: this.helm.view(0),
      pilotName: null,
      presence: [],
      telemetry: null,
      telemetryState: "none",
      telemetryAgeMs: 0,
      control: null,
      link: null,
      latency: this.latency.summary,
      camera: null,
      rotation: 0,
      inputMode: loadInputMode(storage(), touchFirst),
      gamepad: null,
      gamepadOptions: loadGamepadOptions(storage()),
      touch: this.touch.current,
      headset: { status: "off", message: "", reference: null, angles: null, lastHeading: null, lastTilt: null },
      sent: null,
      message: { text: "", kind: "info", source: null },
      fields: {},
      lastStop: null,
    });
    this.keyboard = new KeyboardInput({
      onHeld: (held) => {
        this.heldKeys = held;
        const mode = stickMode(this.controlMode);
        if (mode) this.demand("keyboard", keyboardDemand(held, mode));
        else if (held.size > 0) this.showMessage(`Control mode ${this.controlMode}: keys are ignored.`, "warn", "command");
      },
    });
    this.gamepad = new GamepadPoller({
      source: { getGamepads: () => (typeof navigator.getGamepads === "function" ? navigator.getGamepads() : []) },
      mode: () => stickMode(this.controlMode) ?? "motion",
      options: () => this.store.get().gamepadOptions,
      onDemand: (d) => {
        if (stickMode(this.controlMode)) this.demand("gamepad", d);
      },
      onPad: (pad) => this.store.update({ gamepad: pad }),
    });
  }

  private get state(): OperatorState {
    return this.store.get();
  }

  /** The control mode the vehicle is in (motion until a server says otherwise). */
  get controlMode(): string {
    return this.state.telemetry?.control?.mode ?? this.state.control?.mode ?? "motion";
  }

  // ------------------------------------------------------------------------------------------
  // Start-up and connection

  async start(): Promise<void> {
    this.keyboard.attach(window);
    window.addEventListener("blur", () => this.safetyStop("window lost focus"));
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "hidden") this.safetyStop("page hidden");
    });
    window.addEventListener("pagehide", () => this.safetyStop("page closed"));
    window.setInterval(() => this.tick(), 250);
    window.setInterval(() => this.pingIfWatching(), PING_MS);
    window.setInterval(() => this.readClock(), CLOCK_MS);
    if (this.state.inputMode === "gamepad") this.gamepad.start();

    const session = await this.authenticate();
    const name = displayName(this.params);
    const client = new NeptunusClient({
      ...(session.mode === "local" && name !== undefined ? { name } : {}),
      ...(this.token !== null ? { token: this.token } : {}),
    });
    this.client = client;
    client.socket.onClose(() => {
      if (!this.vehicle) this.setStatus("disconnected");
    });
    client.socket.onOpen(() => {
      if (!this.vehicle) this.setStatus("connecting");
    });
    // a refused upgrade (expired or revoked token) looks like a network error from here
    client.socket.onError(() => void this.recheckSession());
    client.connect();
    const id = await this.chooseVehicle(client);
    this.openVehicle(client, id);
  }

  private setStatus(status: ConnectionStatus): void {
    const was = this.state.status;
    this.store.update({
      status,
      disconnectedAt: status === "connected" ? null : was === "connected" || this.state.disconnectedAt === null ? performance.now() : this.state.disconnectedAt,
    });
  }

  /** Who we are: the session for our stored token; the login page when one is needed. */
  private async authenticate(): Promise<SessionInfo> {
    for (;;) {
      this.token = loadToken(window.localStorage, Date.now());
      try {
        let session: SessionInfo;
        try {
          session = await fetchSession(this.token);
        } catch (err) {
          if (!(err instanceof AuthError) || err.status !== 401) throw err;
          window.localStorage.removeItem(TOKEN_KEY);
          this.token = null;
          session = await fetchSession(null);
        }
        if (session.mode === "secure" && session.user === null && !session.anonymous_observers) {
          toLogin(null);
          return new Promise<SessionInfo>(() => undefined); // leaving the page
        }
        if (session.user === null) this.token = null;
        this.store.update({ banner: { mode: session.mode, user: session.user } });
        this.clearMessage("session");
        return session;
      } catch (err) {
        this.showMessage(`Cannot reach the server: ${reasonOf(err)}`, "warn", "session");
        await sleep(RETRY_MS);
      }
    }
  }

  private async recheckSession(): Promise<void> {
    const now = Date.now();
    if (this.token === null || now - this.lastSessionCheck < SESSION_RECHECK_MS) return;
    this.lastSessionCheck = now;
    try {
      await fetchSession(this.token);
    } catch (err) {
      if (err instanceof AuthError && err.status === 401) {
        window.localStorage.removeItem(TOKEN_KEY);
        toLogin(err.message);
      }
    }
  }

  private async chooseVehicle(client: NeptunusClient): Promise<string> {
    const requested = this.params.get("vehicle");
    if (requested !== null) {
      if (VEHICLE_ID.test(requested)) return requested;
      this.showMessage(`Invalid vehicle id in the address: "${requested}"`, "error");
      return new Promise<string>(() => undefined); // nothing to connect to
    }
    for (;;) {
      try {
        const fleet = await client.fleet();
        const first = fleet.vehicles[0];
        if (first) {
          this.clearMessage("fleet");
          return first.id;
        }
        this.showMessage("The server has no vehicles.", "warn", "fleet");
      } catch (err) {
        this.showMessage(`Cannot list vehicles: ${reasonOf(err)}`, "warn", "fleet");
      }
      await sleep(RETRY_MS);
    }
  }

  private openVehicle(client: NeptunusClient, id: string): void {
    document.title = `Neptunus — ${id}`;
    this.store.update({ vehicleId: id, rotation: loadRotation(storage(), id) });
    const vehicle = client.vehicle(id, {
      snapshot: (snapshot) => {
        // a (re)join: whatever we held is gone (the server freed the helm when we left)
        this.stopHeartbeat();
        this.resetInputs();
        this.helm.reset(snapshot.helm, snapshot.session, performance.now());
        this.store.update({
          pilotName: snapshot.pilot?.name ?? null,
          camera: cameraWithToken(snapshot.camera, this.token),
          control: snapshot.control,
          sent: null,
        });
        this.renderHelm();
        if (snapshot.telemetry) this.onTelemetry(snapshot.telemetry);
        this.clearMessage("join");
      },
      telemetry: (t) => this.onTelemetry(t),
      helm: (h) => this.onHelm(h),
      controlGranted: (grant) => {
        // the reply to our request and the server's event both carry it: once is news
        if (!this.helm.onGrant(grant)) return;
        this.store.update({ pilotName: grant.pilot.name, control: grant.control });
        this.resetInputs();
        this.startHeartbeat();
        this.showMessage("You have control. The thrusters are neutral: move with the selected input.", "info", "helm");
        this.renderHelm();
      },
      controlLost: (reason) => {
        this.stopHeartbeat();
        this.resetInputs();
        this.showMessage(`You no longer have control: ${reason}`, "warn", "helm");
      },
      controlRequest: (from) => {
        beep(2, 660);
        this.showMessage(`${from.name} requests control.`, "warn", "helm");
      },
      requestDenied: (reason) => this.showMessage(`Control request refused: ${reason}`, "warn", "helm"),
      stopped: (reason) => this.onStopped(reason),
      link: (link) => {
        this.store.update({ link });
        if (!link.up) beep(2, 440);
      },
      presence: (entries) => this.store.update({ presence: entries }),
      status: (status) => {
        this.setStatus(status);
        if (status !== "connected") {
          // Key-ups may be lost and the server stops the vehicle when our socket closes;
          // the operator presses again once we are back.
          this.stopHeartbeat();
          this.resetInputs();
          this.latency.reset();
          this.store.update({ latency: this.latency.summary, sent: null });
        }
      },
      protocolError: (what, payload) => {
        console.warn(`neptunus: unexpected ${what} payload`, payload);
      },
    });
    this.vehicle = vehicle;
    this.setStatus(vehicle.status);
    vehicle.join().catch((err: unknown) => {
      this.showMessage(`Cannot join vehicle ${id}: ${reasonOf(err)}`, "error", "join");
      if (err instanceof CommandError && err.kind !== "timeout") {
        // Refused (unknown vehicle, bad reply): the client would retry forever; stop asking.
        void vehicle.leave().then(() => this.setStatus("disconnected"));
      }
    });
  }

  // ------------------------------------------------------------------------------------------
  // Vehicle events

  private onTelemetry(t: Telemetry): void {
    this.lastTelemetryAt = performance.now();
    // a slow link delivers frames that are already old: stale, though they keep coming
    this.lastTelemetryLate = ageOnArrival(t.sent_at, Date.now(), this.clock.offsetMs);
    this.store.update({
      telemetry: t,
      ...freshness(this.lastTelemetryLate ?? 0),
      ...(t.control ? { control: t.control } : {}),
      ...(t.link ? { link: t.link } : {}),
    });
  }

  private onHelm(h: Helm): void {
    const change = this.helm.onHelm(h, performance.now());
    this.store.update({ pilotName: h.pilot?.name ?? null });
    if (change.becamePilot) this.startHeartbeat();
    if (change.lostPilot) {
      this.stopHeartbeat();
      this.resetInputs();
    }
    if (change.restamped) {
      // a deadman stop: the server holds thrust neutral until a fresh command
      this.resetInputs();
      this.showMessage("Stopped by the deadman (no heartbeat): press the keys again.", "warn", "helm");
    }
    const takeover = this.helm.view(performance.now()).takeover;
    if (takeover?.concernsMe && !this.warnedTakeover) beep(3, 990);
    this.warnedTakeover = takeover !== null;
    this.renderHelm();
  }

  private onStopped(reason: string): void {
    this.store.update({ lastStop: { reason, at: Date.now() } });
    if (isSafetyStop(reason)) beep(2, 520, 120, 80);
    if (this.helm.isPilot) {
      // held input must be pressed again to count after any stop
      this.resetInputs();
    }
    this.showMessage(`Vehicle stopped: ${reason}`, isSafetyStop(reason) ? "warn" : "info", "command");
  }

  private renderHelm(): void {
    this.store.update({ helm: this.helm.view(performance.now()) });
  }

  private tick(): void {
    this.renderHelm();
    if (this.lastTelemetryAt !== null) {
      const age = telemetryAge(performance.now(), this.lastTelemetryAt, this.lastTelemetryLate);
      if (age > STALE_AFTER_MS) this.store.update(freshness(age));
    }
    // the first reading as soon as the vehicle is joined, then every CLOCK_MS
    if (this.clock.offsetMs === null) this.readClock();
  }

  private readClock(): void {
    const vehicle = this.vehicle;
    if (this.clockPending || !vehicle || !vehicle.joined) return;
    this.clockPending = true;
    vehicle.clock().then(
      (sample) => {
        this.clockPending = false;
        this.clock.add(sample);
      },
      () => {
        this.clockPending = false;
      },
    );
  }

  // ------------------------------------------------------------------------------------------
  // Heartbeat and latency

  private startHeartbeat(): void {
    if (this.heartbeat !== null) return;
    this.heartbeat = window.setInterval(() => {
      const vehicle = this.vehicle;
      if (!vehicle || !vehicle.joined || !this.helm.isPilot) return;
      vehicle.heartbeat().then(
        (rtt) => this.addLatency(rtt),
        (err: unknown) => {
          if (reasonOf(err) === "not_in_control") this.stopHeartbeat();
        },
      );
    }, this.helm.heartbeatMs);
  }

  private stopHeartbeat(): void {
    if (this.heartbeat !== null) window.clearInterval(this.heartbeat);
    this.heartbeat = null;
  }

  private pingIfWatching(): void {
    if (this.heartbeat !== null || !this.client || this.state.status !== "connected") return;
    this.client.ping().then(
      (rtt) => this.addLatency(rtt),
      () => undefined,
    );
  }

  private addLatency(rtt: number): void {
    this.latency.add(rtt);
    this.store.update({ latency: this.latency.summary });
  }

  // ------------------------------------------------------------------------------------------
  // Input

  /** A demand from `source`: sent when it is from the selected input mode and new. */
  private demand(source: InputMode, demand: ThrustDemand): void {
    if (!accepts(this.state.inputMode, source, this.controlMode)) return;
    if (demandEqual(demand, this.state.sent)) return;
    const vehicle = this.vehicle;
    if (!vehicle || !vehicle.joined) {
      this.showMessage("Not connected: command not sent.", "warn", "command");
      return;
    }
    const stamp = this.helm.stamp;
    if (stamp === null) {
      const who = this.helm.current?.pilot?.name;
      const pilots = who ? ` (${who} pilots)` : "";
      this.showMessage(`Not in control${pilots}: request control first.`, "warn", "command");
      return;
    }
    this.store.update({ sent: demand });
    const push = demand.kind === "motion" ? vehicle.thrust(demand.axes, stamp) : vehicle.thrustManual(demand.thrusters, stamp);
    push.then(
      () => this.clearMessage("command"),
      (err: unknown) => {
        if (demandEqual(this.state.sent, demand)) this.store.update({ sent: null });
        this.commandFailed("Thrust", err);
      },
    );
  }

  /** Forgets held keys, fingers and the pad's deflection: only fresh input counts. */
  private resetInputs(): void {
    this.keyboard.reset("reset", false);
    this.heldKeys = new Set();
    this.touch.reset();
    this.gamepad.reset();
    this.store.update({ touch: this.touch.current, sent: null });
  }

  /** Stops the vehicle for `reason` (when we pilot) and forgets every input. */
  safetyStop(reason: string): void {
    this.resetInputs();
    const vehicle = this.vehicle;
    if (!vehicle || !vehicle.joined || !this.helm.isPilot) return;
    vehicle.stop(reason).then(
      () => this.showMessage(`Stopped: ${reason}.`, "warn", "command"),
      (err: unknown) => this.commandFailed("Stop", err),
    );
  }

  /** The pilot's stop button. */
  stop(): void {
    this.resetInputs();
    this.vehicle?.stop("pilot_stop").catch((err: unknown) => this.commandFailed("Stop", err));
  }

  setInputMode(mode: InputMode): void {
    if (mode === this.state.inputMode) return;
    this.safetyStop("input mode changed");
    this.store.update({ inputMode: mode });
    saveInputMode(storage(), mode);
    if (mode === "gamepad") this.gamepad.start();
    else this.gamepad.stop();
    if (mode !== "headset") this.stopHeadset();
  }

  setGamepadOptions(options: GamepadOptions): void {
    this.store.update({ gamepadOptions: options });
    saveGamepadOptions(storage(), options);
  }

  touchDown(id: number, control: TouchControl, x: number, y: number, cx: number, cy: number, radius: number): void {
    if (this.touch.down(id, control, x, y, cx, cy, radius)) this.touchChanged();
  }

  touchMove(id: number, x: number, y: number): void {
    if (this.touch.move(id, x, y)) this.touchChanged();
  }

  touchUp(id: number): void {
    if (this.touch.up(id)) this.touchChanged();
  }

  private touchChanged(): void {
    const state = this.touch.current;
    this.store.update({ touch: state });
    const mode = stickMode(this.controlMode);
    if (mode) this.demand("touch", touchDemand(state, mode));
  }

  // ------------------------------------------------------------------------------------------
  // Headset

  async startHeadset(): Promise<void> {
    this.stopHeadset();
    this.updateHeadset({ status: "starting", message: "starting head tracking…" });
    try {
      const pose = await startHeadPose(
        (q) => this.onHeadPose(q),
        () => this.updateHeadset({ status: "off", message: "the headset session ended" }),
      );
      this.headPose = pose;
      this.updateHeadset({
        status: pose.source,
        message: pose.source === "webxr" ? "WebXR headset" : "waiting for the orientation sensor…",
      });
      this.headsetWatchdog = window.setTimeout(() => {
        if (this.state.headset.angles === null) {
          this.updateHeadset({ status: "error", message: "no head pose arrives: this device has no working orientation sensor" });
        }
      }, 3000);
    } catch (err) {
      this.updateHeadset({ status: "error", message: reasonOf(err) });
    }
  }

  stopHeadset(): void {
    this.headPose?.stop();
    this.headPose = null;
    if (this.headsetWatchdog !== null) window.clearTimeout(this.headsetWatchdog);
    this.headsetWatchdog = null;
    this.headsetFilter.reset();
    if (this.state.headset.status !== "off") {
      this.updateHeadset({ status: "off", message: "", reference: null, angles: null });
    }
  }

  /** Takes the current head direction as straight ahead at the vehicle's current heading. */
  captureHeadReference(): void {
    const angles = this.state.headset.angles;
    const heading = this.state.telemetry?.measurement.heading;
    if (!angles || heading === undefined || !Number.isFinite(heading)) {
      this.updateHeadset({ message: "no head pose or vehicle heading to take as reference yet" });
      return;
    }
    this.headsetFilter.reset();
    this.updateHeadset({ reference: { yaw: angles.yaw, heading }, message: "reference set: turn your head to steer" });
  }

  private onHeadPose(q: Quaternion): void {
    const angles = headAngles(q);
    const h = this.state.headset;
    const status = h.status === "orientation" && h.angles === null ? { message: "orientation sensor" } : {};
    this.updateHeadset({ angles, ...status });
    if (this.state.inputMode !== "headset" || h.reference === null || !this.helm.isPilot) return;
    const vehicle = this.vehicle;
    if (!vehicle || !vehicle.joined) return;
    const out = this.headsetFilter.update(performance.now(), h.reference, angles);
    if (out.heading !== undefined) {
      const heading = out.heading;
      this.updateHeadset({ lastHeading: heading });
      vehicle.autopilot({ heading }).then(
        (control) => {
          this.store.update({ control });
          this.setField("headset", "ok", "");
        },
        (err: unknown) => this.setField("headset", "error", `heading: ${reasonOf(err)}`),
      );
    }
    if (out.tilt !== undefined) {
      const tilt = out.tilt;
      this.updateHeadset({ lastTilt: tilt });
      vehicle.setValue("set_tilt", tilt).then(
        (control) => this.store.update({ control }),
        (err: unknown) => this.setField("headset", "error", `tilt: ${reasonOf(err)}`),
      );
    }
  }

  private updateHeadset(patch: Partial<HeadsetState>): void {
    this.store.update((s) => ({ headset: { ...s.headset, ...patch } }));
  }

  // ------------------------------------------------------------------------------------------
  // Helm actions

  requestControl(): void {
    this.vehicle
      ?.requestControl()
      .then((reply) => {
        if (reply.status === "pending") {
          const pilot = this.helm.current?.pilot?.name ?? "the pilot";
          this.showMessage(`Waiting for ${pilot} to answer…`, "info", "helm");
        }
      })
      .catch((err: unknown) => this.commandFailed("Request", err));
  }

  takeControl(): void {
    this.vehicle
      ?.takeControl()
      .then((reply) => {
        if (reply.status === "takeover") {
          this.showMessage(`Taking control in ${Math.ceil(reply.countdown_ms / 1000)} s…`, "warn", "helm");
        }
      })
      .catch((err: unknown) => this.commandFailed("Take control", err));
  }

  releaseControl(): void {
    this.vehicle?.releaseControl().catch((err: unknown) => this.commandFailed("Release", err));
  }

  answerRequest(accept: boolean): void {
    this.vehicle
      ?.answerRequest(accept)
      .then(() => this.clearMessage("helm"))
      .catch((err: unknown) => this.commandFailed("Answer", err));
  }

  signOut(): void {
    window.localStorage.removeItem(TOKEN_KEY);
  }

  // ------------------------------------------------------------------------------------------
  // Settings

  setRotation(rotation: Rotation): void {
    const id = this.state.vehicleId;
    this.store.update({ rotation });
    if (id !== null) saveRotation(storage(), id, rotation);
  }

  setControlMode(mode: ControlMode): void {
    this.resetInputs();
    this.setting("control_mode", (v) => v.setControlMode(mode));
  }

  setRunMode(mode: RunMode): void {
    this.resetInputs();
    this.setting("run_mode", (v) => v.setRunMode(mode));
  }

  /** gain, lights, laser: the value as typed; tilt typed in degrees. */
  setValue(field: "gain" | "lights" | "laser" | "tilt", text: string): void {
    const value = field === "tilt" ? formDegrees(text) : formValue(text);
    this.setting(field, (v) => v.setValue(`set_${field}`, value));
  }

  /** Depth (m) or heading (typed in degrees): a value, "hold" (keep the current) or off. */
  setAutopilot(axis: "depth" | "heading", action: "set" | "hold" | "off", text = ""): void {
    const value = action === "off" ? null : action === "hold" ? "hold" : axis === "heading" ? formDegrees(text) : formValue(text);
    this.setting(axis, (v) => v.autopilot(axis === "depth" ? { depth: value } : { heading: value }));
  }

  private setting(field: FieldName, send: (v: VehicleChannel) => Promise<ControlSettings>): void {
    const vehicle = this.vehicle;
    if (!vehicle) return;
    this.setField(field, "busy", "…");
    send(vehicle).then(
      (control) => {
        this.store.update({ control });
        this.setField(field, "ok", "✓");
      },
      (err: unknown) => this.setField(field, "error", reasonOf(err)),
    );
  }

  private setField(field: FieldName, state: FieldStatus["state"], text: string): void {
    this.store.update((s) => ({ fields: { ...s.fields, [field]: { state, text } } }));
  }

  // ------------------------------------------------------------------------------------------
  // Messages

  showMessage(text: string, kind: MessageKind, source: string | null = null): void {
    this.store.update({ message: { text, kind, source } });
  }

  clearMessage(source: string): void {
    if (this.state.message.source === source) this.showMessage("", "info", null);
  }

  private commandFailed(what: string, err: unknown): void {
    const reason = reasonOf(err);
    if (reason === "not_in_control") {
      const who = this.helm.current?.pilot?.name;
      this.showMessage(`${what} refused: not in control${who ? ` (pilot: ${who})` : ""}`, "error", "command");
    } else {
      this.showMessage(`${what} refused: ${reason}`, "error", "command");
    }
  }

  /** Keys held now (for the on-screen key hints). */
  get keysHeld(): ReadonlySet<string> {
    return this.heldKeys;
  }
}
