/**
 * The developer logger (thesis §7.2 plus safety, link and errors): timestamped entries by
 * category, from the vehicle topic (helm, stopped, link, telemetry changes), from the
 * `log:<id>` topic (the server's log entries) and from this page (its commands' replies,
 * connection problems). Pure: the page feeds it events and renders `visible()`.
 */

import type { Telemetry } from "../lib/protocol";
import { formatFixed, formatHeading } from "../lib/units";

export interface Category {
  readonly id: string;
  readonly label: string;
}

/** The thesis' list, then safety, link and errors. */
export const CATEGORIES: readonly Category[] = [
  { id: "gain", label: "Gain change" },
  { id: "thrust_client", label: "Thrust command (client)" },
  { id: "thrust_motors", label: "Thrust command (to motors)" },
  { id: "transfer", label: "Transfer of control" },
  { id: "autopilot_depth", label: "Autopilot depth" },
  { id: "autopilot_heading", label: "Autopilot heading" },
  { id: "stop", label: "Stop" },
  { id: "safety", label: "Safety" },
  { id: "link", label: "Link" },
  { id: "recording", label: "Recordings" },
  { id: "error", label: "Errors" },
];

export type Level = "info" | "warning" | "error";

export interface LogEntry {
  readonly seq: number;
  /** ms since the Unix epoch */
  readonly at: number;
  readonly category: string;
  readonly level: Level;
  readonly message: string;
}

export type NewEntry = Omit<LogEntry, "seq">;

const ALIASES: Readonly<Record<string, string>> = {
  gain: "gain",
  thrust: "thrust_client",
  thrust_client: "thrust_client",
  command: "thrust_client",
  motors: "thrust_motors",
  thrusters: "thrust_motors",
  thrust_motors: "thrust_motors",
  helm: "transfer",
  transfer: "transfer",
  control: "transfer",
  autopilot_depth: "autopilot_depth",
  depth: "autopilot_depth",
  autopilot_heading: "autopilot_heading",
  heading: "autopilot_heading",
  stop: "stop",
  stopped: "stop",
  safety: "safety",
  link: "link",
  board: "link",
  recording: "recording",
  recordings: "recording",
  error: "error",
  errors: "error",
};

/** Our category for a server log entry's `category` (unknown ones are kept as they are). */
export function categoryOf(serverCategory: string): string {
  const key = serverCategory.trim().toLowerCase();
  return Object.prototype.hasOwnProperty.call(ALIASES, key) ? (ALIASES[key] ?? key) : key;
}

export function categoryLabel(id: string): string {
  return CATEGORIES.find((c) => c.id === id)?.label ?? id;
}

function isRecord(value: unknown): value is Record<string, unknown> {
  return typeof value === "object" && value !== null && !Array.isArray(value);
}

const LEVELS: readonly string[] = ["info", "warning", "error"];

/**
 * An entry from a `log` event of the `log:<id>` topic:
 * `{category, level?, message?, at?, …}`; the other fields are appended to the message.
 * `now` (ms) is used when `at` is missing. Null for a payload without a category.
 */
export function entryFromServerLog(payload: unknown, now: number): NewEntry | null {
  if (!isRecord(payload) || typeof payload["category"] !== "string") return null;
  const level = typeof payload["level"] === "string" && LEVELS.includes(payload["level"]) ? (payload["level"] as Level) : "info";
  const at = typeof payload["at"] === "number" && Number.isFinite(payload["at"]) ? payload["at"] : now;
  const message = typeof payload["message"] === "string" ? payload["message"] : "";
  const extra = Object.entries(payload)
    .filter(([k]) => !["category", "level", "message", "at"].includes(k))
    .filter(([k, v]) => !(k === "reason" && typeof v === "string" && message.includes(v)))
    .map(([k, v]) => `${k}=${typeof v === "string" ? v : JSON.stringify(v)}`);
  const text = [message, ...extra].filter((s) => s !== "").join(" ");
  return { at, category: categoryOf(payload["category"]), level, message: text === "" ? "(empty)" : text };
}

/** The entry for a safety stop (the vehicle's `stopped` event). */
export function stopEntry(reason: string, at: number): NewEntry {
  return { at, category: "stop", level: "warning", message: `stopped: ${reason}` };
}

/** The entry for a board link change (the vehicle's `link` event). */
export function linkEntry(up: boolean, reason: string | null, at: number): NewEntry {
  return { at, category: "link", level: up ? "info" : "warning", message: `board link ${up ? "up" : "down"}${reason ? `: ${reason}` : ""}` };
}

/** An entry marked as coming from a server recording. */
export const recorded = (entry: NewEntry): NewEntry => ({ ...entry, message: `[recorded] ${entry.message}` });

/**
 * The logger's entry for an event of a server recording (`stopped`, `link`, `helm`,
 * `recording`, and the vehicle's `log` entries), marked "[recorded]"; null for events the logger does not show (presence,
 * control updates) or malformed ones.
 */
export function entryFromRecordedEvent(event: string, payload: unknown, at: number): NewEntry | null {
  if (!isRecord(payload)) return null;
  const text = (s: unknown): string => (typeof s === "string" ? s : "");
  switch (event) {
    case "stopped":
      return recorded(stopEntry(text(payload["reason"]) || "?", at));
    case "link":
      return recorded(linkEntry(payload["up"] === true, text(payload["reason"]) || null, at));
    case "helm": {
      const state = text(payload["state"]);
      if (state === "") return null;
      const pilot = isRecord(payload["pilot"]) ? text(payload["pilot"]["name"]) : "";
      const epoch = typeof payload["epoch"] === "number" ? ` (epoch ${payload["epoch"]})` : "";
      return { at, category: "transfer", level: state === "takeover" ? "warning" : "info", message: `[recorded] helm ${state}${pilot ? `: ${pilot} pilots` : ""}${epoch}` };
    }
    case "recording":
      return { at, category: "recording", level: "error", message: `[recorded] recording stopped: ${text(payload["error"]) || "?"}` };
    case "log": {
      // a server log entry (safety, link, errors, autopilot, …); a safety entry with the
      // stop's reason mirrors a recorded `stopped` event, which is shown already
      if (payload["category"] === "safety" && typeof payload["reason"] === "string") return null;
      const entry = entryFromServerLog(payload, at);
      return entry === null ? null : recorded(entry);
    }
    default:
      return null;
  }
}

const signed = (v: number | undefined): string => formatFixed(v ?? Number.NaN, 2, true);

function commandText(command: Readonly<Record<string, number>>): string {
  return Object.entries(command)
    .map(([k, v]) => `${k} ${signed(v)}`)
    .join(", ");
}

/** What the logger tracks of telemetry, to report changes only. */
export interface TelemetryFacts {
  readonly command: string;
  readonly motors: string;
  readonly gain: number | null;
  readonly depthSetpoint: number | null | undefined;
  readonly headingSetpoint: number | null | undefined;
  readonly linkUp: boolean | null;
}

function numberAt(value: unknown, ...path: string[]): number | null | undefined {
  let v: unknown = value;
  for (const key of path) {
    if (!isRecord(v)) return undefined;
    v = v[key];
  }
  if (v === null) return null;
  return typeof v === "number" && Number.isFinite(v) ? v : undefined;
}

export function telemetryFacts(t: Telemetry): TelemetryFacts {
  const raw = t.raw;
  const command = isRecord(raw["command"]) ? raw["command"] : {};
  const numericCommand: Record<string, number> = {};
  for (const [k, v] of Object.entries(command)) if (typeof v === "number") numericCommand[k] = v;
  const th = t.thrusters;
  const motors = `port ${signed(th.port)} (${th.port_us} µs), vertical ${signed(th.vertical)} (${th.vertical_us} µs), starboard ${signed(th.starboard)} (${th.starboard_us} µs)`;
  // autopilot setpoints: the control settings' autopilot, else the autopilot status
  const depthSp = numberAt(raw, "control", "autopilot", "depth");
  const headingSp = numberAt(raw, "control", "autopilot", "heading");
  const depthStatus = isRecord(raw["autopilot"]) ? raw["autopilot"]["depth"] : undefined;
  const headingStatus = isRecord(raw["autopilot"]) ? raw["autopilot"]["heading"] : undefined;
  const fromStatus = (s: unknown): number | null | undefined =>
    s === null ? null : isRecord(s) ? numberAt(s, "setpoint") : undefined;
  const link = isRecord(raw["link"]) && typeof raw["link"]["up"] === "boolean" ? raw["link"]["up"] : null;
  return {
    command: commandText(numericCommand),
    motors,
    gain: t.control?.gain ?? null,
    depthSetpoint: depthSp !== undefined ? depthSp : fromStatus(depthStatus),
    headingSetpoint: headingSp !== undefined ? headingSp : fromStatus(headingStatus),
    linkUp: link,
  };
}

/** Log entries for what changed between two telemetry samples (nothing for the first one). */
export function telemetryChanges(prev: TelemetryFacts | null, next: TelemetryFacts, at: number): NewEntry[] {
  if (prev === null) return [];
  const out: NewEntry[] = [];
  if (next.command !== prev.command) out.push({ at, category: "thrust_client", level: "info", message: `command ${next.command}` });
  if (next.motors !== prev.motors) out.push({ at, category: "thrust_motors", level: "info", message: next.motors });
  if (next.gain !== null && next.gain !== prev.gain) {
    out.push({ at, category: "gain", level: "info", message: `gain ${prev.gain === null ? "—" : formatFixed(prev.gain, 2)} → ${formatFixed(next.gain, 2)}` });
  }
  if (next.depthSetpoint !== undefined && next.depthSetpoint !== prev.depthSetpoint) {
    const text = next.depthSetpoint === null ? "depth autopilot off" : `depth setpoint ${formatFixed(next.depthSetpoint, 2)} m`;
    out.push({ at, category: "autopilot_depth", level: "info", message: text });
  }
  if (next.headingSetpoint !== undefined && next.headingSetpoint !== prev.headingSetpoint) {
    const text = next.headingSetpoint === null ? "heading autopilot off" : `heading setpoint ${formatHeading(next.headingSetpoint)}°`;
    out.push({ at, category: "autopilot_heading", level: "info", message: text });
  }
  if (next.linkUp !== null && next.linkUp !== prev.linkUp) {
    out.push({ at, category: "link", level: next.linkUp ? "info" : "warning", message: `board link ${next.linkUp ? "up" : "down"} (telemetry)` });
  }
  return out;
}

export const DEFAULT_LOG_CAPACITY = 5000;

/** The entries, bounded; pause freezes what is shown while entries keep coming. */
export class LogBook {
  private readonly items: LogEntry[] = [];
  private next = 1;
  private pausedAfter: number | null = null;
  readonly capacity: number;

  constructor(capacity = DEFAULT_LOG_CAPACITY) {
    this.capacity = capacity;
  }

  add(entry: NewEntry): LogEntry {
    const e: LogEntry = { ...entry, seq: this.next++ };
    this.items.push(e);
    if (this.items.length > this.capacity) this.items.splice(0, this.items.length - this.capacity);
    return e;
  }

  get all(): readonly LogEntry[] {
    return this.items;
  }

  get paused(): boolean {
    return this.pausedAfter !== null;
  }

  pause(): void {
    this.pausedAfter ??= this.next - 1;
  }

  resume(): void {
    this.pausedAfter = null;
  }

  /** Entries that arrived since the pause. */
  get pending(): number {
    const after = this.pausedAfter;
    return after === null ? 0 : this.items.filter((e) => e.seq > after).length;
  }

  clear(): void {
    this.items.length = 0;
    if (this.pausedAfter !== null) this.pausedAfter = this.next - 1;
  }

  /** Entries to show: frozen at the pause, in the selected categories, matching `filter`. */
  visible(selected: ReadonlySet<string>, filter: string): LogEntry[] {
    const after = this.pausedAfter;
    const text = filter.trim().toLowerCase();
    return this.items.filter(
      (e) =>
        (after === null || e.seq <= after) &&
        selected.has(e.category) &&
        (text === "" || e.message.toLowerCase().includes(text) || categoryLabel(e.category).toLowerCase().includes(text)),
    );
  }
}

/** ISO time with milliseconds, local-independent: "2026-05-01T12:00:00.123Z". */
export function isoTime(at: number): string {
  return new Date(at).toISOString();
}

/** "12:00:00.123" in local time, for the screen. */
export function clockTime(at: number): string {
  const d = new Date(at);
  const p = (n: number, w = 2): string => String(n).padStart(w, "0");
  return `${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}.${p(d.getMilliseconds(), 3)}`;
}

/** The download: one line per entry, tab-separated time, category, level, message. */
export function formatLog(entries: readonly LogEntry[]): string {
  const clean = (s: string): string => s.replace(/[\t\r\n]+/g, " ");
  return entries
    .map((e) => [isoTime(e.at), e.category, e.level, clean(e.message)].join("\t"))
    .join("\n")
    .concat(entries.length > 0 ? "\n" : "");
}
