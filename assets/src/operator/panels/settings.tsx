/**
 * The vehicle's settings panel (the pilot's): control mode, run mode, depth and heading
 * autopilots, gain, lights, laser, camera tilt and the image rotation. Each field sends what
 * was typed (settings_fields.ts) and shows its status beside it.
 */

import type { ComponentChildren } from "preact";
import { useState } from "preact/hooks";
import { ROTATIONS, parseRotation } from "../../lib/prefs";
import { CONTROL_MODES, RUN_MODES } from "../../lib/protocol";
import type { ControlMode, RunMode } from "../../lib/protocol";
import { formatHeading } from "../../lib/units";
import type { OperatorController } from "../controller";
import { dpNote } from "../dp";
import { fmt, formatDeg } from "../format";
import type { ValueField as ValueFieldName } from "../settings_fields";
import type { FieldName, OperatorState } from "../state";
import type { PanelProps } from "./panel";
import { FieldStatusText, Panel, Segmented } from "./panel";

function ValueField(props: {
  s: OperatorState;
  field: ValueFieldName;
  label: string;
  hint: string;
  current: string;
  disabled: boolean;
  onSet: (text: string) => void;
}): preact.JSX.Element {
  const [text, setText] = useState("");
  const submit = (e: Event): void => {
    e.preventDefault();
    props.onSet(text);
  };
  return (
    <form class="setting" onSubmit={submit} data-testid={`${props.field}-form`}>
      <label for={`${props.field}-input`}>
        {props.label} <small>{props.hint}</small>
      </label>
      <span class="current" data-testid={`${props.field}-current`}>
        {props.current}
      </span>
      <input
        id={`${props.field}-input`}
        data-testid={`${props.field}-input`}
        type="text"
        inputMode="decimal"
        autoComplete="off"
        value={text}
        placeholder={props.current}
        onInput={(e) => setText((e.currentTarget as HTMLInputElement).value)}
      />
      <button type="submit" id={`${props.field}-set`} data-testid={`${props.field}-set`} disabled={props.disabled}>
        Set
      </button>
      <FieldStatusText s={props.s} field={props.field} />
    </form>
  );
}

function AutopilotField(props: {
  s: OperatorState;
  c: OperatorController;
  axis: "depth" | "heading";
  current: string;
  disabled: boolean;
}): preact.JSX.Element {
  const [text, setText] = useState("");
  const { axis, c } = props;
  return (
    <form
      class="setting"
      data-testid={`${axis}-form`}
      onSubmit={(e) => {
        e.preventDefault();
        c.fields.setAutopilot(axis, "set", text);
      }}
    >
      <label for={`${axis}-input`}>
        {axis === "depth" ? "Depth" : "Heading"} <small>{axis === "depth" ? "m" : "°"}</small>
      </label>
      <span class="current" data-testid={`${axis}-current`}>
        {props.current}
      </span>
      <input
        id={`${axis}-input`}
        data-testid={`${axis}-input`}
        type="text"
        inputMode="decimal"
        autoComplete="off"
        value={text}
        onInput={(e) => setText((e.currentTarget as HTMLInputElement).value)}
      />
      <span class="buttons">
        <button type="submit" id={`${axis}-set`} disabled={props.disabled}>
          Set
        </button>
        <button type="button" id={`${axis}-hold`} disabled={props.disabled} onClick={() => c.fields.setAutopilot(axis, "hold")}>
          Hold
        </button>
        <button type="button" id={`${axis}-off`} disabled={props.disabled} onClick={() => c.fields.setAutopilot(axis, "off")}>
          Off
        </button>
      </span>
      <FieldStatusText s={props.s} field={axis} />
    </form>
  );
}

/** A setting chosen among a few (control mode, run mode), with its status. */
function ChoiceRow<T extends string>(props: {
  s: OperatorState;
  label: string;
  name: string;
  field: FieldName;
  options: readonly T[];
  value: T | null;
  disabled: boolean;
  labels: Readonly<Record<T, string>>;
  onSelect: (v: T) => void;
  children?: ComponentChildren;
}): preact.JSX.Element {
  return (
    <div class="setting-row">
      <span class="setting-label">{props.label}</span>
      <Segmented name={props.name} options={props.options} value={props.value} disabled={props.disabled} label={(m) => props.labels[m]} onSelect={props.onSelect} />
      <FieldStatusText s={props.s} field={props.field} />
      {props.children}
    </div>
  );
}

const CONTROL_LABELS: Readonly<Record<ControlMode, string>> = { motion: "Motion", manual: "Manual", dp: "DP" };
const RUN_LABELS: Readonly<Record<RunMode, string>> = { normal: "Normal", simulator: "Simulator" };

function isControlMode(v: string | undefined): v is ControlMode {
  return (CONTROL_MODES as readonly string[]).includes(v ?? "");
}
function isRunMode(v: string | null | undefined): v is RunMode {
  return (RUN_MODES as readonly string[]).includes(v ?? "");
}

export function SettingsPanel({ s, c }: PanelProps): preact.JSX.Element {
  const ctl = s.control;
  const pilot = s.helm.me === "pilot";
  const off = !pilot || s.status !== "connected";
  const ap = ctl?.autopilot ?? null;
  return (
    <Panel title="Vehicle" id="settings" class="settings">
      {!pilot && <p class="note">Request control to change these.</p>}
      <ChoiceRow
        s={s}
        label="Control mode"
        name="control-mode"
        field="control_mode"
        options={CONTROL_MODES}
        value={isControlMode(ctl?.mode) ? ctl.mode : null}
        disabled={off}
        labels={CONTROL_LABELS}
        onSelect={(m) => c.fields.setControlMode(m)}
      >
        {dpNote(ctl) !== null && (
          <p class="note" data-testid="dp-note">
            {dpNote(ctl)}
          </p>
        )}
      </ChoiceRow>
      <ChoiceRow
        s={s}
        label="Run mode"
        name="run-mode"
        field="run_mode"
        options={RUN_MODES}
        value={isRunMode(ctl?.run_mode) ? ctl.run_mode : null}
        disabled={off}
        labels={RUN_LABELS}
        onSelect={(m) => c.fields.setRunMode(m)}
      />
      <h3>Autopilot</h3>
      <AutopilotField s={s} c={c} axis="depth" disabled={off} current={ap?.depth == null ? "off" : `${fmt(ap.depth, 2)} m`} />
      <AutopilotField s={s} c={c} axis="heading" disabled={off} current={ap?.heading == null ? "off" : `${formatHeading(ap.heading)}°`} />
      <h3>Settings</h3>
      <ValueField s={s} field="gain" label="Gain" hint="0..1" disabled={off} current={fmt(ctl?.gain, 2)} onSet={(t) => c.fields.setTyped("gain", t)} />
      <ValueField s={s} field="lights" label="Lights" hint="0..255" disabled={off} current={fmt(ctl?.lights, 0)} onSet={(t) => c.fields.setTyped("lights", t)} />
      <ValueField s={s} field="laser" label="Laser" hint="0..255" disabled={off} current={fmt(ctl?.laser, 0)} onSet={(t) => c.fields.setTyped("laser", t)} />
      <ValueField s={s} field="tilt" label="Camera tilt" hint="° ±45" disabled={off} current={ctl?.tilt == null ? "—" : `${formatDeg(ctl.tilt, true)}°`} onSet={(t) => c.fields.setTyped("tilt", t)} />
      <div class="setting-row">
        <label class="setting-label" for="rotation">
          Image rotation
        </label>
        <select
          id="rotation"
          data-testid="rotation"
          disabled={off}
          value={String(s.rotation)}
          onChange={(e) => c.fields.setRotation(parseRotation((e.currentTarget as HTMLSelectElement).value))}
        >
          {ROTATIONS.map((r) => (
            <option key={r} value={String(r)}>
              {r}°
            </option>
          ))}
        </select>
        <small class="note">this vehicle, every page</small>
        <FieldStatusText s={s} field="rotation" />
      </div>
    </Panel>
  );
}
