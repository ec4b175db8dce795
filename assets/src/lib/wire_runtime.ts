/**
 * What the generated decoders (wire.gen.ts, from the server's wire schema) read JSON with. Each
 * reader returns the value when it is of its type, else `undefined` ("does not decode"); the
 * generated code turns that into null or a refused object by the schema's one rule.
 */

export function isRecord(json: unknown): json is Record<string, unknown> {
  return typeof json === "object" && json !== null && !Array.isArray(json);
}

export function readNumber(json: unknown): number | undefined {
  return typeof json === "number" && Number.isFinite(json) ? json : undefined;
}

export function readInteger(json: unknown): number | undefined {
  return typeof json === "number" && Number.isInteger(json) ? json : undefined;
}

export function readString(json: unknown): string | undefined {
  return typeof json === "string" ? json : undefined;
}

export function readBoolean(json: unknown): boolean | undefined {
  return typeof json === "boolean" ? json : undefined;
}

/** One of `values` (the string or number literals of an enum). */
export function readEnum<const T extends readonly (string | number)[]>(json: unknown, values: T): T[number] | undefined {
  return values.find((value) => value === json);
}

/** A list whose every element `read` decodes; undefined if one does not. */
export function readList<T>(json: unknown, read: (item: unknown) => T | undefined): readonly T[] | undefined {
  if (!Array.isArray(json)) return undefined;
  const out: T[] = [];
  for (const item of json) {
    const value = read(item);
    if (value === undefined) return undefined;
    out.push(value);
  }
  return out;
}

/** An object whose keys are data; the entries `read` does not decode are left out. */
export function readMap<T>(json: unknown, read: (item: unknown) => T | undefined): Readonly<Record<string, T>> | undefined {
  if (!isRecord(json)) return undefined;
  const out: Record<string, T> = {};
  for (const [key, item] of Object.entries(json)) {
    const value = read(item);
    if (value !== undefined) out[key] = value;
  }
  return out;
}
