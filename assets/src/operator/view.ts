/**
 * The operator page's DOM: looks up the elements of static/index.html once and writes values
 * into them. No decisions here beyond formatting.
 */

import type { Pilot, PresenceEntry, Telemetry, Thrusters } from "../lib/protocol";
import { PLACEHOLDER, clampUnit, formatFixed, formatHeading } from "../lib/units";
import type { ConnectionStatus } from "../lib/vehicle_client";

export type MessageKind = "info" | "warn" | "error";
export type TelemetryState = "none" | "live" | "stale";

const THRUSTERS = ["port", "vertical", "starboard"] as const;
type ThrusterName = (typeof THRUSTERS)[number];

const STATUS_TEXT: Readonly<Record<ConnectionStatus, string>> = {
  connecting: "connecting",
  connected: "connected",
  disconnected: "disconnected",
};

function byId(doc: Document, id: string): HTMLElement {
  const el = doc.getElementById(id);
  if (!el) throw new Error(`operator page: element #${id} is missing from index.html`);
  return el;
}

/** Sets text only when it changed (telemetry arrives at 20 Hz; most values repeat). */
function setText(el: HTMLElement, text: string): void {
  if (el.textContent !== text) el.textContent = text;
}

/** Bar geometry for a value in [-1, 1] on a meter centred on zero (percent of the width). */
export function barGeometry(value: number): { left: number; width: number; reverse: boolean } {
  const v = clampUnit(value);
  const width = Math.abs(v) * 50;
  return { left: v < 0 ? 50 - width : 50, width, reverse: v < 0 };
}

export class OperatorView {
  private readonly status: HTMLElement;
  private readonly vehicleId: HTMLElement;
  private readonly pilot: HTMLElement;
  private readonly observers: HTMLElement;
  private readonly heading: HTMLElement;
  private readonly depth: HTMLElement;
  private readonly x: HTMLElement;
  private readonly y: HTMLElement;
  private readonly speedU: HTMLElement;
  private readonly telemetryAge: HTMLElement;
  private readonly cmd: Readonly<Record<"surge" | "heave" | "yaw", HTMLElement>>;
  private readonly thrValue: Readonly<Record<ThrusterName, HTMLElement>>;
  private readonly thrBar: Readonly<Record<ThrusterName, HTMLElement>>;
  private readonly message: HTMLElement;
  private messageSource: string | null = null;

  constructor(doc: Document) {
    this.status = byId(doc, "status");
    this.vehicleId = byId(doc, "vehicle-id");
    this.pilot = byId(doc, "pilot");
    this.observers = byId(doc, "observers");
    this.heading = byId(doc, "heading");
    this.depth = byId(doc, "depth");
    this.x = byId(doc, "x");
    this.y = byId(doc, "y");
    this.speedU = byId(doc, "speed-u");
    this.telemetryAge = byId(doc, "telemetry-age");
    this.cmd = {
      surge: byId(doc, "cmd-surge"),
      heave: byId(doc, "cmd-heave"),
      yaw: byId(doc, "cmd-yaw"),
    };
    this.thrValue = {
      port: byId(doc, "thr-port"),
      vertical: byId(doc, "thr-vertical"),
      starboard: byId(doc, "thr-starboard"),
    };
    this.thrBar = {
      port: byId(doc, "bar-port"),
      vertical: byId(doc, "bar-vertical"),
      starboard: byId(doc, "bar-starboard"),
    };
    this.message = byId(doc, "message");
  }

  setVehicle(id: string): void {
    setText(this.vehicleId, id);
    document.title = `Neptunus — ${id}`;
  }

  setStatus(status: ConnectionStatus): void {
    this.status.dataset["state"] = status;
    setText(this.status, STATUS_TEXT[status]);
  }

  setPilot(pilot: Pilot | null): void {
    setText(this.pilot, pilot ? pilot.name : "nobody");
  }

  setPresence(entries: readonly PresenceEntry[]): void {
    const count = entries.reduce((n, e) => n + e.connections, 0);
    setText(this.observers, String(count));
    this.observers.title = entries.map((e) => e.name).join(", ");
  }

  setTelemetryState(state: TelemetryState, ageMs?: number): void {
    this.telemetryAge.dataset["state"] = state;
    const text =
      state === "none"
        ? "none yet"
        : state === "live"
          ? "live"
          : `stale (${((ageMs ?? 0) / 1000).toFixed(1)} s)`;
    setText(this.telemetryAge, text);
  }

  showTelemetry(t: Telemetry): void {
    setText(this.heading, formatHeading(t.measurement.heading));
    setText(this.depth, formatFixed(t.measurement.depth, 2));
    // position and speed come from the simulator; a real board has no position source yet
    setText(this.x, t.sim ? formatFixed(t.sim.x, 2) : PLACEHOLDER);
    setText(this.y, t.sim ? formatFixed(t.sim.y, 2) : PLACEHOLDER);
    setText(this.speedU, t.sim ? formatFixed(t.sim.u, 2) : PLACEHOLDER);
    setText(this.cmd.surge, formatFixed(t.command.surge, 2, true));
    setText(this.cmd.heave, formatFixed(t.command.heave, 2, true));
    setText(this.cmd.yaw, formatFixed(t.command.yaw, 2, true));
    this.showThrusters(t.thrusters);
  }

  showThrusters(thrusters: Thrusters): void {
    for (const name of THRUSTERS) {
      const value = thrusters[name];
      const us = thrusters[`${name}_us`];
      const el = this.thrValue[name];
      setText(el, formatFixed(value, 2, true));
      el.dataset["value"] = String(value);
      el.title = `${Math.round(us)} µs`;
      const bar = this.thrBar[name];
      const g = barGeometry(value);
      bar.style.left = `${g.left}%`;
      bar.style.width = `${g.width}%`;
      bar.classList.toggle("reverse", g.reverse);
    }
  }

  /** Shows a message; `source` lets a later success clear only its own kind of message. */
  showMessage(text: string, kind: MessageKind, source: string | null = null): void {
    this.message.dataset["kind"] = kind;
    setText(this.message, text);
    this.messageSource = source;
  }

  /** Clears the message if it came from `source`. */
  clearMessage(source: string): void {
    if (this.messageSource === source) this.showMessage("", "info", null);
  }
}
