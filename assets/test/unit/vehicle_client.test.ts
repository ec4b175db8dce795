// The typed client against the in-process stand-in server (test/support/fake_server.mjs), over
// real WebSockets with the `ws` package as the phoenix client's transport.
import { describe, expect, it } from "vitest";
import { startFakeServer } from "../support/fake_server.mjs";
import type { Grant, Helm, PresenceEntry, Telemetry } from "../../src/lib/protocol";
import { CommandError, NeptunusClient } from "../../src/lib/vehicle_client";
import type { ConnectionStatus } from "../../src/lib/vehicle_client";
import { eventually, useStandIn } from "./stand_in";

const standIn = useStandIn();

function client(name: string): NeptunusClient {
  const c = standIn.client({ name });
  c.connect();
  return c;
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

    const granted = await pilot.requestControl();
    expect(granted.status).toBe("granted");
    const epoch = granted.status === "granted" ? granted.grant.epoch : -1;

    const reply = await pilot.thrust({ surge: 1, heave: 0, yaw: 0 }, epoch);
    expect(reply.command).toEqual({ surge: 1, heave: 0, yaw: 0 });
    expect(reply.thrusters.port).toBe(0.5); // gain 0.5

    const refused = await other.thrust({ surge: -1, heave: 0, yaw: 0 }, epoch).catch((e: unknown) => e);
    expect(refused).toBeInstanceOf(CommandError);
    expect(refused).toMatchObject({ reason: "not_in_control", kind: "error" });

    const stale = await pilot.thrust({ surge: 1, heave: 0, yaw: 0 }, epoch - 1).catch((e: unknown) => e);
    expect(stale).toMatchObject({ reason: "stale_command" });

    const bad = await pilot.thrust({ surge: 5, heave: 0, yaw: 0 }, epoch).catch((e: unknown) => e);
    expect(bad).toMatchObject({ kind: "error" });
    expect((bad as CommandError).reason).not.toBe("");

    const stopped: string[] = [];
    const watcher = client("watcher").vehicle("neptunus-1", { stopped: (r) => stopped.push(r) });
    await watcher.join();
    await expect(pilot.stop("test")).resolves.toBeUndefined();
    expect(await eventually(() => stopped[0])).toBe("test");
    await pilot.releaseControl();
  });

  it("hands the helm over by request and acknowledge", async () => {
    const granted: Grant[] = [];
    const requests: string[] = [];
    const lost: string[] = [];
    const helms: Helm[] = [];
    const ada = client("ada").vehicle("neptunus-1", {
      controlRequest: (from) => requests.push(from.name),
      controlLost: (reason) => lost.push(reason),
      helm: (h) => helms.push(h),
    });
    const bob = client("bob").vehicle("neptunus-1", { controlGranted: (g) => granted.push(g) });
    const [adaSnap, bobSnap] = await Promise.all([ada.join(), bob.join()]);
    expect(adaSnap.session?.name).toBe("ada");
    expect(bobSnap.helm?.state).toBe("free");

    await ada.requestControl();
    const rtt = await ada.heartbeat();
    expect(rtt).toBeGreaterThanOrEqual(0); // the round trip, in ms
    await expect(bob.heartbeat()).rejects.toMatchObject({ reason: "not_in_control" });
    const pending = await bob.requestControl();
    expect(pending).toEqual({ status: "pending", timeout_ms: 10000 });
    expect(await eventually(() => requests[0])).toBe("bob");
    expect(await eventually(() => helms.find((h) => h.state === "requested"))).toMatchObject({
      request: { from: { name: "bob" } },
    });

    await ada.answerRequest(true);
    const grant = await eventually(() => granted[0]);
    expect(grant.pilot.name).toBe("bob");
    expect(grant.control.command).toEqual({ surge: 0, heave: 0, yaw: 0 });
    expect(await eventually(() => lost[0])).toBe("control_transferred");
    await expect(bob.thrust({ surge: 0.5, heave: 0, yaw: 0 }, grant.epoch)).resolves.toBeDefined();
    await bob.releaseControl();
  });

  it("does not send commands before the channel is joined", async () => {
    const vehicle = client("early").vehicle("neptunus-1");
    await expect(vehicle.thrust({ surge: 1, heave: 0, yaw: 0 }, 1)).rejects.toMatchObject({
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
    const c = standIn.client({}, own.url);
    c.connect();
    const vehicle = c.vehicle("neptunus-1");
    await vehicle.join();
    await own.close();
    await eventually(() => (vehicle.status === "disconnected" ? true : undefined));
    expect(vehicle.joined).toBe(false);
  });

  it("settings commands resolve with the control settings or reject with the server's reason; the log topic delivers entries", async () => {
    const c = client("setter");
    const entries: unknown[] = [];
    const log = c.log("neptunus-1", (p) => entries.push(p));
    await log.join();
    const v = c.vehicle("neptunus-1");
    await v.join();
    await expect(v.setValue("set_gain", 0.7)).rejects.toMatchObject({ reason: "not_in_control" });
    await v.requestControl();
    await expect(v.setValue("set_gain", 0.7)).resolves.toMatchObject({ mode: "motion", gain: 0.7 });
    await expect(v.setValue("set_gain", 2)).rejects.toMatchObject({ reason: "value must be a number in [0, 1], got 2" });
    await expect(v.setValue("set_gain", "abc")).rejects.toMatchObject({ reason: 'value must be a number in [0, 1], got "abc"' });
    // a command the server does not know yet: its reason, not a fake success
    await expect(v.setControlMode("manual")).rejects.toMatchObject({ reason: "unknown event: set_control_mode", kind: "error" });
    await expect(v.autopilot({ depth: 2 })).rejects.toMatchObject({ reason: "unknown event: autopilot" });
    await eventually(() => (entries.length > 0 ? entries : undefined));
    expect(entries[0]).toMatchObject({ category: "gain", message: "gain 0.7" });
    await v.setValue("set_gain", 0.5);
    expect(await c.ping()).toBeGreaterThanOrEqual(0);
    log.leave();
  });
});

describe("a vehicle on another node of the fleet", () => {
  it("reports its node cut off and back (unreachable, reachable); malformed payloads are protocol errors", async () => {
    const seen: [boolean, string][] = [];
    const errors: string[] = [];
    const watcher = client("fleet-watcher").vehicle("neptunus-1", {
      reachability: (reachable, node) => seen.push([reachable, node]),
      protocolError: (what) => errors.push(what),
    });
    await watcher.join();
    standIn.broadcast("vehicle:neptunus-1", "unreachable", { id: "neptunus-1", node: "rov1@10.0.0.2", reason: "node_unreachable" });
    standIn.broadcast("vehicle:neptunus-1", "reachable", { id: "neptunus-1", node: "rov1@10.0.0.2" });
    standIn.broadcast("vehicle:neptunus-1", "unreachable", { id: "neptunus-1" });
    expect(await eventually(() => (errors.length > 0 ? errors : undefined))).toEqual(["unreachable"]);
    expect(seen).toEqual([
      [false, "rov1@10.0.0.2"],
      [true, "rov1@10.0.0.2"],
    ]);
  });
});

describe("the fleet's directory, live", () => {
  it("hands on vehicles, unreachable and reachable pushes of topic fleet; malformed payloads are protocol errors", async () => {
    const lists: (readonly unknown[])[] = [];
    const reach: [string, boolean][] = [];
    const errors: string[] = [];
    await client("fleet-overview").fleet(undefined, {
      vehicles: (vs) => lists.push(vs),
      reachability: (id, reachable) => reach.push([id, reachable]),
      protocolError: (what) => errors.push(what),
    });
    const rov = { id: "rov1", board: "uart", node: "rov1@10.0.0.2", status: "up", helm: "free", pilot: "ada", link: { up: true, reason: null }, depth: 2.5, heading: 1, recording: true };
    standIn.broadcast("fleet", "vehicles", { vehicles: [rov] });
    standIn.broadcast("fleet", "unreachable", { id: "rov1", node: "rov1@10.0.0.2", reason: "node_unreachable" });
    standIn.broadcast("fleet", "reachable", { id: "rov1", node: "rov1@10.0.0.2" });
    standIn.broadcast("fleet", "vehicles", { vehicles: "none" });
    standIn.broadcast("fleet", "reachable", { node: "rov1@10.0.0.2" });
    expect(await eventually(() => (errors.length > 1 ? errors : undefined))).toEqual(["vehicles", "reachable"]);
    expect(lists).toEqual([
      [{ id: "rov1", board: "uart", node: "rov1@10.0.0.2", status: "up", detail: { helm: "free", pilot: "ada", link: { up: true, reason: null }, depth: 2.5, heading: 1, recording: true } }],
    ]);
    expect(reach).toEqual([
      ["rov1", false],
      ["rov1", true],
    ]);
  });
});
