/**
 * The developer page's autopilot tuning: reads the gains in force (`get_tuning`), previews a
 * step with proposed gains on the vehicle's simulator model (`step_response`, run headless on
 * the server, nothing changes on the vehicle), and applies them (`set_tuning`: bumpless on
 * the server, stored for the vehicle). Only the user who pilots (or the main station) may
 * preview and apply; the server says so otherwise.
 */

import { Store } from "../lib/store";
import { CommandError } from "../lib/vehicle_client";
import type { VehicleChannel } from "../lib/vehicle_client";
import { PREVIEW_STEP, decodeSetTuning, decodeStepResponse, decodeTuningInfo, formOf, parseForm } from "./tuning_model";
import type { Axis, GainKey, GainsForm, StepResponse, TuningInfo } from "./tuning_model";

export interface TuningState {
  readonly info: TuningInfo | null;
  readonly form: GainsForm | null;
  readonly axis: Axis;
  readonly preview: StepResponse | null;
  readonly busy: "loading" | "preview" | "apply" | null;
  /** the last outcome, for the pilot */
  readonly message: string;
  readonly error: boolean;
}

const reasonOf = (err: unknown): string => (err instanceof CommandError ? err.reason : err instanceof Error ? err.message : String(err));

/** Step responses and applies take a headless run on the server: a generous timeout. */
const RUN_TIMEOUT_MS = 15_000;

export class TuningController {
  readonly store = new Store<TuningState>({ info: null, form: null, axis: "depth", preview: null, busy: null, message: "", error: false });
  private vehicle: VehicleChannel | null = null;
  /** the gains were asked for before the vehicle's channel joined: read them when it does */
  private wanted = false;

  /** The vehicle channel to talk on. */
  attach(vehicle: VehicleChannel): void {
    this.vehicle = vehicle;
  }

  /** The vehicle's channel joined (again): reads the gains if they were asked for meanwhile. */
  joined(): Promise<void> {
    return this.wanted ? this.load() : Promise.resolve();
  }

  /** Reads the gains in force: now, or once the vehicle's channel has joined (`joined`). */
  async load(): Promise<void> {
    const v = this.vehicle;
    this.store.update({ busy: "loading" });
    if (v === null || !v.joined) {
      this.wanted = true;
      return;
    }
    this.wanted = false;
    try {
      const info = await v.request("get_tuning", {}, decodeTuningInfo);
      this.store.update({ info, form: formOf(info.gains), busy: null, message: `gains in force (simulator model ${info.model})`, error: false });
    } catch (err) {
      this.store.update({ busy: null, message: `cannot read the tuning: ${reasonOf(err)}`, error: true });
    }
  }

  setField(axis: Axis, key: GainKey, text: string): void {
    const form = this.store.get().form;
    if (form === null) return;
    this.store.update({ form: { ...form, [axis]: { ...form[axis], [key]: text } } });
  }

  setAxis(axis: Axis): void {
    this.store.update({ axis, preview: null });
  }

  resetToDefaults(): void {
    const info = this.store.get().info;
    if (info !== null) this.store.update({ form: formOf(info.defaults), message: "default gains in the form (not applied)", error: false });
  }

  /** The joined vehicle, the tuning it reported and the form's gains, or null (a form error is shown). */
  private formGains() {
    const { info, form } = this.store.get();
    const v = this.vehicle;
    if (info === null || form === null || v === null) return null;
    const parsed = parseForm(form, info.ranges);
    if (!parsed.ok) {
      this.store.update({ message: parsed.error, error: true });
      return null;
    }
    return { v, info, gains: parsed.gains };
  }

  /** Runs the step on the vehicle's simulator model with the form's gains. */
  async preview(): Promise<void> {
    const ready = this.formGains();
    if (ready === null) return;
    const { v, gains } = ready;
    const axis = this.store.get().axis;
    this.store.update({ busy: "preview", message: "running the step on the simulator model…", error: false });
    try {
      const preview = await v.request("step_response", { axis, step: PREVIEW_STEP[axis], gains: { [axis]: gains[axis] } }, decodeStepResponse, RUN_TIMEOUT_MS);
      this.store.update({ preview, busy: null, message: "", error: false });
    } catch (err) {
      this.store.update({ busy: null, message: `step response: ${reasonOf(err)}`, error: true });
    }
  }

  /** Applies the form's gains to the vehicle (bumpless; stored for the vehicle). */
  async apply(): Promise<void> {
    const ready = this.formGains();
    if (ready === null) return;
    const { v, info } = ready;
    this.store.update({ busy: "apply", message: "applying…", error: false });
    try {
      const gains = await v.request("set_tuning", ready.gains, decodeSetTuning, RUN_TIMEOUT_MS);
      this.store.update({ info: { ...info, gains }, form: formOf(gains), busy: null, message: "applied to the vehicle and stored", error: false });
    } catch (err) {
      this.store.update({ busy: null, message: `not applied: ${reasonOf(err)}`, error: true });
    }
  }
}
