import { describe, expect, it } from "vitest";
import { decodeLinkStatus, decodeMavlinkStatus } from "../../src/lib/protocol";

describe("a mavlink vehicle's state in telemetry link", () => {
  it("decodes armed, mode and system status", () => {
    const link = decodeLinkStatus({
      up: true,
      reason: "heartbeat",
      rtt_ms: 3.2,
      mavlink: { armed: true, mode: "ALT_HOLD", system_status: "active", servo_us: [1500] },
    });
    expect(link).toEqual({ up: true, reason: "heartbeat", mavlink: { armed: true, mode: "ALT_HOLD", system_status: "active" } });
  });

  it("carries the vehicle's frame once it is known (it decides whether the vehicle sways)", () => {
    expect(decodeMavlinkStatus({ armed: false, mode: "MANUAL", frame: "SimpleROV-3" })?.frame).toBe("SimpleROV-3");
    expect(decodeMavlinkStatus({ armed: false, mode: "MANUAL", frame: null })).toEqual({ armed: false, mode: "MANUAL", system_status: null });
  });

  it("a mode not yet known is null; a malformed state is absent", () => {
    expect(decodeMavlinkStatus({ armed: false, mode: null })).toEqual({ armed: false, mode: null, system_status: null });
    expect(decodeMavlinkStatus({ armed: "yes" })).toBeNull();
    expect(decodeMavlinkStatus(null)).toBeNull();
    expect(decodeLinkStatus({ up: false, reason: "x", mavlink: 3 })).toEqual({ up: false, reason: "x" });
  });
});
