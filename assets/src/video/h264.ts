/**
 * H.264 access units (pure): NAL units of an Annex B access unit, the sequence parameter set
 * (profile, level, picture size), the RFC 6381 codec string and the `avcC` record that MP4
 * needs, and samples in MP4's length-prefixed form.
 */

export const NAL_IDR = 5;
export const NAL_SEI = 6;
export const NAL_SPS = 7;
export const NAL_PPS = 8;
export const NAL_AUD = 9;

/** The NAL units of an Annex B byte stream (3- or 4-byte start codes), as views into it. */
export function splitNals(au: Uint8Array): Uint8Array[] {
  const nals: Uint8Array[] = [];
  let start = -1;
  let i = 0;
  const n = au.length;
  while (i + 2 < n) {
    if (au[i] === 0 && au[i + 1] === 0 && au[i + 2] === 1) {
      if (start >= 0) {
        // a 4-byte start code's leading zero (and trailing zeros) belong to no NAL unit
        let end = i;
        while (end > start && au[end - 1] === 0) end -= 1;
        if (end > start) nals.push(au.subarray(start, end));
      }
      i += 3;
      start = i;
    } else {
      i += 1;
    }
  }
  if (start >= 0 && start < n) nals.push(au.subarray(start, n));
  return nals;
}

export function nalType(nal: Uint8Array): number {
  return (nal[0] ?? 0) & 0x1f;
}

/** The first SPS and every PPS of an access unit (a keyframe carries them in front). */
export function parameterSets(nals: readonly Uint8Array[]): { sps: Uint8Array | null; pps: Uint8Array[] } {
  let sps: Uint8Array | null = null;
  const pps: Uint8Array[] = [];
  for (const nal of nals) {
    const t = nalType(nal);
    if (t === NAL_SPS && sps === null) sps = nal;
    else if (t === NAL_PPS) pps.push(nal);
  }
  return { sps, pps };
}

/** The bytes of a NAL unit without its emulation-prevention bytes (00 00 03 → 00 00). */
export function unescapeRbsp(nal: Uint8Array): Uint8Array {
  const out = new Uint8Array(nal.length);
  let o = 0;
  let zeros = 0;
  for (let i = 0; i < nal.length; i++) {
    const b = nal[i] ?? 0;
    if (zeros >= 2 && b === 3) {
      zeros = 0;
      continue;
    }
    out[o++] = b;
    zeros = b === 0 ? zeros + 1 : 0;
  }
  return out.subarray(0, o);
}

class Bits {
  private pos = 0;
  constructor(private readonly bytes: Uint8Array) {}

  bit(): number {
    const byte = this.bytes[this.pos >> 3];
    if (byte === undefined) throw new RangeError("SPS ends early");
    const b = (byte >> (7 - (this.pos & 7))) & 1;
    this.pos += 1;
    return b;
  }

  bits(n: number): number {
    let v = 0;
    for (let i = 0; i < n; i++) v = v * 2 + this.bit();
    return v;
  }

  /** unsigned Exp-Golomb */
  ue(): number {
    let zeros = 0;
    while (this.bit() === 0) {
      zeros += 1;
      if (zeros > 31) throw new RangeError("bad Exp-Golomb code in SPS");
    }
    return 2 ** zeros - 1 + this.bits(zeros);
  }

  /** signed Exp-Golomb */
  se(): number {
    const k = this.ue();
    return k % 2 === 1 ? (k + 1) / 2 : -(k / 2);
  }
}

export interface Sps {
  readonly profile: number;
  /** constraint_set flags and reserved bits (the byte after profile_idc) */
  readonly constraints: number;
  readonly level: number;
  readonly chromaFormat: number;
  readonly bitDepthLuma: number;
  readonly bitDepthChroma: number;
  /** the picture size after cropping, in pixels */
  readonly width: number;
  readonly height: number;
}

/** Profiles whose SPS carries chroma format, bit depths and scaling lists. */
const HIGH_PROFILES = new Set([100, 110, 122, 244, 44, 83, 86, 118, 128, 138, 139, 134, 135]);

function skipScalingList(r: Bits, size: number): void {
  let last = 8;
  let next = 8;
  for (let j = 0; j < size; j++) {
    if (next !== 0) next = (last + r.se() + 256) % 256;
    last = next === 0 ? last : next;
  }
}

/** The sequence parameter set's profile, level and picture size, or null when it cannot be read. */
export function parseSps(nal: Uint8Array): Sps | null {
  if (nalType(nal) !== NAL_SPS || nal.length < 4) return null;
  try {
    const r = new Bits(unescapeRbsp(nal.subarray(1)));
    const profile = r.bits(8);
    const constraints = r.bits(8);
    const level = r.bits(8);
    r.ue(); // seq_parameter_set_id
    let chromaFormat = 1;
    let bitDepthLuma = 8;
    let bitDepthChroma = 8;
    let separateColourPlane = 0;
    if (HIGH_PROFILES.has(profile)) {
      chromaFormat = r.ue();
      if (chromaFormat === 3) separateColourPlane = r.bit();
      bitDepthLuma = r.ue() + 8;
      bitDepthChroma = r.ue() + 8;
      r.bit(); // qpprime_y_zero_transform_bypass_flag
      if (r.bit() === 1) {
        const lists = chromaFormat === 3 ? 12 : 8;
        for (let i = 0; i < lists; i++) if (r.bit() === 1) skipScalingList(r, i < 6 ? 16 : 64);
      }
    }
    r.ue(); // log2_max_frame_num_minus4
    const pocType = r.ue();
    if (pocType === 0) {
      r.ue(); // log2_max_pic_order_cnt_lsb_minus4
    } else if (pocType === 1) {
      r.bit(); // delta_pic_order_always_zero_flag
      r.se();
      r.se();
      const cycle = r.ue();
      for (let i = 0; i < cycle; i++) r.se();
    }
    r.ue(); // max_num_ref_frames
    r.bit(); // gaps_in_frame_num_value_allowed_flag
    const widthMbs = r.ue() + 1;
    const heightMapUnits = r.ue() + 1;
    const frameMbsOnly = r.bit();
    if (frameMbsOnly === 0) r.bit(); // mb_adaptive_frame_field_flag
    r.bit(); // direct_8x8_inference_flag
    let crop = { left: 0, right: 0, top: 0, bottom: 0 };
    if (r.bit() === 1) crop = { left: r.ue(), right: r.ue(), top: r.ue(), bottom: r.ue() };
    const chroma = separateColourPlane === 1 ? 0 : chromaFormat;
    const cropX = chroma === 1 || chroma === 2 ? 2 : 1;
    const cropY = (chroma === 1 ? 2 : 1) * (2 - frameMbsOnly);
    const width = widthMbs * 16 - (crop.left + crop.right) * cropX;
    const height = (2 - frameMbsOnly) * heightMapUnits * 16 - (crop.top + crop.bottom) * cropY;
    if (width <= 0 || height <= 0) return null;
    return { profile, constraints, level, chromaFormat, bitDepthLuma, bitDepthChroma, width, height };
  } catch {
    return null;
  }
}

const hex2 = (v: number): string => v.toString(16).toUpperCase().padStart(2, "0");

/** RFC 6381 codec string of an SPS: "avc1.PPCCLL" (profile, constraints, level in hex). */
export function codecString(sps: Uint8Array): string | null {
  if (nalType(sps) !== NAL_SPS || sps.length < 4) return null;
  return `avc1.${hex2(sps[1] ?? 0)}${hex2(sps[2] ?? 0)}${hex2(sps[3] ?? 0)}`;
}

/** The AVCDecoderConfigurationRecord (`avcC`, ISO/IEC 14496-15) of one SPS and its PPSs. */
export function avcDecoderConfig(sps: Uint8Array, pps: readonly Uint8Array[], parsed: Sps | null = parseSps(sps)): Uint8Array {
  const high = parsed !== null && HIGH_PROFILES.has(parsed.profile) && parsed.profile !== 44;
  // 5 bytes of header, SPS count and length, the SPS, PPS count, each PPS and length
  const size = 5 + 3 + sps.length + 1 + pps.reduce((n, p) => n + 2 + p.length, 0) + (high ? 4 : 0);
  const out = new Uint8Array(size);
  let o = 0;
  out[o++] = 1; // configurationVersion
  out[o++] = sps[1] ?? 0;
  out[o++] = sps[2] ?? 0;
  out[o++] = sps[3] ?? 0;
  out[o++] = 0xff; // 6 reserved bits, lengthSizeMinusOne = 3
  out[o++] = 0xe1; // 3 reserved bits, one SPS
  out[o++] = sps.length >> 8;
  out[o++] = sps.length & 0xff;
  out.set(sps, o);
  o += sps.length;
  out[o++] = pps.length;
  for (const p of pps) {
    out[o++] = p.length >> 8;
    out[o++] = p.length & 0xff;
    out.set(p, o);
    o += p.length;
  }
  if (high && parsed !== null) {
    out[o++] = 0xfc | (parsed.chromaFormat & 3);
    out[o++] = 0xf8 | ((parsed.bitDepthLuma - 8) & 7);
    out[o++] = 0xf8 | ((parsed.bitDepthChroma - 8) & 7);
    out[o++] = 0; // no SPS extensions
  }
  return out;
}

/**
 * An access unit as one MP4 sample: each NAL unit behind its 4-byte length; parameter sets
 * and delimiters left out (they live in `avcC`).
 */
export function lengthPrefixed(nals: readonly Uint8Array[]): Uint8Array {
  const kept = nals.filter((nal) => {
    const t = nalType(nal);
    return t !== NAL_SPS && t !== NAL_PPS && t !== NAL_AUD;
  });
  const out = new Uint8Array(kept.reduce((n, nal) => n + 4 + nal.length, 0));
  const view = new DataView(out.buffer);
  let o = 0;
  for (const nal of kept) {
    view.setUint32(o, nal.length);
    out.set(nal, o + 4);
    o += 4 + nal.length;
  }
  return out;
}
