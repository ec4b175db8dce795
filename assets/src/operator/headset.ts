/**
 * The operator page's headset input: starts and stops head tracking (WebXR, else
 * DeviceOrientation: `startHeadPose`), takes the head's direction as straight ahead at the
 * vehicle's heading (`capture`), and while the headset input drives a vehicle we pilot, turns
 * head poses into the heading autopilot's setpoint and the camera tilt (`HeadsetFilter`: a
 * step of 1° at most every 200 ms, so a steady head sends nothing). Its state is the page's
 * `headset` (status line, reference, last angles and setpoints sent); the host stores it.
 */

import { startHeadPose } from "../input/head_pose";
import type { HeadPose } from "../input/head_pose";
import { HeadsetFilter, headAngles } from "../input/headset";
import type { HeadAngles, HeadReference, Quaternion } from "../input/headset";
import { reasonOf } from "../lib/errors";
import type { ControlSettings } from "../lib/protocol";

export interface HeadsetState {
  readonly status: "off" | "starting" | "webxr" | "orientation" | "error";
  readonly message: string;
  readonly reference: HeadReference | null;
  readonly angles: HeadAngles | null;
  readonly lastHeading: number | null;
  readonly lastTilt: number | null;
}

export const HEADSET_OFF: HeadsetState = { status: "off", message: "", reference: null, angles: null, lastHeading: null, lastTilt: null };

/** How long a started head tracker may stay silent before it counts as broken (ms). */
export const HEADSET_SILENCE_MS = 3000;

/** The commands head tracking sends (a `VehicleChannel` has them). */
export interface HeadsetVehicle {
  autopilot(setpoints: { heading: number }): Promise<ControlSettings>;
  setValue(event: "set_tilt", value: number): Promise<ControlSettings>;
}

export interface HeadsetHost {
  readonly get: () => HeadsetState;
  readonly update: (patch: Partial<HeadsetState>) => void;
  /** the vehicle's measured heading (rad), if known */
  readonly vehicleHeading: () => number | undefined;
  /** the vehicle head moves steer now: null unless the headset input is selected, we pilot and the channel is joined */
  readonly steering: () => HeadsetVehicle | null;
  /** monotonic clock, ms */
  readonly nowMs: () => number;
  /** the settings a command returned */
  readonly onControl: (control: ControlSettings) => void;
  /** the headset field's status: ok, or an error text */
  readonly onResult: (error: string | null) => void;
  /** defaults to `startHeadPose` (tests pass a fake) */
  readonly startPose?: typeof startHeadPose;
}

export class HeadsetInput {
  private readonly host: HeadsetHost;
  private readonly filter = new HeadsetFilter();
  private pose: HeadPose | null = null;
  private watchdog: ReturnType<typeof setTimeout> | null = null;

  constructor(host: HeadsetHost) {
    this.host = host;
  }

  async start(): Promise<void> {
    this.stop();
    this.host.update({ status: "starting", message: "starting head tracking…" });
    try {
      const pose = await (this.host.startPose ?? startHeadPose)(
        (q) => this.onPose(q),
        () => this.host.update({ status: "off", message: "the headset session ended" }),
      );
      this.pose = pose;
      this.host.update({
        status: pose.source,
        message: pose.source === "webxr" ? "WebXR headset" : "waiting for the orientation sensor…",
      });
      this.watchdog = setTimeout(() => {
        if (this.host.get().angles === null) {
          this.host.update({ status: "error", message: "no head pose arrives: this device has no working orientation sensor" });
        }
      }, HEADSET_SILENCE_MS);
    } catch (err) {
      this.host.update({ status: "error", message: reasonOf(err) });
    }
  }

  stop(): void {
    this.pose?.stop();
    this.pose = null;
    if (this.watchdog !== null) clearTimeout(this.watchdog);
    this.watchdog = null;
    this.filter.reset();
    if (this.host.get().status !== "off") {
      this.host.update({ status: "off", message: "", reference: null, angles: null });
    }
  }

  /** Takes the current head direction as straight ahead at the vehicle's current heading. */
  capture(): void {
    const angles = this.host.get().angles;
    const heading = this.host.vehicleHeading();
    if (!angles || heading === undefined || !Number.isFinite(heading)) {
      this.host.update({ message: "no head pose or vehicle heading to take as reference yet" });
      return;
    }
    this.filter.reset();
    this.host.update({ reference: { yaw: angles.yaw, heading }, message: "reference set: turn your head to steer" });
  }

  private onPose(q: Quaternion): void {
    const angles = headAngles(q);
    const h = this.host.get();
    const status = h.status === "orientation" && h.angles === null ? { message: "orientation sensor" } : {};
    this.host.update({ angles, ...status });
    if (h.reference === null) return;
    const vehicle = this.host.steering();
    if (!vehicle) return;
    const out = this.filter.update(this.host.nowMs(), h.reference, angles);
    if (out.heading !== undefined) {
      const heading = out.heading;
      this.host.update({ lastHeading: heading });
      vehicle.autopilot({ heading }).then(
        (control) => {
          this.host.onControl(control);
          this.host.onResult(null);
        },
        (err: unknown) => this.host.onResult(`heading: ${reasonOf(err)}`),
      );
    }
    if (out.tilt !== undefined) {
      const tilt = out.tilt;
      this.host.update({ lastTilt: tilt });
      vehicle.setValue("set_tilt", tilt).then(
        (control) => this.host.onControl(control),
        (err: unknown) => this.host.onResult(`tilt: ${reasonOf(err)}`),
      );
    }
  }
}
