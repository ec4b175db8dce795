/**
 * Input routing (pure): what a thrust demand from one input device becomes — sent to the
 * vehicle stamped with our grant's epoch, ignored, or blocked with a reason the operator is
 * told (`thrust_blocked`, reactions.ts). The page's `PilotInput` (pilot_input.ts) asks here for
 * every demand its devices make and carries out the answer.
 *
 * ## Rules, in order
 *
 * 1. Only the selected input mode drives, only in a control mode that takes stick input
 *    (motion, manual: not DP), and the headset never sends thrust (`accepts`): else ignored.
 * 2. A demand equal to the last one sent is ignored (demands are absolute values: sending it
 *    again changes nothing; after any stop the last one sent is forgotten).
 * 3. Without a joined channel: blocked, `not_connected`.
 * 4. Without the helm (no epoch to stamp the command with): blocked, `not_in_control`.
 * 5. Else sent, with the epoch.
 */

import { accepts, demandEqual } from "../input/demand";
import type { InputMode, ThrustDemand } from "../input/demand";

/** What the page knows when a demand arrives. */
export interface RoutingContext {
  /** the input mode the operator selected */
  readonly selected: InputMode;
  /** the control mode the vehicle is in (`motion`, `manual`, `dp`…) */
  readonly controlMode: string;
  /** the last demand this page sent (null: none since the last stop or reset) */
  readonly sent: ThrustDemand | null;
  /** the vehicle's channel is joined: commands can be sent */
  readonly joined: boolean;
  /** the helm epoch our thrust carries; null when we do not pilot */
  readonly epoch: number | null;
}

export type Route =
  | { readonly kind: "ignore"; readonly why: "not_selected" | "unchanged" }
  | { readonly kind: "blocked"; readonly why: "not_connected" | "not_in_control" }
  | { readonly kind: "send"; readonly demand: ThrustDemand; readonly epoch: number };

export function routeDemand(ctx: RoutingContext, source: InputMode, demand: ThrustDemand): Route {
  if (!accepts(ctx.selected, source, ctx.controlMode)) return { kind: "ignore", why: "not_selected" };
  if (demandEqual(demand, ctx.sent)) return { kind: "ignore", why: "unchanged" };
  if (!ctx.joined) return { kind: "blocked", why: "not_connected" };
  if (ctx.epoch === null) return { kind: "blocked", why: "not_in_control" };
  return { kind: "send", demand, epoch: ctx.epoch };
}
