import { describe, expect, it } from "vitest";
import {
  CATEGORIES,
  LogBook,
  categoryLabel,
  categoryOf,
  clockTime,
  entryFromRecordedEvent,
  entryFromServerLog,
  formatLog,
  telemetryChanges,
  telemetryFacts,
} from "../../src/logger/model";
import type { NewEntry } from "../../src/logger/model";
import { decodeTelemetry } from "../../src/lib/protocol";
import type { Telemetry } from "../../src/lib/protocol";

const base = {
  t: 1,
  sent_at: 1795000000000,
  measurement: { depth: 1, heading: 0, roll: 0, pitch: 0, voltage: 12, current: 0.2 },
  sim: null,
  command: { surge: 0, heave: 0, yaw: 0 },
  thrusters: { port: 0, vertical: 0, starboard: 0, port_us: 1500, vertical_us: 1500, starboard_us: 1500 },
};

function tel(over: Record<string, unknown> = {}): Telemetry {
  const t = decodeTelemetry({ ...base, ...over });
  if (!t) throw new Error("bad telemetry");
  return t;
}

const entry = (category: string, message: string, at = 0): NewEntry => ({ at, category, level: "info", message });

describe("categories", () => {
  it("has the thesis' seven plus safety, link, recordings and errors", () => {
    expect(CATEGORIES.map((c) => c.label)).toEqual([
      "Gain change",
      "Thrust command (client)",
      "Thrust command (to motors)",
      "Transfer of control",
      "Autopilot depth",
      "Autopilot heading",
      "Stop",
      "Safety",
      "Link",
      "Recordings",
      "Errors",
    ]);
  });

  it("maps the server's category names, keeping unknown ones", () => {
    expect(categoryOf("safety")).toBe("safety");
    expect(categoryOf("Gain")).toBe("gain");
    expect(categoryOf("helm")).toBe("transfer");
    expect(categoryOf("thrusters")).toBe("thrust_motors");
    expect(categoryOf("autopilot_depth")).toBe("autopilot_depth");
    expect(categoryOf("errors")).toBe("error");
    expect(categoryOf("estimator")).toBe("estimator");
    expect(categoryOf("constructor")).toBe("constructor");
    expect(categoryLabel("estimator")).toBe("estimator");
    expect(categoryLabel("stop")).toBe("Stop");
  });
});

describe("entries from the log topic", () => {
  it("takes category, level, message and time; other fields go into the text", () => {
    expect(entryFromServerLog({ category: "safety", level: "warning", message: "stopped: deadman", reason: "deadman", at: 5 }, 9)).toEqual({
      at: 5,
      category: "safety",
      level: "warning",
      message: "stopped: deadman",
    });
    expect(entryFromServerLog({ category: "gain", value: 0.7 }, 9)).toEqual({ at: 9, category: "gain", level: "info", message: "value=0.7" });
    expect(entryFromServerLog({ category: "link", level: "loud", message: "" }, 9)).toEqual({ at: 9, category: "link", level: "info", message: "(empty)" });
  });

  it("refuses payloads without a category", () => {
    expect(entryFromServerLog({ message: "x" }, 0)).toBeNull();
    expect(entryFromServerLog("x", 0)).toBeNull();
  });
});

describe("changes in telemetry", () => {
  it("says nothing for the first sample, then reports each kind of change once", () => {
    const f0 = telemetryFacts(tel());
    expect(telemetryChanges(null, f0, 1)).toEqual([]);
    expect(telemetryChanges(f0, telemetryFacts(tel()), 2)).toEqual([]);

    const moved = telemetryFacts(
      tel({
        command: { surge: 0.5, heave: 0, yaw: 0 },
        thrusters: { port: 0.25, vertical: 0, starboard: 0.25, port_us: 1625, vertical_us: 1500, starboard_us: 1625 },
      }),
    );
    const changes = telemetryChanges(f0, moved, 3);
    expect(changes.map((c) => c.category)).toEqual(["thrust_client", "thrust_motors"]);
    expect(changes[0]?.message).toBe("command surge +0.50, heave 0.00, yaw 0.00");
    expect(changes[1]?.message).toContain("port +0.25 (1625 µs)");
  });

  it("reports gain, autopilot setpoints and the board link", () => {
    const a = telemetryFacts(tel({ control: { mode: "motion", gain: 0.5, autopilot: { depth: null, heading: null } }, link: { up: true } }));
    const b = telemetryFacts(
      tel({ control: { mode: "motion", gain: 0.8, autopilot: { depth: 2, heading: Math.PI / 2 } }, link: { up: false, reason: "x" } }),
    );
    const changes = telemetryChanges(a, b, 4);
    expect(changes.map((c) => [c.category, c.message])).toEqual([
      ["gain", "gain 0.50 → 0.80"],
      ["autopilot_depth", "depth setpoint 2.00 m"],
      ["autopilot_heading", "heading setpoint 90.0°"],
      ["link", "board link down (telemetry)"],
    ]);
    const off = telemetryChanges(b, a, 5).filter((c) => c.category.startsWith("autopilot"));
    expect(off.map((c) => c.message)).toEqual(["depth autopilot off", "heading autopilot off"]);
  });

  it("takes setpoints from the autopilot status when the control settings lack them", () => {
    const a = telemetryFacts(tel({ autopilot: { depth: null, heading: null } }));
    const b = telemetryFacts(tel({ autopilot: { depth: { setpoint: 3, output: 0 }, heading: null } }));
    expect(telemetryChanges(a, b, 1).map((c) => c.message)).toEqual(["depth setpoint 3.00 m"]);
  });
});

describe("LogBook", () => {
  it("filters by category and text, case-insensitively", () => {
    const book = new LogBook();
    book.add(entry("gain", "gain 0.5 → 0.7"));
    book.add(entry("stop", "stopped: deadman"));
    book.add(entry("transfer", "Ada pilots"));
    const all = new Set(CATEGORIES.map((c) => c.id));
    expect(book.visible(all, "").map((e) => e.category)).toEqual(["gain", "stop", "transfer"]);
    expect(book.visible(new Set(["stop", "gain"]), "").map((e) => e.category)).toEqual(["gain", "stop"]);
    expect(book.visible(all, "DEADMAN").map((e) => e.message)).toEqual(["stopped: deadman"]);
    expect(book.visible(all, "transfer of").map((e) => e.message)).toEqual(["Ada pilots"]); // category label
    expect(book.visible(new Set(), "")).toEqual([]);
  });

  it("pause freezes what is shown and counts what arrives meanwhile", () => {
    const book = new LogBook();
    const all = new Set(["stop"]);
    book.add(entry("stop", "one"));
    book.pause();
    book.add(entry("stop", "two"));
    expect(book.paused).toBe(true);
    expect(book.pending).toBe(1);
    expect(book.visible(all, "").map((e) => e.message)).toEqual(["one"]);
    book.resume();
    expect(book.visible(all, "").map((e) => e.message)).toEqual(["one", "two"]);
    expect(book.pending).toBe(0);
  });

  it("clear empties it (also while paused) and it stays bounded", () => {
    const book = new LogBook(3);
    for (let i = 0; i < 5; i++) book.add(entry("stop", String(i)));
    expect(book.all.map((e) => e.message)).toEqual(["2", "3", "4"]);
    book.pause();
    book.clear();
    expect(book.all).toEqual([]);
    book.add(entry("stop", "new"));
    expect(book.pending).toBe(1);
    expect(book.visible(new Set(["stop"]), "")).toEqual([]);
  });

  it("formats the download: ISO time, category, level, message per line, tabs and newlines flattened", () => {
    const book = new LogBook();
    book.add({ at: Date.UTC(2026, 4, 1, 12, 0, 0, 123), category: "stop", level: "warning", message: "a\tb\nc" });
    expect(formatLog(book.all)).toBe("2026-05-01T12:00:00.123Z\tstop\twarning\ta b c\n");
    expect(formatLog([])).toBe("");
  });

  it("shows times with milliseconds", () => {
    expect(clockTime(new Date(2026, 0, 1, 9, 5, 7, 42).getTime())).toBe("09:05:07.042");
  });
});

describe("a server recording's events in the logger", () => {
  it("marks them [recorded] in the logger's categories", () => {
    expect(entryFromRecordedEvent("stopped", { reason: "deadman" }, 5)).toEqual({ at: 5, category: "stop", level: "warning", message: "[recorded] stopped: deadman" });
    expect(entryFromRecordedEvent("link", { up: false, reason: "hangup" }, 6)?.message).toBe("[recorded] board link down: hangup");
    expect(entryFromRecordedEvent("link", { up: true }, 6)?.level).toBe("info");
    expect(entryFromRecordedEvent("helm", { state: "piloted", pilot: { name: "ada" }, epoch: 3 }, 7)?.message).toBe("[recorded] helm piloted: ada pilots (epoch 3)");
    expect(entryFromRecordedEvent("helm", { state: "takeover", pilot: null, epoch: 4 }, 7)?.level).toBe("warning");
    expect(entryFromRecordedEvent("recording", { recording: false, error: "disk nearly full" }, 8)?.category).toBe("recording");
  });

  it("shows the vehicle's recorded log entries, not the safety ones a stop already shows", () => {
    expect(entryFromRecordedEvent("log", { category: "errors", level: "error", message: "camera failed", at: 3 }, 9)).toEqual({
      at: 3,
      category: categoryOf("errors"),
      level: "error",
      message: "[recorded] camera failed",
    });
    expect(entryFromRecordedEvent("log", { category: "autopilot", level: "warning", message: "depth hold: waiting" }, 9)?.at).toBe(9);
    expect(entryFromRecordedEvent("log", { category: "safety", level: "warning", message: "stopped: deadman", reason: "deadman" }, 9)).toBeNull();
    expect(entryFromRecordedEvent("log", { message: "no category" }, 9)).toBeNull();
  });

  it("leaves out what the logger does not show, and malformed events", () => {
    expect(entryFromRecordedEvent("presence_diff", { joins: {}, leaves: {} }, 1)).toBeNull();
    expect(entryFromRecordedEvent("control", { gain: 0.5 }, 1)).toBeNull();
    expect(entryFromRecordedEvent("helm", { epoch: 1 }, 1)).toBeNull();
    expect(entryFromRecordedEvent("stopped", "deadman", 1)).toBeNull();
  });
});
