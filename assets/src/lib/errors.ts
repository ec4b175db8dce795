/**
 * The text to show for a failure: an `Error`'s message (for a `CommandError` that is the
 * server's reason, e.g. "not_in_control"), anything else as a string.
 */
export function reasonOf(err: unknown): string {
  return err instanceof Error ? err.message : String(err);
}

/** The reason in a failed HTTP answer's `{"error": …}` body, else its status ("HTTP 502"). */
export async function responseReason(response: Response): Promise<string> {
  try {
    const body: unknown = await response.json();
    if (typeof body === "object" && body !== null && !Array.isArray(body)) {
      const error = (body as Record<string, unknown>)["error"];
      if (typeof error === "string") return error;
    }
  } catch {
    // not JSON
  }
  return `HTTP ${response.status}`;
}
