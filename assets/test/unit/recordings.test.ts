import { describe, expect, it } from "vitest";
import {
  deleteRecording,
  decodeRecordingList,
  fetchRecording,
  fetchRecordings,
  formatBytes,
  parseRecordingLines,
  recordingUrl,
} from "../../src/lib/recordings";

const info = { vehicle: "rov-1", name: "20261122-130509Z-1.log", bytes: 2048, started_at: 1795352709000, modified_at: 1795352800000 };

function reply(status: number, body: string): Response {
  return new Response(body, { status, headers: { "content-type": "application/json" } });
}

describe("recording list", () => {
  it("decodes the server's list", () => {
    expect(decodeRecordingList({ recording: true, recordings: [info] })).toEqual({
      recording: true,
      recordings: [{ vehicle: "rov-1", name: info.name, bytes: 2048, startedAt: 1795352709000, modifiedAt: 1795352800000 }],
    });
    expect(decodeRecordingList({ recording: false, recordings: [] })).toEqual({ recording: false, recordings: [] });
    expect(decodeRecordingList({ recording: true, recordings: [{ ...info, started_at: null }] })?.recordings[0]?.startedAt).toBeNull();
  });

  it("refuses anything else", () => {
    for (const bad of [null, [], { recording: "yes", recordings: [] }, { recording: true }, { recording: true, recordings: [{ ...info, bytes: "2" }] }, { recording: true, recordings: [{ ...info, started_at: "x" }] }])
      expect(decodeRecordingList(bad)).toBeNull();
  });
});

describe("JSON lines", () => {
  it("splits telemetry from events and counts unreadable lines", () => {
    const text = [
      JSON.stringify({ at: 1, event: "telemetry", payload: { t: 0.05 } }),
      "",
      "{not json",
      JSON.stringify({ at: 2, event: "stopped", payload: { reason: "deadman" } }),
      JSON.stringify({ at: "3", event: "telemetry", payload: {} }),
      JSON.stringify({ at: 4, event: "telemetry", payload: [1] }),
      JSON.stringify({ at: 5, event: "telemetry", payload: { t: 0.1 } }),
    ].join("\n");
    const parsed = parseRecordingLines(text);
    expect(parsed.telemetry.map((e) => e.at)).toEqual([1, 5]);
    expect(parsed.events).toEqual([{ at: 2, event: "stopped", payload: { reason: "deadman" } }]);
    expect(parsed.bad).toBe(3);
    expect(parseRecordingLines("")).toEqual({ telemetry: [], events: [], bad: 0 });
  });
});

describe("addresses and sizes", () => {
  it("encodes names and puts the token in the query", () => {
    expect(recordingUrl({ vehicle: "rov 1", name: info.name }, "csv", null)).toBe("/api/recordings/rov%201/20261122-130509Z-1.log?format=csv");
    expect(recordingUrl(info, "jsonl", "v1.a+b", 12000)).toBe("/api/recordings/rov-1/20261122-130509Z-1.log?format=jsonl&max=12000&token=v1.a%2Bb");
    expect(recordingUrl({ vehicle: "rov-1", name: "20261128-104500Z-1" }, "mp4", "t")).toBe("/api/recordings/rov-1/20261128-104500Z-1?format=mp4&token=t");
  });

  it("formats sizes", () => {
    expect([512, 2048, 3_500_000, 4_200_000_000].map(formatBytes)).toEqual(["512 B", "2.0 kB", "3.5 MB", "4.20 GB"]);
  });
});

describe("fetching", () => {
  it("lists with the token as a bearer header and rejects with the server's reason", async () => {
    const seen: { url: string; init: RequestInit | undefined }[] = [];
    const ok = async (url: string, init?: RequestInit): Promise<Response> => {
      seen.push({ url, init });
      return reply(200, JSON.stringify({ recording: true, recordings: [info] }));
    };
    const list = await fetchRecordings("rov-1", "tok", ok);
    expect(list.recordings).toHaveLength(1);
    expect(seen[0]?.url).toBe("/api/recordings?vehicle=rov-1");
    expect((seen[0]?.init?.headers as Record<string, string>)["authorization"]).toBe("Bearer tok");

    await expect(fetchRecordings("rov-1", null, async () => reply(401, JSON.stringify({ error: "log in to see recordings" })))).rejects.toThrow("log in to see recordings");
    await expect(fetchRecordings("rov-1", null, async () => reply(500, "oops"))).rejects.toThrow("HTTP 500");
    await expect(fetchRecordings("rov-1", null, async () => reply(200, JSON.stringify({ nope: 1 })))).rejects.toThrow("unexpected reply");
  });

  it("fetches a recording thinned to the buffer", async () => {
    let asked = "";
    const body = `${JSON.stringify({ at: 1, event: "telemetry", payload: { t: 0 } })}\n`;
    const parsed = await fetchRecording(
      { vehicle: "rov-1", name: info.name, bytes: 1, startedAt: null, modifiedAt: 0 },
      null,
      500,
      async (url) => {
        asked = url;
        return new Response(body, { status: 200 });
      },
    );
    expect(asked).toContain("format=jsonl&max=500");
    expect(parsed.telemetry).toHaveLength(1);
    await expect(fetchRecording({ vehicle: "a", name: "b", bytes: 1, startedAt: null, modifiedAt: 0 }, null, 5, async () => reply(404, JSON.stringify({ error: "no such recording" })))).rejects.toThrow("no such recording");
  });
});

describe("deleting", () => {
  it("sends DELETE with the token and rejects with the server's reason", async () => {
    let seen: RequestInit | undefined;
    await deleteRecording({ vehicle: "rov-1", name: "x.log" }, "tok", async (_url, init) => {
      seen = init;
      return reply(200, JSON.stringify({ deleted: {} }));
    });
    expect(seen?.method).toBe("DELETE");
    expect((seen?.headers as Record<string, string>)["authorization"]).toBe("Bearer tok");
    await expect(
      deleteRecording({ vehicle: "rov-1", name: "x.log" }, null, async () => reply(409, JSON.stringify({ error: "x.log is being recorded now" }))),
    ).rejects.toThrow("being recorded now");
  });
});
