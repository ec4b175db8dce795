/**
 * Camera snapshots on the server (docs/API.md, "Snapshots"): take one of the vehicle's
 * current picture, list them, their download addresses. Pure decoding plus thin fetch
 * wrappers, like the recordings' (lib/recordings.ts).
 */

import { responseReason } from "../lib/errors";

export interface SnapshotInfo {
  readonly vehicle: string;
  readonly name: string;
  readonly bytes: number;
  /** ms since the epoch */
  readonly takenAt: number;
  /** the vehicle's depth (m) and heading (rad) when it was taken; null when not known */
  readonly depth: number | null;
  readonly heading: number | null;
}

type Fetch = (input: string, init?: RequestInit) => Promise<Response>;

function isRecord(v: unknown): v is Record<string, unknown> {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

export function decodeSnapshot(v: unknown): SnapshotInfo | null {
  if (!isRecord(v)) return null;
  const { vehicle, name, bytes, taken_at: takenAt, depth, heading } = v;
  if (typeof vehicle !== "string" || typeof name !== "string" || typeof bytes !== "number" || typeof takenAt !== "number") return null;
  const num = (x: unknown): number | null => (typeof x === "number" && Number.isFinite(x) ? x : null);
  return { vehicle, name, bytes, takenAt, depth: num(depth), heading: num(heading) };
}

/** The body of `GET /api/snapshots?vehicle=…`, or null when it is not one. */
export function decodeSnapshotList(body: unknown): SnapshotInfo[] | null {
  if (!isRecord(body) || !Array.isArray(body["snapshots"])) return null;
  const out: SnapshotInfo[] = [];
  for (const item of body["snapshots"]) {
    const info = decodeSnapshot(item);
    if (info === null) return null;
    out.push(info);
  }
  return out;
}

/** A snapshot's address; the token rides in the query (a plain link works). */
export function snapshotUrl(info: Pick<SnapshotInfo, "vehicle" | "name">, token: string | null): string {
  const query = token !== null ? `?${new URLSearchParams({ token }).toString()}` : "";
  return `/api/snapshots/${encodeURIComponent(info.vehicle)}/${encodeURIComponent(info.name)}${query}`;
}

function authHeaders(token: string | null): Record<string, string> {
  return token !== null ? { authorization: `Bearer ${token}` } : {};
}

/** `POST /api/vehicles/<vehicle>/snapshot`: the server saves the current picture. Rejects with its reason. */
export async function takeSnapshot(vehicle: string, token: string | null, fetchFn: Fetch = fetch): Promise<SnapshotInfo> {
  const response = await fetchFn(`/api/vehicles/${encodeURIComponent(vehicle)}/snapshot`, { method: "POST", headers: authHeaders(token) });
  if (!response.ok) throw new Error(await responseReason(response));
  const body: unknown = await response.json();
  const info = decodeSnapshot(isRecord(body) ? body["snapshot"] : undefined);
  if (info === null) throw new Error("unexpected reply to a snapshot");
  return info;
}

/** `GET /api/snapshots?vehicle=…`, newest first. Rejects with the server's reason. */
export async function fetchSnapshots(vehicle: string, token: string | null, fetchFn: Fetch = fetch): Promise<SnapshotInfo[]> {
  const response = await fetchFn(`/api/snapshots?${new URLSearchParams({ vehicle }).toString()}`, { headers: authHeaders(token), cache: "no-store" });
  if (!response.ok) throw new Error(await responseReason(response));
  const list = decodeSnapshotList(await response.json());
  if (list === null) throw new Error("unexpected reply to /api/snapshots");
  return [...list].sort((a, b) => b.takenAt - a.takenAt);
}
