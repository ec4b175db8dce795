/**
 * The text to show for a failure: an `Error`'s message (for a `CommandError` that is the
 * server's reason, e.g. "not_in_control"), anything else as a string.
 */
export function reasonOf(err: unknown): string {
  return err instanceof Error ? err.message : String(err);
}
