import { spawnSync } from "node:child_process";
import { mkdtempSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { describe, expect, it } from "vitest";
import { TIMESCALE, initSegment, mediaSegment, topBoxes } from "../../../src/video/fmp4";
import { NAL_AUD, NAL_IDR, avcDecoderConfig, lengthPrefixed, nalType, parameterSets, parseSps, splitNals } from "../../../src/video/h264";

/** Access units of a short H.264 stream made by ffmpeg (with access unit delimiters to cut on). */
function encodedAccessUnits(size: string, frames: number): Uint8Array[] {
  const ffmpeg = spawnSync(
    "ffmpeg",
    ["-hide_banner", "-loglevel", "error", "-f", "lavfi", "-i", `testsrc=size=${size}:rate=30`, "-frames:v", String(frames), "-c:v", "libx264", "-preset", "ultrafast", "-tune", "zerolatency", "-g", "10", "-x264-params", "aud=1", "-pix_fmt", "yuv420p", "-f", "h264", "-"],
    { maxBuffer: 64 * 1024 * 1024 },
  );
  if (ffmpeg.error) throw new Error(`ffmpeg is needed (make setup installs it): ${ffmpeg.error.message}`);
  expect(ffmpeg.status, ffmpeg.stderr.toString()).toBe(0);
  const stream = new Uint8Array(ffmpeg.stdout);
  const nals = splitNals(stream);
  const units: Uint8Array[][] = [];
  for (const nal of nals) {
    if (nalType(nal) === NAL_AUD || units.length === 0) units.push([]);
    units[units.length - 1]?.push(nal);
  }
  // back to Annex B: the server sends access units so
  return units.map((u) => {
    const out = new Uint8Array(u.reduce((n, nal) => n + 4 + nal.length, 0));
    let o = 0;
    for (const nal of u) {
      out.set([0, 0, 0, 1], o);
      out.set(nal, o + 4);
      o += 4 + nal.length;
    }
    return out;
  });
}

function boxAt(bytes: Uint8Array, path: string[]): { start: number; size: number } {
  let start = 0;
  let end = bytes.length;
  let found = { start: 0, size: bytes.length };
  const containers = new Set(["moov", "trak", "mdia", "minf", "stbl", "moof", "traf", "mvex", "dinf"]);
  for (const type of path) {
    const hit = topBoxes(bytes, start, end).find((b) => b.type === type);
    if (hit === undefined) throw new Error(`no ${type} in ${path.join("/")}`);
    found = hit;
    start = hit.start + 8;
    end = hit.start + hit.size;
    if (!containers.has(type)) break;
  }
  return found;
}

describe("fragmented MP4", () => {
  it("makes an init segment of ftyp and moov with the avcC inside", () => {
    const sps = new Uint8Array([0x67, 0x42, 0xc0, 0x1e, 0xda, 0x02, 0x80, 0xbf, 0xe5, 0xc0, 0x44, 0, 0, 3, 0, 4, 0, 0, 3, 0, 0xf2, 0x3c, 0x58, 0xba, 0x80]);
    const pps = new Uint8Array([0x68, 0xce, 0x0f, 0xc8]);
    const init = initSegment({ width: 640, height: 360, avcC: avcDecoderConfig(sps, [pps]) });
    expect(topBoxes(init).map((b) => b.type)).toEqual(["ftyp", "moov"]);
    const moov = boxAt(init, ["moov"]);
    expect(topBoxes(init, moov.start + 8, moov.start + moov.size).map((b) => b.type)).toEqual(["mvhd", "trak", "mvex"]);
    const stbl = boxAt(init, ["moov", "trak", "mdia", "minf", "stbl"]);
    expect(topBoxes(init, stbl.start + 8, stbl.start + stbl.size).map((b) => b.type)).toEqual(["stsd", "stts", "stsc", "stsz", "stco"]);
    const text = new TextDecoder("latin1").decode(init);
    expect(text).toContain("avc1");
    expect(text).toContain("avcC");
  });

  it("puts one sample per fragment, its data offset pointing into the mdat", () => {
    const data = lengthPrefixed([new Uint8Array([0x65, 1, 2, 3])]);
    const seg = mediaSegment({ sequence: 5, decodeTime: 2 ** 33 + 7, duration: 3000, keyframe: true, data });
    expect(topBoxes(seg).map((b) => b.type)).toEqual(["moof", "mdat"]);
    const view = new DataView(seg.buffer);
    const moof = boxAt(seg, ["moof"]);
    const trun = boxAt(seg, ["moof", "traf", "trun"]);
    const tfdt = boxAt(seg, ["moof", "traf", "tfdt"]);
    // tfdt version 1: a 64-bit decode time
    expect(view.getUint32(tfdt.start + 12) * 2 ** 32 + view.getUint32(tfdt.start + 16)).toBe(2 ** 33 + 7);
    const dataOffset = view.getUint32(trun.start + 16);
    expect([...seg.subarray(moof.start + dataOffset, moof.start + dataOffset + data.length)]).toEqual([...data]);
    expect(view.getUint32(trun.start + 20)).toBe(3000);
    expect(view.getUint32(trun.start + 24)).toBe(data.length);
    expect(view.getUint32(trun.start + 28)).toBe(0x02000000);
    const delta = mediaSegment({ sequence: 6, decodeTime: 0, duration: 3000, keyframe: false, data });
    expect(new DataView(delta.buffer).getUint32(boxAt(delta, ["moof", "traf", "trun"]).start + 28)).toBe(0x01010000);
  });

  it("is a stream ffprobe reads: every frame, the size, the frame rate", () => {
    const units = encodedAccessUnits("320x180", 25);
    expect(units.length).toBe(25);
    const first = units[0] ?? new Uint8Array();
    const { sps, pps } = parameterSets(splitNals(first));
    if (sps === null) throw new Error("the first access unit has no SPS");
    expect(splitNals(first).some((n) => nalType(n) === NAL_IDR)).toBe(true);
    const parts = [initSegment({ width: 320, height: 180, avcC: avcDecoderConfig(sps, pps, parseSps(sps)) })];
    units.forEach((au, i) => {
      const keyframe = splitNals(au).some((n) => nalType(n) === NAL_IDR);
      parts.push(mediaSegment({ sequence: i + 1, decodeTime: i * (TIMESCALE / 30), duration: TIMESCALE / 30, keyframe, data: lengthPrefixed(splitNals(au)) }));
    });
    const dir = mkdtempSync(join(tmpdir(), "neptunus-fmp4-"));
    try {
      const file = join(dir, "stream.mp4");
      writeFileSync(file, Buffer.concat(parts));
      const probe = spawnSync("ffprobe", ["-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries", "stream=codec_name,width,height,nb_read_frames,avg_frame_rate", "-of", "json", file]);
      expect(probe.status, probe.stderr.toString()).toBe(0);
      expect(probe.stderr.toString()).toBe("");
      const stream = (JSON.parse(probe.stdout.toString()) as { streams: Record<string, unknown>[] }).streams[0];
      expect(stream).toEqual({ codec_name: "h264", width: 320, height: 180, nb_read_frames: "25", avg_frame_rate: "30/1" });
    } finally {
      rmSync(dir, { recursive: true, force: true });
    }
  });
});
