import { describe, expect, it } from "vitest";
import { decodeSnapshotList, fetchSnapshots, snapshotUrl, takeSnapshot } from "../../../src/video/snapshots";

const S = {
  vehicle: "neptunus-1",
  name: "neptunus-1-20261128-081500.123Z-2.31m-123deg.jpg",
  bytes: 48213,
  taken_at: 1795853700123,
  depth: 2.31,
  heading: 2.147,
  url: "/api/snapshots/neptunus-1/neptunus-1-20261128-081500.123Z-2.31m-123deg.jpg",
  node: "nonode@nohost",
};
const INFO = { vehicle: S.vehicle, name: S.name, bytes: S.bytes, takenAt: S.taken_at, depth: 2.31, heading: 2.147 };

function reply(status: number, body: unknown): Response {
  return new Response(JSON.stringify(body), { status, headers: { "content-type": "application/json" } });
}

describe("snapshots on the server", () => {
  it("reads the list; depth and heading may be unknown", () => {
    expect(decodeSnapshotList({ snapshots: [S, { ...S, depth: null, heading: null }] })).toEqual([INFO, { ...INFO, depth: null, heading: null }]);
    expect(decodeSnapshotList({ snapshots: [{ ...S, bytes: "big" }] })).toBeNull();
    expect(decodeSnapshotList({ recordings: [] })).toBeNull();
  });

  it("links a snapshot with the token in the query (a plain link carries no header)", () => {
    expect(snapshotUrl({ vehicle: "rov 1", name: "a b.jpg" }, "v1.x+y")).toBe("/api/snapshots/rov%201/a%20b.jpg?token=v1.x%2By");
    expect(snapshotUrl({ vehicle: "rov", name: "a.jpg" }, null)).toBe("/api/snapshots/rov/a.jpg");
  });

  it("takes one with POST /api/vehicles/ID/snapshot, the token as a bearer", async () => {
    const calls: [string, RequestInit | undefined][] = [];
    const info = await takeSnapshot("neptunus-1", "tok", async (url, init) => {
      calls.push([url, init]);
      return reply(201, { snapshot: { ...S, width: 640, height: 360 } });
    });
    expect(info).toEqual(INFO);
    expect(calls).toEqual([["/api/vehicles/neptunus-1/snapshot", { method: "POST", headers: { authorization: "Bearer tok" } }]]);
  });

  it("rejects with the server's reason", async () => {
    const refusal = { error: "recording is off on this server: snapshots are saved with the recordings (NEPTUNUS_RECORDINGS)" };
    await expect(takeSnapshot("neptunus-1", null, async () => reply(409, refusal))).rejects.toThrow(refusal.error);
    await expect(fetchSnapshots("neptunus-1", null, async () => new Response("gateway", { status: 502 }))).rejects.toThrow("HTTP 502");
    await expect(fetchSnapshots("neptunus-1", null, async () => reply(200, { nope: 1 }))).rejects.toThrow("unexpected reply to /api/snapshots");
  });

  it("lists the vehicle's, newest first", async () => {
    const older = { ...S, name: "old.jpg", taken_at: S.taken_at - 1000 };
    const list = await fetchSnapshots("neptunus-1", null, async (url) => {
      expect(url).toBe("/api/snapshots?vehicle=neptunus-1");
      return reply(200, { snapshots: [older, S] });
    });
    expect(list.map((s) => s.name)).toEqual([S.name, "old.jpg"]);
  });
});
