// The typed client against the in-process stand-in server (test/support/fake_server.mjs), over
// real WebSockets with the `ws` package as the phoenix client's transport.
import { afterAll, afterEach, beforeAll, describe, expect, it } from "vitest";
import WebSocket from "ws";
import { startFakeServer } from "../support/fake_server.mjs";
import type { FakeServer } from "../support/fake_server.mjs";
import type { PresenceEntry, Telemetry } from "../../src/lib/protocol";
import { CommandError, NeptunusClient } from "../../src/lib/vehicle_client";
import type { ConnectionStatus } from "../../src/lib/vehicle_client";

let server: FakeServer;
const clients: NeptunusClient[] = [];

beforeAll(async () => {
  server = await startFakeServer(0);
});

afterEach(async () => {
  await Promise.all(clients.splice(0).map((c) => c.disconnect()));
});

afterAll(async () => {
  await server.close();
});

function client(name: string): NeptunusClient {
  const c = new NeptunusClient({
    endpoint: `${server.url.replace(/^http/, "ws")}/socket`,
    name,
    transport: WebSocket,
  });
  clients.push(c);
  c.connect();
  return c;
}

function eventually<T>(get: () => T | undefined, ms = 2000): Promise<T> {
  return new Promise((resolve, reject) => {
    const deadline = Date.now() + ms;
    const poll = (): void => {
      const v = get();
      if (v !== undefined) resolve(v);
      else if (Date.now() > deadline) reject(new Error("timed out"));
      else setTimeout(poll, 10);
    };
    poll();
  });
}

describe("NeptunusClient", () => {
  it("joins fleet", async () => {
    const fleet = await client("a").fleet();
    expect(fleet.vehicles).toEqual([{ id: "neptunus-1", board: "simulated" }]);
  });

  it("joins a vehicle: snapshot, status, presence and decoded telemetry", async () => {
    const statuses: ConnectionStatus[] = [];
    const telemetry: Telemetry[] = [];
    let presence: readonly PresenceEntry[] = [];
    const vehicle = client("ada").vehicle("neptunus-1", {
      status: (s) => statuses.push(s),
      telemetry: (t) => telemetry.push(t),
      presence: (p) => {
        presence = p;
      },
    });
    expect(vehicle.joined).toBe(false);
    const snapshot = await vehicle.join();
    expect(snapshot.vehicle.id).toBe("neptunus-1");
    expect(vehicle.joined).toBe(true);
    expect(vehicle.status).toBe("connected");
    expect(statuses.at(-1)).toBe("connected");
    await eventually(() => (presence.length > 0 ? presence : undefined));
    expect(presence.map((p) => p.name)).toContain("ada");
    const t = await eventually(() => telemetry[0]);
    expect(t.thrusters.port_us).toBeGreaterThanOrEqual(1000);
  });

  it("thrust resolves with the reply; refusals reject with the server's reason", async () => {
    const pilot = client("pilot").vehicle("neptunus-1");
    const other = client("other").vehicle("neptunus-1");
    await Promise.all([pilot.join(), other.join()]);

    const reply = await pilot.thrust({ surge: 1, heave: 0, yaw: 0 });
    expect(reply.command).toEqual({ surge: 1, heave: 0, yaw: 0 });
    expect(reply.thrusters.port).toBe(0.5); // gain 0.5

    const refused = await other.thrust({ surge: -1, heave: 0, yaw: 0 }).catch((e: unknown) => e);
    expect(refused).toBeInstanceOf(CommandError);
    expect(refused).toMatchObject({ reason: "not_in_control", kind: "error" });

    const bad = await pilot.thrust({ surge: 5, heave: 0, yaw: 0 }).catch((e: unknown) => e);
    expect(bad).toMatchObject({ kind: "error" });
    expect((bad as CommandError).reason).not.toBe("");

    const stopped: string[] = [];
    const watcher = client("watcher").vehicle("neptunus-1", { stopped: (r) => stopped.push(r) });
    await watcher.join();
    await expect(pilot.stop("test")).resolves.toBeUndefined();
    expect(await eventually(() => stopped[0])).toBe("test");
  });

  it("does not send commands before the channel is joined", async () => {
    const vehicle = client("early").vehicle("neptunus-1");
    await expect(vehicle.thrust({ surge: 1, heave: 0, yaw: 0 })).rejects.toMatchObject({
      kind: "not_joined",
    });
    await expect(vehicle.stop()).rejects.toMatchObject({ kind: "not_joined" });
  });

  it("rejects the join of an unknown vehicle with the server's reason", async () => {
    const vehicle = client("lost").vehicle("nope");
    await expect(vehicle.join()).rejects.toMatchObject({ kind: "error", reason: "unknown vehicle: nope" });
    await vehicle.leave();
  });

  it("reports disconnected when the server goes away", async () => {
    const own = await startFakeServer(0);
    const c = new NeptunusClient({
      endpoint: `${own.url.replace(/^http/, "ws")}/socket`,
      transport: WebSocket,
    });
    clients.push(c);
    c.connect();
    const vehicle = c.vehicle("neptunus-1");
    await vehicle.join();
    await own.close();
    await eventually(() => (vehicle.status === "disconnected" ? true : undefined));
    expect(vehicle.joined).toBe(false);
  });
});
