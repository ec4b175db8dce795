/**
 * The gamepad's buttons on the operator page (input/buttons.ts holds the pure mapping and
 * commands): what a press does, and the editor of the pilot's mapping.
 *
 * - A press while the editor learns assigns that button to the action being learnt (and
 *   saves); otherwise it runs the mapped action's command once (`buttonCommand`), which the
 *   host carries out (stop, helm, settings, autopilot, input mode). The lights come back on
 *   at the brightness they last had. The page shows the last press and what it did.
 * - The mapping is the pilot's, kept on the server (`gamepad.mapping`, lib/kept_setting.ts):
 *   read once signed in, saved on every change, deleted by "reset to default".
 */

import { DEFAULT_MAPPING, REPEATING, actionFor, assign, buttonCommand, encodeMapping, parseMapping, unassign, withRepeatMs } from "../input/buttons";
import type { ButtonAction, ButtonCommand, ButtonMapping } from "../input/buttons";
import { KeptSetting } from "../lib/kept_setting";
import type { SettingsClient } from "../lib/settings";
import { GAMEPAD_MAPPING_KEY } from "../lib/settings";
import type { ButtonHandler } from "./pilot_input";
import type { OperatorState } from "./state";

type ButtonFields = "buttonMapping" | "mappingStatus" | "learning" | "lastPress";

export interface GamepadButtonsHost {
  readonly get: () => Pick<OperatorState, ButtonFields | "control">;
  readonly update: (patch: Partial<Pick<OperatorState, ButtonFields>>) => void;
  /** the user's settings on the server */
  readonly settings: Pick<SettingsClient, "get" | "put" | "delete">;
  /** carries out the command of a pressed `action` */
  readonly perform: (command: ButtonCommand, action: ButtonAction) => void;
}

/** The brightness the lights come back to before any was seen. */
const LIGHTS_FULL = 255;

export class GamepadButtons implements ButtonHandler {
  private readonly host: GamepadButtonsHost;
  private readonly mapping: KeptSetting<ButtonMapping>;
  /** the brightness the lights come back to when a button turns them on */
  private lightsOn = LIGHTS_FULL;

  constructor(host: GamepadButtonsHost) {
    this.host = host;
    this.mapping = new KeptSetting<ButtonMapping>({
      key: GAMEPAD_MAPPING_KEY,
      client: host.settings,
      parse: (stored) => {
        const parsed = parseMapping(stored);
        return parsed.ok ? { ok: true, value: parsed.mapping } : parsed;
      },
      encode: encodeMapping,
      texts: {
        default: "Default mapping.",
        stored: "Your mapping, from the server.",
        unusable: (reason) => `Your stored mapping cannot be used (${reason}): the default applies.`,
        notKept: "Not kept: log in to keep your mapping (it applies on this page until you leave).",
        notSaved: (reason) => `Not saved: ${reason}`,
      },
      get: () => ({ value: host.get().buttonMapping, status: host.get().mappingStatus }),
      set: ({ value, status }) => host.update({ ...(value !== undefined ? { buttonMapping: value } : {}), mappingStatus: status }),
    });
  }

  /** Reads the pilot's mapping from the server (once signed in). */
  load(): Promise<void> {
    return this.mapping.load();
  }

  press(button: number): void {
    const s = this.host.get();
    if (s.learning !== null) {
      this.host.update({ learning: null, lastPress: { button, action: s.learning } });
      this.mapping.save(assign(s.buttonMapping, s.learning, button));
      return;
    }
    const action = actionFor(s.buttonMapping, button);
    this.host.update({ lastPress: { button, action } });
    if (action === null) return;
    const control = s.control;
    if (control?.lights != null && control.lights > 0) this.lightsOn = control.lights;
    this.host.perform(buttonCommand(action, control, this.lightsOn), action);
  }

  /** Whether a held `button` repeats (its action is a step). */
  repeats(button: number): boolean {
    const action = actionFor(this.host.get().buttonMapping, button);
    return action !== null && REPEATING.has(action);
  }

  repeatMs(): number {
    return this.host.get().buttonMapping.repeatMs;
  }

  /** The editor: the next button pressed gets `action` (again: cancel). */
  learn(action: ButtonAction | null): void {
    this.host.update({ learning: this.host.get().learning === action ? null : action });
  }

  unassign(action: ButtonAction): void {
    this.mapping.save(unassign(this.host.get().buttonMapping, action));
  }

  setRepeatMs(ms: number): void {
    this.mapping.save(withRepeatMs(this.host.get().buttonMapping, ms));
  }

  /** Back to the default mapping (the stored one is deleted on the server). */
  reset(): void {
    this.host.update({ learning: null });
    this.mapping.reset(DEFAULT_MAPPING);
  }
}
