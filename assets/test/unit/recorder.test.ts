import { describe, expect, it } from "vitest";
import { DEFAULT_CAPACITY, SeriesRecorder, csvField } from "../../src/plots/recorder";
import { liveRange, panRange, zoomRange } from "../../src/plots/ranges";

const m = (o: Record<string, number>): Map<string, number> => new Map(Object.entries(o));

describe("SeriesRecorder (ring buffer)", () => {
  it("keeps samples oldest first with their series", () => {
    const r = new SeriesRecorder(5);
    r.add(1, m({ a: 1, b: 10 }));
    r.add(2, m({ a: 2, b: 20 }));
    expect(r.size).toBe(2);
    expect(r.times()).toEqual([1, 2]);
    expect(r.values("a")).toEqual([1, 2]);
    expect(r.series).toEqual(["a", "b"]);
  });

  it("is bounded: the oldest samples go first and are counted", () => {
    const r = new SeriesRecorder(3);
    for (let i = 1; i <= 7; i++) r.add(i, m({ a: i * 10 }));
    expect(r.size).toBe(3);
    expect(r.times()).toEqual([5, 6, 7]);
    expect(r.values("a")).toEqual([50, 60, 70]);
    expect(r.dropped).toBe(4);
  });

  it("a series that appears later reads null before it appeared; a missing value reads null", () => {
    const r = new SeriesRecorder(4);
    r.add(1, m({ a: 1 }));
    r.add(2, m({ a: 2, late: 5 }));
    r.add(3, m({ late: 6 }));
    expect(r.values("late")).toEqual([null, 5, 6]);
    expect(r.values("a")).toEqual([1, 2, null]);
    expect(r.values("unknown")).toEqual([null, null, null]);
    expect(r.series).toEqual(["a", "late"]);
  });

  it("refuses samples that go back in time or are not finite", () => {
    const r = new SeriesRecorder(4);
    expect(r.add(2, m({ a: 1 }))).toBe(true);
    expect(r.add(1, m({ a: 2 }))).toBe(false);
    expect(r.add(Number.NaN, m({ a: 2 }))).toBe(false);
    expect(r.add(2, m({ a: 3 }))).toBe(true); // equal time is fine
    expect(r.values("a")).toEqual([1, 3]);
  });

  it("clear drops the data, keeps the series, and bumps the version", () => {
    const r = new SeriesRecorder(3);
    for (let i = 1; i <= 5; i++) r.add(i, m({ a: i }));
    const v = r.version;
    r.clear();
    expect(r.version).toBeGreaterThan(v);
    expect(r.size).toBe(0);
    expect(r.dropped).toBe(0);
    expect(r.series).toEqual(["a"]);
    r.add(0, m({ b: 1 })); // time may start over after a clear
    expect(r.values("a")).toEqual([null]);
    expect(r.values("b")).toEqual([1]);
  });

  it("maps values for display (e.g. rad → deg)", () => {
    const r = new SeriesRecorder(2);
    r.add(1, m({ h: Math.PI }));
    expect(r.values("h", (v) => (v * 180) / Math.PI)).toEqual([180]);
  });

  it("exports CSV: header, one row per sample, empty cells for missing values", () => {
    const r = new SeriesRecorder(2);
    r.add(1795000000.1234, m({ "measurement.depth": 1.5 }));
    r.add(1795000000.2, m({ "measurement.depth": 1.25, "a,b": 3 }));
    r.add(1795000000.3, m({ "a,b": 4 }));
    expect(r.toCsv()).toBe(
      'time,measurement.depth,"a,b"\n1795000000.200,1.25,3\n1795000000.300,,4\n',
    );
    expect(r.toCsv(["a,b"])).toBe('time,"a,b"\n1795000000.200,3\n1795000000.300,4\n');
  });

  it("quotes CSV fields only when needed", () => {
    expect(csvField("plain")).toBe("plain");
    expect(csvField('say "hi"')).toBe('"say ""hi"""');
    expect(csvField("a\nb")).toBe('"a\nb"');
  });

  it("has a sane default capacity and rejects bad ones", () => {
    expect(new SeriesRecorder().capacity).toBe(DEFAULT_CAPACITY);
    expect(() => new SeriesRecorder(0)).toThrow(RangeError);
    expect(() => new SeriesRecorder(1.5)).toThrow(RangeError);
  });
});

describe("plot time ranges", () => {
  it("liveRange shows the last window, or all data when there is less", () => {
    expect(liveRange([], 60)).toBeNull();
    expect(liveRange([100, 130, 200], 60)).toEqual({ min: 140, max: 200 });
    expect(liveRange([100, 110], 60)).toEqual({ min: 100, max: 110 });
    const single = liveRange([5], 60);
    expect(single?.min).toBe(5);
    expect(single?.max).toBeGreaterThan(5);
  });

  it("zoomRange keeps the point under the cursor in place", () => {
    expect(zoomRange(0, 100, 50, 0.5)).toEqual({ min: 25, max: 75 });
    expect(zoomRange(0, 100, 0, 0.5)).toEqual({ min: 0, max: 50 });
    expect(zoomRange(0, 100, 50, 2)).toEqual({ min: -50, max: 150 });
    expect(zoomRange(0, 100, 500, 0.5)).toEqual({ min: 50, max: 100 }); // cursor clamped
  });

  it("panRange moves by a fraction of the width", () => {
    expect(panRange(10, 20, 0.25)).toEqual({ min: 12.5, max: 22.5 });
    expect(panRange(10, 20, -0.5)).toEqual({ min: 5, max: 15 });
  });
});

describe("SeriesRecorder: angles that wrap", () => {
  const TURN = 2 * Math.PI;
  const deg = (d: number): number => (d * Math.PI) / 180;
  const periodOf = (key: string): number | null => (key === "heading" ? TURN : null);

  it("keeps the values as received, and draws the continuous line", () => {
    const r = new SeriesRecorder(10, periodOf);
    [359, 1, 358, 2].forEach((d, i) => r.add(i, m({ heading: deg(d), depth: 1 })));
    expect(r.values("heading").map((v) => Math.round(((v ?? 0) * 180) / Math.PI))).toEqual([359, 1, 358, 2]);
    expect(r.line("heading").map((v) => Math.round(((v ?? 0) * 180) / Math.PI))).toEqual([359, 361, 358, 362]);
    expect(r.line("depth")).toEqual(r.values("depth"));
    expect(r.toCsv(["heading"]).split("\n")[2]).toBe(`1.000,${deg(1)}`);
  });

  it("what is drawn does not move when the oldest samples go", () => {
    const r = new SeriesRecorder(3, periodOf);
    [350, 10, 20].forEach((d, i) => r.add(i, m({ heading: deg(d) })));
    const before = r.line("heading").slice(1);
    r.add(3, m({ heading: deg(30) }));
    expect(r.line("heading").slice(0, 2)).toEqual(before);
    expect((r.line("heading")[2] ?? 0) * (180 / Math.PI)).toBeCloseTo(390);
  });

  it("a sample without the angle is a gap; the line goes on after it", () => {
    const r = new SeriesRecorder(5, periodOf);
    r.add(0, m({ heading: deg(359) }));
    r.add(1, m({ depth: 1 }));
    r.add(2, m({ heading: deg(1) }));
    const line = r.line("heading");
    expect(line[1]).toBeNull();
    expect((line[2] ?? 0) * (180 / Math.PI)).toBeCloseTo(361);
  });

  it("clear starts a new line where the next sample is", () => {
    const r = new SeriesRecorder(5, periodOf);
    r.add(0, m({ heading: deg(350) }));
    r.add(1, m({ heading: deg(10) }));
    r.clear();
    r.add(2, m({ heading: deg(10) }));
    expect((r.line("heading")[0] ?? 0) * (180 / Math.PI)).toBeCloseTo(10);
  });
});
