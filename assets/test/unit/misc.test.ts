import { describe, expect, it } from "vitest";
import { accepts, demandEqual, isNeutralDemand, manualDemand, motionDemand, quantize, stickMode, NEUTRAL_MOTION } from "../../src/input/demand";
import { TABLE_KEYS, keyboardDemand } from "../../src/input/keyboard";
import { KeyboardInput } from "../../src/input/keyboard";
import { bugPosition, compassTicks, diff180, wrap360 } from "../../src/lib/compass";
import { formDegrees, formValue, isSafetyStop } from "../../src/lib/forms";
import { LatencyTracker, formatMs } from "../../src/lib/latency";
import {
  defaultInputMode,
  loadGamepadOptions,
  loadInputMode,
  loadRotation,
  parseGamepadOptions,
  parseRotation,
  saveGamepadOptions,
  saveInputMode,
  saveRotation,
} from "../../src/lib/prefs";
import { Store } from "../../src/lib/store";
import {
  BOARD_DEADMAN_NOT_ARMED,
  boardLinkText,
  boardSettingsText,
  THRUST_HELD,
  cameraElement,
  downFor,
  formatDeg,
  measurementDeg,
  measurementHeading,
  measurementText,
  retryUrl,
  showsUnit,
} from "../../src/operator/format";
import { decodeLinkStatus } from "../../src/lib/protocol";

describe("demands", () => {
  it("only the selected input mode drives, never the headset, never in DP", () => {
    expect(accepts("keyboard", "keyboard", "motion")).toBe(true);
    expect(accepts("keyboard", "keyboard", "manual")).toBe(true);
    expect(accepts("keyboard", "touch", "motion")).toBe(false);
    expect(accepts("gamepad", "keyboard", "motion")).toBe(false);
    expect(accepts("headset", "headset", "motion")).toBe(false);
    expect(accepts("touch", "touch", "dp")).toBe(false);
  });

  it("quantizes to 1/1000 within [-1, 1] without negative zero", () => {
    expect(quantize(0.12345)).toBe(0.123);
    expect(quantize(-0.0001)).toBe(0);
    expect(Object.is(quantize(-0.0001), -0)).toBe(false);
    expect(quantize(5)).toBe(1);
    expect(quantize(Number.NaN)).toBe(0);
  });

  it("compares demands by kind and values", () => {
    expect(demandEqual(motionDemand(1, 0, 0), motionDemand(1, 0, 0))).toBe(true);
    expect(demandEqual(motionDemand(1, 0, 0), motionDemand(0, 0, 0))).toBe(false);
    expect(demandEqual(motionDemand(0, 0, 0), manualDemand(0, 0, 0))).toBe(false);
    expect(demandEqual(null, null)).toBe(true);
    expect(demandEqual(NEUTRAL_MOTION, null)).toBe(false);
    expect(isNeutralDemand(manualDemand(0, 0, 0))).toBe(true);
    expect(stickMode("dp")).toBeNull();
    expect(stickMode("manual")).toBe("manual");
  });
});

describe("keyboard: both columns of table 7.1", () => {
  it("motion column", () => {
    expect(keyboardDemand(new Set(["KeyW", "KeyD"]), "motion")).toEqual({ kind: "motion", axes: { surge: 1, heave: 0, yaw: 1 } });
    expect(keyboardDemand(new Set(["KeyQ"]), "motion")).toEqual({ kind: "motion", axes: { surge: 0, heave: 1, yaw: 0 } });
  });

  it("manual column: W/S vertical, Q/A port, E/D starboard", () => {
    expect(keyboardDemand(new Set(["KeyW"]), "manual")).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 1, starboard: 0 } });
    expect(keyboardDemand(new Set(["KeyS", "KeyQ"]), "manual")).toEqual({ kind: "manual", thrusters: { port: 1, vertical: -1, starboard: 0 } });
    expect(keyboardDemand(new Set(["KeyA", "KeyD"]), "manual")).toEqual({ kind: "manual", thrusters: { port: -1, vertical: 0, starboard: -1 } });
    expect(keyboardDemand(new Set(["KeyE", "KeyD"]), "manual")).toEqual({ kind: "manual", thrusters: { port: 0, vertical: 0, starboard: 0 } });
  });

  it("the same six keys drive both columns", () => {
    expect([...TABLE_KEYS].sort()).toEqual(["KeyA", "KeyD", "KeyE", "KeyQ", "KeyS", "KeyW"]);
  });

  it("KeyboardInput reports the held keys on every change (for manual mode)", () => {
    const held: string[][] = [];
    const input = new KeyboardInput({ onHeld: (h) => held.push([...h].sort()) });
    input.handleKeyDown({ code: "KeyE" });
    input.handleKeyDown({ code: "KeyD" }); // cancels in manual, but is a new held set
    input.handleKeyUp({ code: "KeyE" });
    expect(held).toEqual([["KeyE"], ["KeyD", "KeyE"], ["KeyD"]]);
  });
});

describe("compass tape", () => {
  it("wraps", () => {
    expect(wrap360(-10)).toBe(350);
    expect(wrap360(725)).toBe(5);
    expect(diff180(10, 350)).toBe(20);
    expect(diff180(350, 10)).toBe(-20);
    expect(diff180(180, 0)).toBe(180);
  });

  it("ticks every 5° around the heading, majors every 15° with cardinal names", () => {
    const ticks = compassTicks(0, 60, 5);
    expect(ticks.map((t) => t.deg)).toEqual([330, 335, 340, 345, 350, 355, 0, 5, 10, 15, 20, 25, 30]);
    expect(ticks.find((t) => t.deg === 0)).toEqual({ deg: 0, offset: 0, major: true, label: "N" });
    expect(ticks.find((t) => t.deg === 345)?.label).toBe("345");
    expect(ticks.find((t) => t.deg === 5)?.major).toBe(false);
    expect(compassTicks(92.5, 20, 5).map((t) => [t.deg, t.offset])).toEqual([[85, -7.5], [90, -2.5], [95, 2.5], [100, 7.5]]);
    expect(compassTicks(90, 30, 5).find((t) => t.deg === 90)?.label).toBe("E");
    expect(compassTicks(Number.NaN)).toEqual([]);
  });

  it("labels no major tick within labelMargin of the tape's edges (a label there would be cut)", () => {
    // heading 0, span 120: 300 sits on the left edge, 60 on the right
    const edge = compassTicks(0, 120, 5);
    expect(edge.find((t) => t.deg === 300)?.label).toBe("300");
    const margin = compassTicks(0, 120, 5, 8);
    expect(margin.find((t) => t.deg === 300)).toMatchObject({ major: true, label: null });
    expect(margin.find((t) => t.deg === 60)).toMatchObject({ major: true, label: null });
    expect(margin.find((t) => t.deg === 315)?.label).toBe("NW");
    expect(margin.find((t) => t.deg === 45)?.label).toBe("NE");
    // a heading between ticks: 307 is 53 from 0 and 52 from 359
    for (let h = 0; h < 360; h += 0.7) {
      for (const t of compassTicks(h, 120, 5, 8)) if (t.label !== null) expect(Math.abs(t.offset)).toBeLessThanOrEqual(52 + 1e-9);
    }
  });

  it("puts the heading bug on the tape, clamped at its edge", () => {
    expect(bugPosition(10, 30, 120)).toEqual({ offset: 20, clamped: false });
    expect(bugPosition(350, 10, 120)).toEqual({ offset: 20, clamped: false });
    expect(bugPosition(0, 180, 120)).toEqual({ offset: 60, clamped: true });
    expect(bugPosition(0, 270, 120)).toEqual({ offset: -60, clamped: true });
    expect(bugPosition(0, null)).toBeNull();
  });
});

describe("forms", () => {
  it("sends numbers as numbers and anything else as typed (the server names the problem)", () => {
    expect(formValue("0.7")).toBe(0.7);
    expect(formValue(" 255 ")).toBe(255);
    expect(formValue("0,5")).toBe(0.5);
    expect(formValue("-1e-2")).toBe(-0.01);
    expect(formValue("abc")).toBe("abc");
    expect(formValue("")).toBe("");
    expect(formValue("1.2.3")).toBe("1.2.3");
  });

  it("takes angles in degrees and sends radians", () => {
    expect(formDegrees("90")).toBeCloseTo(Math.PI / 2);
    expect(formDegrees("x")).toBe("x");
  });

  it("beeps for safety stops, not for the pilot's own", () => {
    for (const r of ["deadman", "pilot_disconnected", "main_station_takeover", "window lost focus", "helm_started"]) expect(isSafetyStop(r)).toBe(true);
    for (const r of ["released", "pilot_stop", "sim_reset"]) expect(isSafetyStop(r)).toBe(false);
  });
});

describe("latency from heartbeat replies", () => {
  it("keeps the last, a smoothed mean and the recent maximum", () => {
    const l = new LatencyTracker(3, 0.5);
    expect(l.summary).toEqual({ last: null, mean: null, max: null, samples: 0 });
    l.add(10);
    l.add(20);
    expect(l.summary).toEqual({ last: 20, mean: 15, max: 20, samples: 2 });
    l.add(100);
    l.add(5);
    l.add(6);
    expect(l.summary.max).toBe(100);
    l.add(7);
    expect(l.summary.max).toBe(7); // 100 left the window of 3
    l.add(-1);
    l.add(Number.NaN);
    expect(l.summary.samples).toBe(6);
    l.reset();
    expect(l.summary.last).toBeNull();
  });

  it("formats", () => {
    expect(formatMs(null)).toBe("—");
    expect(formatMs(3.14)).toBe("3.1 ms");
    expect(formatMs(42.6)).toBe("43 ms");
  });
});

describe("preferences", () => {
  const store = (): { getItem(k: string): string | null; setItem(k: string, v: string): void; map: Map<string, string> } => {
    const map = new Map<string, string>();
    return { map, getItem: (k) => map.get(k) ?? null, setItem: (k, v) => void map.set(k, v) };
  };

  it("camera rotation per vehicle", () => {
    const s = store();
    expect(loadRotation(s, "a")).toBe(0);
    saveRotation(s, "a", 180);
    expect(loadRotation(s, "a")).toBe(180);
    expect(loadRotation(s, "b")).toBe(0);
    expect(parseRotation("90")).toBe(90);
    expect(parseRotation("45")).toBe(0);
    expect(loadRotation(null, "a")).toBe(0);
  });

  it("input mode: saved, else touch on touch-first devices and the keyboard elsewhere", () => {
    const s = store();
    expect(loadInputMode(s, true)).toBe("touch");
    expect(loadInputMode(s, false)).toBe("keyboard");
    expect(defaultInputMode(false)).toBe("keyboard");
    saveInputMode(s, "gamepad");
    expect(loadInputMode(s, true)).toBe("gamepad");
    s.map.set("neptunus.input.mode", "telepathy");
    expect(loadInputMode(s, false)).toBe("keyboard");
  });

  it("gamepad deadband and expo, validated", () => {
    const s = store();
    expect(loadGamepadOptions(s)).toEqual({ deadband: 0.1, expo: 0 });
    saveGamepadOptions(s, { deadband: 0.2, expo: 0.5 });
    expect(loadGamepadOptions(s)).toEqual({ deadband: 0.2, expo: 0.5 });
    expect(parseGamepadOptions('{"deadband": 2, "expo": -1}')).toEqual({ deadband: 0.1, expo: 0 });
    expect(parseGamepadOptions("not json")).toEqual({ deadband: 0.1, expo: 0 });
  });

  it("survives a storage that throws", () => {
    const broken = {
      getItem: (): string | null => {
        throw new Error("denied");
      },
      setItem: (): void => {
        throw new Error("denied");
      },
    };
    expect(loadRotation(broken, "a")).toBe(0);
    expect(() => saveRotation(broken, "a", 90)).not.toThrow();
  });
});

describe("store and display helpers", () => {
  it("notifies on real changes only", () => {
    const s = new Store({ a: 1, b: "x" });
    const seen: number[] = [];
    const off = s.subscribe((st) => seen.push(st.a));
    s.update({ a: 1 });
    s.update({ a: 2 });
    s.update((st) => ({ a: st.a + 1 }));
    off();
    s.update({ a: 9 });
    expect(seen).toEqual([2, 3]);
    expect(s.get()).toEqual({ a: 9, b: "x" });
  });

  it("formats", () => {
    expect(cameraElement("http://cam:8080/?action=stream")).toBe("img");
    expect(cameraElement("/v/a.mp4")).toBe("video");
    expect(cameraElement("/v/a.m3u8?x=1")).toBe("video");
    expect(downFor(12_400)).toBe("12 s");
    expect(downFor(75_000)).toBe("1 min 15 s");
    expect(formatDeg(Math.PI / 2, true)).toBe("+90.0");
    expect(formatDeg(null)).toBe("—");
  });
});

describe("camera feed retries", () => {
  it("asks for the stream again with a fresh address each attempt", () => {
    expect(retryUrl("/camera/rov.mjpg", 0)).toBe("/camera/rov.mjpg");
    expect(retryUrl("/camera/rov.mjpg", 1)).toBe("/camera/rov.mjpg?retry=1");
    expect(retryUrl("/camera/rov.mjpg?token=t", 2)).toBe("/camera/rov.mjpg?token=t&retry=2");
    expect(retryUrl("http://cam/x.jpg#f", 3)).toBe("http://cam/x.jpg?retry=3#f");
  });
});

describe("measurements that are initialising (no valid reading since link up or board reset)", () => {
  it("show the word, never a number, whatever value came with them", () => {
    expect(measurementText(0, "initialising", 2)).toBe("initialising");
    expect(measurementText(1.2, "initialising", 2)).toBe("initialising");
    expect(measurementText(Number.NaN, "initialising", 2)).toBe("initialising");
    expect(measurementDeg(0, "initialising", true)).toBe("initialising");
    expect(measurementHeading(0, "initialising")).toBe("initialising");
    expect(showsUnit("initialising")).toBe(false);
  });

  it("valid, stale or unknown state: the value (a dash when there is none)", () => {
    expect(measurementText(1.2, "valid", 2)).toBe("1.20");
    expect(measurementText(1.2, "stale", 2)).toBe("1.20");
    expect(measurementText(1.2, null, 2)).toBe("1.20");
    expect(measurementText(Number.NaN, "valid", 2)).toBe("—");
    expect(measurementDeg(Math.PI / 2, "valid")).toBe("90.0");
    expect(measurementHeading(Math.PI, undefined)).toBe("180.0");
    expect(showsUnit("valid") && showsUnit("stale") && showsUnit(null)).toBe(true);
  });
});

describe("the board link's liveness (telemetry link fields)", () => {
  const wire = {
    up: true,
    reason: "open",
    rtt_ms: 12,
    pong_age_ms: 340,
    board_uptime_ms: 42_000,
    board_deadman_armed: false,
    firmware: "openrov-2.5",
    detected_firmware: "openrov-30",
    firmware_mismatch: true,
    commands_sent: 120,
    commands_confirmed: 118,
  };

  it("decodes them under board, and a link without them as before", () => {
    const link = decodeLinkStatus(wire);
    expect(link?.board?.rtt_ms).toBe(12);
    expect(link?.board?.board_deadman_armed).toBe(false);
    expect(decodeLinkStatus({ up: true, reason: "open" })).toEqual({ up: true, reason: "open" });
  });

  it("summarises pong age, round trip and confirmed commands; warns while the board's deadman is not armed and on a firmware mismatch", () => {
    const board = decodeLinkStatus(wire)?.board;
    if (!board) throw new Error("no board details");
    const { summary, warnings } = boardLinkText(board);
    expect(summary).toBe("pong 0.3 s ago · board RTT 12 ms · 118/120 confirmed");
    expect(warnings).toEqual([BOARD_DEADMAN_NOT_ARMED, "board talks openrov-30, configured openrov-2.5"]);
    expect(BOARD_DEADMAN_NOT_ARMED).toBe("board deadman not armed: only the server's deadman protects");
    const armed = boardLinkText({ ...board, board_deadman_armed: true, firmware_mismatch: false, pong_age_ms: null, rtt_ms: null });
    expect(armed).toEqual({ summary: "no pong yet · 118/120 confirmed", warnings: [] });
  });

  it("says whether the board confirmed its settings, what is pending, and warns while thrust is held or a setting failed", () => {
    const settled = { ...wire, board_deadman_armed: true, firmware_mismatch: false };
    const confirmed = decodeLinkStatus({ ...settled, board_settings: "confirmed", board_settings_pending: [], board_settings_reason: null, thrust_held: false })?.board;
    if (!confirmed) throw new Error("no board details");
    expect(boardLinkText(confirmed)).toEqual({ summary: "pong 0.3 s ago · board RTT 12 ms · 118/120 confirmed · board settings: confirmed", warnings: [] });

    const held = decodeLinkStatus({ ...settled, board_settings: "pending", board_settings_pending: ["mtrmod1", "mtrmod2", "lights"], thrust_held: true })?.board;
    if (!held) throw new Error("no board details");
    expect(boardSettingsText(held)).toBe("board settings: pending (motor modifiers, lights)");
    expect(boardLinkText(held).warnings).toEqual([THRUST_HELD]);
    expect(THRUST_HELD).toBe("board settings not confirmed: thrust held at neutral");

    const why = "the board has not confirmed mtrmod2(100,100,100); (no echo after 8 writes in 2.0 s: …)";
    const failed = decodeLinkStatus({ ...settled, board_settings: "failed", board_settings_pending: ["mtrmod2"], board_settings_reason: why, thrust_held: true })?.board;
    if (!failed) throw new Error("no board details");
    expect(boardSettingsText(failed)).toBe("board settings: failed (motor modifiers)");
    expect(boardLinkText(failed).warnings).toEqual([THRUST_HELD, why]);

    // a link that does not report them (older server, MAVLink) shows nothing about them
    const none = decodeLinkStatus({ ...settled, board_settings: 7, board_settings_pending: "x" })?.board;
    if (!none) throw new Error("no board details");
    expect(boardSettingsText(none)).toBeNull();
    expect(none.board_settings_pending).toEqual([]);
    expect(none.thrust_held).toBe(false);
  });
});
