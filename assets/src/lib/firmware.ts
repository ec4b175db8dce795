/**
 * The SD-card image's record of its last firmware update, as `GET /api/health` carries it
 * (`firmware_update`, written by the card's `neptunus-firmware`): the operator page says when
 * an update was rolled back, and why.
 */

/** What the page says, or null when there is nothing to say (no record, or an update kept). */
export function rollbackNotice(health: unknown): string | null {
  if (typeof health !== "object" || health === null) return null;
  const record: unknown = (health as { firmware_update?: unknown }).firmware_update;
  if (typeof record !== "object" || record === null) return null;
  const r = record as Record<string, unknown>;
  if (r["result"] !== "rolled-back") return null;
  const text = (key: string): string | null => (typeof r[key] === "string" && r[key] !== "" ? (r[key] as string) : null);
  const version = text("version") ?? "a new firmware";
  const running = text("running");
  const reason = text("reason") ?? "no reason recorded";
  const at = text("at");
  return (
    `The firmware update to ${version} was rolled back${at === null ? "" : ` (${at})`}: ${reason}.` +
    (running === null ? "" : ` The vehicle runs ${running}.`)
  );
}

/** Fetches /api/health once: the notice, or null (also when the server cannot be asked). */
export async function fetchRollbackNotice(fetcher: typeof fetch = fetch): Promise<string | null> {
  try {
    const response = await fetcher("/api/health", { cache: "no-store" });
    if (!response.ok) return null;
    return rollbackNotice(await response.json());
  } catch {
    return null;
  }
}
