import { describe, expect, it } from "vitest";
import {
  KeyboardInput,
  MANUAL_KEYMAP,
  MOTION_KEYMAP,
  NEUTRAL_AXES,
  axesEqual,
  axesFromKeys,
  isEditableTarget,
  isNeutral,
  keyToAxis,
  keyToThruster,
  thrustersFromKeys,
} from "../../src/input/keyboard";
import type { KeyEventLike, MotionAxes } from "../../src/input/keyboard";

const keys = (...codes: string[]): ReadonlySet<string> => new Set(codes);

describe("keyToAxis (table 7.1, motion)", () => {
  it.each([
    ["KeyW", "surge", 1],
    ["KeyS", "surge", -1],
    ["KeyQ", "heave", 1],
    ["KeyE", "heave", -1],
    ["KeyD", "yaw", 1],
    ["KeyA", "yaw", -1],
  ] as const)("%s → %s %i", (code, target, sign) => {
    expect(keyToAxis(code)).toEqual({ target, sign });
  });

  it("ignores other keys, letters given as characters, and prototype names", () => {
    for (const code of ["KeyX", "Space", "ArrowUp", "w", "W", "", "toString", "__proto__"]) {
      expect(keyToAxis(code)).toBeUndefined();
    }
  });

  it("maps exactly six keys", () => {
    expect(Object.keys(MOTION_KEYMAP).sort()).toEqual(
      ["KeyA", "KeyD", "KeyE", "KeyQ", "KeyS", "KeyW"],
    );
  });
});

describe("axesFromKeys", () => {
  it("is neutral with nothing held", () => {
    expect(axesFromKeys(keys())).toEqual(NEUTRAL_AXES);
  });

  it.each([
    [["KeyW"], { surge: 1, heave: 0, yaw: 0 }],
    [["KeyS"], { surge: -1, heave: 0, yaw: 0 }],
    [["KeyQ"], { surge: 0, heave: 1, yaw: 0 }],
    [["KeyE"], { surge: 0, heave: -1, yaw: 0 }],
    [["KeyD"], { surge: 0, heave: 0, yaw: 1 }],
    [["KeyA"], { surge: 0, heave: 0, yaw: -1 }],
  ])("%j → %j", (held, axes) => {
    expect(axesFromKeys(keys(...held))).toEqual(axes);
  });

  it("cancels opposing keys", () => {
    expect(axesFromKeys(keys("KeyW", "KeyS"))).toEqual(NEUTRAL_AXES);
    expect(axesFromKeys(keys("KeyQ", "KeyE"))).toEqual(NEUTRAL_AXES);
    expect(axesFromKeys(keys("KeyA", "KeyD"))).toEqual(NEUTRAL_AXES);
    expect(axesFromKeys(keys("KeyW", "KeyS", "KeyD"))).toEqual({ surge: 0, heave: 0, yaw: 1 });
  });

  it("combines axes", () => {
    expect(axesFromKeys(keys("KeyW", "KeyE", "KeyA"))).toEqual({ surge: 1, heave: -1, yaw: -1 });
  });

  it("ignores unknown codes", () => {
    expect(axesFromKeys(keys("KeyW", "ShiftLeft", "KeyZ"))).toEqual({
      surge: 1,
      heave: 0,
      yaw: 0,
    });
  });

  it("stays within [-1, 1] for every combination of the six keys", () => {
    const codes = Object.keys(MOTION_KEYMAP);
    for (let mask = 0; mask < 1 << codes.length; mask++) {
      const held = new Set(codes.filter((_, i) => (mask & (1 << i)) !== 0));
      const a = axesFromKeys(held);
      for (const v of [a.surge, a.heave, a.yaw]) {
        expect(Math.abs(v)).toBeLessThanOrEqual(1);
      }
    }
  });
});

describe("manual mode (table 7.1, manual)", () => {
  it.each([
    ["KeyW", "vertical", 1],
    ["KeyS", "vertical", -1],
    ["KeyQ", "port", 1],
    ["KeyA", "port", -1],
    ["KeyE", "starboard", 1],
    ["KeyD", "starboard", -1],
  ] as const)("%s → %s %i", (code, target, sign) => {
    expect(keyToThruster(code)).toEqual({ target, sign });
  });

  it("maps exactly six keys and nothing else", () => {
    expect(Object.keys(MANUAL_KEYMAP).sort()).toEqual(
      ["KeyA", "KeyD", "KeyE", "KeyQ", "KeyS", "KeyW"],
    );
    expect(keyToThruster("KeyX")).toBeUndefined();
  });

  it("sums held keys per thruster", () => {
    expect(thrustersFromKeys(keys())).toEqual({ port: 0, vertical: 0, starboard: 0 });
    expect(thrustersFromKeys(keys("KeyW", "KeyQ", "KeyD"))).toEqual({
      port: 1,
      vertical: 1,
      starboard: -1,
    });
    expect(thrustersFromKeys(keys("KeyQ", "KeyA", "KeyE"))).toEqual({
      port: 0,
      vertical: 0,
      starboard: 1,
    });
  });
});

describe("axesEqual / isNeutral", () => {
  it("compares all three axes", () => {
    expect(axesEqual({ surge: 1, heave: 0, yaw: 0 }, { surge: 1, heave: 0, yaw: 0 })).toBe(true);
    expect(axesEqual({ surge: 1, heave: 0, yaw: 0 }, { surge: 1, heave: 0, yaw: 1 })).toBe(false);
    expect(isNeutral(NEUTRAL_AXES)).toBe(true);
    expect(isNeutral({ surge: 0, heave: -1, yaw: 0 })).toBe(false);
  });
});

describe("isEditableTarget", () => {
  it("treats text fields as editable", () => {
    expect(isEditableTarget({ tagName: "INPUT", type: "text" })).toBe(true);
    expect(isEditableTarget({ tagName: "input", type: "number" })).toBe(true);
    expect(isEditableTarget({ tagName: "INPUT" })).toBe(true);
    expect(isEditableTarget({ tagName: "TEXTAREA" })).toBe(true);
    expect(isEditableTarget({ tagName: "SELECT" })).toBe(true);
    expect(isEditableTarget({ tagName: "DIV", isContentEditable: true })).toBe(true);
  });

  it("does not treat the page, buttons or checkboxes as editable", () => {
    expect(isEditableTarget(null)).toBe(false);
    expect(isEditableTarget(undefined)).toBe(false);
    expect(isEditableTarget({ tagName: "BODY" })).toBe(false);
    expect(isEditableTarget({ tagName: "BUTTON" })).toBe(false);
    expect(isEditableTarget({ tagName: "INPUT", type: "checkbox" })).toBe(false);
    expect(isEditableTarget({ tagName: "INPUT", type: "range" })).toBe(false);
  });
});

/** A KeyboardInput with its callbacks recorded: the motion axes of each held set reported. */
function recorder(): { input: KeyboardInput; changes: MotionAxes[]; resets: string[] } {
  const changes: MotionAxes[] = [];
  const resets: string[] = [];
  const input = new KeyboardInput({
    onHeld: (held) => changes.push(axesFromKeys(held)),
    onReset: (r) => resets.push(r),
  });
  return { input, changes, resets };
}

const down = (code: string, extra: Partial<KeyEventLike> = {}): KeyEventLike => ({
  code,
  repeat: false,
  ...extra,
});
const up = (code: string): KeyEventLike => ({ code });

describe("KeyboardInput", () => {
  it("reports absolute axes on press and release", () => {
    const { input, changes } = recorder();
    input.handleKeyDown(down("KeyW"));
    input.handleKeyUp(up("KeyW"));
    expect(changes).toEqual([{ surge: 1, heave: 0, yaw: 0 }, NEUTRAL_AXES]);
    expect(input.current).toEqual(NEUTRAL_AXES);
  });

  it("reports only changes: opposing keys cancel, auto-repeat is ignored", () => {
    const { input, changes } = recorder();
    input.handleKeyDown(down("KeyW"));
    input.handleKeyDown(down("KeyW", { repeat: true }));
    input.handleKeyDown(down("KeyW", { repeat: true }));
    input.handleKeyDown(down("KeyS"));
    input.handleKeyDown(down("KeyS", { repeat: true }));
    input.handleKeyUp(up("KeyW"));
    input.handleKeyUp(up("KeyS"));
    expect(changes).toEqual([
      { surge: 1, heave: 0, yaw: 0 },
      NEUTRAL_AXES,
      { surge: -1, heave: 0, yaw: 0 },
      NEUTRAL_AXES,
    ]);
  });

  it("does not report a second keydown of a held key without the repeat flag", () => {
    const { input, changes } = recorder();
    input.handleKeyDown(down("KeyD"));
    input.handleKeyDown(down("KeyD"));
    expect(changes).toEqual([{ surge: 0, heave: 0, yaw: 1 }]);
  });

  it("ignores unknown keys and key-ups of keys it did not see go down", () => {
    const { input, changes } = recorder();
    expect(input.handleKeyDown(down("KeyX"))).toBe(false);
    expect(input.handleKeyUp(up("KeyW"))).toBe(false);
    expect(changes).toEqual([]);
  });

  it("ignores keys typed into text fields and shortcuts with modifiers", () => {
    const { input, changes } = recorder();
    input.handleKeyDown(down("KeyW", { target: { tagName: "INPUT", type: "text" } }));
    input.handleKeyDown(down("KeyS", { target: { tagName: "TEXTAREA" } }));
    input.handleKeyDown(down("KeyA", { ctrlKey: true }));
    input.handleKeyDown(down("KeyD", { metaKey: true }));
    input.handleKeyDown(down("KeyQ", { altKey: true }));
    expect(changes).toEqual([]);
    expect(input.heldKeys.size).toBe(0);
  });

  it("releases a held key even if the key-up comes from a text field", () => {
    const { input, changes } = recorder();
    input.handleKeyDown(down("KeyQ"));
    input.handleKeyUp({ code: "KeyQ", target: { tagName: "INPUT" } });
    expect(changes).toEqual([{ surge: 0, heave: 1, yaw: 0 }, NEUTRAL_AXES]);
  });

  it("prevents the default action only for keys it handles", () => {
    const { input } = recorder();
    let prevented = 0;
    const preventDefault = (): void => {
      prevented += 1;
    };
    input.handleKeyDown({ code: "KeyW", preventDefault });
    input.handleKeyDown({ code: "KeyX", preventDefault });
    input.handleKeyDown({ code: "KeyS", target: { tagName: "INPUT" }, preventDefault });
    input.handleKeyUp({ code: "KeyW", preventDefault });
    expect(prevented).toBe(2);
  });

  it("reset clears every held key, reports the reason, and does not call onHeld", () => {
    const { input, changes, resets } = recorder();
    input.handleKeyDown(down("KeyW"));
    input.handleKeyDown(down("KeyE"));
    expect(input.reset("window lost focus")).toBe(true);
    expect(resets).toEqual(["window lost focus"]);
    expect(input.current).toEqual(NEUTRAL_AXES);
    expect(input.heldKeys.size).toBe(0);
    expect(changes).toHaveLength(2);
    // key-ups after the reset change nothing; a new press reports again
    input.handleKeyUp(up("KeyW"));
    input.handleKeyDown(down("KeyW"));
    expect(changes).toEqual([
      { surge: 1, heave: 0, yaw: 0 },
      { surge: 1, heave: -1, yaw: 0 },
      { surge: 1, heave: 0, yaw: 0 },
    ]);
    expect(input.reset("again")).toBe(true);
    expect(input.reset("nothing held")).toBe(false);
  });

  it("attach listens for keydown, keyup and blur and detach stops listening", () => {
    const { input, changes, resets } = recorder();
    const target = new EventTarget();
    const key = (type: string, code: string, repeat = false): Event => {
      const e = new Event(type);
      Object.defineProperties(e, { code: { value: code }, repeat: { value: repeat } });
      return e;
    };
    const detach = input.attach(target);
    target.dispatchEvent(key("keydown", "KeyA"));
    target.dispatchEvent(key("keydown", "KeyA", true));
    target.dispatchEvent(key("keyup", "KeyA"));
    target.dispatchEvent(key("keydown", "KeyS"));
    target.dispatchEvent(new Event("blur"));
    expect(changes).toEqual([
      { surge: 0, heave: 0, yaw: -1 },
      NEUTRAL_AXES,
      { surge: -1, heave: 0, yaw: 0 },
    ]);
    expect(resets).toEqual(["window lost focus"]);
    detach();
    target.dispatchEvent(key("keydown", "KeyW"));
    target.dispatchEvent(new Event("blur"));
    expect(changes).toHaveLength(3);
    expect(resets).toHaveLength(1);
  });
});
