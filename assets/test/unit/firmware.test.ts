import { describe, expect, it } from "vitest";
import { fetchRollbackNotice, rollbackNotice } from "../../src/lib/firmware";

describe("rollbackNotice", () => {
  it("says which update was rolled back, why, and what runs", () => {
    const health = {
      status: "ok",
      firmware_update: {
        result: "rolled-back",
        version: "0.2.0",
        running: "0.1.0",
        reason: "Neptunus 0.2.0 did not become healthy within 300s",
        at: "2026-11-28T08:00:00Z",
      },
    };
    expect(rollbackNotice(health)).toBe(
      "The firmware update to 0.2.0 was rolled back (2026-11-28T08:00:00Z): " +
        "Neptunus 0.2.0 did not become healthy within 300s. The vehicle runs 0.1.0.",
    );
  });

  it("says nothing without a record, for a kept update, or for malformed input", () => {
    expect(rollbackNotice({ status: "ok" })).toBeNull();
    expect(rollbackNotice({ firmware_update: { result: "updated", version: "0.2.0" } })).toBeNull();
    expect(rollbackNotice(null)).toBeNull();
    expect(rollbackNotice("ok")).toBeNull();
    expect(rollbackNotice({ firmware_update: "rolled-back" })).toBeNull();
  });

  it("fills in what the record lacks", () => {
    expect(rollbackNotice({ firmware_update: { result: "rolled-back" } })).toBe(
      "The firmware update to a new firmware was rolled back: no reason recorded.",
    );
  });
});

describe("fetchRollbackNotice", () => {
  it("reads /api/health; a failed request is no notice", async () => {
    const body = { firmware_update: { result: "rolled-back", version: "9", reason: "did not boot" } };
    const ok = (async () => new Response(JSON.stringify(body), { status: 200 })) as typeof fetch;
    expect(await fetchRollbackNotice(ok)).toBe("The firmware update to 9 was rolled back: did not boot.");
    const down = (async () => {
      throw new TypeError("network");
    }) as typeof fetch;
    expect(await fetchRollbackNotice(down)).toBeNull();
    const error = (async () => new Response("no", { status: 500 })) as typeof fetch;
    expect(await fetchRollbackNotice(error)).toBeNull();
  });
});
