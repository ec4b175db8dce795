import { describe, expect, it } from "vitest";
import { TuningController } from "../../src/developer/tuning";
import type { VehicleChannel } from "../../src/lib/vehicle_client";
import { decodeSetTuning, decodeStepResponse, decodeTuningInfo, figures, formOf, parseForm, polylines } from "../../src/developer/tuning_model";

const gains = { depth: { kp: 3, ki: 0.1, kd: 1.5 }, heading: { kp: 4, ki: 0.3, kd: 2 } };
const info = { gains, defaults: gains, ranges: { kp: [0, 20], ki: [0, 5], kd: [0, 20] }, model: "neptunus" };

describe("autopilot tuning on the developer page", () => {
  it("decodes the server's replies and refuses malformed ones", () => {
    expect(decodeTuningInfo(info)?.ranges.ki).toEqual([0, 5]);
    expect(decodeTuningInfo({ ...info, gains: { depth: gains.depth } })).toBeNull();
    expect(decodeTuningInfo({ ...info, ranges: { kp: [0] } })).toBeNull();
    expect(decodeSetTuning({ tuning: gains })).toEqual(gains);
    expect(decodeSetTuning({ tuning: { depth: { kp: "3" } } })).toBeNull();
  });

  it("validates the form like the server", () => {
    const ranges = decodeTuningInfo(info)!.ranges;
    const form = formOf(gains);
    expect(parseForm(form, ranges)).toEqual({ ok: true, gains });
    expect(parseForm({ ...form, depth: { ...form.depth, kp: "25" } }, ranges)).toEqual({ ok: false, error: "depth.kp must be a number in [0, 20]" });
    expect(parseForm({ ...form, heading: { ...form.heading, kd: "" } }, ranges)).toEqual({ ok: false, error: "heading.kd must be a number in [0, 20]" });
    expect(parseForm({ ...form, heading: { ...form.heading, ki: "x" } }, ranges).ok).toBe(false);
  });

  const response = {
    axis: "depth",
    step: 1,
    target: 2,
    band: 0.05,
    t: [0, 1, 2, 3],
    setpoint: [1, 2, 2, 2],
    reference: [1, 1, 1.5, 2],
    value: [1, 1, 1.4, 2.006],
    output: [0, 0.2, 0.3, 0],
    overshoot: 0.006,
    settle: 1.9,
  };

  it("decodes a step response and draws it in the box", () => {
    const r = decodeStepResponse(response)!;
    expect(r.settle).toBe(1.9);
    expect(decodeStepResponse({ ...response, settle: null })?.settle).toBeNull();
    expect(decodeStepResponse({ ...response, value: [1, 2] })).toBeNull();
    expect(decodeStepResponse({ ...response, axis: "roll" })).toBeNull();
    const p = polylines(r, 300, 100);
    expect(p.min).toBe(1);
    expect(p.max).toBe(2.006);
    expect(p.value.split(" ")).toHaveLength(4);
    expect(p.value.startsWith("0.0,100.0")).toBe(true);
    expect(p.setpoint.split(" ")[3]).toBe("300.0,0.6");
    expect(figures(r)).toBe("overshoot 0.6 cm, within ±5 cm after 1.9 s");
    expect(figures({ ...r, axis: "heading", overshoot: Math.PI / 180, band: (2 * Math.PI) / 180, settle: null })).toBe("overshoot 1.0°, never within ±2° in 3 s");
  });

  // the part of a VehicleChannel the tuning panel uses: joined or not, and requests (answered
  // with the tuning above)
  class StubChannel {
    joined = false;
    readonly asked: string[] = [];
    request<T>(event: string, _payload: object, decode: (response: unknown) => T | null): Promise<T> {
      this.asked.push(event);
      const decoded = decode(info);
      return decoded === null ? Promise.reject(new Error("bad reply")) : Promise.resolve(decoded);
    }
  }

  it("opened before the vehicle's channel joins, reads the gains once it has", async () => {
    const tuning = new TuningController();
    const channel = new StubChannel();
    tuning.attach(channel as unknown as VehicleChannel);

    await tuning.load();
    expect(channel.asked).toEqual([]);
    expect(tuning.store.get()).toMatchObject({ busy: "loading", form: null });

    channel.joined = true;
    await tuning.joined();
    expect(channel.asked).toEqual(["get_tuning"]);
    expect(tuning.store.get()).toMatchObject({ busy: null, form: formOf(gains), error: false });

    // a later rejoin does not read them again unasked
    await tuning.joined();
    expect(channel.asked).toEqual(["get_tuning"]);
  });
});

describe("the tuning panel opened before the page has its vehicle", () => {
  it("reads the gains once the vehicle is attached and its channel has joined", async () => {
    const asked: string[] = [];
    const vehicle = {
      joined: false,
      request: <T>(event: string, _payload: unknown, decode: (v: unknown) => T | null): Promise<T> => {
        asked.push(event);
        const value = decode(info);
        return value === null ? Promise.reject(new Error("bad reply")) : Promise.resolve(value);
      },
    };
    const c = new TuningController();
    await c.load();
    expect(c.store.get().form).toBeNull();
    c.attach(vehicle as unknown as VehicleChannel);
    expect(asked).toEqual([]);
    vehicle.joined = true;
    await c.joined();
    expect(asked).toEqual(["get_tuning"]);
    expect(c.store.get().form).toEqual(formOf(gains));
  });
});
