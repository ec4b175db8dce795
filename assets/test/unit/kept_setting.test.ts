import { describe, expect, it } from "vitest";
import { KEPT_LOADING, KeptSetting } from "../../src/lib/kept_setting";
import type { KeptSettingHost, KeptStatus } from "../../src/lib/kept_setting";
import { SettingsError } from "../../src/lib/settings";

interface Call {
  readonly method: "get" | "put" | "delete";
  readonly key: string;
  readonly value?: unknown;
  readonly resolve: (value?: unknown) => void;
  readonly reject: (err: unknown) => void;
}

/** A number kept under "test.number"; the server answers when the test says. */
function harness(initial = 1) {
  let value = initial;
  let status: KeptStatus = KEPT_LOADING;
  const statuses: KeptStatus["state"][] = [];
  const calls: Call[] = [];
  const call =
    (method: Call["method"]) =>
    (key: string, v?: unknown): Promise<never> =>
      new Promise((resolve, reject) => calls.push({ method, key, value: v, resolve: resolve as (value?: unknown) => void, reject }));
  const host: KeptSettingHost<number> = {
    key: "test.number",
    client: { get: call("get"), put: call("put"), delete: call("delete") },
    parse: (stored) => (typeof stored === "number" ? { ok: true, value: stored } : { ok: false, reason: "not a number" }),
    encode: (v) => ({ n: v }),
    texts: {
      default: "Default number.",
      stored: "Your number.",
      unusable: (reason) => `Unusable (${reason}).`,
      notKept: "Not kept.",
      notSaved: (reason) => `Not saved: ${reason}`,
    },
    get: () => ({ value, status }),
    set: (next) => {
      if (next.value !== undefined) value = next.value;
      status = next.status;
      statuses.push(status.state);
    },
  };
  const settled = (): Promise<void> => new Promise((r) => setTimeout(r, 0));
  return { kept: new KeptSetting(host), value: () => value, status: () => status, statuses, calls, settled };
}

const unauthorized = new SettingsError("unauthorized", 401);

describe("KeptSetting.load", () => {
  it("nothing stored: the page's default stays", async () => {
    const h = harness();
    const loading = h.kept.load();
    h.calls[0]?.resolve(undefined);
    await loading;
    expect(h.calls.map((c) => [c.method, c.key])).toEqual([["get", "test.number"]]);
    expect(h.value()).toBe(1);
    expect(h.status()).toEqual({ state: "default", text: "Default number." });
  });

  it("a stored value is used", async () => {
    const h = harness();
    const loading = h.kept.load();
    h.calls[0]?.resolve(7);
    await loading;
    expect(h.value()).toBe(7);
    expect(h.status()).toEqual({ state: "stored", text: "Your number." });
  });

  it("a stored value that cannot be used leaves the default, and says why", async () => {
    const h = harness();
    const loading = h.kept.load();
    h.calls[0]?.resolve("seven");
    await loading;
    expect(h.value()).toBe(1);
    expect(h.status()).toEqual({ state: "error", text: "Unusable (not a number)." });
  });

  it("a change made while the server was asked wins", async () => {
    const h = harness();
    const loading = h.kept.load();
    h.kept.save(3);
    h.calls[0]?.resolve(7);
    await loading;
    expect(h.value()).toBe(3);
    expect(h.status().state).toBe("saving");
  });

  it("without a login nothing is kept; another failure says why", async () => {
    const anonymous = harness();
    const a = anonymous.kept.load();
    anonymous.calls[0]?.reject(unauthorized);
    await a;
    expect(anonymous.status()).toEqual({ state: "not_kept", text: "Not kept." });
    const broken = harness();
    const b = broken.kept.load();
    broken.calls[0]?.reject(new SettingsError("cannot reach the server: down", 0));
    await b;
    expect(broken.status()).toEqual({ state: "error", text: "Not saved: cannot reach the server: down" });
  });
});

describe("KeptSetting.save and reset", () => {
  it("a change is used at once, saved encoded, then says so", async () => {
    const h = harness();
    h.kept.save(5);
    expect(h.value()).toBe(5);
    expect(h.status()).toEqual({ state: "saving", text: "Saving…" });
    expect(h.calls[0]).toMatchObject({ method: "put", key: "test.number", value: { n: 5 } });
    h.calls[0]?.resolve();
    await h.settled();
    expect(h.status()).toEqual({ state: "saved", text: "Saved on the server." });
  });

  it("only the newest save says saved", async () => {
    const h = harness();
    h.kept.save(5);
    h.kept.save(6);
    h.calls[0]?.resolve();
    await h.settled();
    expect(h.status().state).toBe("saving");
    h.calls[1]?.resolve();
    await h.settled();
    expect(h.status().state).toBe("saved");
  });

  it("saves and resets go one at a time, the newest last: an older one never lands after it", async () => {
    const h = harness();
    h.kept.save(5);
    h.kept.save(6);
    h.kept.reset(1);
    h.kept.save(7);
    // one request on its way; of those asked for meanwhile only the newest is sent, after it
    expect(h.calls.map((c) => [c.method, c.value])).toEqual([["put", { n: 5 }]]);
    h.calls[0]?.resolve();
    await h.settled();
    expect(h.calls.map((c) => [c.method, c.value])).toEqual([
      ["put", { n: 5 }],
      ["put", { n: 7 }],
    ]);
    expect(h.status().state).toBe("saving");
    h.calls[1]?.resolve();
    await h.settled();
    expect(h.calls).toHaveLength(2);
    expect([h.value(), h.status().state]).toEqual([7, "saved"]);
  });

  it("a reset superseded by a save does not say default", async () => {
    const h = harness(9);
    h.kept.save(5);
    h.kept.reset(1);
    h.calls[0]?.resolve();
    await h.settled();
    expect(h.calls[1]).toMatchObject({ method: "delete" });
    h.kept.save(8);
    h.calls[1]?.resolve();
    await h.settled();
    expect(h.status().state).toBe("saving");
    h.calls[2]?.resolve();
    await h.settled();
    expect([h.value(), h.status().state]).toEqual([8, "saved"]);
  });

  it("a save without a login still applies on the page", async () => {
    const h = harness();
    h.kept.save(5);
    h.calls[0]?.reject(unauthorized);
    await h.settled();
    expect(h.value()).toBe(5);
    expect(h.status().state).toBe("not_kept");
  });

  it("reset goes back to the default and deletes the stored value", async () => {
    const h = harness(9);
    h.kept.reset(1);
    expect(h.value()).toBe(1);
    expect(h.status()).toEqual({ state: "saving", text: "Resetting…" });
    expect(h.calls[0]).toMatchObject({ method: "delete", key: "test.number" });
    h.calls[0]?.resolve();
    await h.settled();
    expect(h.status()).toEqual({ state: "default", text: "Default number." });
  });

  it("a failed reset says why", async () => {
    const h = harness(9);
    h.kept.reset(1);
    h.calls[0]?.reject(new SettingsError("disk full", 500));
    await h.settled();
    expect(h.status()).toEqual({ state: "error", text: "Not saved: disk full" });
  });
});
