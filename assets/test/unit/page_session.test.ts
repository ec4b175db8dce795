import { describe, expect, it } from "vitest";
import { PageSession, SESSION_RECHECK_MS, SESSION_RETRY_MS, TOKEN_KEY, loginUrl, nextPath } from "../../src/lib/session";
import type { Fetch, SessionEnv, TokenStore } from "../../src/lib/session";

function b64url(text: string): string {
  return Buffer.from(text).toString("base64").replace(/\+/g, "-").replace(/\//g, "_").replace(/=+$/, "");
}

/** A token for `sub` that expires at `exp` s since the epoch. */
const token = (sub: string, exp = 2_000_000_000): string => `v1.${b64url(JSON.stringify({ sub, iat: 0, exp }))}.sig`;

const local = { mode: "local", anonymous_observers: false, user: null, expires_at: null };
const secureNobody = { mode: "secure", anonymous_observers: false, user: null, expires_at: null };
const secureAnon = { mode: "secure", anonymous_observers: true, user: null, expires_at: null };
const secureAda = { mode: "secure", anonymous_observers: false, user: { name: "ada", role: "pilot" }, expires_at: 5 };

type Reply = { status: number; body: unknown } | Error;

interface Page {
  session: PageSession;
  tokens: TokenStore & { data: Map<string, string> };
  /** Authorization header of each request (null: none) */
  asked: (string | null)[];
  logins: (string | null)[];
  problems: (string | null)[];
  sleeps: number[];
  setMonotonic: (ms: number) => void;
}

/** A page whose server answers `replies` in turn (the last one again when they run out). */
function page(replies: Reply[], stored: string | null = null): Page {
  const data = new Map<string, string>(stored === null ? [] : [[TOKEN_KEY, stored]]);
  const tokens = {
    data,
    getItem: (k: string) => data.get(k) ?? null,
    setItem: (k: string, v: string) => void data.set(k, v),
    removeItem: (k: string) => void data.delete(k),
  };
  const asked: (string | null)[] = [];
  const logins: (string | null)[] = [];
  const problems: (string | null)[] = [];
  const sleeps: number[] = [];
  let monotonic = 0;
  let n = 0;
  const fetchFn: Fetch = (_input, init) => {
    const headers = (init?.headers ?? {}) as Record<string, string>;
    asked.push(headers["authorization"] ?? null);
    const reply = replies[Math.min(n++, replies.length - 1)];
    if (reply === undefined) return Promise.reject(new Error("no reply"));
    if (reply instanceof Error) return Promise.reject(reply);
    return Promise.resolve(new Response(JSON.stringify(reply.body), { status: reply.status }));
  };
  const env: SessionEnv = {
    tokens,
    fetch: fetchFn,
    wallMs: () => 1_000_000,
    monotonicMs: () => monotonic,
    sleep: (ms) => {
      sleeps.push(ms);
      return Promise.resolve();
    },
    toLogin: (reason) => logins.push(reason),
    onUnreachable: (reason) => problems.push(reason),
  };
  return { session: new PageSession(env), tokens, asked, logins, problems, sleeps, setMonotonic: (ms) => void (monotonic = ms) };
}

describe("loginUrl", () => {
  it("comes back here after the login, with the reason shown there", () => {
    expect(loginUrl("/?vehicle=a", null)).toBe("/login.html?next=%2F%3Fvehicle%3Da");
    const url = new URL(loginUrl("/dev.html", "token expired"), "http://x");
    expect(url.pathname).toBe("/login.html");
    expect(url.searchParams.get("reason")).toBe("token expired");
    expect(nextPath(url.searchParams)).toBe("/dev.html");
  });
});

describe("PageSession.authenticate", () => {
  it("local mode: no token, no login", async () => {
    const p = page([{ status: 200, body: local }]);
    await expect(p.session.authenticate()).resolves.toMatchObject({ mode: "local" });
    expect(p.session.token).toBeNull();
    expect(p.asked).toEqual([null]);
    expect(p.logins).toEqual([]);
    expect(p.problems).toEqual([null]);
  });

  it("secure mode with a good token: the token is used", async () => {
    const t = token("ada");
    const p = page([{ status: 200, body: secureAda }], t);
    await expect(p.session.authenticate()).resolves.toMatchObject({ user: { name: "ada" } });
    expect(p.session.token).toBe(t);
    expect(p.asked).toEqual([`Bearer ${t}`]);
  });

  it("a refused token is dropped and the session asked for without it", async () => {
    const p = page([{ status: 401, body: { error: "token revoked" } }, { status: 200, body: secureAnon }], token("ada"));
    await expect(p.session.authenticate()).resolves.toMatchObject({ anonymous_observers: true });
    expect(p.session.token).toBeNull();
    expect(p.tokens.data.has(TOKEN_KEY)).toBe(false);
    expect(p.asked).toEqual([`Bearer ${token("ada")}`, null]);
  });

  it("an expired token is not even sent", async () => {
    const p = page([{ status: 200, body: secureAnon }], token("ada", 10));
    await p.session.authenticate();
    expect(p.asked).toEqual([null]);
    expect(p.tokens.data.has(TOKEN_KEY)).toBe(false);
  });

  it("secure mode without a user or anonymous observers: to the login page", async () => {
    const p = page([{ status: 200, body: secureNobody }]);
    await expect(p.session.authenticate()).resolves.toBeNull();
    expect(p.logins).toEqual([null]);
  });

  it("a session that names no user does not keep the token", async () => {
    const p = page([{ status: 200, body: local }], token("ada"));
    await p.session.authenticate();
    expect(p.session.token).toBeNull();
  });

  it("an unreachable server is reported and asked again every SESSION_RETRY_MS", async () => {
    const p = page([new Error("Failed to fetch"), { status: 503, body: { error: "starting" } }, { status: 200, body: local }]);
    await expect(p.session.authenticate()).resolves.toMatchObject({ mode: "local" });
    expect(p.problems).toEqual(["Failed to fetch", "starting", null]);
    expect(p.sleeps).toEqual([SESSION_RETRY_MS, SESSION_RETRY_MS]);
  });
});

describe("PageSession.recheck and signOut", () => {
  it("a token refused later sends the page to the login page with the reason", async () => {
    const p = page([{ status: 200, body: secureAda }, { status: 401, body: { error: "token expired" } }], token("ada"));
    await p.session.authenticate();
    await p.session.recheck();
    expect(p.logins).toEqual(["token expired"]);
    expect(p.tokens.data.has(TOKEN_KEY)).toBe(false);
  });

  it("asks at most every SESSION_RECHECK_MS, and never without a token", async () => {
    const p = page([{ status: 200, body: secureAda }], token("ada"));
    await p.session.recheck();
    expect(p.asked).toEqual([]);
    await p.session.authenticate();
    await p.session.recheck();
    p.setMonotonic(SESSION_RECHECK_MS - 1);
    await p.session.recheck();
    expect(p.asked).toHaveLength(2);
    p.setMonotonic(SESSION_RECHECK_MS);
    await p.session.recheck();
    expect(p.asked).toHaveLength(3);
    expect(p.logins).toEqual([]);
  });

  it("a network error on recheck keeps the token", async () => {
    const p = page([{ status: 200, body: secureAda }, new Error("Failed to fetch")], token("ada"));
    await p.session.authenticate();
    await p.session.recheck();
    expect(p.logins).toEqual([]);
    expect(p.tokens.data.has(TOKEN_KEY)).toBe(true);
  });

  it("signOut forgets the token", () => {
    const p = page([], token("ada"));
    p.session.signOut();
    expect(p.tokens.data.has(TOKEN_KEY)).toBe(false);
  });
});
