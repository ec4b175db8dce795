import { describe, expect, it } from "vitest";
import {
  AuthError,
  TOKEN_KEY,
  decodeSessionInfo,
  fetchSession,
  loadToken,
  login,
  nextPath,
  tokenClaims,
} from "../../src/lib/session";
import type { Fetch, TokenStore } from "../../src/lib/session";

function b64url(text: string): string {
  return Buffer.from(text).toString("base64").replace(/\+/g, "-").replace(/\//g, "_").replace(/=+$/, "");
}

const token = (sub: string, exp: number): string => `v1.${b64url(JSON.stringify({ sub, iat: 0, exp }))}.sig`;

function store(initial: Record<string, string> = {}): TokenStore & { data: Map<string, string> } {
  const data = new Map(Object.entries(initial));
  return {
    data,
    getItem: (k) => data.get(k) ?? null,
    setItem: (k, v) => void data.set(k, v),
    removeItem: (k) => void data.delete(k),
  };
}

function fakeFetch(status: number, body: unknown, headers: Record<string, string> = {}): Fetch & { calls: [string, RequestInit | undefined][] } {
  const calls: [string, RequestInit | undefined][] = [];
  const f = (input: string, init?: RequestInit): Promise<Response> => {
    calls.push([input, init]);
    return Promise.resolve(new Response(JSON.stringify(body), { status, headers }));
  };
  return Object.assign(f, { calls });
}

describe("tokens", () => {
  it("reads the name and expiry from the payload", () => {
    expect(tokenClaims(token("ada", 100))).toEqual({ name: "ada", expiresAt: 100_000 });
    expect(tokenClaims("nonsense")).toBeNull();
    expect(tokenClaims("v1.!!!.x")).toBeNull();
  });

  it("loadToken drops an expired or malformed token", () => {
    const s = store({ [TOKEN_KEY]: token("ada", 100) });
    expect(loadToken(s, 99_000)).toBe(token("ada", 100));
    expect(loadToken(s, 100_000)).toBeNull();
    expect(s.data.has(TOKEN_KEY)).toBe(false);
    expect(loadToken(store({ [TOKEN_KEY]: "junk" }), 0)).toBeNull();
  });
});

describe("session and login", () => {
  it("decodes the session document", () => {
    expect(decodeSessionInfo({ mode: "local", anonymous_observers: false, user: null, expires_at: null })).toEqual({
      mode: "local",
      anonymous_observers: false,
      user: null,
      expires_at: null,
    });
    expect(decodeSessionInfo({ mode: "open", anonymous_observers: false })).toBeNull();
    expect(decodeSessionInfo({ mode: "secure", anonymous_observers: true, user: { name: "x", role: "captain" } })).toBeNull();
  });

  it("fetchSession sends the token as a bearer and reports a 401 with its reason", async () => {
    const ok = fakeFetch(200, { mode: "secure", anonymous_observers: false, user: { name: "ada", role: "pilot" }, expires_at: 5 });
    await expect(fetchSession("tok", ok)).resolves.toMatchObject({ user: { name: "ada" } });
    expect(ok.calls[0]?.[1]?.headers).toEqual({ authorization: "Bearer tok" });

    const expired = fakeFetch(401, { error: "token expired", mode: "secure", anonymous_observers: false });
    await expect(fetchSession("tok", expired)).rejects.toMatchObject({ status: 401, message: "token expired" });
  });

  it("login posts JSON and returns the token; refusals carry the reason and Retry-After", async () => {
    const ok = fakeFetch(200, { token: "t", expires_at: 1, user: { name: "ada", role: "pilot" } });
    await expect(login("ada", "pw", ok)).resolves.toEqual({ token: "t", expires_at: 1, user: { name: "ada", role: "pilot" } });
    expect(ok.calls[0]?.[1]?.method).toBe("POST");
    expect(ok.calls[0]?.[1]?.body).toBe(JSON.stringify({ name: "ada", password: "pw" }));

    const err = await login("ada", "x", fakeFetch(429, { error: "too many login attempts: try again in 7 s" }, { "retry-after": "7" })).catch(
      (e: unknown) => e,
    );
    expect(err).toBeInstanceOf(AuthError);
    expect(err).toMatchObject({ status: 429, retryAfterS: 7 });
  });

  it("nextPath only follows same-site paths", () => {
    expect(nextPath(new URLSearchParams("next=/%3Fvehicle%3Da"))).toBe("/?vehicle=a");
    expect(nextPath(new URLSearchParams("next=//evil.example/"))).toBe("/");
    expect(nextPath(new URLSearchParams("next=https://evil.example/"))).toBe("/");
    expect(nextPath(new URLSearchParams(""))).toBe("/");
  });
});
