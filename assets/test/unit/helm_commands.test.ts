import { describe, expect, it } from "vitest";
import type { ControlReply } from "../../src/lib/protocol";
import type { ArmReply } from "../../src/lib/vehicle_client";
import { HelmCommands, vehicleAnswerMessage } from "../../src/operator/helm_commands";
import type { HelmVehicle } from "../../src/operator/helm_commands";
import type { ReactionEvent } from "../../src/operator/reactions";
import { ada, grant } from "./helm_fixtures";

function harness(replies: { control?: ControlReply; arm?: ArmReply; refuse?: string } = {}) {
  const events: ReactionEvent[] = [];
  const messages: { text: string; kind: string; source: string }[] = [];
  const sent: string[] = [];
  const answer = <T>(name: string, value: T): Promise<T> => {
    sent.push(name);
    return replies.refuse ? Promise.reject(new Error(replies.refuse)) : Promise.resolve(value);
  };
  const vehicle: HelmVehicle = {
    requestControl: () => answer("request_control", replies.control ?? { status: "granted", grant: grant(ada, 1) }),
    takeControl: () => answer("take_control", replies.control ?? { status: "granted", grant: grant(ada, 1) }),
    releaseControl: () => answer("release_control", undefined),
    answerRequest: (accept) => answer(`answer_request ${String(accept)}`, undefined),
    arm: (arm) => answer(arm ? "arm" : "disarm", replies.arm ?? "ok"),
  };
  const helm = new HelmCommands({
    vehicle: () => vehicle,
    dispatch: (e) => events.push(e),
    showMessage: (text, kind, source) => messages.push({ text, kind, source }),
  });
  return { helm, events, messages, sent, settled: (): Promise<void> => new Promise((r) => setTimeout(r, 0)) };
}

describe("HelmCommands", () => {
  it("a request the pilot must answer: the reactions hear it is pending; a grant comes as an event", async () => {
    const pending = harness({ control: { status: "pending", timeout_ms: 10_000 } });
    pending.helm.request();
    await pending.settled();
    expect(pending.sent).toEqual(["request_control"]);
    expect(pending.events).toEqual([{ type: "request_pending" }]);
    const granted = harness();
    granted.helm.request();
    await granted.settled();
    expect(granted.events).toEqual([]);
  });

  it("a takeover counts down", async () => {
    const h = harness({ control: { status: "takeover", countdown_ms: 3000 } });
    h.helm.take();
    await h.settled();
    expect(h.events).toEqual([{ type: "takeover_started", countdownMs: 3000 }]);
  });

  it("answering a request clears the prompt's message", async () => {
    const h = harness();
    h.helm.answer(true);
    await h.settled();
    expect(h.sent).toEqual(["answer_request true"]);
    expect(h.events).toEqual([{ type: "answered" }]);
  });

  it("each refusal names its command and the server's reason", async () => {
    const h = harness({ refuse: "not_in_control" });
    h.helm.request();
    h.helm.take();
    h.helm.release();
    h.helm.answer(false);
    await h.settled();
    // each reply settles on its own: no order between them
    const refused = h.events.map((e) => (e.type === "refused" ? `${e.what}: ${e.reason}` : e.type)).sort();
    expect(refused).toEqual(["Answer: not_in_control", "Release: not_in_control", "Request: not_in_control", "Take control: not_in_control"]);
  });

  it("arm: done at once, or waiting for the vehicle's later answer; a refusal is said", async () => {
    const now = harness();
    now.helm.arm(true);
    await now.settled();
    expect(now.messages).toEqual([{ text: "Vehicle armed", kind: "info", source: "arm" }]);
    const later = harness({ arm: "pending" });
    later.helm.arm(false);
    await later.settled();
    expect(later.messages).toEqual([{ text: "Disarming: waiting for the vehicle…", kind: "info", source: "arm" }]);
    later.helm.answered("disarm", null);
    expect(later.messages.at(-1)).toEqual({ text: "Vehicle disarmed", kind: "info", source: "arm" });
    const refused = harness({ refuse: "pre-arm check" });
    refused.helm.arm(true);
    await refused.settled();
    expect(refused.messages).toEqual([{ text: "Arm refused: pre-arm check", kind: "error", source: "arm" }]);
  });
});

describe("vehicleAnswerMessage", () => {
  it("arm and disarm are said either way; other commands only when refused", () => {
    expect(vehicleAnswerMessage("arm", null)).toEqual({ text: "Vehicle armed", kind: "info" });
    expect(vehicleAnswerMessage("disarm", "busy")).toEqual({ text: "Disarm refused: busy", kind: "error" });
    expect(vehicleAnswerMessage("autopilot", null)).toBeNull();
    expect(vehicleAnswerMessage("autopilot", "no position")).toEqual({ text: "The vehicle refused autopilot: no position", kind: "error" });
  });
});
