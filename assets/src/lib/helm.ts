/**
 * The helm as this client sees it: who pilots, whether we do, what we may do, and the stamp
 * (`epoch`) our thrust commands must carry. Pure: no DOM, no timers; the page feeds it the
 * server's events and the current time (ms, any monotonic clock) and renders `view()`.
 *
 * Stamps (pick-up procedure, docs/API.md): the server refuses a thrust whose `epoch` is not
 * the current one. We take the epoch from our grant; when the server changes it while we
 * pilot (a deadman stop), `onHelm` reports `restamped` — the page must then forget held keys
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

/** Follows the helm events for one connection and keeps the stamp for its commands. */
export class HelmTracker {
  private helm: Helm | null = null;
  private receivedAt = 0;
  private session: Session | null = null;
  private epoch: number | null = null;

  setSession(session: Session | null): void {
    this.session = session;
  }

  get current(): Helm | null {
    return this.helm;
  }

  /** True while this connection pilots. */
  get isPilot(): boolean {
    return this.session !== null && this.helm?.pilot?.id === this.session.id;
  }

  /** The epoch to stamp thrust with, or null when we do not pilot. */
  get stamp(): number | null {
    return this.isPilot ? this.epoch : null;
  }

  /** Heartbeat period the server asks for (ms). */
  get heartbeatMs(): number {
    return this.helm?.heartbeat_ms ?? 100;
  }

  onHelm(helm: Helm, now: number): HelmChange {
    const was = this.isPilot;
    const oldEpoch = this.epoch;
    this.helm = helm;
    this.receivedAt = now;
    const is = this.isPilot;
    if (is) this.epoch = helm.epoch;
    else this.epoch = null;
    return {
      becamePilot: is && !was,
      lostPilot: was && !is,
      restamped: is && was && oldEpoch !== null && oldEpoch !== helm.epoch,
    };
  }

  /**
   * Our grant (from `control_granted` or a `granted` reply — both come for a request on a free
   * helm). Returns false for a grant already known (same epoch, still piloting): the page must
   * not treat it as a new pick-up, or it would forget keys that are held and applied.
   */
  onGrant(grant: Grant): boolean {
    if (this.isPilot && this.epoch === grant.epoch) return false;
    this.epoch = grant.epoch;
    if (this.helm && this.session && grant.pilot.id === this.session.id) {
      // the helm broadcast follows; until then, the grant is the news
      this.helm = { ...this.helm, state: "piloted", epoch: grant.epoch, pilot: grant.pilot, request: null, takeover: null };
    }
    return true;
  }

  /** The channel was (re)joined with a fresh snapshot: we pilot nothing on a new join. */
  reset(helm: Helm | null, session: Session | null, now: number): void {
    this.session = session;
    this.helm = helm;
    this.receivedAt = now;
    this.epoch = null;
  }

  view(now: number): HelmView {
    return helmView(this.helm, this.session, now - this.receivedAt);
  }
}
