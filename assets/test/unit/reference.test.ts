import { describe, expect, it } from "vitest";
import { decodeAutopilotStatus } from "../../src/lib/protocol";
import { DEPTH_TOLERANCE, HEADING_TOLERANCE, movingReference } from "../../src/operator/reference";

describe("the autopilot reference on the HUD", () => {
  it("is decoded when the server sends it, absent otherwise", () => {
    const s = decodeAutopilotStatus({
      depth: { setpoint: 1, reference: 0.4, reference_rate: 0.3, output: 0.2, overridden: false, waiting: null },
      heading: { setpoint: 1, output: 0 },
    });
    expect(s?.depth?.reference).toBe(0.4);
    expect(s?.heading?.reference).toBeUndefined();
  });

  it("shows while on its way, not once settled", () => {
    expect(movingReference({ setpoint: 1, reference: 0.4, output: 0, waiting: null }, DEPTH_TOLERANCE, false)).toBe(0.4);
    expect(movingReference({ setpoint: 1, reference: 0.999, output: 0, waiting: null }, DEPTH_TOLERANCE, false)).toBeNull();
    expect(movingReference({ setpoint: 1, output: 0, waiting: null }, DEPTH_TOLERANCE, false)).toBeNull();
    expect(movingReference(null, DEPTH_TOLERANCE, false)).toBeNull();
  });

  it("compares headings across north", () => {
    const near = 2 * Math.PI - 0.001;
    expect(movingReference({ setpoint: 0.001, reference: near, output: 0, waiting: null }, HEADING_TOLERANCE, true)).toBeNull();
    expect(movingReference({ setpoint: 0.5, reference: near, output: 0, waiting: null }, HEADING_TOLERANCE, true)).toBe(near);
  });
});

describe("the vehicle's settings (camera rotation)", () => {
  it("are decoded from vehicle_settings and the snapshot, refused when malformed", async () => {
    const { decodeVehicleSettings, decodeVehicleSnapshot } = await import("../../src/lib/protocol");
    expect(decodeVehicleSettings({ camera_rotation: 180 })).toEqual({ camera_rotation: 180 });
    expect(decodeVehicleSettings({ camera_rotation: 45 })).toBeNull();
    expect(decodeVehicleSettings(null)).toBeNull();
    const snapshot = { vehicle: { id: "v", board: "simulated" }, telemetry: null, pilot: null };
    expect(decodeVehicleSnapshot({ ...snapshot, settings: { camera_rotation: 90 } })?.settings).toEqual({ camera_rotation: 90 });
    expect(decodeVehicleSnapshot(snapshot)?.settings).toBeUndefined();
  });
});
