/**
 * The fleet overview's view model (pure): every vehicle of the fleet as the server's
 * directory lists it (topic `fleet`: the join reply, then `vehicles` when it changes, and
 * `unreachable` / `reachable` at once), turned into the rows the operator page shows —
 * depth, heading, pilot, link, REC, node and status — each opening its vehicle
 * (`?vehicle=ID`).
 */

import type { VehicleInfo } from "../lib/protocol";
import { PLACEHOLDER, formatFixed, formatHeading } from "../lib/units";
import { vehicleHref } from "./format";

export interface OverviewRow {
  readonly id: string;
  /** the operator page's address of this vehicle (this page's other parameters kept) */
  readonly href: string;
  /** the vehicle this page shows */
  readonly current: boolean;
  readonly node: string;
  readonly status: "up" | "unreachable";
  /** "12.34 m" or "—" */
  readonly depth: string;
  /** "45.0°" or "—" */
  readonly heading: string;
  /** the pilot's name, "nobody", or "—" when unknown */
  readonly pilot: string;
  /** "up", "down (reason)", or "—" */
  readonly link: string;
  /** true: up; false: down; null: unknown */
  readonly linkUp: boolean | null;
  /** its recorder records */
  readonly rec: boolean;
  /** one line for a screen reader or a tooltip */
  readonly summary: string;
}

/** The rows of the overview, in the server's order (by id). */
export function overviewRows(fleet: readonly VehicleInfo[], currentId: string | null, search: string): OverviewRow[] {
  return fleet.map((v) => {
    const status = v.status === "unreachable" ? "unreachable" : "up";
    const d = status === "up" ? (v.detail ?? null) : null;
    const depth = d?.depth == null ? PLACEHOLDER : `${formatFixed(d.depth, 2)} m`;
    const heading = d?.heading == null ? PLACEHOLDER : `${formatHeading(d.heading)}°`;
    const pilot = d === null ? PLACEHOLDER : (d.pilot ?? "nobody");
    const link = d?.link == null ? PLACEHOLDER : d.link.up ? "up" : `down${d.link.reason ? ` (${d.link.reason})` : ""}`;
    const linkUp = d?.link == null ? null : d.link.up;
    const rec = d?.recording ?? false;
    const node = v.node ?? PLACEHOLDER;
    const summary =
      status === "unreachable"
        ? `${v.id} on ${node}: unreachable`
        : `${v.id} on ${node}: depth ${depth}, heading ${heading}, pilot ${pilot}, link ${link}${rec ? ", recording" : ""}`;
    return { id: v.id, href: vehicleHref(search, v.id), current: v.id === currentId, node, status, depth, heading, pilot, link, linkUp, rec, summary };
  });
}

/**
 * The fleet after `unreachable` (the vehicle's node is cut off: what it said is no longer
 * known) or `reachable` (up again; its details come with the next `vehicles`). An id not in
 * the list changes nothing (the next `vehicles` lists it).
 */
export function withReachability(fleet: readonly VehicleInfo[], id: string, reachable: boolean): readonly VehicleInfo[] {
  if (!fleet.some((v) => v.id === id)) return fleet;
  return fleet.map((v) => {
    if (v.id !== id) return v;
    if (reachable) return { ...v, status: "up" };
    const { detail: _dropped, ...rest } = v;
    return { ...rest, status: "unreachable" };
  });
}
