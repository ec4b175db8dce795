import { describe, expect, it } from "vitest";
import { decodeDive, decodeDiveList } from "../../src/replay/dives";
import { avcCodec } from "../../src/replay/video";

describe("the dives as the replay page lists them", () => {
  it("a dive's summary, with what the server may leave out defaulted", () => {
    const body = {
      recording: true,
      recordings: [
        {
          vehicle: "rov",
          name: "20261128-100000Z-1",
          started_at: 1_000,
          ended_at: 61_000,
          duration_ms: 60_000,
          max_depth: 3.5,
          pilots: ["ada", 7],
          stops: 2,
          snapshots: 1,
          video: { codec: "h264", segments: 3, bytes: 9 },
          title: "",
          recording: false,
          problems: ["segment 2: the index is cut off"],
        },
        { vehicle: "rov", name: "20200101-000000Z-1.log", legacy: true, video: null },
      ],
    };
    expect(decodeDiveList(body)).toEqual([
      {
        vehicle: "rov",
        name: "20261128-100000Z-1",
        startedAt: 1_000,
        endedAt: 61_000,
        durationMs: 60_000,
        maxDepth: 3.5,
        pilots: ["ada"],
        stops: 2,
        snapshots: 1,
        video: { codec: "h264", segments: 3 },
        title: null,
        recording: false,
        problems: ["segment 2: the index is cut off"],
      },
      {
        vehicle: "rov",
        name: "20200101-000000Z-1.log",
        startedAt: null,
        endedAt: null,
        durationMs: null,
        maxDepth: null,
        pilots: [],
        stops: 0,
        snapshots: 0,
        video: null,
        title: null,
        recording: false,
        problems: [],
      },
    ]);
  });

  it("what is not a listing is refused", () => {
    expect(decodeDiveList({ recordings: [{ name: "x" }] })).toBe(null);
    expect(decodeDiveList([])).toBe(null);
    expect(decodeDive("rov")).toBe(null);
  });
});

describe("the H.264 codec string of a keyframe", () => {
  it("from its SPS: profile, constraints, level", () => {
    const keyframe = new Uint8Array([0, 0, 0, 1, 0x67, 0x42, 0xc0, 0x1e, 0xda, 0, 0, 0, 1, 0x68, 0xce]);
    expect(avcCodec(keyframe)).toBe("avc1.42c01e");
    expect(avcCodec(new Uint8Array([0, 0, 0, 1, 0x65, 1, 2, 3, 4, 5, 6, 7]))).toBe(null);
  });
});
