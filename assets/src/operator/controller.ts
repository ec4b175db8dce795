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
 *   These reactions are decided by `react` (reactions.ts, pure); this class carries out its
 *   effects (`perform`). Session handling is `PageSession` (lib/session.ts), head tracking
 *   `HeadsetInput` (headset.ts).
 * - Settings (control mode, run mode, autopilot, gain, lights, laser, tilt) go to the server as
 *   typed; its `error` reason is shown beside the field.
 * - Gamepad buttons (input/buttons.ts): the pad is read in every input mode (its sticks drive
 *   only in gamepad mode); each press runs its action once (steps repeat while held, at most
 *   every `repeatMs`). The mapping is the user's, kept on the server (`gamepad.mapping`,
 *   lib/settings.ts); the editor assigns an action to the next button pressed.
 */

import { accepts, demandEqual, stickMode } from "../input/demand";
import type { InputMode, ThrustDemand } from "../input/demand";
import { ACTION_LABELS, DEFAULT_MAPPING, REPEATING, actionFor, assign, buttonCommand, encodeMapping, parseMapping, unassign, withRepeatMs } from "../input/buttons";
import type { ButtonAction, ButtonMapping } from "../input/buttons";
import { GamepadPoller } from "../input/gamepad";
import type { GamepadOptions } from "../input/gamepad";
import { KeyboardInput, keyboardDemand } from "../input/keyboard";
import { TouchTracker, touchDemand } from "../input/touch";
import type { TouchControl, TouchState } from "../input/touch";
import { beep } from "../lib/beep";
import { TelemetryClock } from "../lib/clock";
import type { TelemetryState } from "../lib/clock";
import { reasonOf } from "../lib/errors";
import { formDegrees, formValue } from "../lib/forms";
import { heartbeatMsOf, isPilot, seenView, stampOf } from "../lib/helm";
import type { HelmView } from "../lib/helm";
import { LatencyTracker } from "../lib/latency";
import type { LatencySummary } from "../lib/latency";
import {
  loadGamepadOptions,
  loadInputMode,
  loadRotation,
  saveGamepadOptions,
  saveInputMode,
  parseRotation,
} from "../lib/prefs";
import type { Rotation } from "../lib/prefs";
import { cameraWithToken } from "../lib/protocol";
import type {
  AuthMode,
  CameraInfo,
  ControlMode,
  ControlSettings,
  LinkStatus,
  PresenceEntry,
  Role,
  RunMode,
  Telemetry,
  VehicleInfo,
} from "../lib/protocol";
import { PageSession, browserSessionEnv } from "../lib/session";
import { GAMEPAD_MAPPING_KEY, SettingsClient, notKept } from "../lib/settings";
import { Store } from "../lib/store";
import { CommandError, NeptunusClient } from "../lib/vehicle_client";
import type { ConnectionStatus, FleetHandlers, VehicleChannel } from "../lib/vehicle_client";
import { withReachability } from "./fleet";
import { HEADSET_OFF, HeadsetInput } from "./headset";
import type { HeadsetState } from "./headset";
import { INITIAL_REACTIONS, TONES, isNewGrant, react } from "./reactions";
import { loadPathChoice } from "../video/path";
import { VideoPlayer } from "../video/player";
import { takeSnapshot } from "../video/snapshots";
import type { Effect, MessageKind, ReactionEvent, ReactionState } from "./reactions";

export type { TelemetryState };
export type FieldName =
  | "control_mode"
  | "run_mode"
  | "depth"
  | "heading"
  | "gain"
  | "lights"
  | "laser"
  | "tilt"
  | "rotation"
  | "headset";

/** Where the button mapping stands: read from the server, saved, or why not. */
export interface MappingStatus {
  readonly state: "loading" | "default" | "stored" | "saving" | "saved" | "not_kept" | "error";
  readonly text: string;
}

export interface FieldStatus {
  readonly state: "busy" | "ok" | "error";
  readonly text: string;
}

export interface OperatorState {
  readonly status: ConnectionStatus;
  /** when the connection was lost (ms, performance clock), for "reconnecting for N s" */
  readonly disconnectedAt: number | null;
  readonly vehicleId: string | null;
  /** every vehicle of the fleet, for the picker (empty until listed) */
  readonly fleet: readonly VehicleInfo[];
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
  readonly buttonMapping: ButtonMapping;
  readonly mappingStatus: MappingStatus;
  /** the action the editor assigns to the next button pressed (null: none) */
  readonly learning: ButtonAction | null;
  /** the last button pressed and what it did */
  readonly lastPress: { readonly button: number; readonly action: ButtonAction | null } | null;
  readonly touch: TouchState;
  readonly headset: HeadsetState;
  /** the last demand this page sent */
  readonly sent: ThrustDemand | null;
  readonly message: { readonly text: string; readonly kind: MessageKind; readonly source: string | null };
  readonly fields: Readonly<Partial<Record<FieldName, FieldStatus>>>;
  /** the last stop the vehicle made (reason, ms since the epoch) */
  readonly lastStop: { readonly reason: string; readonly at: number } | null;
}

const RETRY_MS = 2000;
const PING_MS = 1000;
/** how often the page reads the server's clock (to tell how old telemetry is on arrival) */
const CLOCK_MS = 10_000;
const VEHICLE_ID = /^[A-Za-z0-9_.-]{1,64}$/;

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

function touchFirstDevice(): boolean {
  return typeof window.matchMedia === "function" && window.matchMedia("(pointer: coarse)").matches;
}

export class OperatorController {
  readonly store: Store<OperatorState>;
  private readonly params: URLSearchParams;
  /** the helm as seen, the heartbeat, the takeover warning: see reactions.ts */
  private reactions: ReactionState = INITIAL_REACTIONS;
  private readonly latency = new LatencyTracker();
  private readonly keyboard: KeyboardInput;
  private readonly touch = new TouchTracker();
  private readonly gamepad: GamepadPoller;
  private readonly headset: HeadsetInput;
  private readonly session: PageSession;
  private client: NeptunusClient | null = null;
  private vehicle: VehicleChannel | null = null;
  /** how old the newest telemetry is, on the server's clock */
  private readonly clock = new TelemetryClock(() => this.vehicle);
  private heartbeat: number | null = null;
  private heldKeys: ReadonlySet<string> = new Set();
  private readonly settings: SettingsClient;
  /** the brightness the lights come back to when a button turns them on */
  private lightsOn = 255;
  /** the vehicle's camera over the video socket (src/video/) */
  readonly video: VideoPlayer;

  constructor(params: URLSearchParams) {
    this.params = params;
    const touchFirst = touchFirstDevice();
    this.store = new Store<OperatorState>({
      status: "connecting",
      disconnectedAt: null,
      vehicleId: null,
      fleet: [],
      banner: null,
      helm: seenView(INITIAL_REACTIONS.helm, 0),
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
      buttonMapping: DEFAULT_MAPPING,
      mappingStatus: { state: "loading", text: "" },
      learning: null,
      lastPress: null,
      touch: this.touch.current,
      headset: HEADSET_OFF,
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
      onPress: (button) => this.onButton(button),
      repeats: (button) => {
        const action = actionFor(this.state.buttonMapping, button);
        return action !== null && REPEATING.has(action);
      },
      repeatMs: () => this.state.buttonMapping.repeatMs,
    });
    this.headset = new HeadsetInput({
      get: () => this.state.headset,
      update: (patch) => this.store.update((s) => ({ headset: { ...s.headset, ...patch } })),
      vehicleHeading: () => this.state.telemetry?.measurement.heading,
      steering: () => {
        const vehicle = this.vehicle;
        return this.state.inputMode === "headset" && isPilot(this.reactions.helm) && vehicle && vehicle.joined ? vehicle : null;
      },
      nowMs: () => performance.now(),
      onControl: (control) => this.store.update({ control }),
      onResult: (error) => (error === null ? this.setField("headset", "ok", "") : this.setField("headset", "error", error)),
    });
    this.session = new PageSession(
      browserSessionEnv((reason) =>
        reason === null ? this.clearMessage("session") : this.showMessage(`Cannot reach the server: ${reason}`, "warn", "session"),
      ),
    );
    this.settings = new SettingsClient(() => this.session.token);
    this.video = new VideoPlayer({
      token: () => this.session.token,
      serverOffsetMs: () => this.clock.offset.offsetMs,
      readClock: () => this.clock.read(),
      choice: loadPathChoice(params, storage()),
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
    window.setInterval(() => this.clock.read(), CLOCK_MS);
    // buttons act in every input mode; the sticks only in gamepad mode (`accepts`)
    this.gamepad.start();

    const session = await this.session.authenticate();
    if (session === null) return; // leaving for the login page
    this.store.update({ banner: { mode: session.mode, user: session.user } });
    void this.loadMapping();
    const token = this.session.token;
    const name = displayName(this.params);
    const client = new NeptunusClient({
      ...(session.mode === "local" && name !== undefined ? { name } : {}),
      ...(token !== null ? { token } : {}),
    });
    this.client = client;
    client.socket.onClose(() => {
      if (!this.vehicle) this.setStatus("disconnected");
    });
    client.socket.onOpen(() => {
      if (!this.vehicle) this.setStatus("connecting");
    });
    // a refused upgrade (expired or revoked token) looks like a network error from here
    client.socket.onError(() => void this.session.recheck());
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

  private async chooseVehicle(client: NeptunusClient): Promise<string> {
    const requested = this.params.get("vehicle");
    if (requested !== null) {
      // the picker's list; the requested vehicle opens whatever it says
      client.fleet(undefined, this.fleetHandlers()).then(
        (fleet) => this.store.update({ fleet: fleet.vehicles }),
        () => undefined,
      );
      if (VEHICLE_ID.test(requested)) return requested;
      this.showMessage(`Invalid vehicle id in the address: "${requested}"`, "error");
      return new Promise<string>(() => undefined); // nothing to connect to
    }
    for (;;) {
      try {
        const fleet = await client.fleet(undefined, this.fleetHandlers());
        // the first vehicle that can be reached (one whose node of the fleet is cut off cannot be joined)
        const first = fleet.vehicles.find((v) => v.status !== "unreachable") ?? fleet.vehicles[0];
        this.store.update({ fleet: fleet.vehicles });
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

  /** The fleet overview follows the directory's updates. */
  private fleetHandlers(): FleetHandlers {
    return {
      vehicles: (vehicles) => this.store.update({ fleet: vehicles }),
      reachability: (id, reachable) => this.store.update({ fleet: withReachability(this.state.fleet, id, reachable) }),
      protocolError: (what, payload) => console.warn(`neptunus: unexpected fleet ${what} payload`, payload),
    };
  }

  private openVehicle(client: NeptunusClient, id: string): void {
    document.title = `Neptunus — ${id}`;
    // the camera rotation is the vehicle's (the server's settings); the browser's earlier
    // per-vehicle choice shows only until the server's comes (an older server sends none)
    this.store.update({ vehicleId: id, rotation: loadRotation(storage(), id) });
    const vehicle = client.vehicle(id, {
      snapshot: (snapshot) => {
        if (snapshot.settings) this.store.update({ rotation: parseRotation(snapshot.settings.camera_rotation) });
        this.dispatch({ type: "joined", helm: snapshot.helm, session: snapshot.session, atMs: performance.now() });
        this.store.update({
          pilotName: snapshot.pilot?.name ?? null,
          camera: cameraWithToken(snapshot.camera, this.session.token),
          control: snapshot.control,
          sent: null,
        });
        this.video.watch(snapshot.camera?.video ?? null);
        if (snapshot.telemetry) this.onTelemetry(snapshot.telemetry);
      },
      telemetry: (t) => this.onTelemetry(t),
      vehicleSettings: (settings) => this.store.update({ rotation: parseRotation(settings.camera_rotation) }),
      helm: (h) => {
        this.store.update({ pilotName: h.pilot?.name ?? null });
        this.dispatch({ type: "helm", helm: h, atMs: performance.now() });
      },
      controlGranted: (grant) => {
        if (isNewGrant(this.reactions, grant)) this.store.update({ pilotName: grant.pilot.name, control: grant.control });
        this.dispatch({ type: "granted", grant });
      },
      controlLost: (reason) => this.dispatch({ type: "lost", reason }),
      controlRequest: (from) => this.dispatch({ type: "request", from }),
      requestDenied: (reason) => this.dispatch({ type: "denied", reason }),
      stopped: (reason) => {
        this.store.update({ lastStop: { reason, at: Date.now() } });
        this.dispatch({ type: "stopped", reason });
      },
      link: (link) => {
        this.store.update({ link });
        this.dispatch({ type: "link", up: link.up });
      },
      vehicleAnswer: (answer) => this.vehicleAnswer(answer.command, answer.ok ? null : (answer.reason ?? "refused")),
      // the vehicle runs on another node of the fleet, now cut off from this one (or back)
      reachability: (reachable, node) => {
        if (reachable) this.clearMessage("unreachable");
        else this.showMessage(`Vehicle unreachable: its node ${node} is cut off from this server.`, "error", "unreachable");
      },
      presence: (entries) => this.store.update({ presence: entries }),
      status: (status) => {
        this.setStatus(status);
        if (status !== "connected") this.dispatch({ type: "disconnected" });
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
    this.store.update({
      telemetry: t,
      ...this.clock.received(t.sent_at, performance.now(), Date.now()),
      ...(t.control ? { control: t.control } : {}),
      ...(t.link ? { link: t.link } : {}),
    });
  }

  // ------------------------------------------------------------------------------------------
  // Reactions (helm, stops, disconnection): decided by `react`, carried out here

  private dispatch(event: ReactionEvent): void {
    const { state, effects } = react(this.reactions, event);
    this.reactions = state;
    for (const effect of effects) this.perform(effect);
    this.renderHelm();
  }

  private perform(effect: Effect): void {
    switch (effect.type) {
      case "reset_inputs":
        this.resetInputs();
        return;
      case "heartbeat":
        if (effect.on) this.startHeartbeat();
        else this.stopHeartbeat();
        return;
      case "reset_latency":
        this.latency.reset();
        this.store.update({ latency: this.latency.summary });
        return;
      case "send_stop": {
        const { reason, announce } = effect;
        this.vehicle?.stop(reason).then(
          () => (announce ? this.dispatch({ type: "stop_sent", reason }) : undefined),
          (err: unknown) => this.dispatch({ type: "refused", what: "Stop", reason: reasonOf(err) }),
        );
        return;
      }
      case "beep": {
        const tone = TONES[effect.sound];
        beep(tone.count, tone.hz, tone.ms, tone.gapMs);
        return;
      }
      case "message":
        this.showMessage(effect.text, effect.kind, effect.source);
        return;
      case "clear_message":
        this.clearMessage(effect.source);
        return;
    }
  }

  private renderHelm(): void {
    this.store.update({ helm: seenView(this.reactions.helm, performance.now()) });
  }

  private tick(): void {
    this.renderHelm();
    // stale telemetry ages on screen; the clock is read as soon as the vehicle is joined
    const stale = this.clock.tick(performance.now());
    if (stale !== null) this.store.update(stale);
  }

  // ------------------------------------------------------------------------------------------
  // Heartbeat and latency

  private startHeartbeat(): void {
    if (this.heartbeat !== null) return;
    this.heartbeat = window.setInterval(() => {
      const vehicle = this.vehicle;
      if (!vehicle || !vehicle.joined || !isPilot(this.reactions.helm)) return;
      vehicle.heartbeat().then(
        (rtt) => this.addLatency(rtt),
        (err: unknown) => this.dispatch({ type: "heartbeat_refused", reason: reasonOf(err) }),
      );
    }, heartbeatMsOf(this.reactions.helm));
  }

  private stopHeartbeat(): void {
    if (this.heartbeat !== null) window.clearInterval(this.heartbeat);
    this.heartbeat = null;
  }

  private pingIfWatching(): void {
    if (this.reactions.heartbeat || !this.client || this.state.status !== "connected") return;
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
      this.dispatch({ type: "thrust_blocked", why: "not_connected" });
      return;
    }
    const stamp = stampOf(this.reactions.helm);
    if (stamp === null) {
      this.dispatch({ type: "thrust_blocked", why: "not_in_control" });
      return;
    }
    this.store.update({ sent: demand });
    const push = demand.kind === "motion" ? vehicle.thrust(demand.axes, stamp) : vehicle.thrustManual(demand.thrusters, stamp);
    push.then(
      () => this.dispatch({ type: "thrust_sent" }),
      (err: unknown) => {
        if (demandEqual(this.state.sent, demand)) this.store.update({ sent: null });
        this.refused("Thrust", err);
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
    this.dispatch({ type: "safety_stop", reason, joined: this.vehicle?.joined ?? false });
  }

  /** The pilot's stop button. */
  stop(): void {
    this.dispatch({ type: "pilot_stop" });
  }

  setInputMode(mode: InputMode): void {
    if (mode === this.state.inputMode) return;
    this.safetyStop("input mode changed");
    this.store.update({ inputMode: mode });
    saveInputMode(storage(), mode);
    if (mode !== "headset") this.headset.stop();
  }

  setGamepadOptions(options: GamepadOptions): void {
    this.store.update({ gamepadOptions: options });
    saveGamepadOptions(storage(), options);
  }

  // ------------------------------------------------------------------------------------------
  // Gamepad buttons

  private onButton(button: number): void {
    const learning = this.state.learning;
    if (learning !== null) {
      this.store.update({ learning: null, lastPress: { button, action: learning } });
      this.saveMapping(assign(this.state.buttonMapping, learning, button));
      return;
    }
    const action = actionFor(this.state.buttonMapping, button);
    this.store.update({ lastPress: { button, action } });
    if (action === null) return;
    const control = this.state.control;
    if (control?.lights != null && control.lights > 0) this.lightsOn = control.lights;
    const command = buttonCommand(action, control, this.lightsOn);
    switch (command.kind) {
      case "stop":
        this.stop();
        return;
      case "request_control":
        this.requestControl();
        return;
      case "release_control":
        this.releaseControl();
        return;
      case "input_gamepad":
        this.setInputMode("gamepad");
        return;
      case "snapshot":
        this.snapshot();
        return;
      case "set": {
        const { field, value } = command;
        this.setting(field, (v) => v.setValue(`set_${field}`, value));
        return;
      }
      case "autopilot": {
        const { axis, action: hold } = command;
        this.setAutopilot(axis, hold);
        return;
      }
      case "none":
        this.showMessage(`${ACTION_LABELS[action]}: ${command.why}.`, "info", "button");
        return;
    }
  }

  /** The editor: the next button pressed gets `action` (again: cancel). */
  learnButton(action: ButtonAction | null): void {
    this.store.update((s) => ({ learning: s.learning === action ? null : action }));
  }

  unassignButton(action: ButtonAction): void {
    this.saveMapping(unassign(this.state.buttonMapping, action));
  }

  setRepeatMs(ms: number): void {
    this.saveMapping(withRepeatMs(this.state.buttonMapping, ms));
  }

  /** Back to the default mapping (the stored one is deleted on the server). */
  resetMapping(): void {
    this.store.update({ buttonMapping: DEFAULT_MAPPING, learning: null, mappingStatus: { state: "saving", text: "Resetting…" } });
    this.settings.delete(GAMEPAD_MAPPING_KEY).then(
      () => this.store.update({ mappingStatus: { state: "default", text: "Default mapping." } }),
      (err: unknown) => this.mappingError(err),
    );
  }

  private async loadMapping(): Promise<void> {
    try {
      const stored = await this.settings.get(GAMEPAD_MAPPING_KEY);
      // the pilot changed the mapping while we asked: theirs wins (and is being saved)
      if (this.state.mappingStatus.state !== "loading") return;
      if (stored === undefined) {
        this.store.update({ mappingStatus: { state: "default", text: "Default mapping." } });
        return;
      }
      const parsed = parseMapping(stored);
      if (parsed.ok) this.store.update({ buttonMapping: parsed.mapping, mappingStatus: { state: "stored", text: "Your mapping, from the server." } });
      else this.store.update({ mappingStatus: { state: "error", text: `Your stored mapping cannot be used (${parsed.reason}): the default applies.` } });
    } catch (err) {
      this.mappingError(err);
    }
  }

  private saveMapping(mapping: ButtonMapping): void {
    this.store.update({ buttonMapping: mapping, mappingStatus: { state: "saving", text: "Saving…" } });
    this.settings.put(GAMEPAD_MAPPING_KEY, encodeMapping(mapping)).then(
      () => {
        // a later change may have been saved meanwhile: only the newest says "saved"
        if (this.state.buttonMapping === mapping) this.store.update({ mappingStatus: { state: "saved", text: "Saved on the server." } });
      },
      (err: unknown) => this.mappingError(err),
    );
  }

  private mappingError(err: unknown): void {
    this.store.update({
      mappingStatus: notKept(err)
        ? { state: "not_kept", text: "Not kept: log in to keep your mapping (it applies on this page until you leave)." }
        : { state: "error", text: `Not saved: ${reasonOf(err)}` },
    });
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

  startHeadset(): Promise<void> {
    return this.headset.start();
  }

  stopHeadset(): void {
    this.headset.stop();
  }

  /** Takes the current head direction as straight ahead at the vehicle's current heading. */
  captureHeadReference(): void {
    this.headset.capture();
  }

  // ------------------------------------------------------------------------------------------
  // Helm actions

  requestControl(): void {
    this.vehicle
      ?.requestControl()
      .then((reply) => {
        if (reply.status === "pending") this.dispatch({ type: "request_pending" });
      })
      .catch((err: unknown) => this.refused("Request", err));
  }

  takeControl(): void {
    this.vehicle
      ?.takeControl()
      .then((reply) => {
        if (reply.status === "takeover") this.dispatch({ type: "takeover_started", countdownMs: reply.countdown_ms });
      })
      .catch((err: unknown) => this.refused("Take control", err));
  }

  releaseControl(): void {
    this.vehicle?.releaseControl().catch((err: unknown) => this.refused("Release", err));
  }

  answerRequest(accept: boolean): void {
    this.vehicle
      ?.answerRequest(accept)
      .then(() => this.dispatch({ type: "answered" }))
      .catch((err: unknown) => this.refused("Answer", err));
  }

  /** Arms (`true`) or disarms a mavlink vehicle; the vehicle's answer is shown as a message. */
  arm(arm: boolean): void {
    const command = arm ? "arm" : "disarm";
    this.vehicle
      ?.arm(arm)
      .then((reply) => {
        if (reply === "ok") this.vehicleAnswer(command, null);
        else this.showMessage(`${arm ? "Arming" : "Disarming"}: waiting for the vehicle…`, "info", "arm");
      })
      .catch((err: unknown) => this.vehicleAnswer(command, reasonOf(err)));
  }

  private vehicleAnswer(command: string, refusal: string | null): void {
    if (command !== "arm" && command !== "disarm") {
      if (refusal !== null) this.showMessage(`The vehicle refused ${command}: ${refusal}`, "error", "arm");
      return;
    }
    if (refusal === null) this.showMessage(command === "arm" ? "Vehicle armed" : "Vehicle disarmed", "info", "arm");
    else this.showMessage(`${command === "arm" ? "Arm" : "Disarm"} refused: ${refusal}`, "error", "arm");
  }

  signOut(): void {
    this.session.signOut();
  }

  /** The camera's current picture saved on the server, next to the recordings (Snapshot button, gamepad). */
  snapshot(): void {
    const id = this.state.vehicleId;
    if (id === null || this.state.camera === null) {
      this.showMessage("Snapshot: this vehicle has no camera.", "warn", "snapshot");
      return;
    }
    this.showMessage("Taking a snapshot…", "info", "snapshot");
    takeSnapshot(id, this.session.token).then(
      (info) => this.showMessage(`Snapshot saved: ${info.name}`, "info", "snapshot"),
      (err: unknown) => this.showMessage(`Snapshot not saved: ${reasonOf(err)}`, "error", "snapshot"),
    );
  }

  // ------------------------------------------------------------------------------------------
  // Settings

  /**
   * The vehicle's camera rotation, for every page: stored on the server (the pilot or the main
   * station may change it); every page turns its image when the server says so.
   */
  setRotation(rotation: Rotation): void {
    const vehicle = this.vehicle;
    if (vehicle === null) return;
    this.setField("rotation", "busy", "…");
    vehicle.setCameraRotation(rotation).then(
      (settings) => {
        this.store.update({ rotation: parseRotation(settings.camera_rotation) });
        this.setField("rotation", "ok", "✓");
      },
      (err: unknown) => this.setField("rotation", "error", reasonOf(err)),
    );
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

  private refused(what: string, err: unknown): void {
    this.dispatch({ type: "refused", what, reason: reasonOf(err) });
  }

  /** Keys held now (for the on-screen key hints). */
  get keysHeld(): ReadonlySet<string> {
    return this.heldKeys;
  }
}
