/**
 * Which decode path the pilot forces (pure, plus its localStorage key): `?video=webcodecs`,
 * `?video=mse` or `?video=auto` in the page's address wins over the choice kept in the
 * browser (the health line's selector); "auto" is WebCodecs where the page has it (a secure
 * context: https or localhost), else Media Source Extensions.
 */

import type { KeyValueStore } from "../lib/prefs";
import type { DecodePath } from "./sink";

export type PathChoice = "auto" | "webcodecs" | "mse";
export const PATH_CHOICES: readonly PathChoice[] = ["auto", "webcodecs", "mse"];
const KEY = "neptunus.video.path";

export function parsePathChoice(value: string | null | undefined): PathChoice | null {
  return PATH_CHOICES.find((c) => c === value) ?? null;
}

/** The forced path (null: auto) from the address, else from the browser's storage. */
export function loadPathChoice(params: URLSearchParams, store: KeyValueStore | null): PathChoice {
  const fromUrl = parsePathChoice(params.get("video"));
  if (fromUrl !== null) return fromUrl;
  try {
    return parsePathChoice(store?.getItem(KEY)) ?? "auto";
  } catch {
    return "auto";
  }
}

export function savePathChoice(store: KeyValueStore | null, choice: PathChoice): void {
  try {
    store?.setItem(KEY, choice);
  } catch {
    // not kept: fine
  }
}

export function forcedPath(choice: PathChoice): DecodePath | null {
  return choice === "auto" ? null : choice;
}

export const PATH_LABELS: Readonly<Record<DecodePath, string>> = { webcodecs: "WebCodecs", mse: "MSE", jpeg: "JPEG" };
