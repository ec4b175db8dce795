import { describe, expect, it } from "vitest";
import { DEFAULT_MAPPING, encodeMapping } from "../../src/input/buttons";
import type { ButtonAction, ButtonCommand } from "../../src/input/buttons";
import type { ControlSettings } from "../../src/lib/protocol";
import { GAMEPAD_MAPPING_KEY } from "../../src/lib/settings";
import { GamepadButtons } from "../../src/operator/gamepad_buttons";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";

const control: ControlSettings = { mode: "motion", gain: 0.5, lights: 100, laser: 0, tilt: 0, run_mode: null, autopilot: null };
const B = 1; // stop in the default mapping
const Y = 3; // lights on/off
const RB = 5; // gain up

function harness(stored?: unknown) {
  let state: OperatorState = { ...initialState("keyboard", { deadband: 0.1, expo: 0 }), control };
  const performed: [ButtonCommand, ButtonAction][] = [];
  const puts: [string, unknown][] = [];
  const deletes: string[] = [];
  const buttons = new GamepadButtons({
    get: () => state,
    update: (patch) => {
      state = { ...state, ...patch };
    },
    settings: {
      get: () => Promise.resolve(stored),
      put: (key, value) => {
        puts.push([key, value]);
        return Promise.resolve();
      },
      delete: (key) => {
        deletes.push(key);
        return Promise.resolve();
      },
    },
    perform: (command, action) => performed.push([command, action]),
  });
  return {
    buttons,
    state: () => state,
    setControl: (c: ControlSettings) => void (state = { ...state, control: c }),
    performed,
    puts,
    deletes,
    settled: (): Promise<void> => new Promise((r) => setTimeout(r, 0)),
  };
}

describe("GamepadButtons: presses", () => {
  it("a mapped button runs its action's command once, and the page shows the press", () => {
    const h = harness();
    h.buttons.press(B);
    expect(h.performed).toEqual([[{ kind: "stop" }, "stop"]]);
    expect(h.state().lastPress).toEqual({ button: B, action: "stop" });
  });

  it("an unmapped button does nothing but show it was pressed", () => {
    const h = harness();
    h.buttons.press(7);
    expect(h.performed).toEqual([]);
    expect(h.state().lastPress).toEqual({ button: 7, action: null });
  });

  it("steps are computed from the vehicle's settings", () => {
    const h = harness();
    h.buttons.press(RB);
    expect(h.performed).toEqual([[{ kind: "set", field: "gain", value: 0.6 }, "gain_up"]]);
  });

  it("the lights come back on at the brightness they last had", () => {
    const h = harness();
    h.buttons.press(Y); // at 100: off
    expect(h.performed.at(-1)?.[0]).toEqual({ kind: "set", field: "lights", value: 0 });
    h.setControl({ ...control, lights: 0 });
    h.buttons.press(Y);
    expect(h.performed.at(-1)?.[0]).toEqual({ kind: "set", field: "lights", value: 100 });
  });

  it("held steps repeat at the mapping's pace; other actions act once per press", () => {
    const h = harness();
    expect(h.buttons.repeats(RB)).toBe(true);
    expect(h.buttons.repeats(B)).toBe(false);
    expect(h.buttons.repeats(7)).toBe(false);
    expect(h.buttons.repeatMs()).toBe(DEFAULT_MAPPING.repeatMs);
  });
});

describe("GamepadButtons: the mapping editor", () => {
  it("learning: the next button pressed gets the action (and does not act); the mapping is saved", () => {
    const h = harness();
    h.buttons.learn("stop");
    expect(h.state().learning).toBe("stop");
    h.buttons.press(7);
    expect(h.performed).toEqual([]);
    expect(h.state().learning).toBeNull();
    expect(h.state().lastPress).toEqual({ button: 7, action: "stop" });
    expect(h.state().buttonMapping.actions.stop).toBe(7);
    expect(h.puts).toEqual([[GAMEPAD_MAPPING_KEY, encodeMapping(h.state().buttonMapping)]]);
    expect(h.state().mappingStatus.state).toBe("saving");
  });

  it("learning the same action again cancels", () => {
    const h = harness();
    h.buttons.learn("stop");
    h.buttons.learn("stop");
    expect(h.state().learning).toBeNull();
  });

  it("unassign and the repeat interval are saved", async () => {
    const h = harness();
    h.buttons.unassign("stop");
    h.buttons.setRepeatMs(400);
    expect(h.state().buttonMapping.actions.stop).toBeUndefined();
    expect(h.state().buttonMapping.repeatMs).toBe(400);
    // one request at a time: the second change goes once the first is stored
    expect(h.puts).toHaveLength(1);
    await h.settled();
    expect(h.puts).toHaveLength(2);
    expect(h.puts[1]).toEqual([GAMEPAD_MAPPING_KEY, encodeMapping(h.state().buttonMapping)]);
    expect(h.state().mappingStatus).toEqual({ state: "saved", text: "Saved on the server." });
  });

  it("reset: the default mapping, the editor stops learning, the stored mapping is deleted", async () => {
    const h = harness();
    h.buttons.unassign("stop");
    h.buttons.learn("laser");
    h.buttons.reset();
    expect(h.state().buttonMapping).toBe(DEFAULT_MAPPING);
    expect(h.state().learning).toBeNull();
    // after the save of the unassign on its way (one request at a time)
    await h.settled();
    expect(h.deletes).toEqual([GAMEPAD_MAPPING_KEY]);
    expect(h.state().mappingStatus).toEqual({ state: "default", text: "Default mapping." });
  });

  it("the pilot's stored mapping is read from the server", async () => {
    const mine = encodeMapping({ ...DEFAULT_MAPPING, actions: { ...DEFAULT_MAPPING.actions, stop: 6 } });
    const h = harness(mine);
    await h.buttons.load();
    expect(h.state().buttonMapping.actions.stop).toBe(6);
    expect(h.state().mappingStatus).toEqual({ state: "stored", text: "Your mapping, from the server." });
    h.buttons.press(6);
    expect(h.performed).toEqual([[{ kind: "stop" }, "stop"]]);
  });

  it("a stored mapping that cannot be used leaves the default, and says why", async () => {
    const h = harness({ version: 99 });
    await h.buttons.load();
    expect(h.state().buttonMapping).toBe(DEFAULT_MAPPING);
    expect(h.state().mappingStatus.state).toBe("error");
    expect(h.state().mappingStatus.text).toMatch(/^Your stored mapping cannot be used \(.+\): the default applies\.$/);
  });
});
