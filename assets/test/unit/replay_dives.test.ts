import { describe, expect, it } from "vitest";
import { decodeDive, decodeDiveList, mayEditNotes, notesChanges, withNotes } from "../../src/replay/dives";
import type { DiveInfo } from "../../src/replay/dives";
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
          notes: "hull: two anodes to change",
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
        notes: "hull: two anodes to change",
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
        notes: null,
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

describe("a dive's title and notes as the replay page edits them", () => {
  const dive = decodeDive({ vehicle: "rov", name: "d1", title: "Pier 4", notes: null }) as DiveInfo;

  it("who may edit: local mode, a pilot, the main station (as the server decides)", () => {
    const secure = { mode: "secure" as const, anonymous_observers: true, expires_at: null };
    expect(mayEditNotes({ ...secure, mode: "local", user: null })).toBe(true);
    expect(mayEditNotes({ ...secure, user: { name: "ada", role: "pilot" } })).toBe(true);
    expect(mayEditNotes({ ...secure, user: { name: "mo", role: "main_station" } })).toBe(true);
    expect(mayEditNotes({ ...secure, user: { name: "olga", role: "observer" } })).toBe(false);
    expect(mayEditNotes({ ...secure, user: null })).toBe(false);
    expect(mayEditNotes(null)).toBe(false);
  });

  it("only what changed is sent, trimmed; emptied clears it; nothing changed is nothing to send", () => {
    expect(notesChanges(dive, "Pier 4", "")).toBeNull();
    expect(notesChanges(dive, "  Pier 4 ", "   ")).toBeNull();
    expect(notesChanges(dive, "Pier 5", "")).toEqual({ title: "Pier 5" });
    expect(notesChanges(dive, "Pier 4", " two anodes\nto change ")).toEqual({ notes: "two anodes\nto change" });
    expect(notesChanges(dive, " ", "x")).toEqual({ title: null, notes: "x" });
  });

  it("the dive with what the server saved; a reply that is not one is refused", () => {
    const reply = { notes: { title: "Pier 5", notes: "x", edited_at: 1, edited_by: "ada" } };
    expect(withNotes(dive, reply)).toEqual({ ...dive, title: "Pier 5", notes: "x" });
    expect(withNotes(dive, { notes: { title: null, notes: null } })).toEqual({ ...dive, title: null, notes: null });
    expect(withNotes(dive, { notes: { title: 5, notes: null } })).toBeNull();
    expect(withNotes(dive, { error: "no" })).toBeNull();
    expect(withNotes(dive, null)).toBeNull();
  });
});
