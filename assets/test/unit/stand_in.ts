// The in-process stand-in server (test/support/fake_server.mjs) for one test file: started
// before its tests, its clients (real WebSockets, the `ws` package) disconnected after each.
import { afterAll, afterEach, beforeAll } from "vitest";
import WebSocket from "ws";
import { startFakeServer } from "../support/fake_server.mjs";
import type { FakeServer } from "../support/fake_server.mjs";
import { NeptunusClient } from "../../src/lib/vehicle_client";
import type { NeptunusClientOptions } from "../../src/lib/vehicle_client";

export interface StandIn {
  /** A client (not yet connected) of the stand-in, or of the server at `url`. */
  client(options?: NeptunusClientOptions, url?: string): NeptunusClient;
  /** Sends `event` to every connection joined to `topic`, as the server would. */
  broadcast(topic: string, event: string, payload: unknown): void;
}

/** Registers the file's hooks: call at the top level of a test file. */
export function useStandIn(): StandIn {
  let server: FakeServer | null = null;
  const clients: NeptunusClient[] = [];
  beforeAll(async () => {
    server = await startFakeServer(0);
  });
  afterEach(async () => {
    await Promise.all(clients.splice(0).map((c) => c.disconnect()));
  });
  afterAll(async () => {
    await server?.close();
  });
  return {
    client(options = {}, url) {
      const base = url ?? server?.url;
      if (base === undefined) throw new Error("the stand-in server is not started (use the client inside a test)");
      const c = new NeptunusClient({ ...options, endpoint: `${base.replace(/^http/, "ws")}/socket`, transport: WebSocket });
      clients.push(c);
      return c;
    },
    broadcast(topic, event, payload) {
      if (server === null) throw new Error("the stand-in server is not started");
      server.broadcast(topic, event, payload);
    },
  };
}

/** Resolves with what `get` returns once it is neither undefined nor false (polled every 10 ms). */
export function eventually<T>(get: () => T | undefined | false, ms = 5000): Promise<T> {
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
