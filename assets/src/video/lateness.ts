/**
 * How late a frame reaches the page's code (pure), without trusting any clock: a browser
 * hands WebSocket messages to a page in order, however long its main thread was busy, so a
 * starved page can find seconds of frames waiting for it. For each frame the page knows
 * `local − server`: this page's wall clock when it handles the frame minus the server's
 * arrival stamp — the clocks' offset plus the link's delay plus the wait in the page. The
 * lowest of the last WINDOW_MS is the link's own (nothing waited then); a frame above it by
 * more than LATE_MS waited in the page, and is dropped (up to a fresh keyframe, core.ts).
 * A link that is slow all the time is not late: its floor is high too. Frames late without a
 * break for RESET_MS mean the floor is wrong (a clock was set, the route changed; a page
 * catching up drops a backlog in far less): the floor starts again from the frame at hand.
 * `localMs` should be a monotonic wall clock (performance.timeOrigin + performance.now()).
 */

export const WINDOW_MS = 30_000;
/** waited this long in the page (ms): drop it, catch up */
export const LATE_MS = 1000;
export const RESET_MS = 3000;
const BUCKET_MS = 1000;

interface Bucket {
  readonly start: number;
  min: number;
}

export class Lateness {
  private buckets: Bucket[] = [];
  /** when the frames began to come late without a break (null: the last was not late) */
  private lateSince: number | null = null;

  /**
   * A frame stamped `serverMs` (the server's clock) handled at `localMs` (this page's wall
   * clock): how much later than the link's floor it came (ms, ≥ 0).
   */
  observe(localMs: number, serverMs: number): number {
    const delay = localMs - serverMs;
    if (!Number.isFinite(delay)) return 0;
    const start = Math.floor(localMs / BUCKET_MS) * BUCKET_MS;
    const last = this.buckets[this.buckets.length - 1];
    if (last !== undefined && last.start === start) last.min = Math.min(last.min, delay);
    else this.buckets.push({ start, min: delay });
    this.buckets = this.buckets.filter((b) => b.start > localMs - WINDOW_MS);
    let floor = delay;
    for (const b of this.buckets) floor = Math.min(floor, b.min);
    const late = delay - floor;
    if (late <= LATE_MS) {
      this.lateSince = null;
      return late;
    }
    this.lateSince ??= localMs;
    if (localMs - this.lateSince < RESET_MS) return late;
    this.reset();
    this.buckets.push({ start, min: delay });
    return 0;
  }

  reset(): void {
    this.buckets = [];
    this.lateSince = null;
  }
}
