import { describe, expect, it } from "vitest";
import {
  PLACEHOLDER,
  clampUnit,
  degToRad,
  formatFixed,
  formatHeading,
  headingDeg,
  radToDeg,
  wrapTwoPi,
} from "../../src/lib/units";

describe("radToDeg / degToRad", () => {
  it("converts known angles", () => {
    expect(radToDeg(0)).toBe(0);
    expect(radToDeg(Math.PI)).toBeCloseTo(180, 12);
    expect(radToDeg(Math.PI / 2)).toBeCloseTo(90, 12);
    expect(radToDeg(-Math.PI / 4)).toBeCloseTo(-45, 12);
    expect(degToRad(180)).toBeCloseTo(Math.PI, 12);
  });

  it("round-trips", () => {
    for (const deg of [-720, -33.3, 0, 1, 90, 359.9, 1234.5]) {
      expect(radToDeg(degToRad(deg))).toBeCloseTo(deg, 9);
    }
  });
});

describe("wrapTwoPi", () => {
  it("wraps into [0, 2π)", () => {
    expect(wrapTwoPi(0)).toBe(0);
    expect(wrapTwoPi(2 * Math.PI)).toBe(0);
    expect(wrapTwoPi(-Math.PI / 2)).toBeCloseTo((3 * Math.PI) / 2, 12);
    expect(wrapTwoPi(5 * Math.PI)).toBeCloseTo(Math.PI, 12);
  });
});

describe("heading", () => {
  it("shows degrees with one decimal", () => {
    expect(formatHeading(0)).toBe("0.0");
    expect(formatHeading(Math.PI / 2)).toBe("90.0");
    expect(formatHeading(Math.PI)).toBe("180.0");
    expect(formatHeading(degToRad(123.44))).toBe("123.4");
    expect(formatHeading(degToRad(123.46))).toBe("123.5");
    expect(formatHeading(degToRad(359.9))).toBe("359.9");
  });

  it("never shows 360.0: values that round up to it wrap to 0.0", () => {
    expect(formatHeading(2 * Math.PI - 1e-9)).toBe("0.0");
    expect(formatHeading(degToRad(359.96))).toBe("0.0");
    expect(headingDeg(degToRad(359.95))).toBe(0);
  });

  it("wraps negative and large angles", () => {
    expect(formatHeading(-Math.PI / 2)).toBe("270.0");
    expect(formatHeading(degToRad(-0.01))).toBe("0.0");
    expect(formatHeading(degToRad(725))).toBe("5.0");
  });

  it("stays within 0..359.9 for a sweep of angles", () => {
    for (let i = -2000; i <= 2000; i++) {
      const deg = headingDeg(i * 0.0071);
      expect(deg).toBeGreaterThanOrEqual(0);
      expect(deg).toBeLessThanOrEqual(359.9);
    }
  });

  it("shows a placeholder for non-finite input", () => {
    expect(formatHeading(Number.NaN)).toBe(PLACEHOLDER);
    expect(formatHeading(Number.POSITIVE_INFINITY)).toBe(PLACEHOLDER);
  });
});

describe("formatFixed", () => {
  it("rounds to the given decimals", () => {
    expect(formatFixed(1.234, 2)).toBe("1.23");
    expect(formatFixed(1.235, 1)).toBe("1.2");
    expect(formatFixed(12, 2)).toBe("12.00");
    expect(formatFixed(-3.456, 2)).toBe("-3.46");
  });

  it("never shows a negative zero", () => {
    expect(formatFixed(-0, 2)).toBe("0.00");
    expect(formatFixed(-0.001, 2)).toBe("0.00");
    expect(formatFixed(-0.001, 2, true)).toBe("0.00");
  });

  it("adds + to positive values when signed", () => {
    expect(formatFixed(0.5, 2, true)).toBe("+0.50");
    expect(formatFixed(-0.5, 2, true)).toBe("-0.50");
    expect(formatFixed(0, 2, true)).toBe("0.00");
  });

  it("shows a placeholder for non-finite input", () => {
    expect(formatFixed(Number.NaN, 2)).toBe(PLACEHOLDER);
  });
});

describe("clampUnit", () => {
  it("clamps to [-1, 1]", () => {
    expect(clampUnit(2)).toBe(1);
    expect(clampUnit(-7)).toBe(-1);
    expect(clampUnit(0.25)).toBe(0.25);
    expect(clampUnit(Number.NaN)).toBe(0);
  });
});
