/**
 * The plots' recording: a bounded ring buffer of telemetry samples, one time column plus one
 * column per series (Float64Array each, NaN where a sample lacked the series). Recording starts
 * when the page connects; when the buffer is full the oldest sample is dropped. Series that
 * appear later (a field added to telemetry) get a column filled with NaN for earlier samples.
 */

export const DEFAULT_CAPACITY = 12_000; // 10 min at 20 Hz

export class SeriesRecorder {
  readonly capacity: number;
  private readonly time: Float64Array;
  private readonly columns = new Map<string, Float64Array>();
  private readonly order: string[] = [];
  private start = 0;
  private length = 0;
  private revision = 0;
  private droppedCount = 0;

  constructor(capacity = DEFAULT_CAPACITY) {
    if (!Number.isInteger(capacity) || capacity < 1) throw new RangeError(`capacity must be a positive integer, got ${capacity}`);
    this.capacity = capacity;
    this.time = new Float64Array(capacity);
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
    this.revision += 1;
    return true;
  }

  /** Drops every sample; the series stay known (plots keep their selection). */
  clear(): void {
    this.start = 0;
    this.length = 0;
    this.droppedCount = 0;
    for (const column of this.columns.values()) column.fill(Number.NaN);
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
    const column = this.columns.get(key);
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
