/**
 * Round-trip latency from heartbeat replies: the time from sending a `heartbeat` (the pilot's,
 * every 100 ms, or the socket's own `phoenix` heartbeat for watchers) to its reply.
 * Keeps the last value, an exponentially smoothed mean and the maximum of the last `window`
 * samples. Pure: the page passes measured durations in ms.
 */

export interface LatencySummary {
  /** ms, the last round trip; null before the first */
  readonly last: number | null;
  /** ms, smoothed mean */
  readonly mean: number | null;
  /** ms, worst of the recent samples */
  readonly max: number | null;
  readonly samples: number;
}

export class LatencyTracker {
  private readonly recent: number[] = [];
  private lastValue: number | null = null;
  private meanValue: number | null = null;
  private count = 0;
  private readonly window: number;
  private readonly alpha: number;

  constructor(window = 50, alpha = 0.2) {
    this.window = Math.max(1, window);
    this.alpha = alpha;
  }

  add(rttMs: number): void {
    if (!Number.isFinite(rttMs) || rttMs < 0) return;
    this.lastValue = rttMs;
    this.meanValue = this.meanValue === null ? rttMs : this.meanValue + this.alpha * (rttMs - this.meanValue);
    this.recent.push(rttMs);
    if (this.recent.length > this.window) this.recent.shift();
    this.count += 1;
  }

  reset(): void {
    this.recent.length = 0;
    this.lastValue = null;
    this.meanValue = null;
    this.count = 0;
  }

  get summary(): LatencySummary {
    return {
      last: this.lastValue,
      mean: this.meanValue,
      max: this.recent.length > 0 ? Math.max(...this.recent) : null,
      samples: this.count,
    };
  }
}

/** "12 ms" (< 10 ms with one decimal); "—" without a value. */
export function formatMs(ms: number | null): string {
  if (ms === null || !Number.isFinite(ms)) return "—";
  return ms < 10 ? `${ms.toFixed(1)} ms` : `${Math.round(ms)} ms`;
}
