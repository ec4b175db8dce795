/**
 * The helm as this client sees it: who pilots, whether we do, what we may do, and the stamp
 * (`epoch`) our thrust commands must carry. Pure: no DOM, no timers; the page feeds it the
 * server's events and the current time (ms, any monotonic clock) and renders `seenView()`.
 *
 * Stamps (pick-up procedure, docs/API.md): the server refuses a thrust whose `epoch` is not
 * the current one. We take the epoch from our grant; when the server changes it while we
 * pilot (a deadman stop), `seeHelm` reports `restamped` — the page must then forget held keys
 * so that only a fresh input moves the vehicle.
 */

import type { Grant, Helm, HelmStateName, Party, Session } from "./protocol";

export type MyPart = "pilot" | "requesting" | "taking_over" | "watching";

export interface HelmView {
  readonly me: MyPart;
  readonly state: HelmStateName | "unknown";
  /** one line for people */
  readonly summary: string;
  readonly pilotName: string | null;
  readonly canRequest: boolean;
  readonly canTake: boolean;
  readonly canRelease: boolean;
  /** what the release button does for us now */
  readonly releaseLabel: string;
  /** a request for us (the pilot) to answer */
  readonly prompt: { readonly from: Party; readonly remainingMs: number } | null;
  /** a main-station takeover in progress; `concernsMe` when we pilot or take over */
  readonly takeover: {
    readonly by: Party;
    readonly remainingMs: number;
    readonly concernsMe: boolean;
  } | null;
}

export interface HelmChange {
  readonly becamePilot: boolean;
  readonly lostPilot: boolean;
  /** we still pilot but the epoch changed (deadman): held input must be dropped */
  readonly restamped: boolean;
}

const seconds = (ms: number): string => `${Math.max(0, Math.ceil(ms / 1000))} s`;

/** What `helm` means for the connection `session` (null: not known yet), `elapsedMs` after it arrived. */
export function helmView(helm: Helm | null, session: Session | null, elapsedMs = 0): HelmView {
  if (!helm) {
    return {
      me: "watching",
      state: "unknown",
      summary: "—",
      pilotName: null,
      canRequest: false,
      canTake: false,
      canRelease: false,
      releaseLabel: "Release control",
      prompt: null,
      takeover: null,
    };
  }

  const myId = session?.id;
  const role = session?.role ?? "observer";
  const me: MyPart =
    myId === undefined
      ? "watching"
      : helm.pilot?.id === myId
        ? "pilot"
        : helm.request?.from.id === myId
          ? "requesting"
          : helm.takeover?.by.id === myId
            ? "taking_over"
            : "watching";

  const pilotName = helm.pilot?.name ?? null;
  const pilotLabel = me === "pilot" ? "you" : (pilotName ?? "nobody");
  let summary: string;
  switch (helm.state) {
    case "free":
      summary = "Free: nobody pilots";
      break;
    case "piloted":
      summary = me === "pilot" ? "You pilot" : `${pilotName ?? "?"} pilots`;
      break;
    case "requested": {
      const from = me === "requesting" ? "You ask" : `${helm.request?.from.name ?? "?"} asks`;
      const left = seconds((helm.request?.remaining_ms ?? 0) - elapsedMs);
      summary = `${from} ${pilotLabel} for control (${left})`;
      break;
    }
    case "takeover": {
      const by = me === "taking_over" ? "You take" : `Main station ${helm.takeover?.by.name ?? "?"} takes`;
      const left = seconds((helm.takeover?.countdown_ms ?? 0) - elapsedMs);
      summary = `${by} control from ${pilotLabel} in ${left}`;
      break;
    }
  }

  const prompt =
    me === "pilot" && helm.request
      ? { from: helm.request.from, remainingMs: Math.max(0, helm.request.remaining_ms - elapsedMs) }
      : null;

  const takeover = helm.takeover
    ? {
        by: helm.takeover.by,
        remainingMs: Math.max(0, helm.takeover.countdown_ms - elapsedMs),
        concernsMe: me === "pilot" || me === "taking_over",
      }
    : null;

  const mayPilot = role !== "observer";
  return {
    me,
    state: helm.state,
    summary,
    pilotName,
    canRequest: mayPilot && me === "watching" && (helm.state === "free" || helm.state === "piloted"),
    canTake: role === "main_station" && (me === "watching" || me === "requesting") && helm.state !== "free",
    canRelease: me !== "watching",
    releaseLabel:
      me === "requesting" ? "Withdraw request" : me === "taking_over" ? "Cancel takeover" : "Release control",
    prompt,
    takeover,
  };
}

/**
 * The helm as one connection has seen it: the last helm (and when it arrived, ms on the
 * page's monotonic clock), who we are, and the epoch our thrust must carry (null unless we
 * pilot). A value: the functions below return a new one.
 */
export interface HelmSeen {
  readonly helm: Helm | null;
  readonly session: Session | null;
  readonly epoch: number | null;
  readonly receivedAtMs: number;
}

/** Nothing seen yet (before the first join). */
export const HELM_UNSEEN: HelmSeen = { helm: null, session: null, epoch: null, receivedAtMs: 0 };

/** True while this connection pilots. */
export function isPilot(seen: HelmSeen): boolean {
  return seen.session !== null && seen.helm?.pilot?.id === seen.session.id;
}

/** The epoch to stamp thrust with, or null when we do not pilot. */
export function stampOf(seen: HelmSeen): number | null {
  return isPilot(seen) ? seen.epoch : null;
}

/** Heartbeat period the server asks for (ms). */
export function heartbeatMsOf(seen: HelmSeen): number {
  return seen.helm?.heartbeat_ms ?? 100;
}

/** The channel was (re)joined with a fresh snapshot: we pilot nothing on a new join. */
export function helmRejoined(helm: Helm | null, session: Session | null, nowMs: number): HelmSeen {
  return { helm, session, epoch: null, receivedAtMs: nowMs };
}

/** A `helm` broadcast: the new value and what it changed for us. */
export function seeHelm(seen: HelmSeen, helm: Helm, nowMs: number): { readonly seen: HelmSeen; readonly change: HelmChange } {
  const was = isPilot(seen);
  const oldEpoch = seen.epoch;
  const next0: HelmSeen = { ...seen, helm, receivedAtMs: nowMs };
  const is = isPilot(next0);
  const next: HelmSeen = { ...next0, epoch: is ? helm.epoch : null };
  return {
    seen: next,
    change: {
      becamePilot: is && !was,
      lostPilot: was && !is,
      restamped: is && was && oldEpoch !== null && oldEpoch !== helm.epoch,
    },
  };
}

/**
 * Our grant (from `control_granted` or a `granted` reply — both come for a request on a free
 * helm). Null for a grant already known (same epoch, still piloting): the page must not treat
 * it as a new pick-up, or it would forget keys that are held and applied.
 */
export function seeGrant(seen: HelmSeen, grant: Grant): HelmSeen | null {
  if (isPilot(seen) && seen.epoch === grant.epoch) return null;
  const { helm, session } = seen;
  if (helm && session && grant.pilot.id === session.id) {
    // the helm broadcast follows; until then, the grant is the news
    const piloted: Helm = { ...helm, state: "piloted", epoch: grant.epoch, pilot: grant.pilot, request: null, takeover: null };
    return { ...seen, helm: piloted, epoch: grant.epoch };
  }
  return { ...seen, epoch: grant.epoch };
}

/** The view of what was seen, at `nowMs` (countdowns run from when the helm arrived). */
export function seenView(seen: HelmSeen, nowMs: number): HelmView {
  return helmView(seen.helm, seen.session, nowMs - seen.receivedAtMs);
}
