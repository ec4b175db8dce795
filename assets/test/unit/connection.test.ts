// The operator page's connection against the in-process stand-in server
// (test/support/fake_server.mjs), over real WebSockets (`ws`).
import { afterAll, afterEach, beforeAll, describe, expect, it } from "vitest";
import WebSocket from "ws";
import { startFakeServer } from "../support/fake_server.mjs";
import type { FakeServer } from "../support/fake_server.mjs";
import type { VehicleSnapshot } from "../../src/lib/protocol";
import { NeptunusClient } from "../../src/lib/vehicle_client";
import type { NeptunusClientOptions } from "../../src/lib/vehicle_client";
import { OperatorConnection, displayName, firstVehicle } from "../../src/operator/connection";
import type { Identity } from "../../src/operator/connection";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";

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

function eventually<T>(get: () => T | undefined | false, ms = 3000): Promise<T> {
  return new Promise((resolve, reject) => {
    const deadline = Date.now() + ms;
    const poll = (): void => {
      const v = get();
      if (v !== undefined && v !== false) resolve(v);
      else if (Date.now() > deadline) reject(new Error("timed out"));
      else setTimeout(poll, 10);
    };
    poll();
  });
}

const local: Identity = { mode: "local", token: null };

function harness(query: string) {
  let state: OperatorState = initialState("keyboard", { deadband: 0.1, expo: 0 });
  const messages: { text: string; source: string | null }[] = [];
  const opened: string[] = [];
  const snapshots: VehicleSnapshot[] = [];
  const options: NeptunusClientOptions[] = [];
  const connection = new OperatorConnection(
    {
      get: () => state,
      update: (patch) => {
        state = { ...state, ...patch };
      },
      showMessage: (text, _kind, source) => messages.push({ text, source }),
      clearMessage: () => undefined,
      recheck: () => undefined,
      client: (o) => {
        options.push(o);
        const c = new NeptunusClient({ ...o, endpoint: `${server.url.replace(/^http/, "ws")}/socket`, transport: WebSocket });
        clients.push(c);
        return c;
      },
      opening: (id) => opened.push(id),
      events: { snapshot: (s) => snapshots.push(s) },
      nowMs: () => 1,
    },
    new URLSearchParams(query),
  );
  return { connection, state: () => state, messages, opened, snapshots, options };
}

describe("OperatorConnection", () => {
  it("without ?vehicle= opens the fleet's first vehicle and joins it with the page's handlers", async () => {
    const h = harness("");
    await h.connection.open(local);
    expect(h.opened).toEqual(["neptunus-1"]);
    expect(h.state().fleet.map((v) => v.id)).toEqual(["neptunus-1"]);
    await eventually(() => h.snapshots.length > 0);
    await eventually(() => h.state().status === "connected");
    expect(h.state().disconnectedAt).toBeNull();
    expect(h.connection.vehicle?.joined).toBe(true);
  });

  it("?vehicle=ID opens that vehicle; the fleet still fills the picker", async () => {
    const h = harness("vehicle=neptunus-1");
    await h.connection.open(local);
    expect(h.opened).toEqual(["neptunus-1"]);
    await eventually(() => h.state().fleet.length === 1);
  });

  it("an invalid id in the address is said, and nothing is joined", async () => {
    const h = harness("vehicle=no%20such!");
    await h.connection.open(local);
    expect(h.opened).toEqual([]);
    expect(h.connection.vehicle).toBeNull();
    expect(h.messages).toEqual([{ text: 'Invalid vehicle id in the address: "no such!"', source: null }]);
  });

  it("a vehicle the server refuses is said and not asked again", async () => {
    const h = harness("vehicle=nope");
    await h.connection.open(local);
    const said = await eventually(() => h.messages.find((m) => m.source === "join"));
    expect(said.text).toBe("Cannot join vehicle nope: unknown vehicle: nope");
    await eventually(() => h.state().status === "disconnected");
  });

  it("the socket is named ?name= only in local mode, and carries the token", async () => {
    const named = harness("name=%20ada%20");
    await named.connection.open(local);
    expect(named.options).toEqual([{ name: "ada" }]);
    const secure = harness("name=ada");
    await secure.connection.open({ mode: "secure", token: "t0k" });
    expect(secure.options).toEqual([{ token: "t0k" }]);
  });
});

describe("firstVehicle and displayName", () => {
  it("the first vehicle that can be reached, else the first", () => {
    expect(firstVehicle([{ id: "a", status: "unreachable" }, { id: "b" }])?.id).toBe("b");
    expect(firstVehicle([{ id: "a", status: "unreachable" }])?.id).toBe("a");
    expect(firstVehicle([])).toBeUndefined();
  });

  it("?name= trimmed to 40 characters; empty means the server's guest name", () => {
    expect(displayName(new URLSearchParams("name=%20%20"))).toBeUndefined();
    expect(displayName(new URLSearchParams(""))).toBeUndefined();
    expect(displayName(new URLSearchParams(`name=${"x".repeat(50)}`))).toBe("x".repeat(40));
  });
});
