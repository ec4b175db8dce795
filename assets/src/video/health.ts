/**
 * The stream's health as the pilot sees it (pure): frames shown per second, bitrate, frames
 * dropped, freezes, and the picture's latency — server→display for any camera (the server's
 * arrival stamp against the server's clock) and render→display for the sim camera (the
 * stamp in its picture). The page feeds events with its own clock (ms); `summary` says what
 * the last seconds looked like.
 */

/** figures over this window (ms) */
export const WINDOW_MS = 2000;
/** no new picture for this long is a freeze (ms), however slow the camera (see freezeAfterMs) */
export const FREEZE_MIN_MS = 250;

/** A gap between pictures that counts as a freeze: 4 frame intervals, at least FREEZE_MIN_MS. */
export function freezeAfterMs(fps: number): number {
  return fps > 0 ? Math.max(FREEZE_MIN_MS, 4000 / fps) : FREEZE_MIN_MS * 4;
}

export interface LatencyFigures {
  /** median and 99th percentile over the window (ms); null without samples */
  readonly p50: number | null;
  readonly p99: number | null;
  /** the newest sample (ms) */
  readonly last: number | null;
}

export interface HealthSummary {
  /** pictures shown per second over the window */
  readonly fps: number;
  /** bits per second received over the window */
  readonly bitrate: number;
  /** frames this page never showed: skipped by the server, lost, dropped to catch up */
  readonly dropped: number;
  readonly freezes: number;
  /** no picture for longer than a freeze right now */
  readonly frozen: boolean;
  readonly serverToDisplay: LatencyFigures;
  readonly renderToDisplay: LatencyFigures;
}

/** The value at quantile q of ascending `sorted` (nearest rank); null when empty. */
export function quantile(sorted: readonly number[], q: number): number | null {
  if (sorted.length === 0) return null;
  const rank = Math.min(sorted.length - 1, Math.max(0, Math.ceil(q * sorted.length) - 1));
  return sorted[rank] ?? null;
}

interface Timed {
  readonly at: number;
  readonly value: number;
}

/** Samples of the last WINDOW_MS. */
class Window {
  private items: Timed[] = [];

  add(at: number, value: number): void {
    this.items.push({ at, value });
  }

  /** Forgets samples older than the window, returns those left. */
  current(now: number): readonly Timed[] {
    const from = now - WINDOW_MS;
    let i = 0;
    while (i < this.items.length && (this.items[i]?.at ?? 0) < from) i += 1;
    if (i > 0) this.items = this.items.slice(i);
    return this.items;
  }

  clear(): void {
    this.items = [];
  }
}

function figures(samples: readonly Timed[]): LatencyFigures {
  const sorted = samples.map((s) => s.value).sort((a, b) => a - b);
  return { p50: quantile(sorted, 0.5), p99: quantile(sorted, 0.99), last: samples[samples.length - 1]?.value ?? null };
}

export class StreamHealth {
  private readonly bytes = new Window();
  private readonly shown = new Window();
  private readonly serverLatency = new Window();
  private readonly renderLatency = new Window();
  private lastShownAt: number | null = null;
  private inFreeze = false;
  private expectedFps = 0;
  dropped = 0;
  freezes = 0;

  /** The camera's nominal rate (from the `stream` event): sets what counts as a freeze. */
  setFps(fps: number): void {
    this.expectedFps = fps;
  }

  received(now: number, bytes: number): void {
    this.bytes.add(now, bytes);
  }

  drop(frames: number): void {
    if (frames > 0) this.dropped += frames;
  }

  /** A picture reached the screen at `now`, with its latencies (ms) where known. */
  displayed(now: number, serverToDisplayMs: number | null, renderToDisplayMs: number | null): void {
    if (this.lastShownAt !== null && !this.inFreeze && now - this.lastShownAt > freezeAfterMs(this.expectedFps)) this.freezes += 1;
    this.inFreeze = false;
    this.lastShownAt = now;
    this.shown.add(now, 1);
    if (serverToDisplayMs !== null && Number.isFinite(serverToDisplayMs)) this.serverLatency.add(now, serverToDisplayMs);
    if (renderToDisplayMs !== null && Number.isFinite(renderToDisplayMs)) this.renderLatency.add(now, renderToDisplayMs);
  }

  /**
   * The stream stopped on purpose (camera restarting, socket closed, a new stream): the wait
   * for the next picture is not a freeze of a running stream.
   */
  pause(): void {
    this.lastShownAt = null;
    this.inFreeze = false;
  }

  summary(now: number): HealthSummary {
    const frozen = this.lastShownAt !== null && now - this.lastShownAt > freezeAfterMs(this.expectedFps);
    if (frozen && !this.inFreeze) {
      // counted once, when first seen (a picture that ends it does not count it again)
      this.freezes += 1;
      this.inFreeze = true;
    }
    const shown = this.shown.current(now);
    const bytes = this.bytes.current(now).reduce((n, s) => n + s.value, 0);
    return {
      fps: (shown.length * 1000) / WINDOW_MS,
      bitrate: (bytes * 8 * 1000) / WINDOW_MS,
      dropped: this.dropped,
      freezes: this.freezes,
      frozen,
      serverToDisplay: figures(this.serverLatency.current(now)),
      renderToDisplay: figures(this.renderLatency.current(now)),
    };
  }

  reset(): void {
    for (const w of [this.bytes, this.shown, this.serverLatency, this.renderLatency]) w.clear();
    this.lastShownAt = null;
    this.inFreeze = false;
    this.dropped = 0;
    this.freezes = 0;
  }
}

/** "1.2 Mbit/s" */
export function formatBitrate(bps: number): string {
  if (bps < 1000) return `${Math.round(bps)} bit/s`;
  if (bps < 1e6) return `${(bps / 1e3).toFixed(0)} kbit/s`;
  return `${(bps / 1e6).toFixed(1)} Mbit/s`;
}

/** "83 ms", "—" when unknown. */
export function formatLatency(ms: number | null): string {
  return ms === null ? "—" : `${Math.round(ms)} ms`;
}
