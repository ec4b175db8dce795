/**
 * The operator page's logic (no DOM building here: the Preact view renders `store`), as a
 * composition of parts, each with a host that gives it what it needs of the page:
 *
 * - `state.ts`: the page's state and the pure operations on it (the `Store` holds it);
 * - `connection.ts`: the socket (login in secure mode, banner in local mode), the vehicle's
 *   choice and channel; the phoenix client reconnects on its own and the page says so;
 * - `pilot_input.ts`: keyboard (table 7.1), touch sticks, gamepad (table 7.2) → thrust, routed
 *   by `routeDemand` (routing.ts, pure): only the selected input mode drives, absolute values
 *   stamped with our grant's epoch, sent when they change;
 * - `gamepad_buttons.ts`: each press runs its action once (steps repeat while held); the
 *   pilot's mapping is kept on the server and edited on the page;
 * - `settings_fields.ts`: control mode, run mode, autopilots, gain, lights, laser, tilt and
 *   the camera rotation go to the server as typed; its `error` reason is shown beside the field;
 * - `helm_commands.ts`: request / take / release / answer control, arm / disarm;
 * - `heartbeat.ts`: the pilot's heartbeat every `heartbeat_ms`, the round-trip latency;
 * - `headset.ts`: head tracking → heading setpoint and camera tilt.
 *
 * What the helm, stops and the connection mean for the page is decided by `react`
 * (reactions.ts, pure); this class feeds it the vehicle's events, the page's own stops and the
 * replies, and carries out its effects (`perform`) with the parts. Safety: window blur, a
 * hidden page, closing it or changing the input mode sends `stop`; after any stop, loss of
 * control or grant every input is forgotten — only a fresh press, touch or stick movement
 * moves the vehicle. Session handling is `PageSession` (lib/session.ts).
 */

import type { InputMode } from "../input/demand";
import { ACTION_LABELS } from "../input/buttons";
import type { ButtonAction, ButtonCommand } from "../input/buttons";
import { beep } from "../lib/beep";
import { TelemetryClock } from "../lib/clock";
import { reasonOf } from "../lib/errors";
import { heartbeatMsOf, isPilot, seenView, stampOf } from "../lib/helm";
import { loadGamepadOptions, loadInputMode, loadRotation, parseRotation } from "../lib/prefs";
import { cameraWithToken } from "../lib/protocol";
import type { Telemetry } from "../lib/protocol";
import { PageSession, browserSessionEnv } from "../lib/session";
import { SettingsClient } from "../lib/settings";
import { Store } from "../lib/store";
import { NeptunusClient } from "../lib/vehicle_client";
import type { VehicleChannel, VehicleHandlers } from "../lib/vehicle_client";
import { OperatorConnection } from "./connection";
import { GamepadButtons } from "./gamepad_buttons";
import { HeadsetInput } from "./headset";
import { Heartbeat } from "./heartbeat";
import { HelmCommands } from "./helm_commands";
import { PilotInput } from "./pilot_input";
import { INITIAL_REACTIONS, TONES, isNewGrant, react } from "./reactions";
import type { Effect, MessageKind, ReactionEvent, ReactionState } from "./reactions";
import { SettingsFields } from "./settings_fields";
import { controlModeOf, initialState, withMessage, withTelemetry, withoutMessage } from "./state";
import type { OperatorState } from "./state";

// the views (app, hud) take the page's state type from here too; state.ts defines it
export type { OperatorState } from "./state";

/** how often the page reads the server's clock (to tell how old telemetry is on arrival) */
const CLOCK_MS = 10_000;

function storage(): Storage | null {
  try {
    return window.localStorage;
  } catch {
    return null;
  }
}

function touchFirstDevice(): boolean {
  return typeof window.matchMedia === "function" && window.matchMedia("(pointer: coarse)").matches;
}

export class OperatorController {
  readonly store: Store<OperatorState>;
  /** the helm as seen, the heartbeat, the takeover warning: see reactions.ts */
  private reactions: ReactionState = INITIAL_REACTIONS;
  /** keyboard, touch sticks and gamepad → thrust */
  readonly input: PilotInput;
  /** the gamepad's buttons and the editor of their mapping */
  readonly buttons: GamepadButtons;
  /** the settings fields: control and run mode, autopilots, gain, lights, laser, tilt, rotation */
  readonly fields: SettingsFields;
  /** request, take, release and hand over control; arm and disarm */
  readonly helm: HelmCommands;
  /** the pilot's heartbeat and the round-trip latency */
  private readonly heartbeat: Heartbeat;
  /** head tracking: heading setpoint and camera tilt */
  readonly headset: HeadsetInput;
  private readonly session: PageSession;
  /** the socket and the vehicle's channel */
  private readonly connection: OperatorConnection;
  /** how old the newest telemetry is, on the server's clock */
  private readonly clock = new TelemetryClock(() => this.vehicle);

  constructor(params: URLSearchParams) {
    const prefs = storage();
    this.store = new Store<OperatorState>(initialState(loadInputMode(prefs, touchFirstDevice()), loadGamepadOptions(prefs)));
    this.session = new PageSession(
      browserSessionEnv((reason) =>
        reason === null ? this.clearMessage("session") : this.showMessage(`Cannot reach the server: ${reason}`, "warn", "session"),
      ),
    );
    this.buttons = new GamepadButtons({
      get: () => this.state,
      update: (patch) => this.store.update(patch),
      settings: new SettingsClient(() => this.session.token),
      perform: (command, action) => this.onButtonCommand(command, action),
    });
    this.helm = new HelmCommands({
      vehicle: () => this.vehicle,
      dispatch: (event) => this.dispatch(event),
      showMessage: (text, kind, source) => this.showMessage(text, kind, source),
    });
    this.heartbeat = new Heartbeat({
      update: (patch) => this.store.update(patch),
      vehicle: () => this.vehicle,
      piloting: () => isPilot(this.reactions.helm),
      intervalMs: () => heartbeatMsOf(this.reactions.helm),
      ping: () => {
        const client = this.connection.client;
        return client !== null && this.state.status === "connected" ? client.ping() : null;
      },
      refused: (reason) => this.dispatch({ type: "heartbeat_refused", reason }),
    });
    this.fields = new SettingsFields({
      get: () => this.state,
      update: (patch) => this.store.update(patch),
      vehicle: () => this.vehicle,
      resetInputs: () => this.input.reset(),
    });
    this.input = new PilotInput({
      get: () => this.state,
      update: (patch) => this.store.update(patch),
      controlMode: () => this.controlMode,
      vehicle: () => this.vehicle,
      epoch: () => stampOf(this.reactions.helm),
      dispatch: (event) => this.dispatch(event),
      showMessage: (text, kind, source) => this.showMessage(text, kind, source),
      buttons: this.buttons,
      gamepads: { getGamepads: () => (typeof navigator.getGamepads === "function" ? navigator.getGamepads() : []) },
      storage: prefs,
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
      onResult: (error) => (error === null ? this.fields.mark("headset", "ok", "") : this.fields.mark("headset", "error", error)),
    });
    this.connection = new OperatorConnection(
      {
        get: () => this.state,
        update: (patch) => this.store.update(patch),
        showMessage: (text, kind, source) => this.showMessage(text, kind, source),
        clearMessage: (source) => this.clearMessage(source),
        recheck: () => void this.session.recheck(),
        client: (options) => new NeptunusClient(options),
        opening: (id) => this.opening(id),
        events: this.vehicleEvents(),
        nowMs: () => performance.now(),
      },
      params,
    );
  }

  private get state(): OperatorState {
    return this.store.get();
  }

  private get vehicle(): VehicleChannel | null {
    return this.connection.vehicle;
  }

  /** The control mode the vehicle is in (motion until a server says otherwise). */
  private get controlMode(): string {
    return controlModeOf(this.state);
  }

  async start(): Promise<void> {
    // the keys (table 7.1) and the pad: its buttons act in every input mode, its sticks only in gamepad mode
    this.input.start(window);
    window.addEventListener("blur", () => this.safetyStop("window lost focus"));
    document.addEventListener("visibilitychange", () => {
      if (document.visibilityState === "hidden") this.safetyStop("page hidden");
    });
    window.addEventListener("pagehide", () => this.safetyStop("page closed"));
    window.setInterval(() => this.tick(), 250);
    this.heartbeat.start();
    window.setInterval(() => this.clock.read(), CLOCK_MS);

    const session = await this.session.authenticate();
    if (session === null) return; // leaving for the login page
    this.store.update({ banner: { mode: session.mode, user: session.user } });
    void this.buttons.load();
    await this.connection.open({ mode: session.mode, token: this.session.token });
  }

  /** The vehicle `id` is about to be joined. */
  private opening(id: string): void {
    document.title = `Neptunus — ${id}`;
    // the camera rotation is the vehicle's (the server's settings); the browser's earlier
    // per-vehicle choice shows only until the server's comes (an older server sends none)
    this.store.update({ vehicleId: id, rotation: loadRotation(storage(), id) });
  }

  // ------------------------------------------------------------------------------------------
  // The vehicle's events

  /** What the page does with the vehicle's events. */
  private vehicleEvents(): VehicleHandlers {
    return {
      snapshot: (snapshot) => {
        if (snapshot.settings) this.store.update({ rotation: parseRotation(snapshot.settings.camera_rotation) });
        this.dispatch({ type: "joined", helm: snapshot.helm, session: snapshot.session, atMs: performance.now() });
        this.store.update({
          pilotName: snapshot.pilot?.name ?? null,
          camera: cameraWithToken(snapshot.camera, this.session.token),
          control: snapshot.control,
          sent: null,
        });
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
      vehicleAnswer: (answer) => this.helm.answered(answer.command, answer.ok ? null : (answer.reason ?? "refused")),
      // the vehicle runs on another node of the fleet, now cut off from this one (or back)
      reachability: (reachable, node) => {
        if (reachable) this.clearMessage("unreachable");
        else this.showMessage(`Vehicle unreachable: its node ${node} is cut off from this server.`, "error", "unreachable");
      },
      presence: (entries) => this.store.update({ presence: entries }),
      status: (status) => {
        if (status !== "connected") this.dispatch({ type: "disconnected" });
      },
      protocolError: (what, payload) => {
        console.warn(`neptunus: unexpected ${what} payload`, payload);
      },
    };
  }

  private onTelemetry(t: Telemetry): void {
    this.store.update(withTelemetry(t, this.clock.received(t.sent_at, performance.now(), Date.now())));
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
        this.input.reset();
        return;
      case "heartbeat":
        this.heartbeat.pilot(effect.on);
        return;
      case "reset_latency":
        this.heartbeat.resetLatency();
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
  // The page's own commands

  /** Stops the vehicle for `reason` (when we pilot) and forgets every input. */
  safetyStop(reason: string): void {
    this.dispatch({ type: "safety_stop", reason, joined: this.vehicle?.joined ?? false });
  }

  /** The pilot's stop button. */
  stop(): void {
    this.dispatch({ type: "pilot_stop" });
  }

  /** The input mode that drives: the vehicle stops first, head tracking stops when left. */
  setInputMode(mode: InputMode): void {
    if (mode === this.state.inputMode) return;
    this.safetyStop("input mode changed");
    this.input.select(mode);
    if (mode !== "headset") this.headset.stop();
  }

  signOut(): void {
    this.session.signOut();
  }

  /** What a pressed button's action asks for (gamepad_buttons.ts), carried out. */
  private onButtonCommand(command: ButtonCommand, action: ButtonAction): void {
    switch (command.kind) {
      case "stop":
        this.stop();
        return;
      case "request_control":
        this.helm.request();
        return;
      case "release_control":
        this.helm.release();
        return;
      case "input_gamepad":
        this.setInputMode("gamepad");
        return;
      case "set": {
        const { field, value } = command;
        this.fields.set(field, value);
        return;
      }
      case "autopilot": {
        const { axis, action: hold } = command;
        this.fields.setAutopilot(axis, hold);
        return;
      }
      case "none":
        this.showMessage(`${ACTION_LABELS[action]}: ${command.why}.`, "info", "button");
        return;
    }
  }

  // ------------------------------------------------------------------------------------------
  // Messages

  showMessage(text: string, kind: MessageKind, source: string | null = null): void {
    this.store.update(withMessage(text, kind, source));
  }

  clearMessage(source: string): void {
    this.store.update(withoutMessage(this.state, source));
  }
}
