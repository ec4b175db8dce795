/**
 * The operator page's settings fields: control mode, run mode, the depth and heading
 * autopilots, gain, lights, laser, camera tilt and the camera rotation. Each value goes to the
 * server as typed (lib/forms.ts: degrees become radians, text that is no number stays text so
 * the server's reason names it); the field shows "…" while it waits, ✓ once the vehicle took
 * it, or the server's `error` reason. The settings the server answers with become the page's.
 * A new control or run mode forgets held input first (the same keys then mean other things).
 * The gamepad's steps (gamepad_buttons.ts) and the headset's result use the same fields.
 */

import { formDegrees, formValue } from "../lib/forms";
import { reasonOf } from "../lib/errors";
import { parseRotation } from "../lib/prefs";
import type { Rotation } from "../lib/prefs";
import type { ControlMode, ControlSettings, RunMode } from "../lib/protocol";
import type { VehicleChannel } from "../lib/vehicle_client";
import { withField } from "./state";
import type { FieldName, FieldStatus, OperatorState } from "./state";

/** The setting commands (a `VehicleChannel` has them). */
export type SettingsVehicle = Pick<VehicleChannel, "setControlMode" | "setRunMode" | "setValue" | "autopilot" | "setCameraRotation">;

/** The fields that take a number (typed, or a gamepad's step). */
export type ValueField = "gain" | "lights" | "laser" | "tilt";

export interface SettingsFieldsHost {
  readonly get: () => Pick<OperatorState, "fields">;
  readonly update: (patch: Partial<Pick<OperatorState, "fields" | "control" | "rotation">>) => void;
  /** the vehicle's channel, once opened */
  readonly vehicle: () => SettingsVehicle | null;
  /** forgets held keys, fingers and the pad's deflection */
  readonly resetInputs: () => void;
}

export class SettingsFields {
  private readonly host: SettingsFieldsHost;

  constructor(host: SettingsFieldsHost) {
    this.host = host;
  }

  setControlMode(mode: ControlMode): void {
    this.host.resetInputs();
    this.send("control_mode", (v) => v.setControlMode(mode));
  }

  setRunMode(mode: RunMode): void {
    this.host.resetInputs();
    this.send("run_mode", (v) => v.setRunMode(mode));
  }

  /** gain, lights, laser: the value as typed; tilt typed in degrees. */
  setTyped(field: ValueField, text: string): void {
    this.set(field, field === "tilt" ? formDegrees(text) : formValue(text));
  }

  /** A value for the wire (tilt in radians). */
  set(field: ValueField, value: number | string): void {
    this.send(field, (v) => v.setValue(`set_${field}`, value));
  }

  /** Depth (m) or heading (typed in degrees): a value, "hold" (keep the current) or off. */
  setAutopilot(axis: "depth" | "heading", action: "set" | "hold" | "off", text = ""): void {
    const value = action === "off" ? null : action === "hold" ? "hold" : axis === "heading" ? formDegrees(text) : formValue(text);
    this.send(axis, (v) => v.autopilot(axis === "depth" ? { depth: value } : { heading: value }));
  }

  /**
   * The vehicle's camera rotation, for every page: stored on the server (the pilot or the main
   * station may change it); every page turns its image when the server says so.
   */
  setRotation(rotation: Rotation): void {
    const vehicle = this.host.vehicle();
    if (vehicle === null) return;
    this.mark("rotation", "busy", "…");
    vehicle.setCameraRotation(rotation).then(
      (settings) => {
        this.host.update({ rotation: parseRotation(settings.camera_rotation) });
        this.mark("rotation", "ok", "✓");
      },
      (err: unknown) => this.mark("rotation", "error", reasonOf(err)),
    );
  }

  /** A field's status beside it. */
  mark(field: FieldName, state: FieldStatus["state"], text: string): void {
    this.host.update(withField(this.host.get(), field, state, text));
  }

  private send(field: FieldName, command: (v: SettingsVehicle) => Promise<ControlSettings>): void {
    const vehicle = this.host.vehicle();
    if (vehicle === null) return;
    this.mark(field, "busy", "…");
    command(vehicle).then(
      (control) => {
        this.host.update({ control });
        this.mark(field, "ok", "✓");
      },
      (err: unknown) => this.mark(field, "error", reasonOf(err)),
    );
  }
}
