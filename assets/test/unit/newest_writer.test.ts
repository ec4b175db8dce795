import { describe, expect, it } from "vitest";
import { NewestWriter } from "../../src/lib/newest_writer";

/** A request the test completes by hand: what it carries, and its resolve/reject. */
interface Request {
  readonly value: string;
  readonly done: () => void;
  readonly fail: (err: Error) => void;
}

function server() {
  const requests: Request[] = [];
  const stored: string[] = [];
  const send = (value: string) => () =>
    new Promise<void>((resolve, reject) => {
      requests.push({
        value,
        done: () => {
          stored.push(value);
          resolve();
        },
        fail: reject,
      });
    });
  return { requests, stored, send };
}

const settle = () => new Promise((r) => setTimeout(r, 0));

describe("NewestWriter: one request at a time, the newest last", () => {
  it("a write asked for while another is on its way waits for it", async () => {
    const s = server();
    const writer = new NewestWriter();
    const first = writer.write(s.send("a"));
    const second = writer.write(s.send("b"));
    await settle();
    expect(s.requests.map((r) => r.value)).toEqual(["a"]);
    s.requests[0]!.done();
    await first;
    await settle();
    expect(s.requests.map((r) => r.value)).toEqual(["a", "b"]);
    s.requests[1]!.done();
    await second;
    expect(s.stored).toEqual(["a", "b"]);
  });

  it("of the writes asked for meanwhile only the newest is sent; the others resolve with it", async () => {
    const s = server();
    const writer = new NewestWriter();
    const outcomes: string[] = [];
    const note = (name: string, p: Promise<void>) => p.then(() => outcomes.push(name));
    const first = note("a", writer.write(s.send("a")));
    const superseded = note("b", writer.write(s.send("b")));
    const newest = note("c", writer.write(s.send("c")));
    await settle();
    s.requests[0]!.done();
    await first;
    await settle();
    expect(s.requests.map((r) => r.value)).toEqual(["a", "c"]);
    expect(outcomes).toEqual(["a"]);
    s.requests[1]!.done();
    await Promise.all([superseded, newest]);
    expect(outcomes).toEqual(["a", "b", "c"]);
    expect(s.stored).toEqual(["a", "c"]);
  });

  it("a failed request rejects its writes and the next one is still sent", async () => {
    const s = server();
    const writer = new NewestWriter();
    const failing = writer.write(s.send("a"));
    const next = writer.write(s.send("b"));
    await settle();
    s.requests[0]!.fail(new Error("offline"));
    await expect(failing).rejects.toThrow("offline");
    await settle();
    s.requests[1]!.done();
    await next;
    expect(s.stored).toEqual(["b"]);
  });
});
