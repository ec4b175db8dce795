/**
 * The user's settings kept on the server (`/api/settings/<key>`, docs/API.md): they follow
 * the user from device to device (in local mode the node has one user). The pages keep
 * there the gamepad mapping (`gamepad.mapping`) and the developer page's plots
 * (`developer.plots`). Thin fetch wrappers; the token is the page's (`PageSession`).
 */

import { isRecord } from "./protocol";

export const GAMEPAD_MAPPING_KEY = "gamepad.mapping";
export const DEVELOPER_PLOTS_KEY = "developer.plots";

type Fetch = (input: string, init?: RequestInit) => Promise<Response>;

/** A refused or failed settings request: the server's reason and the HTTP status (0: no answer). */
export class SettingsError extends Error {
  readonly status: number;

  constructor(message: string, status: number) {
    super(message);
    this.name = "SettingsError";
    this.status = status;
  }
}

/** Whether `err` means "this user keeps no settings here" (no login: 401). */
export function notKept(err: unknown): boolean {
  return err instanceof SettingsError && err.status === 401;
}

export class SettingsClient {
  private readonly token: () => string | null;
  private readonly fetchFn: Fetch;

  constructor(token: () => string | null, fetchFn: Fetch = (input, init) => fetch(input, init)) {
    this.token = token;
    this.fetchFn = fetchFn;
  }

  /**
   * The value stored under `key`, or undefined when none is. (Asks for all the user's
   * settings, which always answers 200: a browser reports every 404 in its console.)
   */
  async get(key: string): Promise<unknown> {
    const body = await this.request("GET", null);
    const settings = body?.["settings"];
    if (!isRecord(settings)) throw new SettingsError(`unexpected answer: ${JSON.stringify(body)}`, 200);
    return Object.prototype.hasOwnProperty.call(settings, key) ? settings[key] : undefined;
  }

  /** Stores `value` under `key` (on the server's disk when this resolves). */
  async put(key: string, value: unknown): Promise<void> {
    await this.request("PUT", key, JSON.stringify({ value }));
  }

  /** Removes `key` (the page's default applies again). */
  async delete(key: string): Promise<void> {
    await this.request("DELETE", key);
  }

  private async request(method: string, key: string | null, body?: string): Promise<Record<string, unknown> | undefined> {
    const headers: Record<string, string> = {};
    const token = this.token();
    if (token !== null) headers["authorization"] = `Bearer ${token}`;
    if (body !== undefined) headers["content-type"] = "application/json";
    let response: Response;
    try {
      response = await this.fetchFn(key === null ? "/api/settings" : `/api/settings/${encodeURIComponent(key)}`, {
        method,
        headers,
        cache: "no-store",
        ...(body !== undefined ? { body } : {}),
      });
    } catch (err) {
      throw new SettingsError(`cannot reach the server: ${err instanceof Error ? err.message : String(err)}`, 0);
    }
    let json: unknown = null;
    try {
      json = (await response.json()) as unknown;
    } catch {
      json = null;
    }
    if (method === "GET" && response.status === 404) return undefined;
    if (!response.ok) {
      const reason = isRecord(json) && typeof json["error"] === "string" ? json["error"] : `HTTP ${response.status}`;
      throw new SettingsError(reason, response.status);
    }
    if (!isRecord(json)) throw new SettingsError(`unexpected answer: ${JSON.stringify(json)}`, response.status);
    return json;
  }
}
