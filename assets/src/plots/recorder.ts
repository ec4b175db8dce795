/**
 * The plots' recording: a bounded ring buffer of telemetry samples, one time column plus one
 * column per series (Float64Array each, NaN where a sample lacked the series). Recording starts
 * when the page connects; when the buffer is full the oldest sample is dropped. Series that
 * appear later (a field added to telemetry) get a column filled with NaN for earlier samples.
 *
 * An angle that wraps (a heading near north jumps between 0 and one turn) also gets its
 * continuous line, for the plots: each sample moved by whole turns to within half a turn of
 * the one before (`unwrapNext`), as it arrives, so what is drawn never moves when the oldest
 * samples go. The CSV keeps the values as received.
 */

import { unwrapNext } from "./series";

export const DEFAULT_CAPACITY = 12_000; // 10 min at 20 Hz

export class SeriesRecorder {
  readonly capacity: number;
  private readonly time: Float64Array;
  private readonly columns = new Map<string, Float64Array>();
  /** the continuous line of each wrapping series, and its newest value */
  private readonly lines = new Map<string, { readonly column: Float64Array; readonly period: number; last: number | null }>();
  private readonly periodOf: (key: string) => number | null;
  private readonly order: string[] = [];
  private start = 0;
  private length = 0;
  private revision = 0;
  private droppedCount = 0;

  /** `periodOf(key)`: one turn of a series that wraps (in its unit), else null (default: none wraps). */
  constructor(capacity = DEFAULT_CAPACITY, periodOf: (key: string) => number | null = () => null) {
    if (!Number.isInteger(capacity) || capacity < 1) throw new RangeError(`capacity must be a positive integer, got ${capacity}`);
    this.capacity = capacity;
    this.time = new Float64Array(capacity);
    this.periodOf = periodOf;
  }

  /** Samples held now (≤ capacity). */
  get size(): number {
    return this.length;
  }

  /** Samples dropped because the buffer was full. */
  get dropped(): number {
    return this.droppedCount;
  }

  /** Changes on every add and clear (to redraw only when needed). */
  get version(): number {
    return this.revision;
  }

  /** Every series seen, in the order they first appeared. */
  get series(): readonly string[] {
    return this.order;
  }

  /**
   * Adds a sample at `time` (s; must not go back: an older sample is refused and false
   * returned). Series in `values` not seen before get a new column.
   */
  add(time: number, values: ReadonlyMap<string, number>): boolean {
    if (!Number.isFinite(time)) return false;
    if (this.length > 0 && time < this.at(this.length - 1)) return false;
    for (const key of values.keys()) {
      if (!this.columns.has(key)) {
        this.columns.set(key, new Float64Array(this.capacity).fill(Number.NaN));
        this.order.push(key);
        const period = this.periodOf(key);
        if (period !== null) this.lines.set(key, { column: new Float64Array(this.capacity).fill(Number.NaN), period, last: null });
      }
    }
    let slot: number;
    if (this.length < this.capacity) {
      slot = (this.start + this.length) % this.capacity;
      this.length += 1;
    } else {
      slot = this.start;
      this.start = (this.start + 1) % this.capacity;
      this.droppedCount += 1;
    }
    this.time[slot] = time;
    for (const [key, column] of this.columns) {
      const v = values.get(key);
      column[slot] = v === undefined ? Number.NaN : v;
    }
    for (const [key, line] of this.lines) {
      const v = values.get(key);
      if (v === undefined) {
        line.column[slot] = Number.NaN;
      } else {
        line.last = unwrapNext(line.last, v, line.period);
        line.column[slot] = line.last;
      }
    }
    this.revision += 1;
    return true;
  }

  /** Drops every sample; the series stay known (plots keep their selection). */
  clear(): void {
    this.start = 0;
    this.length = 0;
    this.droppedCount = 0;
    for (const column of this.columns.values()) column.fill(Number.NaN);
    for (const line of this.lines.values()) {
      line.column.fill(Number.NaN);
      line.last = null;
    }
    this.revision += 1;
  }

  /** Times, oldest first. */
  times(): number[] {
    const out = new Array<number>(this.length);
    for (let i = 0; i < this.length; i++) out[i] = this.at(i);
    return out;
  }

  /** A series' values, oldest first; null where a sample had none (or for an unknown series). */
  values(key: string, map: (v: number) => number = (v) => v): (number | null)[] {
    return this.read(this.columns.get(key), map);
  }

  /** What a plot draws of a series: its continuous line if it wraps, else its values. */
  line(key: string, map: (v: number) => number = (v) => v): (number | null)[] {
    return this.read(this.lines.get(key)?.column ?? this.columns.get(key), map);
  }

  private read(column: Float64Array | undefined, map: (v: number) => number): (number | null)[] {
    const out = new Array<number | null>(this.length);
    for (let i = 0; i < this.length; i++) {
      const v = column ? column[(this.start + i) % this.capacity] : Number.NaN;
      out[i] = v === undefined || Number.isNaN(v) ? null : map(v);
    }
    return out;
  }

  /**
   * CSV of the buffer: a header `time,<series…>` and one row per sample, oldest first; time in
   * seconds since the Unix epoch (ms resolution), values in SI units as received, empty where
   * a sample lacked the series.
   */
  toCsv(keys: readonly string[] = this.order): string {
    const lines: string[] = [["time", ...keys].map(csvField).join(",")];
    const columns = keys.map((k) => this.columns.get(k));
    for (let i = 0; i < this.length; i++) {
      const slot = (this.start + i) % this.capacity;
      const row = [this.at(i).toFixed(3)];
      for (const column of columns) {
        const v = column ? column[slot] : Number.NaN;
        row.push(v === undefined || Number.isNaN(v) ? "" : String(v));
      }
      lines.push(row.join(","));
    }
    return lines.join("\n") + "\n";
  }

  private at(i: number): number {
    return this.time[(this.start + i) % this.capacity] ?? Number.NaN;
  }
}

/** A CSV field, quoted when it holds a comma, quote or line break. */
export function csvField(text: string): string {
  return /[",\n\r]/.test(text) ? `"${text.replace(/"/g, '""')}"` : text;
}
