import { describe, expect, it } from "vitest";
import { HEADER_BYTES, encodeFrame, parseEvent, parseFrame, videoSocketUrl } from "../../../src/video/wire";

const payload = new Uint8Array([0, 0, 0, 1, 0x65, 0x88]);

describe("binary frames", () => {
  it("reads the 28-byte header: kind, flags, generation, sequence, times", () => {
    const bytes = new Uint8Array(HEADER_BYTES + 2);
    const view = new DataView(bytes.buffer);
    view.setUint8(0, 1);
    view.setUint8(1, 1);
    view.setUint8(2, 3);
    view.setUint32(4, 7);
    view.setUint32(8, 0xfffffffe);
    // 1 700 000 000 123 456 µs: above 2^32, below 2^53
    view.setUint32(12, Math.floor(1_700_000_000_123_456 / 2 ** 32));
    view.setUint32(16, 1_700_000_000_123_456 % 2 ** 32);
    bytes.set([0xab, 0xcd], HEADER_BYTES);
    const parsed = parseFrame(bytes.buffer);
    expect(parsed).toEqual({
      ok: true,
      value: {
        kind: "h264",
        keyframe: true,
        first: true,
        generation: 7,
        sequence: 0xfffffffe,
        serverUs: 1_700_000_000_123_456,
        captureUs: null,
        payload: new Uint8Array([0xab, 0xcd]),
      },
    });
  });

  it("round-trips through encodeFrame; the payload is a view, not a copy", () => {
    const frame = { kind: "h264" as const, keyframe: false, first: false, generation: 2, sequence: 41, serverUs: 1_722_000_000_000_001, captureUs: 1_721_999_999_990_000, payload };
    const bytes = encodeFrame(frame);
    const parsed = parseFrame(bytes);
    expect(parsed).toEqual({ ok: true, value: frame });
    if (parsed.ok) expect(parsed.value.payload.buffer).toBe(bytes.buffer);
  });

  it("takes every JPEG as a keyframe", () => {
    const parsed = parseFrame(encodeFrame({ kind: "jpeg", keyframe: false, first: false, generation: 1, sequence: 1, serverUs: 1, payload }));
    expect(parsed.ok && parsed.value.keyframe).toBe(true);
  });

  it("refuses short frames, unknown versions and kinds with a reason", () => {
    expect(parseFrame(new Uint8Array(27))).toEqual({ ok: false, reason: "frame of 27 bytes is shorter than its 28-byte header" });
    const bad = encodeFrame({ kind: "h264", keyframe: true, first: false, generation: 1, sequence: 1, serverUs: 1, payload });
    bad[0] = 2;
    expect(parseFrame(bad)).toEqual({ ok: false, reason: "unknown frame version 2" });
    bad[0] = 1;
    bad[1] = 9;
    expect(parseFrame(bad)).toEqual({ ok: false, reason: "unknown frame kind 9" });
  });
});

describe("text events", () => {
  it("reads stream, camera and skipped", () => {
    expect(parseEvent('{"event":"stream","codec":"h264","width":640,"height":360,"fps":30,"generation":3,"source":"sim","avc":"avc1.42C01E"}')).toEqual({
      ok: true,
      value: { event: "stream", codec: "h264", width: 640, height: 360, fps: 30, generation: 3, source: "sim", avc: "avc1.42C01E" },
    });
    expect(parseEvent('{"event":"stream","codec":"mjpeg","width":320,"height":240,"fps":15,"generation":1,"source":"v4l2","avc":null}')).toMatchObject({ ok: true, value: { codec: "mjpeg", avc: null } });
    expect(parseEvent('{"event":"stream","codec":"h264","width":1280,"height":720,"fps":null,"generation":2,"source":"rtsp","avc":"avc1.640028"}')).toMatchObject({ ok: true, value: { fps: 0 } });
    expect(parseEvent('{"event":"camera","state":"idle","reason":null,"restarts":0}')).toMatchObject({ ok: true, value: { state: "idle" } });
    expect(parseEvent('{"event":"camera","state":"restarting","reason":"exited with status 1","restarts":2}')).toEqual({
      ok: true,
      value: { event: "camera", state: "restarting", reason: "exited with status 1", restarts: 2 },
    });
    expect(parseEvent('{"event":"skipped","frames":12,"reason":"slow_viewer"}')).toEqual({ ok: true, value: { event: "skipped", frames: 12, reason: "slow_viewer" } });
  });

  it("says why a message is not an event it knows", () => {
    expect(parseEvent("not json")).toEqual({ ok: false, reason: "text message is not JSON" });
    expect(parseEvent("[1]")).toEqual({ ok: false, reason: "text message is not a JSON object" });
    expect(parseEvent('{"event":"clock","server_ms":1}')).toEqual({ ok: false, reason: 'unknown event "clock"' });
    expect(parseEvent('{"event":"stream","codec":"vp8","width":1,"height":1,"fps":1,"generation":1,"source":"sim","avc":null}')).toEqual({ ok: false, reason: 'stream: unknown codec "vp8"' });
    expect(parseEvent('{"event":"stream","codec":"h264","width":1.5,"height":1,"fps":1,"generation":1,"source":"sim","avc":null}').ok).toBe(false);
    expect(parseEvent('{"event":"stream","codec":"h264","width":1,"height":1,"fps":1,"generation":1,"source":"sim","avc":"avc1.zz"}').ok).toBe(false);
    expect(parseEvent('{"event":"camera","state":"exploded","reason":null,"restarts":0}')).toEqual({ ok: false, reason: 'camera: unknown state "exploded"' });
    expect(parseEvent('{"event":"skipped","frames":-1}').ok).toBe(false);
  });
});

describe("the socket's address", () => {
  it("is ws on http and wss on https, with the token and the version", () => {
    expect(videoSocketUrl({ protocol: "http:", host: "10.0.0.2:4000" }, "/video/rov%201/websocket", "a+b")).toBe("ws://10.0.0.2:4000/video/rov%201/websocket?vsn=1&token=a%2Bb");
    expect(videoSocketUrl({ protocol: "https:", host: "rov.example" }, "/video/neptunus-1/websocket", null)).toBe("wss://rov.example/video/neptunus-1/websocket?vsn=1");
    // the snapshot's path may carry a token already (cameraWithToken): the page's current one replaces it
    expect(videoSocketUrl({ protocol: "http:", host: "h" }, "/video/v/websocket?token=old", "new")).toBe("ws://h/video/v/websocket?token=new&vsn=1");
    expect(videoSocketUrl({ protocol: "http:", host: "h" }, "/video/v/websocket?token=old", null)).toBe("ws://h/video/v/websocket?token=old&vsn=1");
  });
});
