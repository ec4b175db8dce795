import { describe, expect, it } from "vitest";
import type { InputMode } from "../../src/input/demand";
import type { PadSnapshot } from "../../src/input/gamepad";
import type { MotionAxes, ThrusterCommands } from "../../src/input/keyboard";
import { TOUCH_REST } from "../../src/input/touch";
import type { KeyValueStore } from "../../src/lib/prefs";
import { PilotInput } from "../../src/operator/pilot_input";
import type { PilotInputHost, ThrustVehicle } from "../../src/operator/pilot_input";
import type { ReactionEvent } from "../../src/operator/reactions";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";

type Sent = { kind: "motion"; axes: MotionAxes; epoch: number } | { kind: "manual"; thrusters: ThrusterCommands; epoch: number };

/** A standard-mapping pad with button `pressed` down (or none) and the right stick forward by `surge`. */
function pad(surge = 0, pressed: number | null = null): Gamepad {
  const buttons = Array.from({ length: 17 }, (_, i) => ({ value: i === pressed ? 1 : 0, pressed: i === pressed }));
  const snapshot: PadSnapshot = { axes: [0, 0, 0, -surge], buttons };
  return { ...snapshot, id: "Xbox pad", connected: true, mapping: "standard" } as unknown as Gamepad;
}

function harness(options: { mode?: InputMode; controlMode?: string; refuse?: string } = {}) {
  let state: OperatorState = initialState(options.mode ?? "keyboard", { deadband: 0, expo: 0 });
  let controlMode = options.controlMode ?? "motion";
  let epoch: number | null = 4;
  let joined = true;
  let pads: Gamepad[] = [];
  const sent: Sent[] = [];
  const events: ReactionEvent[] = [];
  const messages: string[] = [];
  const presses: number[] = [];
  const frames: (() => void)[] = [];
  const saved = new Map<string, string>();
  const replies: { settle: () => void }[] = [];
  const reply = (): Promise<unknown> =>
    new Promise((resolve, reject) => replies.push({ settle: () => (options.refuse ? reject(new Error(options.refuse)) : resolve({})) }));
  const vehicle: ThrustVehicle = {
    get joined() {
      return joined;
    },
    thrust: (axes, e) => {
      sent.push({ kind: "motion", axes, epoch: e });
      return reply();
    },
    thrustManual: (thrusters, e) => {
      sent.push({ kind: "manual", thrusters, epoch: e });
      return reply();
    },
  };
  const storage: KeyValueStore = { getItem: (k) => saved.get(k) ?? null, setItem: (k, v) => void saved.set(k, v) };
  const host: PilotInputHost = {
    get: () => state,
    update: (patch) => {
      state = { ...state, ...patch };
    },
    controlMode: () => controlMode,
    vehicle: () => vehicle,
    epoch: () => epoch,
    dispatch: (event) => events.push(event),
    showMessage: (text) => messages.push(text),
    buttons: { press: (b) => presses.push(b), repeats: () => false, repeatMs: () => 250 },
    gamepads: { getGamepads: () => pads },
    storage,
    requestFrame: (cb) => frames.push(cb),
  };
  const input = new PilotInput(host);
  const keys = new EventTarget();
  input.start(keys);
  const key = (type: "keydown" | "keyup", code: string): void => {
    keys.dispatchEvent(Object.assign(new Event(type), { code }));
  };
  return {
    input,
    state: () => state,
    sent,
    events,
    messages,
    presses,
    saved,
    down: (code: string) => key("keydown", code),
    up: (code: string) => key("keyup", code),
    /** the pad now reads `p`; one animation frame passes */
    frame: (p: Gamepad | null) => {
      pads = p === null ? [] : [p];
      frames.shift()?.();
    },
    /** the vehicle answers every command sent so far */
    settle: async () => {
      for (const r of replies.splice(0)) r.settle();
      await new Promise((r) => setTimeout(r, 0));
    },
    setControlMode: (m: string) => void (controlMode = m),
    setEpoch: (e: number | null) => void (epoch = e),
    setJoined: (j: boolean) => void (joined = j),
  };
}

describe("PilotInput: the keyboard", () => {
  it("a held key sends its absolute demand with our epoch; releasing it sends neutral", async () => {
    const h = harness();
    h.down("KeyW");
    expect(h.sent).toEqual([{ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 }, epoch: 4 }]);
    expect(h.state().sent).toEqual({ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 } });
    await h.settle();
    expect(h.events).toEqual([{ type: "thrust_sent" }]);
    h.up("KeyW");
    expect(h.sent.at(-1)).toEqual({ kind: "motion", axes: { surge: 0, heave: 0, yaw: 0 }, epoch: 4 });
  });

  it("in manual mode the same keys drive single thrusters", () => {
    const h = harness({ controlMode: "manual" });
    h.down("KeyQ");
    expect(h.sent).toEqual([{ kind: "manual", thrusters: { port: 1, vertical: 0, starboard: 0 }, epoch: 4 }]);
  });

  it("in DP the keys are ignored, and the operator told so", () => {
    const h = harness({ controlMode: "dp" });
    h.down("KeyW");
    expect(h.sent).toEqual([]);
    expect(h.messages).toEqual(["Control mode dp: keys are ignored."]);
  });

  it("drives nothing unless the keyboard is the selected input", () => {
    const h = harness({ mode: "touch" });
    h.down("KeyW");
    expect(h.sent).toEqual([]);
    expect(h.events).toEqual([]);
  });

  it("without the helm or a joined channel the demand is blocked, and the reactions told why", () => {
    const h = harness();
    h.setEpoch(null);
    h.down("KeyW");
    h.setJoined(false);
    h.down("KeyA");
    expect(h.sent).toEqual([]);
    expect(h.events).toEqual([
      { type: "thrust_blocked", why: "not_in_control" },
      { type: "thrust_blocked", why: "not_connected" },
    ]);
  });

  it("a refused demand is forgotten: pressing the same keys again sends again", async () => {
    const h = harness({ refuse: "stale_command" });
    h.down("KeyW");
    await h.settle();
    expect(h.events).toEqual([{ type: "refused", what: "Thrust", reason: "stale_command" }]);
    expect(h.state().sent).toBeNull();
    h.up("KeyW");
    h.down("KeyW");
    expect(h.sent.filter((s) => s.kind === "motion" && s.axes.surge === 1)).toHaveLength(2);
  });
});

describe("PilotInput: reset", () => {
  it("forgets held keys and the last demand: a key held across it counts only when pressed again", () => {
    const h = harness();
    h.down("KeyW");
    h.input.reset();
    expect(h.state().sent).toBeNull();
    h.down("KeyD");
    // W was forgotten: only yaw
    expect(h.sent.at(-1)).toEqual({ kind: "motion", axes: { surge: 0, heave: 0, yaw: 1 }, epoch: 4 });
  });

  it("lifts every finger", () => {
    const h = harness({ mode: "touch" });
    h.input.touchDown(1, "right", 0, -50, 0, 0, 50);
    expect(h.state().touch).not.toEqual(TOUCH_REST);
    h.input.reset();
    expect(h.state().touch).toEqual(TOUCH_REST);
    h.input.touchMove(1, 0, -50);
    expect(h.sent).toHaveLength(1); // the finger lifted with the reset: its moves are not a stick
  });
});

describe("PilotInput: touch and the gamepad", () => {
  it("a finger on the right stick drives in touch mode", () => {
    const h = harness({ mode: "touch" });
    h.input.touchDown(1, "right", 0, -50, 0, 0, 50);
    expect(h.sent).toHaveLength(1);
    const first = h.sent[0];
    expect(first?.kind === "motion" && first.axes.surge > 0).toBe(true);
    h.input.touchUp(1);
    expect(h.state().touch).toEqual(TOUCH_REST);
    expect(h.sent.at(-1)).toEqual({ kind: "motion", axes: { surge: 0, heave: 0, yaw: 0 }, epoch: 4 });
  });

  it("the pad's stick drives only in gamepad mode; its buttons act in every mode", () => {
    const keyboard = harness();
    keyboard.frame(pad());
    keyboard.frame(pad(1, 1));
    expect(keyboard.sent).toEqual([]);
    expect(keyboard.presses).toEqual([1]);
    expect(keyboard.state().gamepad).toEqual({ id: "Xbox pad", armed: true });

    const gamepad = harness({ mode: "gamepad" });
    gamepad.frame(pad());
    gamepad.frame(pad(1));
    expect(gamepad.sent).toEqual([{ kind: "motion", axes: { surge: 1, heave: 0, yaw: 0 }, epoch: 4 }]);
  });
});

describe("PilotInput: the operator's choices", () => {
  it("the input mode and the pad options are kept in the browser", () => {
    const h = harness();
    h.input.select("gamepad");
    h.input.setGamepadOptions({ deadband: 0.2, expo: 0.5 });
    expect(h.state().inputMode).toBe("gamepad");
    expect(h.state().gamepadOptions).toEqual({ deadband: 0.2, expo: 0.5 });
    expect([...h.saved.values()]).toContain("gamepad");
    expect(h.saved.size).toBe(2);
  });
});
