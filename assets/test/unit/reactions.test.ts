import { describe, expect, it } from "vitest";
import { isPilot, stampOf } from "../../src/lib/helm";
import type { Helm } from "../../src/lib/protocol";
import { INITIAL_REACTIONS, TONES, isNewGrant, pilotName, react } from "../../src/operator/reactions";
import type { Effect, ReactionEvent, ReactionState } from "../../src/operator/reactions";
import { ada, bob, free, grant, main, piloted, session, takeover } from "./helm_fixtures";

const me = session(ada);

/** Runs `events` from `state`; the final state and every effect, in order. */
function run(state: ReactionState, ...events: ReactionEvent[]): { state: ReactionState; effects: Effect[] } {
  const effects: Effect[] = [];
  for (const event of events) {
    const r = react(state, event);
    state = r.state;
    effects.push(...r.effects);
  }
  return { state, effects };
}

const joined = (helm: Helm | null): ReactionEvent => ({ type: "joined", helm, session: me, atMs: 0 });
/** joined on a free helm, then granted: we pilot with epoch 1 and the heartbeat runs */
const piloting = (): ReactionState => run(INITIAL_REACTIONS, joined(free), { type: "granted", grant: grant(ada, 1) }).state;
/** joined while bob pilots: we watch */
const watching = (): ReactionState => run(INITIAL_REACTIONS, joined(piloted(bob))).state;

const RESET: Effect = { type: "reset_inputs" };
const ON: Effect = { type: "heartbeat", on: true };
const OFF: Effect = { type: "heartbeat", on: false };
const messages = (effects: readonly Effect[]): Effect[] => effects.filter((e) => e.type === "message");

describe("joining", () => {
  it("a first join forgets input, pilots nothing and clears a join error", () => {
    const { state, effects } = run(INITIAL_REACTIONS, joined(piloted(bob)));
    expect(effects).toEqual([RESET, { type: "clear_message", source: "join" }]);
    expect(state.heartbeat).toBe(false);
    expect(pilotName(state)).toBe("bob");
    expect(isPilot(state.helm)).toBe(false);
  });

  it("a rejoin while piloting stops the heartbeat and drops the stamp (the server freed the helm)", () => {
    const { state, effects } = run(piloting(), joined(piloted(ada, 1)));
    expect(effects).toEqual([OFF, RESET, { type: "clear_message", source: "join" }]);
    expect(state.heartbeat).toBe(false);
    expect(stampOf(state.helm)).toBeNull();
  });
});

describe("grants", () => {
  it("the grant's message goes once the pilot drives (the first thrust sent clears it)", () => {
    const { effects } = run(INITIAL_REACTIONS, joined(free), { type: "granted", grant: grant(ada, 1) });
    const said = effects.find((e) => e.type === "message");
    expect(said?.type === "message" && /thrusters are neutral/.test(said.text)).toBe(true);
    const cleared = react(run(INITIAL_REACTIONS, joined(free), { type: "granted", grant: grant(ada, 1) }).state, { type: "thrust_sent" }).effects;
    expect(cleared).toContainEqual({ type: "clear_message", source: said?.type === "message" ? (said.source ?? "") : "" });
  });

  it("a grant resets input, starts the heartbeat and says the thrusters are neutral", () => {
    const { state, effects } = run(INITIAL_REACTIONS, joined(free), { type: "granted", grant: grant(ada, 1) });
    expect(effects.slice(2)).toEqual([
      RESET,
      ON,
      { type: "message", text: "You have control. The thrusters are neutral: move with the selected input.", kind: "info", source: "grant" },
    ]);
    expect(state.heartbeat).toBe(true);
    expect(stampOf(state.helm)).toBe(1);
    expect(pilotName(state)).toBe("ada");
  });

  it("the same grant twice (reply and event) is news once: held keys are kept", () => {
    const state = piloting();
    expect(isNewGrant(state, grant(ada, 1))).toBe(false);
    expect(isNewGrant(state, grant(ada, 2))).toBe(true);
    expect(react(state, { type: "granted", grant: grant(ada, 1) })).toEqual({ state, effects: [] });
  });

  it("the helm broadcast that follows the grant changes nothing more", () => {
    const { state, effects } = run(piloting(), { type: "helm", helm: piloted(ada, 1), atMs: 10 });
    expect(effects).toEqual([]);
    expect(state.heartbeat).toBe(true);
  });
});

describe("helm broadcasts", () => {
  it("becoming pilot by a helm broadcast starts the heartbeat (once)", () => {
    const { state, effects } = run(INITIAL_REACTIONS, joined(free), { type: "helm", helm: piloted(ada, 1), atMs: 5 });
    expect(effects.filter((e) => e.type === "heartbeat")).toEqual([ON]);
    expect(state.heartbeat).toBe(true);
  });

  it("losing the helm stops the heartbeat and forgets input", () => {
    const { state, effects } = run(piloting(), { type: "helm", helm: piloted(bob, 2), atMs: 5 });
    expect(effects).toEqual([OFF, RESET]);
    expect(state.heartbeat).toBe(false);
    expect(stampOf(state.helm)).toBeNull();
  });

  it("a deadman restamp while piloting forgets input and says why; the heartbeat stays on", () => {
    const { state, effects } = run(piloting(), { type: "helm", helm: piloted(ada, 2), atMs: 5 });
    expect(effects).toEqual([RESET, { type: "message", text: "Stopped by the deadman (no heartbeat): press the keys again.", kind: "warn", source: "helm" }]);
    expect(state.heartbeat).toBe(true);
    expect(stampOf(state.helm)).toBe(2);
  });

  it("a takeover that concerns us beeps once, and again for the next takeover", () => {
    const beep: Effect = { type: "beep", sound: "takeover" };
    const s1 = run(piloting(), { type: "helm", helm: takeover(ada, main), atMs: 1 });
    expect(s1.effects).toEqual([beep]);
    const s2 = run(s1.state, { type: "helm", helm: takeover(ada, main), atMs: 2 });
    expect(s2.effects).toEqual([]);
    const s3 = run(s2.state, { type: "helm", helm: piloted(ada, 1), atMs: 3 }, { type: "helm", helm: takeover(ada, main), atMs: 4 });
    expect(s3.effects).toEqual([beep]);
  });

  it("a takeover between others does not beep", () => {
    const { effects } = run(watching(), { type: "helm", helm: takeover(bob, main), atMs: 1 });
    expect(effects).toEqual([]);
  });
});

describe("loss of control, requests", () => {
  it("control_lost stops the heartbeat, forgets input and says why", () => {
    const { state, effects } = run(piloting(), { type: "lost", reason: "takeover" });
    expect(effects).toEqual([OFF, RESET, { type: "message", text: "You no longer have control: takeover", kind: "warn", source: "helm" }]);
    expect(state.heartbeat).toBe(false);
  });

  it("a control request beeps and names who asks", () => {
    const { effects } = run(piloting(), { type: "request", from: bob });
    expect(effects).toEqual([{ type: "beep", sound: "request" }, { type: "message", text: "bob requests control.", kind: "warn", source: "helm" }]);
  });

  it("denied, pending, takeover started, answered", () => {
    expect(run(watching(), { type: "denied", reason: "busy" }).effects).toEqual([
      { type: "message", text: "Control request refused: busy", kind: "warn", source: "helm" },
    ]);
    expect(run(watching(), { type: "request_pending" }).effects).toEqual([
      { type: "message", text: "Waiting for bob to answer…", kind: "info", source: "helm" },
    ]);
    expect(run(INITIAL_REACTIONS, { type: "request_pending" }).effects).toEqual([
      { type: "message", text: "Waiting for the pilot to answer…", kind: "info", source: "helm" },
    ]);
    expect(run(watching(), { type: "takeover_started", countdownMs: 2500 }).effects).toEqual([
      { type: "message", text: "Taking control in 3 s…", kind: "warn", source: "helm" },
    ]);
    expect(run(piloting(), { type: "answered" }).effects).toEqual([{ type: "clear_message", source: "helm" }]);
  });
});

describe("stops", () => {
  it("a safety stop of the vehicle beeps, forgets the pilot's input and warns", () => {
    const { state, effects } = run(piloting(), { type: "stopped", reason: "deadman" });
    expect(effects).toEqual([{ type: "beep", sound: "safety_stop" }, RESET, { type: "message", text: "Vehicle stopped: deadman", kind: "warn", source: "command" }]);
    expect(state).toEqual(piloting());
  });

  it("a stop the pilot asked for is only news; a watcher's input is not touched", () => {
    expect(run(piloting(), { type: "stopped", reason: "pilot_stop" }).effects).toEqual([
      RESET,
      { type: "message", text: "Vehicle stopped: pilot_stop", kind: "info", source: "command" },
    ]);
    expect(run(watching(), { type: "stopped", reason: "link_lost" }).effects).toEqual([
      { type: "beep", sound: "safety_stop" },
      { type: "message", text: "Vehicle stopped: link_lost", kind: "warn", source: "command" },
    ]);
  });

  it("the page's safety stop is sent only by a joined pilot; input is always forgotten", () => {
    const stop = (joinedNow: boolean): ReactionEvent => ({ type: "safety_stop", reason: "window lost focus", joined: joinedNow });
    expect(run(piloting(), stop(true)).effects).toEqual([RESET, { type: "send_stop", reason: "window lost focus", announce: true }]);
    expect(run(piloting(), stop(false)).effects).toEqual([RESET]);
    expect(run(watching(), stop(true)).effects).toEqual([RESET]);
    expect(run(piloting(), { type: "stop_sent", reason: "window lost focus" }).effects).toEqual([
      { type: "message", text: "Stopped: window lost focus.", kind: "warn", source: "command" },
    ]);
  });

  it("the stop button always asks the server (which refuses a non-pilot)", () => {
    expect(run(watching(), { type: "pilot_stop" }).effects).toEqual([RESET, { type: "send_stop", reason: "pilot_stop", announce: false }]);
  });
});

describe("disconnection and heartbeat refusals", () => {
  it("a disconnection stops the heartbeat, forgets input and the latency", () => {
    const { state, effects } = run(piloting(), { type: "disconnected" });
    expect(effects).toEqual([OFF, RESET, { type: "reset_latency" }]);
    expect(state.heartbeat).toBe(false);
    // a watcher has no heartbeat to stop
    expect(run(watching(), { type: "disconnected" }).effects).toEqual([RESET, { type: "reset_latency" }]);
  });

  it("a heartbeat refused as not_in_control stops it; other refusals do not", () => {
    const off = run(piloting(), { type: "heartbeat_refused", reason: "not_in_control" });
    expect(off.effects).toEqual([OFF]);
    expect(off.state.heartbeat).toBe(false);
    expect(run(piloting(), { type: "heartbeat_refused", reason: "timeout" }).effects).toEqual([]);
    // and a later grant starts it again
    expect(run(off.state, { type: "granted", grant: grant(ada, 2) }).effects).toContainEqual(ON);
  });

  it("the heartbeat is on exactly while we pilot, whatever the order of events", () => {
    const events: ReactionEvent[] = [
      joined(free),
      { type: "helm", helm: piloted(ada, 1), atMs: 1 },
      { type: "granted", grant: grant(ada, 1) },
      { type: "helm", helm: piloted(ada, 2), atMs: 2 },
      // a grant with a new epoch while we pilot: the heartbeat already runs
      { type: "granted", grant: grant(ada, 3) },
      { type: "disconnected" },
      joined(piloted(bob, 3)),
      { type: "granted", grant: grant(ada, 4) },
      { type: "helm", helm: takeover(ada, main, 4), atMs: 3 },
      { type: "helm", helm: piloted(main, 5), atMs: 4 },
      { type: "lost", reason: "takeover" },
    ];
    let state = INITIAL_REACTIONS;
    let on = false;
    for (const event of events) {
      const r = react(state, event);
      for (const e of r.effects) {
        if (e.type !== "heartbeat") continue;
        // never started twice nor stopped when not running
        expect(e.on).toBe(!on);
        on = e.on;
      }
      state = r.state;
      expect(on).toBe(state.heartbeat);
      if (event.type !== "disconnected" && event.type !== "lost") expect(state.heartbeat).toBe(isPilot(state.helm));
    }
  });
});

describe("commands and the link", () => {
  it("a refusal names the pilot when we are not in control", () => {
    expect(messages(run(watching(), { type: "refused", what: "Thrust", reason: "not_in_control" }).effects)).toEqual([
      { type: "message", text: "Thrust refused: not in control (pilot: bob)", kind: "error", source: "command" },
    ]);
    expect(messages(run(joinedFree(), { type: "refused", what: "Stop", reason: "not_in_control" }).effects)).toEqual([
      { type: "message", text: "Stop refused: not in control", kind: "error", source: "command" },
    ]);
    expect(messages(run(piloting(), { type: "refused", what: "Stop", reason: "timeout" }).effects)).toEqual([
      { type: "message", text: "Stop refused: timeout", kind: "error", source: "command" },
    ]);
  });

  it("a thrust that cannot be sent says why; one that went through clears the command message", () => {
    expect(run(piloting(), { type: "thrust_blocked", why: "not_connected" }).effects).toEqual([
      { type: "message", text: "Not connected: command not sent.", kind: "warn", source: "command" },
    ]);
    expect(run(watching(), { type: "thrust_blocked", why: "not_in_control" }).effects).toEqual([
      { type: "message", text: "Not in control (bob pilots): request control first.", kind: "warn", source: "command" },
    ]);
    expect(run(joinedFree(), { type: "thrust_blocked", why: "not_in_control" }).effects).toEqual([
      { type: "message", text: "Not in control: request control first.", kind: "warn", source: "command" },
    ]);
    expect(run(piloting(), { type: "thrust_sent" }).effects).toEqual([
      { type: "clear_message", source: "command" },
      { type: "clear_message", source: "grant" },
    ]);
  });

  it("a link that goes down beeps; one that comes up does not", () => {
    expect(run(watching(), { type: "link", up: false }).effects).toEqual([{ type: "beep", sound: "link_down" }]);
    expect(run(watching(), { type: "link", up: true }).effects).toEqual([]);
  });

  it("every sound has audible tones", () => {
    for (const tone of Object.values(TONES)) {
      expect(tone.count).toBeGreaterThan(0);
      expect(tone.hz).toBeGreaterThan(20);
      expect(tone.ms).toBeGreaterThan(0);
    }
  });

  it("events that change nothing return the same state", () => {
    const state = piloting();
    const quiet: ReactionEvent[] = [
      { type: "request", from: bob },
      { type: "denied", reason: "busy" },
      { type: "stopped", reason: "deadman" },
      { type: "link", up: false },
      { type: "safety_stop", reason: "page hidden", joined: true },
      { type: "pilot_stop" },
      { type: "refused", what: "Thrust", reason: "x" },
      { type: "thrust_sent" },
      { type: "answered" },
    ];
    for (const event of quiet) expect(react(state, event).state).toBe(state);
  });
});

function joinedFree(): ReactionState {
  return run(INITIAL_REACTIONS, joined(free)).state;
}
