/**
 * How old is the telemetry on this page? The server stamps each frame with its wall clock
 * (`sent_at`, ms since the epoch), but this computer's clock may be off by seconds. The page
 * asks the server for its clock now and then (`clock`), and this estimates the offset from
 * the round trip: offset = server − (sent + received) / 2, trusting the sample with the
 * shortest round trip among the recent ones (its error is at most half that round trip).
 * Pure: the page passes `Date.now()` readings.
 */

export interface ClockSample {
  /** this computer's Date.now() when the request left */
  readonly sentAt: number;
  /** the server's clock in its reply */
  readonly serverNow: number;
  /** this computer's Date.now() when the reply arrived */
  readonly receivedAt: number;
}

export class ClockOffset {
  private readonly recent: ClockSample[] = [];
  private readonly window: number;

  constructor(window = 8) {
    this.window = Math.max(1, window);
  }

  /** Keeps a sample; ignores impossible ones (non-finite, negative round trip). */
  add(sample: ClockSample): void {
    const { sentAt, serverNow, receivedAt } = sample;
    if (![sentAt, serverNow, receivedAt].every(Number.isFinite) || receivedAt < sentAt) return;
    this.recent.push(sample);
    if (this.recent.length > this.window) this.recent.shift();
  }

  /** server clock − this clock, in ms; null before the first sample. */
  get offsetMs(): number | null {
    const best = this.best();
    return best === null ? null : best.serverNow - (best.sentAt + best.receivedAt) / 2;
  }

  /** How far the offset may be wrong, in ms (half the best round trip); null before the first sample. */
  get uncertaintyMs(): number | null {
    const best = this.best();
    return best === null ? null : (best.receivedAt - best.sentAt) / 2;
  }

  reset(): void {
    this.recent.length = 0;
  }

  private best(): ClockSample | null {
    let best: ClockSample | null = null;
    for (const s of this.recent) {
      if (best === null || s.receivedAt - s.sentAt < best.receivedAt - best.sentAt) best = s;
    }
    return best;
  }
}

/**
 * Age in ms, on arrival, of a frame the server stamped `sentAt` (its clock), received at
 * `receivedAt` (this clock), given the offset: never negative (the offset's own error can make
 * a fresh frame look a little early). Null without an offset.
 */
export function ageOnArrival(sentAt: number, receivedAt: number, offsetMs: number | null): number | null {
  if (offsetMs === null || !Number.isFinite(sentAt) || !Number.isFinite(receivedAt)) return null;
  return Math.max(0, receivedAt + offsetMs - sentAt);
}

/**
 * How old the newest telemetry is now, in ms: the time since it arrived plus how old it was
 * when it arrived (0 when that is not known). A slow link shows as a frame that is already
 * old when it comes, a silent one as time passing since the last.
 */
export function telemetryAge(now: number, receivedAt: number, ageOnArrivalMs: number | null): number {
  return Math.max(0, now - receivedAt) + (ageOnArrivalMs ?? 0);
}

/** Telemetry older than this is stale (ms). */
export const STALE_AFTER_MS = 1000;

export type TelemetryState = "none" | "live" | "stale";

/**
 * The telemetry state for data `ageMs` old: stale past STALE_AFTER_MS (its age rounded to
 * 0.1 s), else live (age 0: within the second, the exact figure is noise).
 */
export function freshness(ageMs: number): { telemetryState: TelemetryState; telemetryAgeMs: number } {
  return ageMs > STALE_AFTER_MS
    ? { telemetryState: "stale", telemetryAgeMs: Math.round(ageMs / 100) * 100 }
    : { telemetryState: "live", telemetryAgeMs: 0 };
}

/** What the pages show for the telemetry's age: "none yet", "live" or "stale (1.2 s)". */
export function ageText(state: TelemetryState, ageMs: number): string {
  return state === "none" ? "none yet" : state === "live" ? "live" : `stale (${(ageMs / 1000).toFixed(1)} s)`;
}

/** What the telemetry clock asks the server's clock through: a joined vehicle channel. */
export interface ClockSource {
  readonly joined: boolean;
  clock(): Promise<ClockSample>;
}

/**
 * The pages' telemetry age: when the newest frame arrived and how old it was then, and the
 * server's clock offset that says so (read through `source()` when a vehicle is joined: at
 * once while the offset is unknown, then on `read()`, one request at a time).
 */
export class TelemetryClock {
  private receivedAt: number | null = null;
  private lateMs: number | null = null;
  private pending = false;
  /** the server's clock against ours: 60 readings, the quickest round trip wins */
  readonly offset = new ClockOffset(60);

  constructor(private readonly source: () => ClockSource | null) {}

  /** A frame stamped `sentAt` (server ms) arrived at `now` (performance.now()), `wall` (Date.now()). */
  received(sentAt: number, now: number, wall: number): { telemetryState: TelemetryState; telemetryAgeMs: number } {
    this.receivedAt = now;
    // a slow link delivers frames that are already old: stale, though they keep coming
    this.lateMs = ageOnArrival(sentAt, wall, this.offset.offsetMs);
    return freshness(this.lateMs ?? 0);
  }

  /** Every tick: the freshness when the telemetry has gone stale (else null); reads the clock while unknown. */
  tick(now: number): { telemetryState: TelemetryState; telemetryAgeMs: number } | null {
    if (this.offset.offsetMs === null) this.read();
    if (this.receivedAt === null) return null;
    const age = telemetryAge(now, this.receivedAt, this.lateMs);
    return age > STALE_AFTER_MS ? freshness(age) : null;
  }

  /** One reading of the server's clock, unless one is under way or no vehicle is joined. */
  read(): void {
    const source = this.source();
    if (this.pending || source === null || !source.joined) return;
    this.pending = true;
    source.clock().then(
      (sample) => {
        this.pending = false;
        this.offset.add(sample);
      },
      () => {
        this.pending = false;
      },
    );
  }
}
