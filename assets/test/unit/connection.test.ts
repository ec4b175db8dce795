// The operator page's connection against the in-process stand-in server
// (test/support/fake_server.mjs), over real WebSockets (`ws`).
import { describe, expect, it } from "vitest";
import type { VehicleSnapshot } from "../../src/lib/protocol";
import type { NeptunusClientOptions } from "../../src/lib/vehicle_client";
import { OperatorConnection, displayName, firstVehicle } from "../../src/operator/connection";
import type { Identity } from "../../src/operator/connection";
import { initialState } from "../../src/operator/state";
import type { OperatorState } from "../../src/operator/state";
import { eventually, useStandIn } from "./stand_in";

const standIn = useStandIn();

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
        return standIn.client(o);
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
