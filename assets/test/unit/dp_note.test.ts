import { describe, expect, it } from "vitest";
import { decodeControlSettings } from "../../src/lib/protocol";
import { dpNote } from "../../src/operator/dp";

const base = { gain: 0.5, lights: 0, laser: 0, tilt: 0, run_mode: "normal", autopilot: { depth: 1, heading: 0, position: null } };

describe("what DP holds", () => {
  it("says so when DP has no position source", () => {
    const c = decodeControlSettings({ ...base, mode: "dp", dp_holds: ["depth", "heading"] });
    expect(c?.dp_holds).toEqual(["depth", "heading"]);
    expect(dpNote(c)).toMatch(/depth and heading only/);
  });

  it("says nothing with position hold, outside DP, or from an older server", () => {
    expect(dpNote(decodeControlSettings({ ...base, mode: "dp", dp_holds: ["depth", "heading", "position"] }))).toBeNull();
    expect(dpNote(decodeControlSettings({ ...base, mode: "motion", dp_holds: null }))).toBeNull();
    expect(dpNote(decodeControlSettings({ ...base, mode: "dp" }))).toBeNull();
    expect(dpNote(null)).toBeNull();
  });
});
