/**
 * The dives of `GET /api/recordings` (docs/API.md) as the replay page lists them, and their
 * title and notes as the page edits them (`PUT /api/recordings/ID/NAME`) (pure).
 */

import type { SessionInfo } from "../lib/session";

export interface DiveInfo {
  readonly vehicle: string;
  readonly name: string;
  readonly startedAt: number | null;
  readonly endedAt: number | null;
  readonly durationMs: number | null;
  readonly maxDepth: number | null;
  readonly pilots: readonly string[];
  readonly stops: number;
  readonly snapshots: number;
  readonly video: { readonly codec: string; readonly segments: number } | null;
  readonly title: string | null;
  readonly notes: string | null;
  readonly recording: boolean;
  readonly problems: readonly string[];
}

function isRecord(v: unknown): v is Record<string, unknown> {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

function numOrNull(v: unknown): number | null {
  return typeof v === "number" ? v : null;
}

function strings(v: unknown): string[] {
  return Array.isArray(v) ? v.filter((x): x is string => typeof x === "string") : [];
}

function textOrNull(v: unknown): string | null {
  return typeof v === "string" && v !== "" ? v : null;
}

/** One dive as listed, or null when it is not one (a name and vehicle are needed). */
export function decodeDive(v: unknown): DiveInfo | null {
  if (!isRecord(v) || typeof v["vehicle"] !== "string" || typeof v["name"] !== "string") return null;
  const video = v["video"];
  return {
    vehicle: v["vehicle"],
    name: v["name"],
    startedAt: numOrNull(v["started_at"]),
    endedAt: numOrNull(v["ended_at"]),
    durationMs: numOrNull(v["duration_ms"]),
    maxDepth: numOrNull(v["max_depth"]),
    pilots: strings(v["pilots"]),
    stops: numOrNull(v["stops"]) ?? 0,
    snapshots: numOrNull(v["snapshots"]) ?? 0,
    video: isRecord(video) && typeof video["codec"] === "string" ? { codec: video["codec"], segments: numOrNull(video["segments"]) ?? 0 } : null,
    title: textOrNull(v["title"]),
    notes: textOrNull(v["notes"]),
    recording: v["recording"] === true,
    problems: strings(v["problems"]),
  };
}

/** The dives of a `GET /api/recordings` body, or null when it is not one. */
export function decodeDiveList(body: unknown): DiveInfo[] | null {
  if (!isRecord(body) || !Array.isArray(body["recordings"])) return null;
  const out: DiveInfo[] = [];
  for (const item of body["recordings"]) {
    const dive = decodeDive(item);
    if (dive === null) return null;
    out.push(dive);
  }
  return out;
}

/** Who may edit a dive's title and notes, as the server decides: local mode, a pilot or the main station. */
export function mayEditNotes(session: SessionInfo | null): boolean {
  if (session === null) return false;
  if (session.mode === "local") return true;
  return session.user?.role === "pilot" || session.user?.role === "main_station";
}

export interface NotesChanges {
  title?: string | null;
  notes?: string | null;
}

/**
 * The body of `PUT /api/recordings/ID/NAME` for the title and notes typed: only what changed
 * (trimmed, as the server keeps it; empty clears it); null when nothing did.
 */
export function notesChanges(dive: Pick<DiveInfo, "title" | "notes">, title: string, notes: string): NotesChanges | null {
  const changes: NotesChanges = {};
  const t = title.trim() === "" ? null : title.trim();
  const n = notes.trim() === "" ? null : notes.trim();
  if (t !== dive.title) changes.title = t;
  if (n !== dive.notes) changes.notes = n;
  return Object.keys(changes).length > 0 ? changes : null;
}

/** The dive with the title and notes of a `PUT` reply (`{"notes": {"title", "notes", …}}`), or null when it is not one. */
export function withNotes(dive: DiveInfo, reply: unknown): DiveInfo | null {
  if (!isRecord(reply)) return null;
  const saved = reply["notes"];
  if (!isRecord(saved)) return null;
  const { title, notes } = saved;
  if ((title !== null && typeof title !== "string") || (notes !== null && typeof notes !== "string")) return null;
  return { ...dive, title: textOrNull(title), notes: textOrNull(notes) };
}
