/**
 * The operator's helm commands: request control, take it (the main station), release it,
 * answer a request (hand over or keep), and arm / disarm a mavlink vehicle. What the replies
 * mean for the helm goes to the reactions (`request_pending`, `takeover_started`, `answered`,
 * `refused`: reactions.ts); the grant itself comes as a vehicle event. A vehicle's answer to
 * arm / disarm — in the reply, or later as `vehicle_answer` — is shown as a message.
 */

import { reasonOf } from "../lib/errors";
import type { VehicleChannel } from "../lib/vehicle_client";
import type { MessageKind, ReactionEvent } from "./reactions";

/** The helm commands (a `VehicleChannel` has them). */
export type HelmVehicle = Pick<VehicleChannel, "requestControl" | "takeControl" | "releaseControl" | "answerRequest" | "arm">;

export interface HelmCommandsHost {
  /** the vehicle's channel, once opened */
  readonly vehicle: () => HelmVehicle | null;
  readonly dispatch: (event: ReactionEvent) => void;
  readonly showMessage: (text: string, kind: MessageKind, source: string) => void;
}

/**
 * What to say of the vehicle's answer to `command` (`refusal` null: done). Other commands
 * than arm and disarm are said only when refused.
 */
export function vehicleAnswerMessage(command: string, refusal: string | null): { readonly text: string; readonly kind: MessageKind } | null {
  if (command !== "arm" && command !== "disarm") return refusal === null ? null : { text: `The vehicle refused ${command}: ${refusal}`, kind: "error" };
  if (refusal === null) return { text: command === "arm" ? "Vehicle armed" : "Vehicle disarmed", kind: "info" };
  return { text: `${command === "arm" ? "Arm" : "Disarm"} refused: ${refusal}`, kind: "error" };
}

export class HelmCommands {
  private readonly host: HelmCommandsHost;

  constructor(host: HelmCommandsHost) {
    this.host = host;
  }

  request(): void {
    this.host
      .vehicle()
      ?.requestControl()
      .then((reply) => {
        if (reply.status === "pending") this.host.dispatch({ type: "request_pending" });
      })
      .catch((err: unknown) => this.refused("Request", err));
  }

  take(): void {
    this.host
      .vehicle()
      ?.takeControl()
      .then((reply) => {
        if (reply.status === "takeover") this.host.dispatch({ type: "takeover_started", countdownMs: reply.countdown_ms });
      })
      .catch((err: unknown) => this.refused("Take control", err));
  }

  release(): void {
    this.host
      .vehicle()
      ?.releaseControl()
      .catch((err: unknown) => this.refused("Release", err));
  }

  /** Our answer to a control request: hand over (`true`) or keep control. */
  answer(accept: boolean): void {
    this.host
      .vehicle()
      ?.answerRequest(accept)
      .then(() => this.host.dispatch({ type: "answered" }))
      .catch((err: unknown) => this.refused("Answer", err));
  }

  /** Arms (`true`) or disarms a mavlink vehicle. */
  arm(arm: boolean): void {
    const command = arm ? "arm" : "disarm";
    this.host
      .vehicle()
      ?.arm(arm)
      .then((reply) => {
        if (reply === "ok") this.answered(command, null);
        else this.host.showMessage(`${arm ? "Arming" : "Disarming"}: waiting for the vehicle…`, "info", "arm");
      })
      .catch((err: unknown) => this.answered(command, reasonOf(err)));
  }

  /** The vehicle's answer to `command`, now or later (`refusal` null: done). */
  answered(command: string, refusal: string | null): void {
    const said = vehicleAnswerMessage(command, refusal);
    if (said !== null) this.host.showMessage(said.text, said.kind, "arm");
  }

  private refused(what: string, err: unknown): void {
    this.host.dispatch({ type: "refused", what, reason: reasonOf(err) });
  }
}
