/**
 * How the operator page reacts to the helm, to stops and to losing the connection, as a pure
 * function `react(state, event) -> {state, effects}` (the shape of the server's
 * `Helm.Policy`). `OperatorController` feeds it the vehicle's events, its own stops and the
 * replies to its helm commands, keeps the state and carries out the effects in order; nothing
 * here sends, beeps, reads a clock or touches the page.
 *
 * ## State
 *
 * What this connection knows of the helm (`HelmSeen`: the helm, who we are, the epoch our
 * thrust carries), whether the pilot's heartbeat runs, and whether the operator has already
 * been warned of the takeover in progress (it beeps once per takeover).
 *
 * ## Rules
 *
 * - After any stop, loss or gain of control, reconnection or disconnection every input is
 *   forgotten (`reset_inputs`): only a fresh press, touch or stick movement moves the vehicle.
 *   A deadman stop (a new epoch while we pilot) also says so.
 * - The heartbeat runs exactly while we pilot: on with the grant (or a helm that makes us
 *   pilot), off when we lose the helm, rejoin, disconnect, or the server says we are not in
 *   control.
 * - Safety stops (blur, hidden or closed page, input mode change) are sent only when we pilot
 *   on a joined channel; the stop button always asks the server (which refuses a non-pilot).
 * - Beeps: a control request for us, a takeover that concerns us (once), a stop the pilot did
 *   not ask for (`isSafetyStop`), a link that goes down.
 * - Messages carry a source (`helm`, `grant`, `command`, `join`) so that a later success
 *   clears only its own kind of message. The grant's "the thrusters are neutral: move" is
 *   gone once the pilot moves (the first thrust sent).
 */

import { isSafetyStop } from "../lib/forms";
import { HELM_UNSEEN, helmRejoined, isPilot, seeGrant, seeHelm, seenView } from "../lib/helm";
import type { HelmSeen } from "../lib/helm";
import type { Grant, Helm, Party, Session } from "../lib/protocol";

export type MessageKind = "info" | "warn" | "error";

export interface ReactionState {
  readonly helm: HelmSeen;
  /** the pilot's heartbeat is running */
  readonly heartbeat: boolean;
  /** a takeover that concerns us has beeped already */
  readonly warnedTakeover: boolean;
}

export const INITIAL_REACTIONS: ReactionState = { helm: HELM_UNSEEN, heartbeat: false, warnedTakeover: false };

export type ReactionEvent =
  /** the channel was (re)joined: its snapshot's helm and our session; `atMs` monotonic */
  | { readonly type: "joined"; readonly helm: Helm | null; readonly session: Session | null; readonly atMs: number }
  /** a `helm` broadcast, arrived at `atMs` (monotonic) */
  | { readonly type: "helm"; readonly helm: Helm; readonly atMs: number }
  /** `control_granted` (event or reply) */
  | { readonly type: "granted"; readonly grant: Grant }
  /** `control_lost` */
  | { readonly type: "lost"; readonly reason: string }
  /** `control_request`: someone asks us (the pilot) for control */
  | { readonly type: "request"; readonly from: Party }
  /** `request_denied` */
  | { readonly type: "denied"; readonly reason: string }
  /** `stopped`: the vehicle stopped its thrusters */
  | { readonly type: "stopped"; readonly reason: string }
  /** the board link came up or went down */
  | { readonly type: "link"; readonly up: boolean }
  /** the socket or channel left the connected state */
  | { readonly type: "disconnected" }
  /** a heartbeat was refused with `reason` */
  | { readonly type: "heartbeat_refused"; readonly reason: string }
  /** the page must stop the vehicle (blur, hidden, closed, input mode changed); `joined`: the channel is */
  | { readonly type: "safety_stop"; readonly reason: string; readonly joined: boolean }
  /** the pilot's stop button */
  | { readonly type: "pilot_stop" }
  /** the server confirmed a safety stop we sent */
  | { readonly type: "stop_sent"; readonly reason: string }
  /** a command (`what`: Thrust, Stop, Request…) was refused with `reason` */
  | { readonly type: "refused"; readonly what: string; readonly reason: string }
  /** a thrust went through */
  | { readonly type: "thrust_sent" }
  /** a thrust could not be sent: no joined channel, or we do not pilot */
  | { readonly type: "thrust_blocked"; readonly why: "not_connected" | "not_in_control" }
  /** our control request waits for the pilot's answer */
  | { readonly type: "request_pending" }
  /** our takeover runs; control is ours in `countdownMs` */
  | { readonly type: "takeover_started"; readonly countdownMs: number }
  /** our answer to a control request went through */
  | { readonly type: "answered" };

export type Sound = "request" | "takeover" | "safety_stop" | "link_down";

export type Effect =
  /** forget held keys, fingers and the pad's deflection, and the last demand sent */
  | { readonly type: "reset_inputs" }
  /** start (every `heartbeatMsOf(state.helm)` ms) or stop the pilot's heartbeat */
  | { readonly type: "heartbeat"; readonly on: boolean }
  /** forget the round-trip times measured so far */
  | { readonly type: "reset_latency" }
  /** ask the vehicle to stop for `reason`; `announce`: say so once it has */
  | { readonly type: "send_stop"; readonly reason: string; readonly announce: boolean }
  | { readonly type: "beep"; readonly sound: Sound }
  | { readonly type: "message"; readonly text: string; readonly kind: MessageKind; readonly source: string | null }
  /** clear the message shown if it came from `source` */
  | { readonly type: "clear_message"; readonly source: string };

export interface Reaction {
  readonly state: ReactionState;
  readonly effects: readonly Effect[];
}

/** The tones of each warning: `count` tones of `hz` Hz, `ms` long, `gapMs` apart. */
export const TONES: Readonly<Record<Sound, { readonly count: number; readonly hz: number; readonly ms: number; readonly gapMs: number }>> = {
  request: { count: 2, hz: 660, ms: 150, gapMs: 120 },
  takeover: { count: 3, hz: 990, ms: 150, gapMs: 120 },
  safety_stop: { count: 2, hz: 520, ms: 120, gapMs: 80 },
  link_down: { count: 2, hz: 440, ms: 150, gapMs: 120 },
};

const RESET: Effect = { type: "reset_inputs" };

function message(text: string, kind: MessageKind, source: string | null): Effect {
  return { type: "message", text, kind, source };
}

/** The heartbeat off (when it runs): the state and the effect, if any. */
function heartbeatOff(state: ReactionState): Reaction {
  return state.heartbeat ? { state: { ...state, heartbeat: false }, effects: [{ type: "heartbeat", on: false }] } : { state, effects: [] };
}

function heartbeatOn(state: ReactionState): Reaction {
  return state.heartbeat ? { state, effects: [] } : { state: { ...state, heartbeat: true }, effects: [{ type: "heartbeat", on: true }] };
}

/** The name of who pilots now, if anyone. */
export function pilotName(state: ReactionState): string | null {
  return state.helm.helm?.pilot?.name ?? null;
}

/** Is `grant` news (not a grant we already hold)? The page adopts its control settings only then. */
export function isNewGrant(state: ReactionState, grant: Grant): boolean {
  return seeGrant(state.helm, grant) !== null;
}

export function react(state: ReactionState, event: ReactionEvent): Reaction {
  switch (event.type) {
    case "joined": {
      // a (re)join: whatever we held is gone (the server freed the helm when we left)
      const off = heartbeatOff(state);
      return {
        state: { ...off.state, helm: helmRejoined(event.helm, event.session, event.atMs) },
        effects: [...off.effects, RESET, { type: "clear_message", source: "join" }],
      };
    }

    case "helm": {
      const { seen, change } = seeHelm(state.helm, event.helm, event.atMs);
      let next: ReactionState = { ...state, helm: seen };
      const effects: Effect[] = [];
      if (change.becamePilot) {
        const on = heartbeatOn(next);
        next = on.state;
        effects.push(...on.effects);
      }
      if (change.lostPilot) {
        const off = heartbeatOff(next);
        next = off.state;
        effects.push(...off.effects, RESET);
      }
      if (change.restamped) {
        // a deadman stop: the server holds thrust neutral until a fresh command
        effects.push(RESET, message("Stopped by the deadman (no heartbeat): press the keys again.", "warn", "helm"));
      }
      const takeover = seenView(seen, event.atMs).takeover;
      if (takeover?.concernsMe && !state.warnedTakeover) effects.push({ type: "beep", sound: "takeover" });
      return { state: { ...next, warnedTakeover: takeover !== null }, effects };
    }

    case "granted": {
      // the reply to our request and the server's event both carry it: once is news
      const seen = seeGrant(state.helm, event.grant);
      if (seen === null) return { state, effects: [] };
      const on = heartbeatOn({ ...state, helm: seen });
      return {
        state: on.state,
        effects: [
          RESET,
          ...on.effects,
          message("You have control. The thrusters are neutral: move with the selected input.", "info", "grant"),
        ],
      };
    }

    case "lost": {
      const off = heartbeatOff(state);
      return { state: off.state, effects: [...off.effects, RESET, message(`You no longer have control: ${event.reason}`, "warn", "helm")] };
    }

    case "request":
      return { state, effects: [{ type: "beep", sound: "request" }, message(`${event.from.name} requests control.`, "warn", "helm")] };

    case "denied":
      return { state, effects: [message(`Control request refused: ${event.reason}`, "warn", "helm")] };

    case "stopped": {
      const safety = isSafetyStop(event.reason);
      return {
        state,
        effects: [
          ...(safety ? [{ type: "beep", sound: "safety_stop" } as const] : []),
          // held input must be pressed again to count after any stop
          ...(isPilot(state.helm) ? [RESET] : []),
          message(`Vehicle stopped: ${event.reason}`, safety ? "warn" : "info", "command"),
        ],
      };
    }

    case "link":
      return { state, effects: event.up ? [] : [{ type: "beep", sound: "link_down" }] };

    case "disconnected": {
      // Key-ups may be lost and the server stops the vehicle when our socket closes;
      // the operator presses again once we are back.
      const off = heartbeatOff(state);
      return { state: off.state, effects: [...off.effects, RESET, { type: "reset_latency" }] };
    }

    case "heartbeat_refused":
      return event.reason === "not_in_control" ? heartbeatOff(state) : { state, effects: [] };

    case "safety_stop": {
      const send = event.joined && isPilot(state.helm);
      return { state, effects: send ? [RESET, { type: "send_stop", reason: event.reason, announce: true }] : [RESET] };
    }

    case "pilot_stop":
      return { state, effects: [RESET, { type: "send_stop", reason: "pilot_stop", announce: false }] };

    case "stop_sent":
      return { state, effects: [message(`Stopped: ${event.reason}.`, "warn", "command")] };

    case "refused": {
      const who = pilotName(state);
      const text =
        event.reason === "not_in_control"
          ? `${event.what} refused: not in control${who ? ` (pilot: ${who})` : ""}`
          : `${event.what} refused: ${event.reason}`;
      return { state, effects: [message(text, "error", "command")] };
    }

    case "thrust_sent":
      return {
        state,
        effects: [
          { type: "clear_message", source: "command" },
          { type: "clear_message", source: "grant" },
        ],
      };

    case "thrust_blocked": {
      if (event.why === "not_connected") return { state, effects: [message("Not connected: command not sent.", "warn", "command")] };
      const who = pilotName(state);
      const pilots = who ? ` (${who} pilots)` : "";
      return { state, effects: [message(`Not in control${pilots}: request control first.`, "warn", "command")] };
    }

    case "request_pending":
      return { state, effects: [message(`Waiting for ${pilotName(state) ?? "the pilot"} to answer…`, "info", "helm")] };

    case "takeover_started":
      return { state, effects: [message(`Taking control in ${Math.ceil(event.countdownMs / 1000)} s…`, "warn", "helm")] };

    case "answered":
      return { state, effects: [{ type: "clear_message", source: "helm" }] };
  }
}
