/**
 * The server's recordings (`/api/recordings`, docs/API.md): listing, download addresses and
 * the JSON lines the developer page replays. Pure decoding plus thin fetch wrappers.
 */

import { responseReason } from "./errors";

export interface RecordingInfo {
  readonly vehicle: string;
  readonly name: string;
  readonly bytes: number;
  /** ms since the epoch, from the file name (null if it does not say) */
  readonly startedAt: number | null;
  readonly modifiedAt: number;
}

export interface RecordingList {
  /** whether the server records at all */
  readonly recording: boolean;
  readonly recordings: readonly RecordingInfo[];
}

export interface RecordedEntry {
  readonly at: number;
  readonly event: string;
  readonly payload: Readonly<Record<string, unknown>>;
}

export interface ParsedRecording {
  readonly telemetry: readonly RecordedEntry[];
  readonly events: readonly RecordedEntry[];
  /** lines that were not entries (reported, not fatal) */
  readonly bad: number;
}

type Fetch = (input: string, init?: RequestInit) => Promise<Response>;

function isRecord(v: unknown): v is Record<string, unknown> {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

function decodeInfo(v: unknown): RecordingInfo | null {
  if (!isRecord(v)) return null;
  const { vehicle, name, bytes, started_at: startedAt, modified_at: modifiedAt } = v;
  if (typeof vehicle !== "string" || typeof name !== "string" || typeof bytes !== "number" || typeof modifiedAt !== "number") return null;
  if (startedAt !== null && typeof startedAt !== "number") return null;
  return { vehicle, name, bytes, startedAt, modifiedAt };
}

/** The body of `GET /api/recordings`, or null when it is not one. */
export function decodeRecordingList(body: unknown): RecordingList | null {
  if (!isRecord(body) || typeof body["recording"] !== "boolean" || !Array.isArray(body["recordings"])) return null;
  const recordings: RecordingInfo[] = [];
  for (const item of body["recordings"]) {
    const info = decodeInfo(item);
    if (info === null) return null;
    recordings.push(info);
  }
  return { recording: body["recording"], recordings };
}

/** JSON lines `{"at", "event", "payload"}` split into telemetry and the other events. */
export function parseRecordingLines(text: string): ParsedRecording {
  const telemetry: RecordedEntry[] = [];
  const events: RecordedEntry[] = [];
  let bad = 0;
  for (const line of text.split("\n")) {
    if (line.trim() === "") continue;
    let value: unknown;
    try {
      value = JSON.parse(line);
    } catch {
      bad += 1;
      continue;
    }
    if (!isRecord(value) || typeof value["at"] !== "number" || typeof value["event"] !== "string" || !isRecord(value["payload"])) {
      bad += 1;
      continue;
    }
    const entry: RecordedEntry = { at: value["at"], event: value["event"], payload: value["payload"] };
    (entry.event === "telemetry" ? telemetry : events).push(entry);
  }
  return { telemetry, events, bad };
}

/** The address of a recording's export; the token rides in the query (a plain link works). */
/** The exports the server makes of a recording or dive (docs/API.md, `GET /api/recordings/ID/NAME`). */
export type ExportFormat = "csv" | "jsonl" | "ass" | "mp4" | "mcap";

/** A download address of a recording's export; the token (if any) in the query, as links carry no header. */
export function recordingUrl(
  info: Pick<RecordingInfo, "vehicle" | "name">,
  format: ExportFormat,
  token: string | null,
  max?: number,
): string {
  const query = new URLSearchParams({ format });
  if (max !== undefined) query.set("max", String(max));
  if (token !== null) query.set("token", token);
  return `/api/recordings/${encodeURIComponent(info.vehicle)}/${encodeURIComponent(info.name)}?${query.toString()}`;
}

/** "1.2 MB" */
export function formatBytes(bytes: number): string {
  if (bytes < 1000) return `${bytes} B`;
  if (bytes < 1e6) return `${(bytes / 1e3).toFixed(1)} kB`;
  if (bytes < 1e9) return `${(bytes / 1e6).toFixed(1)} MB`;
  return `${(bytes / 1e9).toFixed(2)} GB`;
}

/** `GET /api/recordings?vehicle=…`. Rejects with the server's reason. */
export async function fetchRecordings(vehicle: string, token: string | null, fetchFn: Fetch = fetch): Promise<RecordingList> {
  const headers: Record<string, string> = {};
  if (token !== null) headers["authorization"] = `Bearer ${token}`;
  const response = await fetchFn(`/api/recordings?${new URLSearchParams({ vehicle }).toString()}`, { headers, cache: "no-store" });
  if (!response.ok) throw new Error(await responseReason(response));
  const list = decodeRecordingList(await response.json());
  if (list === null) throw new Error("unexpected reply to /api/recordings");
  return list;
}

/** A recording's entries, thinned by the server to at most `max` telemetry samples. */
export async function fetchRecording(info: RecordingInfo, token: string | null, max: number, fetchFn: Fetch = fetch): Promise<ParsedRecording> {
  const response = await fetchFn(recordingUrl(info, "jsonl", token, max), { cache: "no-store" });
  if (!response.ok) throw new Error(await responseReason(response));
  return parseRecordingLines(await response.text());
}

/** `DELETE /api/recordings/<vehicle>/<name>`. Rejects with the server's reason. */
export async function deleteRecording(info: Pick<RecordingInfo, "vehicle" | "name">, token: string | null, fetchFn: Fetch = fetch): Promise<void> {
  const headers: Record<string, string> = {};
  if (token !== null) headers["authorization"] = `Bearer ${token}`;
  const response = await fetchFn(`/api/recordings/${encodeURIComponent(info.vehicle)}/${encodeURIComponent(info.name)}`, { method: "DELETE", headers });
  if (!response.ok) throw new Error(await responseReason(response));
}
