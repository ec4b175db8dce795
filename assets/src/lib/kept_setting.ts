/**
 * One of the user's settings kept on the server (lib/settings.ts), as a page holds it: the
 * value in use and where it stands (`KeptStatus`: read from the server, saved, or why not).
 * The operator page keeps the gamepad mapping so, the developer page its plots.
 *
 * - `load` (once signed in): the stored value if there is one and it can be used, else the
 *   page's default stays, and the status says which. A change made while the server was asked
 *   wins (it is being saved).
 * - `save(value)`: the value is used at once and saved; only the newest save says "saved".
 * - `reset(value)`: back to the page's default, the stored one deleted.
 * - Saves and resets are sent one request at a time, the newest last (`NewestWriter`): two on
 *   their way at once could be served out of order, the older landing last and the user's
 *   last change lost.
 * - Without a login the server keeps nothing (401): the value still applies on this page and
 *   the status says it is not kept.
 */

import { reasonOf } from "./errors";
import { NewestWriter } from "./newest_writer";
import { notKept } from "./settings";
import type { SettingsClient } from "./settings";

export interface KeptStatus {
  readonly state: "loading" | "default" | "stored" | "saving" | "saved" | "not_kept" | "error";
  readonly text: string;
}

export const KEPT_LOADING: KeptStatus = Object.freeze({ state: "loading", text: "" });

/** What the status says of this setting. */
export interface KeptTexts {
  /** no stored value: the page's default applies */
  readonly default: string;
  /** the stored value is in use */
  readonly stored: string;
  /** the stored value cannot be used, for `reason` */
  readonly unusable: (reason: string) => string;
  /** not kept (no login) */
  readonly notKept: string;
  /** not saved, for `reason` */
  readonly notSaved: (reason: string) => string;
}

export interface KeptSettingHost<T> {
  /** the settings key (`gamepad.mapping`, `developer.plots`) */
  readonly key: string;
  readonly client: Pick<SettingsClient, "get" | "put" | "delete">;
  /** the stored JSON as a value, or why it cannot be used */
  readonly parse: (stored: unknown) => { readonly ok: true; readonly value: T } | { readonly ok: false; readonly reason: string };
  readonly encode: (value: T) => unknown;
  readonly texts: KeptTexts;
  /** the value in use and the status */
  readonly get: () => { readonly value: T; readonly status: KeptStatus };
  readonly set: (next: { readonly value?: T; readonly status: KeptStatus }) => void;
}

export class KeptSetting<T> {
  private readonly host: KeptSettingHost<T>;
  private readonly writer = new NewestWriter();

  constructor(host: KeptSettingHost<T>) {
    this.host = host;
  }

  async load(): Promise<void> {
    const { client, key, texts } = this.host;
    try {
      const stored = await client.get(key);
      // the user changed it while we asked: theirs wins (and is being saved)
      if (this.host.get().status.state !== "loading") return;
      if (stored === undefined) {
        this.host.set({ status: { state: "default", text: texts.default } });
        return;
      }
      const parsed = this.host.parse(stored);
      if (parsed.ok) this.host.set({ value: parsed.value, status: { state: "stored", text: texts.stored } });
      else this.host.set({ status: { state: "error", text: texts.unusable(parsed.reason) } });
    } catch (err) {
      this.failed(err);
    }
  }

  save(value: T): void {
    this.host.set({ value, status: { state: "saving", text: "Saving…" } });
    const { client, key } = this.host;
    const encoded = this.host.encode(value);
    this.writer.write(() => client.put(key, encoded)).then(
      () => {
        // a later change may have been saved meanwhile: only the newest says "saved"
        if (this.host.get().value === value) this.host.set({ status: { state: "saved", text: "Saved on the server." } });
      },
      (err: unknown) => this.failed(err),
    );
  }

  /** Back to `value`, the page's default (the stored one is deleted on the server). */
  reset(value: T): void {
    this.host.set({ value, status: { state: "saving", text: "Resetting…" } });
    const { client, key } = this.host;
    this.writer.write(() => client.delete(key)).then(
      () => {
        if (this.host.get().value === value) this.host.set({ status: { state: "default", text: this.host.texts.default } });
      },
      (err: unknown) => this.failed(err),
    );
  }

  private failed(err: unknown): void {
    const texts = this.host.texts;
    this.host.set({ status: notKept(err) ? { state: "not_kept", text: texts.notKept } : { state: "error", text: texts.notSaved(reasonOf(err)) } });
  }
}
