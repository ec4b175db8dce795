/**
 * Writes to one place on the server one request at a time, the newest last.
 *
 * Two requests on their way at once may be served in either order, so the older one can land
 * last and undo the newer (a change to the plots lost). Here a write asked for while another
 * is on its way waits for it; of several asked for meanwhile only the newest is sent (the
 * others are superseded by it). The promise of a write resolves once it, or a write newer
 * than it, has been stored; it rejects with the error of the request that carried it.
 */
export class NewestWriter {
  private running = false;
  private pending: { readonly write: () => Promise<void>; readonly waiters: Waiter[] } | null = null;

  write(write: () => Promise<void>): Promise<void> {
    return new Promise<void>((resolve, reject) => {
      const waiters = [...(this.pending?.waiters ?? []), { resolve, reject }];
      this.pending = { write, waiters };
      if (!this.running) void this.run();
    });
  }

  private async run(): Promise<void> {
    this.running = true;
    try {
      while (this.pending !== null) {
        const { write, waiters } = this.pending;
        this.pending = null;
        try {
          await write();
          for (const w of waiters) w.resolve();
        } catch (err) {
          for (const w of waiters) w.reject(err);
        }
      }
    } finally {
      this.running = false;
    }
  }
}

interface Waiter {
  readonly resolve: () => void;
  readonly reject: (err: unknown) => void;
}
