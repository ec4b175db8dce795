import { describe, expect, it } from "vitest";
import { SettingsClient, SettingsError, notKept } from "../../src/lib/settings";

interface Call {
  url: string;
  method: string;
  headers: Record<string, string>;
  body: string | undefined;
}

function fake(status: number, body: unknown, calls: Call[]) {
  return (url: string, init?: RequestInit): Promise<Response> => {
    calls.push({
      url,
      method: init?.method ?? "GET",
      headers: (init?.headers ?? {}) as Record<string, string>,
      body: typeof init?.body === "string" ? init.body : undefined,
    });
    return Promise.resolve(new Response(JSON.stringify(body), { status, headers: { "content-type": "application/json" } }));
  };
}

describe("SettingsClient", () => {
  it("gets a value, with the page's token", async () => {
    const calls: Call[] = [];
    const client = new SettingsClient(() => "v1.t.s", fake(200, { user: "ada", settings: { "gamepad.mapping": { a: 1 }, other: 2 } }, calls));
    expect(await client.get("gamepad.mapping")).toEqual({ a: 1 });
    expect(calls[0]).toMatchObject({ url: "/api/settings", method: "GET", headers: { authorization: "Bearer v1.t.s" } });
  });

  it("a key with none stored is undefined (even one named like an Object property)", async () => {
    const client = new SettingsClient(() => null, fake(200, { user: "local", settings: {} }, []));
    expect(await client.get("k")).toBeUndefined();
    expect(await client.get("constructor")).toBeUndefined();
  });

  it("an answer without settings is an error", async () => {
    const client = new SettingsClient(() => null, fake(200, { user: "local" }, []));
    await expect(client.get("k")).rejects.toThrow(/unexpected answer/);
  });

  it("puts {value} as JSON and deletes; no token in local mode", async () => {
    const calls: Call[] = [];
    const client = new SettingsClient(() => null, fake(200, { key: "k", value: [1] }, calls));
    await client.put("k", [1]);
    await client.delete("k");
    expect(calls.map((c) => c.method)).toEqual(["PUT", "DELETE"]);
    expect(calls.map((c) => c.url)).toEqual(["/api/settings/k", "/api/settings/k"]);
    expect(JSON.parse(calls[0]?.body ?? "")).toEqual({ value: [1] });
    expect(calls[0]?.headers["authorization"]).toBeUndefined();
    expect(calls[0]?.headers["content-type"]).toBe("application/json");
  });

  it("a refusal carries the server's reason and status; 401 means not kept", async () => {
    const client = new SettingsClient(() => null, fake(401, { error: "log in to keep settings" }, []));
    const err = await client.put("k", 1).catch((e: unknown) => e);
    expect(err).toBeInstanceOf(SettingsError);
    expect((err as SettingsError).message).toBe("log in to keep settings");
    expect(notKept(err)).toBe(true);
    const other = await new SettingsClient(() => null, fake(500, { error: "cannot store the setting: disk full" }, [])).put("k", 1).catch((e: unknown) => e);
    expect(notKept(other)).toBe(false);
    expect((other as SettingsError).status).toBe(500);
  });

  it("no answer is an error with status 0", async () => {
    const client = new SettingsClient(() => null, () => Promise.reject(new Error("offline")));
    const err = await client.get("k").catch((e: unknown) => e);
    expect(err).toBeInstanceOf(SettingsError);
    expect((err as SettingsError).status).toBe(0);
    expect((err as SettingsError).message).toMatch(/offline/);
  });
});
