/**
 * The sim camera's render stamp (pure): 48 black/white blocks of 8×8 px in the picture's
 * top-left corner (bit 47 first) hold the render time, wall-clock ms since the epoch modulo
 * 2^48; the row of blocks under it holds the same bits inverted. The page reads it from the
 * decoded picture to tell how long the picture took from the renderer to the screen.
 */

export const STAMP_BITS = 48;
export const STAMP_BLOCK = 8;
/** the corner the stamp takes: 384 × 16 px */
export const STAMP_WIDTH = STAMP_BITS * STAMP_BLOCK;
export const STAMP_HEIGHT = 2 * STAMP_BLOCK;
export const STAMP_MODULUS = 2 ** STAMP_BITS;
/** how far from mid-grey a block must be to count as black or white (0..255) */
const MARGIN = 48;

/** Pixels as a canvas gives them: RGBA rows of `width` pixels. */
export interface Pixels {
  readonly data: Uint8ClampedArray | Uint8Array;
  readonly width: number;
  readonly height: number;
}

/** Mean luma of the 4×4 centre of the block at (bx, by), from RGBA. */
function blockLuma(p: Pixels, bx: number, by: number): number {
  let sum = 0;
  for (let y = by * STAMP_BLOCK + 2; y < by * STAMP_BLOCK + 6; y++) {
    for (let x = bx * STAMP_BLOCK + 2; x < bx * STAMP_BLOCK + 6; x++) {
      const i = (y * p.width + x) * 4;
      sum += 0.299 * (p.data[i] ?? 0) + 0.587 * (p.data[i + 1] ?? 0) + 0.114 * (p.data[i + 2] ?? 0);
    }
  }
  return sum / 16;
}

/**
 * The render time in the corner (ms modulo 2^48), or null when there is no valid stamp: each
 * block must be clearly black or white and its twin in the second row the opposite.
 */
export function readStamp(p: Pixels): number | null {
  if (p.width < STAMP_WIDTH || p.height < STAMP_HEIGHT || p.data.length < p.width * STAMP_HEIGHT * 4) return null;
  let value = 0;
  for (let i = 0; i < STAMP_BITS; i++) {
    const code = blockLuma(p, i, 0);
    const inverse = blockLuma(p, i, 1);
    const one = code > 128 + MARGIN && inverse < 128 - MARGIN;
    const zero = code < 128 - MARGIN && inverse > 128 + MARGIN;
    if (!one && !zero) return null;
    value = value * 2 + (one ? 1 : 0);
  }
  return value;
}

/** Draws `ms` as a stamp into RGBA pixels (the renderer's side, for tests). */
export function drawStamp(p: Pixels & { readonly data: Uint8ClampedArray | Uint8Array }, ms: number): void {
  const value = ((Math.floor(ms) % STAMP_MODULUS) + STAMP_MODULUS) % STAMP_MODULUS;
  for (let i = 0; i < STAMP_BITS; i++) {
    const bit = Math.floor(value / 2 ** (STAMP_BITS - 1 - i)) % 2;
    for (let row = 0; row < 2; row++) {
      const level = (row === 0 ? bit : 1 - bit) === 1 ? 255 : 0;
      for (let y = row * STAMP_BLOCK; y < (row + 1) * STAMP_BLOCK; y++) {
        for (let x = i * STAMP_BLOCK; x < (i + 1) * STAMP_BLOCK; x++) {
          const o = (y * p.width + x) * 4;
          p.data[o] = level;
          p.data[o + 1] = level;
          p.data[o + 2] = level;
          p.data[o + 3] = 255;
        }
      }
    }
  }
}

/**
 * How long ago (ms) a picture stamped `stamp` was rendered, at `serverNowMs` (the server's
 * wall clock, ms): the difference modulo 2^48, as a signed number (a stamp a little ahead
 * of the estimated clock gives a small negative figure, not 2^48).
 */
export function stampAgeMs(stamp: number, serverNowMs: number): number {
  const now = ((Math.floor(serverNowMs) % STAMP_MODULUS) + STAMP_MODULUS) % STAMP_MODULUS;
  let d = (now - stamp) % STAMP_MODULUS;
  if (d >= STAMP_MODULUS / 2) d -= STAMP_MODULUS;
  if (d < -STAMP_MODULUS / 2) d += STAMP_MODULUS;
  return d;
}
