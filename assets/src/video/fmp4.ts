/**
 * Fragmented MP4 for Media Source Extensions (pure): the initialisation segment (`ftyp` +
 * `moov` with one H.264 track) and one media segment (`moof` + `mdat`) per access unit, so
 * the browser gets each frame as soon as it arrives (ISO/IEC 14496-12 and -15).
 *
 * Timing: a 90 kHz timescale; the caller gives each sample its decode time and duration
 * (no B-frames: presentation = decode time, as low-latency cameras send).
 */

export const TIMESCALE = 90_000;
const TRACK_ID = 1;

function fourcc(s: string): number[] {
  return [s.charCodeAt(0), s.charCodeAt(1), s.charCodeAt(2), s.charCodeAt(3)];
}

function u16(v: number): number[] {
  return [(v >>> 8) & 0xff, v & 0xff];
}

function u32(v: number): number[] {
  return [(v >>> 24) & 0xff, (v >>> 16) & 0xff, (v >>> 8) & 0xff, v & 0xff];
}

function u64(v: number): number[] {
  return [...u32(Math.floor(v / 2 ** 32)), ...u32(v % 2 ** 32)];
}

type Part = Uint8Array | readonly number[];

function concat(parts: readonly Part[]): Uint8Array<ArrayBuffer> {
  const out = new Uint8Array(parts.reduce((n, p) => n + p.length, 0));
  let o = 0;
  for (const p of parts) {
    out.set(p, o);
    o += p.length;
  }
  return out;
}

/** A box: 32-bit size, type, contents. */
export function box(type: string, ...parts: Part[]): Uint8Array<ArrayBuffer> {
  const body = concat(parts);
  return concat([u32(8 + body.length), fourcc(type), body]);
}

/** A full box: version and 24-bit flags before the contents. */
function fullBox(type: string, version: number, flags: number, ...parts: Part[]): Uint8Array<ArrayBuffer> {
  return box(type, [version, (flags >>> 16) & 0xff, (flags >>> 8) & 0xff, flags & 0xff], ...parts);
}

const MATRIX = [...u32(0x00010000), ...u32(0), ...u32(0), ...u32(0), ...u32(0x00010000), ...u32(0), ...u32(0), ...u32(0), ...u32(0x40000000)];

export interface TrackConfig {
  readonly width: number;
  readonly height: number;
  /** the AVCDecoderConfigurationRecord (h264.ts avcDecoderConfig) */
  readonly avcC: Uint8Array;
}

/** `ftyp` + `moov`: one video track, no samples (they come in fragments). */
export function initSegment(track: TrackConfig): Uint8Array<ArrayBuffer> {
  const { width, height, avcC } = track;
  const ftyp = box("ftyp", fourcc("isom"), u32(0x200), fourcc("isom"), fourcc("iso6"), fourcc("avc1"), fourcc("mp41"));
  const mvhd = fullBox("mvhd", 0, 0, u32(0), u32(0), u32(TIMESCALE), u32(0), u32(0x00010000), u16(0x0100), new Uint8Array(10), MATRIX, new Uint8Array(24), u32(TRACK_ID + 1));
  const tkhd = fullBox("tkhd", 0, 3, u32(0), u32(0), u32(TRACK_ID), u32(0), u32(0), new Uint8Array(8), u16(0), u16(0), u16(0), u16(0), MATRIX, u32(width * 0x10000), u32(height * 0x10000));
  const mdhd = fullBox("mdhd", 0, 0, u32(0), u32(0), u32(TIMESCALE), u32(0), u16(0x55c4 /* "und" */), u16(0));
  const hdlr = fullBox("hdlr", 0, 0, u32(0), fourcc("vide"), new Uint8Array(12), [..."VideoHandler"].map((c) => c.charCodeAt(0)), [0]);
  const vmhd = fullBox("vmhd", 0, 1, u16(0), u16(0), u16(0), u16(0));
  const dinf = box("dinf", fullBox("dref", 0, 0, u32(1), fullBox("url ", 0, 1)));
  const avc1 = box(
    "avc1",
    new Uint8Array(6), // reserved
    u16(1), // data_reference_index
    new Uint8Array(16), // pre_defined, reserved
    u16(width),
    u16(height),
    u32(0x00480000), // 72 dpi
    u32(0x00480000),
    u32(0),
    u16(1), // frame_count
    new Uint8Array(32), // compressorname
    u16(0x0018), // depth
    u16(0xffff), // pre_defined = -1
    box("avcC", avcC),
  );
  const stbl = box(
    "stbl",
    fullBox("stsd", 0, 0, u32(1), avc1),
    fullBox("stts", 0, 0, u32(0)),
    fullBox("stsc", 0, 0, u32(0)),
    fullBox("stsz", 0, 0, u32(0), u32(0)),
    fullBox("stco", 0, 0, u32(0)),
  );
  const trak = box("trak", tkhd, box("mdia", mdhd, hdlr, box("minf", vmhd, dinf, stbl)));
  const mvex = box("mvex", fullBox("trex", 0, 0, u32(TRACK_ID), u32(1), u32(0), u32(0), u32(0)));
  return concat([ftyp, box("moov", mvhd, trak, mvex)]);
}

export interface Sample {
  /** fragment sequence number (mfhd), from 1 */
  readonly sequence: number;
  /** decode (= presentation) time in TIMESCALE ticks */
  readonly decodeTime: number;
  /** in TIMESCALE ticks */
  readonly duration: number;
  readonly keyframe: boolean;
  /** the access unit, length-prefixed (h264.ts lengthPrefixed) */
  readonly data: Uint8Array;
}

/** sample_flags: sample_depends_on 2 (a sync sample) or 1 and sample_is_non_sync_sample */
const KEY_FLAGS = 0x02000000;
const DELTA_FLAGS = 0x01010000;

/** `moof` + `mdat` holding one sample. */
export function mediaSegment(sample: Sample): Uint8Array<ArrayBuffer> {
  const { sequence, decodeTime, duration, keyframe, data } = sample;
  const mfhd = fullBox("mfhd", 0, 0, u32(sequence));
  // default-base-is-moof: the data offset counts from the start of this moof
  const tfhd = fullBox("tfhd", 0, 0x020000, u32(TRACK_ID));
  const tfdt = fullBox("tfdt", 1, 0, u64(decodeTime));
  // data offset, then duration, size and flags of the one sample
  const trunSize = 12 + 4 + 4 + 12;
  const moofSize = 8 + mfhd.length + 8 + tfhd.length + tfdt.length + trunSize;
  const trun = fullBox("trun", 0, 0x000701, u32(1), u32(moofSize + 8), u32(duration), u32(data.length), u32(keyframe ? KEY_FLAGS : DELTA_FLAGS));
  const moof = box("moof", mfhd, box("traf", tfhd, tfdt, trun));
  return concat([moof, box("mdat", data)]);
}

/** The boxes at the top of `bytes` (type, start, size), for tests and checks. */
export function topBoxes(bytes: Uint8Array, start = 0, end = bytes.length): { type: string; start: number; size: number }[] {
  const out: { type: string; start: number; size: number }[] = [];
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let o = start;
  while (o + 8 <= end) {
    const size = view.getUint32(o);
    const type = String.fromCharCode(bytes[o + 4] ?? 0, bytes[o + 5] ?? 0, bytes[o + 6] ?? 0, bytes[o + 7] ?? 0);
    if (size < 8 || o + size > end) throw new RangeError(`box ${type} at ${o} has size ${size} past the end ${end}`);
    out.push({ type, start: o, size });
    o += size;
  }
  if (o !== end) throw new RangeError(`${end - o} bytes left after the boxes`);
  return out;
}
