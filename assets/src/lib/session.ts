/**
 * Login and session for the pages: `POST /api/login`, `GET /api/session`, and the token kept
 * in `localStorage` (key `neptunus.token`). The token is signed by the server, not secret
 * from its holder: its payload (name, expiry) is readable here, see `tokenClaims`.
 */

import { reasonOf } from "./errors";
import { errorReason, isRecord } from "./protocol";
import type { AuthMode, Role } from "./protocol";

export const TOKEN_KEY = "neptunus.token";

export interface SessionInfo {
  readonly mode: AuthMode;
  readonly anonymous_observers: boolean;
  readonly user: { readonly name: string; readonly role: Role } | null;
  /** ms since the Unix epoch */
  readonly expires_at: number | null;
}

export interface LoginResult {
  readonly token: string;
  readonly expires_at: number;
  readonly user: { readonly name: string; readonly role: Role };
}

/** A refused login or session check, with the server's reason and HTTP status. */
export class AuthError extends Error {
  readonly status: number;
  readonly retryAfterS: number | null;

  constructor(message: string, status: number, retryAfterS: number | null = null) {
    super(message);
    this.name = "AuthError";
    this.status = status;
    this.retryAfterS = retryAfterS;
  }
}

export type Fetch = (input: string, init?: RequestInit) => Promise<Response>;

/** The part of `Storage` we use (tests pass a Map-backed object). */
export interface TokenStore {
  getItem(key: string): string | null;
  setItem(key: string, value: string): void;
  removeItem(key: string): void;
}

const ROLES: readonly string[] = ["pilot", "observer", "main_station"];

function decodeUser(value: unknown): { name: string; role: Role } | null {
  if (!isRecord(value)) return null;
  const { name, role } = value;
  if (typeof name !== "string" || typeof role !== "string" || !ROLES.includes(role)) return null;
  return { name, role: role as Role };
}

export function decodeSessionInfo(value: unknown): SessionInfo | null {
  if (!isRecord(value)) return null;
  const { mode, anonymous_observers, expires_at } = value;
  if (mode !== "local" && mode !== "secure") return null;
  if (typeof anonymous_observers !== "boolean") return null;
  const rawUser = value["user"];
  const user = rawUser === null || rawUser === undefined ? null : decodeUser(rawUser);
  if (user === null && rawUser !== null && rawUser !== undefined) return null;
  return {
    mode,
    anonymous_observers,
    user,
    expires_at: typeof expires_at === "number" ? expires_at : null,
  };
}

export function decodeLoginResult(value: unknown): LoginResult | null {
  if (!isRecord(value)) return null;
  const { token, expires_at } = value;
  const user = decodeUser(value["user"]);
  if (typeof token !== "string" || typeof expires_at !== "number" || !user) return null;
  return { token, expires_at, user };
}

/** Name and expiry (ms) read from a token's payload, or null if it is not a token. */
export function tokenClaims(token: string): { name: string; expiresAt: number } | null {
  const parts = token.split(".");
  if (parts.length !== 3 || parts[0] !== "v1" || parts[1] === undefined) return null;
  try {
    const b64 = parts[1].replace(/-/g, "+").replace(/_/g, "/");
    const json: unknown = JSON.parse(atob(b64 + "=".repeat((4 - (b64.length % 4)) % 4)));
    if (!isRecord(json) || typeof json["sub"] !== "string" || typeof json["exp"] !== "number") {
      return null;
    }
    return { name: json["sub"], expiresAt: json["exp"] * 1000 };
  } catch {
    return null;
  }
}

/** The stored token if it has not expired at `nowMs` (an expired one is removed). */
export function loadToken(store: TokenStore, nowMs: number): string | null {
  const token = store.getItem(TOKEN_KEY);
  if (token === null) return null;
  const claims = tokenClaims(token);
  if (!claims || claims.expiresAt <= nowMs) {
    store.removeItem(TOKEN_KEY);
    return null;
  }
  return token;
}

async function readJson(response: Response): Promise<unknown> {
  try {
    return (await response.json()) as unknown;
  } catch {
    return null;
  }
}

/** `GET /api/session` for `token` (null: none). Rejects with an AuthError on 401. */
export async function fetchSession(token: string | null, fetchFn: Fetch = fetch): Promise<SessionInfo> {
  const headers: Record<string, string> = {};
  if (token !== null) headers["authorization"] = `Bearer ${token}`;
  const response = await fetchFn("/api/session", { headers, cache: "no-store" });
  const body = await readJson(response);
  if (!response.ok) throw new AuthError(errorReason(isRecord(body) ? { reason: body["error"] } : body), response.status);
  const info = decodeSessionInfo(body);
  if (!info) throw new AuthError(`unexpected session reply: ${JSON.stringify(body)}`, response.status);
  return info;
}

/** `POST /api/login`. Rejects with an AuthError carrying the server's reason. */
export async function login(name: string, password: string, fetchFn: Fetch = fetch): Promise<LoginResult> {
  const response = await fetchFn("/api/login", {
    method: "POST",
    headers: { "content-type": "application/json" },
    body: JSON.stringify({ name, password }),
    cache: "no-store",
  });
  const body = await readJson(response);
  if (!response.ok) {
    const retry = Number.parseInt(response.headers.get("retry-after") ?? "", 10);
    const reason = isRecord(body) && typeof body["error"] === "string" ? body["error"] : `HTTP ${response.status}`;
    throw new AuthError(reason, response.status, Number.isFinite(retry) ? retry : null);
  }
  const result = decodeLoginResult(body);
  if (!result) throw new AuthError(`unexpected login reply: ${JSON.stringify(body)}`, response.status);
  return result;
}

/** Where to go after a login: a same-site path from `?next=`, else the operator page. */
export function nextPath(params: URLSearchParams): string {
  const next = params.get("next") ?? "";
  return /^\/(?!\/)[^\\]*$/.test(next) ? next : "/";
}

/** The login page's address for coming back to `here` (path and query); `reason` is shown there. */
export function loginUrl(here: string, reason: string | null): string {
  const query = new URLSearchParams({ next: here });
  if (reason) query.set("reason", reason);
  return `/login.html?${query.toString()}`;
}

/** What a `PageSession` needs from the page (the browser's, or a test's). */
export interface SessionEnv {
  readonly tokens: TokenStore;
  readonly fetch: Fetch;
  /** wall clock, ms since the Unix epoch (token expiry) */
  readonly wallMs: () => number;
  /** monotonic clock, ms (how often the session is rechecked) */
  readonly monotonicMs: () => number;
  readonly sleep: (ms: number) => Promise<void>;
  /** go to the login page (and back here after it), showing `reason` there */
  readonly toLogin: (reason: string | null) => void;
  /** the server cannot be reached (`reason`), or (null) it can again */
  readonly onUnreachable: (reason: string | null) => void;
}

/**
 * A page's session in the browser: tokens in localStorage (read when used, so a page whose
 * storage is blocked still renders and says why it cannot connect), the browser's fetch and
 * clocks, and the login page for this address. `onUnreachable` is the page's own.
 */
export function browserSessionEnv(onUnreachable: (reason: string | null) => void): SessionEnv {
  return {
    tokens: {
      getItem: (key) => window.localStorage.getItem(key),
      setItem: (key, value) => window.localStorage.setItem(key, value),
      removeItem: (key) => window.localStorage.removeItem(key),
    },
    fetch: (input, init) => fetch(input, init),
    wallMs: () => Date.now(),
    monotonicMs: () => performance.now(),
    sleep: (ms) => new Promise((resolve) => setTimeout(resolve, ms)),
    toLogin: (reason) => window.location.assign(loginUrl(window.location.pathname + window.location.search, reason)),
    onUnreachable,
  };
}

/** How long `authenticate` waits before asking again after a failure (ms). */
export const SESSION_RETRY_MS = 2000;
/** `recheck` asks the server at most this often (ms). */
export const SESSION_RECHECK_MS = 5000;

/**
 * A page's session: the stored token, whether the server accepts it, and the way to the
 * login page. A token the server refuses (401) is dropped: the page goes on without one,
 * or to the login page when the server is in secure mode and lets no anonymous observer in.
 */
export class PageSession {
  private readonly env: SessionEnv;
  private currentToken: string | null = null;
  private lastCheckMs: number | null = null;

  constructor(env: SessionEnv) {
    this.env = env;
  }

  /** The token the page connects with (null: none, or one that names no user). */
  get token(): string | null {
    return this.currentToken;
  }

  /**
   * Who we are: the session for our stored token, asking again every SESSION_RETRY_MS while
   * the server cannot be reached. Null when the page was sent to the login page.
   */
  async authenticate(): Promise<SessionInfo | null> {
    for (;;) {
      this.currentToken = loadToken(this.env.tokens, this.env.wallMs());
      try {
        let session: SessionInfo;
        try {
          session = await fetchSession(this.currentToken, this.env.fetch);
        } catch (err) {
          if (!(err instanceof AuthError) || err.status !== 401) throw err;
          this.env.tokens.removeItem(TOKEN_KEY);
          this.currentToken = null;
          session = await fetchSession(null, this.env.fetch);
        }
        if (session.mode === "secure" && session.user === null && !session.anonymous_observers) {
          this.env.toLogin(null);
          return null;
        }
        if (session.user === null) this.currentToken = null;
        this.env.onUnreachable(null);
        return session;
      } catch (err) {
        this.env.onUnreachable(reasonOf(err));
        await this.env.sleep(SESSION_RETRY_MS);
      }
    }
  }

  /**
   * After a connection error (a refused upgrade looks like a network error from the page):
   * is our token still good? At most every SESSION_RECHECK_MS; a refused token is dropped and
   * the page sent to the login page with the server's reason.
   */
  async recheck(): Promise<void> {
    const now = this.env.monotonicMs();
    if (this.currentToken === null || (this.lastCheckMs !== null && now - this.lastCheckMs < SESSION_RECHECK_MS)) return;
    this.lastCheckMs = now;
    try {
      await fetchSession(this.currentToken, this.env.fetch);
    } catch (err) {
      if (err instanceof AuthError && err.status === 401) {
        this.env.tokens.removeItem(TOKEN_KEY);
        this.env.toLogin(err.message);
      }
    }
  }

  /** Forgets the token (the sign-out link then goes to the login page). */
  signOut(): void {
    this.env.tokens.removeItem(TOKEN_KEY);
  }
}
