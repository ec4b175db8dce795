/**
 * The dives of `GET /api/recordings` (docs/API.md) as the replay page lists them (pure).
 */

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
    title: typeof v["title"] === "string" && v["title"] !== "" ? v["title"] : null,
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
