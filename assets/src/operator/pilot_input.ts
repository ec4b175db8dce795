/**
 * The operator page's thrust inputs: the keyboard (table 7.1), the touch sticks and the
 * gamepad (table 7.2, polled on animation frames in every input mode: its buttons act in every
 * mode, its sticks drive only in gamepad mode). Each device's demand goes through
 * `routeDemand` (routing.ts): sent as absolute values stamped with our grant's epoch (`thrust`
 * motion or manual), ignored, or blocked with a reason for the reactions. The last demand
 * sent is the page's `sent`; a refused one is forgotten so the next press sends again.
 *
 * `reset` forgets held keys, fingers and the pad's deflection: after any stop, loss of control
 * or grant only a fresh press, touch or stick movement moves the vehicle. The operator's
 * input mode and pad options are kept in the browser (lib/prefs.ts).
 */

import { demandEqual, stickMode } from "../input/demand";
import type { InputMode, ThrustDemand } from "../input/demand";
import { GamepadPoller } from "../input/gamepad";
import type { GamepadOptions, GamepadSource } from "../input/gamepad";
import { KeyboardInput, keyboardDemand } from "../input/keyboard";
import type { KeySource, MotionAxes, ThrusterCommands } from "../input/keyboard";
import { TouchTracker, touchDemand } from "../input/touch";
import type { TouchControl } from "../input/touch";
import { reasonOf } from "../lib/errors";
import { saveGamepadOptions, saveInputMode } from "../lib/prefs";
import type { KeyValueStore } from "../lib/prefs";
import type { MessageKind, ReactionEvent } from "./reactions";
import { routeDemand } from "./routing";
import type { OperatorState } from "./state";

/** The commands thrust needs (a `VehicleChannel` has them). */
export interface ThrustVehicle {
  /** commands can be sent (socket open, channel joined) */
  readonly joined: boolean;
  thrust(axes: MotionAxes, epoch: number): Promise<unknown>;
  thrustManual(thrusters: ThrusterCommands, epoch: number): Promise<unknown>;
}

type InputFields = "inputMode" | "gamepad" | "gamepadOptions" | "touch" | "sent";

/** What the gamepad's buttons do (gamepad_buttons.ts). */
export interface ButtonHandler {
  press(button: number): void;
  repeats(button: number): boolean;
  repeatMs(): number;
}

export interface PilotInputHost {
  readonly get: () => Pick<OperatorState, InputFields>;
  readonly update: (patch: Partial<Pick<OperatorState, InputFields>>) => void;
  /** the control mode the vehicle is in */
  readonly controlMode: () => string;
  /** the vehicle's channel, once opened */
  readonly vehicle: () => ThrustVehicle | null;
  /** the helm epoch our thrust carries; null when we do not pilot */
  readonly epoch: () => number | null;
  /** thrust sent, blocked or refused (reactions.ts) */
  readonly dispatch: (event: ReactionEvent) => void;
  readonly showMessage: (text: string, kind: MessageKind, source: string) => void;
  readonly buttons: ButtonHandler;
  /** the browser's gamepads */
  readonly gamepads: GamepadSource;
  /** where the input mode and the pad options are kept (null: nowhere) */
  readonly storage: KeyValueStore | null;
  /** animation frames (defaults to the window's; tests pass their own) */
  readonly requestFrame?: (cb: () => void) => number;
}

export class PilotInput {
  private readonly host: PilotInputHost;
  private readonly keyboard: KeyboardInput;
  private readonly touch = new TouchTracker();
  private readonly gamepad: GamepadPoller;

  constructor(host: PilotInputHost) {
    this.host = host;
    this.keyboard = new KeyboardInput({
      onHeld: (held) => {
        const controlMode = host.controlMode();
        const mode = stickMode(controlMode);
        if (mode) this.demand("keyboard", keyboardDemand(held, mode));
        else if (held.size > 0) host.showMessage(`Control mode ${controlMode}: keys are ignored.`, "warn", "command");
      },
    });
    this.gamepad = new GamepadPoller({
      source: host.gamepads,
      mode: () => stickMode(host.controlMode()) ?? "motion",
      options: () => host.get().gamepadOptions,
      onDemand: (d) => {
        if (stickMode(host.controlMode())) this.demand("gamepad", d);
      },
      onPad: (pad) => host.update({ gamepad: pad }),
      onPress: (button) => host.buttons.press(button),
      repeats: (button) => host.buttons.repeats(button),
      repeatMs: () => host.buttons.repeatMs(),
      ...(host.requestFrame ? { requestFrame: host.requestFrame } : {}),
    });
  }

  /** Listens to the keyboard on `keys` (the window) and starts reading the pad. */
  start(keys: KeySource): void {
    this.keyboard.attach(keys);
    this.gamepad.start();
  }

  /** Forgets held keys, fingers and the pad's deflection, and the last demand sent. */
  reset(): void {
    this.keyboard.reset("reset", false);
    this.touch.reset();
    this.gamepad.reset();
    this.host.update({ touch: this.touch.current, sent: null });
  }

  /** The input mode that drives from now on (the caller stops the vehicle first). */
  select(mode: InputMode): void {
    this.host.update({ inputMode: mode });
    saveInputMode(this.host.storage, mode);
  }

  setGamepadOptions(options: GamepadOptions): void {
    this.host.update({ gamepadOptions: options });
    saveGamepadOptions(this.host.storage, options);
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
    this.host.update({ touch: state });
    const mode = stickMode(this.host.controlMode());
    if (mode) this.demand("touch", touchDemand(state, mode));
  }

  private demand(source: InputMode, demand: ThrustDemand): void {
    const host = this.host;
    const vehicle = host.vehicle();
    const s = host.get();
    const route = routeDemand(
      { selected: s.inputMode, controlMode: host.controlMode(), sent: s.sent, joined: vehicle?.joined ?? false, epoch: host.epoch() },
      source,
      demand,
    );
    switch (route.kind) {
      case "ignore":
        return;
      case "blocked":
        host.dispatch({ type: "thrust_blocked", why: route.why });
        return;
      case "send":
        if (vehicle !== null) this.send(vehicle, demand, route.epoch);
        return;
    }
  }

  private send(vehicle: ThrustVehicle, demand: ThrustDemand, epoch: number): void {
    const host = this.host;
    host.update({ sent: demand });
    const push = demand.kind === "motion" ? vehicle.thrust(demand.axes, epoch) : vehicle.thrustManual(demand.thrusters, epoch);
    push.then(
      () => host.dispatch({ type: "thrust_sent" }),
      (err: unknown) => {
        // the next demand, even the same one, must be sent again
        if (demandEqual(host.get().sent, demand)) host.update({ sent: null });
        host.dispatch({ type: "refused", what: "Thrust", reason: reasonOf(err) });
      },
    );
  }
}
