import { describe, expect, it } from "vitest";
import { NAL_IDR, NAL_PPS, NAL_SPS, avcDecoderConfig, codecString, lengthPrefixed, nalType, parameterSets, parseSps, splitNals, unescapeRbsp } from "../../../src/video/h264";

const hex = (s: string): Uint8Array => new Uint8Array(s.match(/../g)?.map((b) => Number.parseInt(b, 16)) ?? []);

// SPS and PPS written by ffmpeg's libx264 (-tune zerolatency)
const SPS_640x360_BASELINE = hex("6742c01eda0280bfe5c044000003000400000300f23c58ba80");
const SPS_320x180_HIGH = hex("6764000dacb40a0cfcf80880000003008000001e478a1550");
const SPS_1920x1080_BASELINE = hex("6742c028da01e0089f970110000003001000000303c8f1832a");
const PPS = hex("68ce0fc8");

describe("NAL units of an access unit", () => {
  it("splits on 3- and 4-byte start codes, as views", () => {
    const au = new Uint8Array([0, 0, 0, 1, 0x67, 1, 2, 0, 0, 1, 0x68, 3, 0, 0, 0, 1, 0x65, 4, 5, 6]);
    const nals = splitNals(au);
    expect(nals.map((n) => [...n])).toEqual([[0x67, 1, 2], [0x68, 3], [0x65, 4, 5, 6]]);
    expect(nals.map(nalType)).toEqual([NAL_SPS, NAL_PPS, NAL_IDR]);
    expect(nals[2]?.buffer).toBe(au.buffer);
  });

  it("finds nothing in bytes without a start code, and copes with an empty unit", () => {
    expect(splitNals(new Uint8Array([1, 2, 3, 4]))).toEqual([]);
    expect(splitNals(new Uint8Array([0, 0, 1, 0, 0, 1, 0x41, 9])).map((n) => [...n])).toEqual([[0x41, 9]]);
  });

  it("picks the SPS and the PPSs of a keyframe", () => {
    const { sps, pps } = parameterSets([SPS_640x360_BASELINE, PPS, hex("65aa")]);
    expect(sps).toBe(SPS_640x360_BASELINE);
    expect(pps).toEqual([PPS]);
  });

  it("removes emulation prevention bytes", () => {
    expect([...unescapeRbsp(hex("000003010000030000"))]).toEqual([0, 0, 1, 0, 0, 0, 0]);
  });
});

describe("the sequence parameter set", () => {
  it("gives the picture size after cropping (baseline: 360 = 23 macroblocks − 8 px)", () => {
    expect(parseSps(SPS_640x360_BASELINE)).toMatchObject({ profile: 66, constraints: 0xc0, level: 30, width: 640, height: 360 });
    expect(parseSps(SPS_1920x1080_BASELINE)).toMatchObject({ profile: 66, level: 40, width: 1920, height: 1080 });
  });

  it("reads a High profile SPS (chroma format, bit depth)", () => {
    expect(parseSps(SPS_320x180_HIGH)).toEqual({ profile: 100, constraints: 0, level: 13, chromaFormat: 1, bitDepthLuma: 8, bitDepthChroma: 8, width: 320, height: 180 });
  });

  it("is null for what is not an SPS, or a truncated one", () => {
    expect(parseSps(PPS)).toBeNull();
    expect(parseSps(SPS_640x360_BASELINE.subarray(0, 6))).toBeNull();
  });

  it("names the codec as RFC 6381 says", () => {
    expect(codecString(SPS_640x360_BASELINE)).toBe("avc1.42C01E");
    expect(codecString(SPS_320x180_HIGH)).toBe("avc1.64000D");
    expect(codecString(PPS)).toBeNull();
  });
});

describe("MP4's form of H.264", () => {
  it("builds the avcC record: version, profile, 4-byte lengths, one SPS, the PPSs", () => {
    const avcC = avcDecoderConfig(SPS_640x360_BASELINE, [PPS]);
    expect([...avcC.subarray(0, 8)]).toEqual([1, 0x42, 0xc0, 0x1e, 0xff, 0xe1, 0, SPS_640x360_BASELINE.length]);
    expect([...avcC.subarray(8, 8 + SPS_640x360_BASELINE.length)]).toEqual([...SPS_640x360_BASELINE]);
    expect([...avcC.subarray(8 + SPS_640x360_BASELINE.length)]).toEqual([1, 0, 4, ...PPS]);
  });

  it("adds chroma format and bit depths for High profiles", () => {
    const avcC = avcDecoderConfig(SPS_320x180_HIGH, [PPS]);
    expect(avcC.length).toBe(6 + 2 + SPS_320x180_HIGH.length + 1 + 2 + PPS.length + 4);
    expect([...avcC.subarray(avcC.length - 4)]).toEqual([0xfd, 0xf8, 0xf8, 0]);
  });

  it("writes a sample as length-prefixed NAL units without parameter sets or delimiters", () => {
    const aud = hex("09f0");
    const idr = hex("6588841a");
    const sample = lengthPrefixed([aud, SPS_640x360_BASELINE, PPS, idr]);
    expect([...sample]).toEqual([0, 0, 0, 4, ...idr]);
  });
});
