/** The operator page's side panels: helm, input mode, vehicle settings. */

import { useState } from "preact/hooks";
import type { ComponentChildren } from "preact";
import { ACTION_LABELS, BUTTON_ACTIONS, REPEAT_MS, buttonName } from "../input/buttons";
import { INPUT_MODES, stickMode } from "../input/demand";
import type { InputMode } from "../input/demand";
import { MANUAL_KEYMAP, MOTION_KEYMAP } from "../input/keyboard";
import { ROTATIONS, parseRotation } from "../lib/prefs";
import { CONTROL_MODES, RUN_MODES } from "../lib/protocol";
import type { ControlMode, RunMode } from "../lib/protocol";
import { formatHeading } from "../lib/units";
import type { FieldName, OperatorController, OperatorState } from "./controller";
import { dpNote } from "./dp";
import { fmt, formatDeg } from "./format";

interface Props {
  readonly s: OperatorState;
  readonly c: OperatorController;
}

export function Panel(props: { title: string; id: string; children: ComponentChildren; class?: string }): preact.JSX.Element {
  return (
    <section class={`panel ${props.class ?? ""}`} aria-labelledby={`${props.id}-title`}>
      <h2 id={`${props.id}-title`}>{props.title}</h2>
      {props.children}
    </section>
  );
}

export function HelmPanel({ s, c }: Props): preact.JSX.Element {
  const v = s.helm;
  const warning = v.takeover?.concernsMe ?? false;
  return (
    <Panel title="Helm" id="helm" class="helm">
      <p id="helm-state" class="helm-state" data-testid="helm-state" data-state={v.state} data-me={v.me} data-warning={String(warning)} role="status">
        {v.summary}
      </p>
      <div class="helm-actions">
        <button type="button" id="request-control" data-testid="request-control" disabled={!v.canRequest} hidden={v.me !== "watching"} onClick={() => c.helm.request()}>
          Request control
        </button>
        <button type="button" id="take-control" data-testid="take-control" hidden={!v.canTake} onClick={() => c.helm.take()}>
          Take control
        </button>
        <button type="button" id="release-control" data-testid="release-control" hidden={!v.canRelease} onClick={() => c.helm.release()}>
          {v.releaseLabel}
        </button>
        <button type="button" id="stop" class="stop" data-testid="stop" hidden={v.me !== "pilot"} onClick={() => c.stop()}>
          Stop
        </button>
      </div>
      <div id="control-request" class="prompt" data-testid="control-request" role="alertdialog" aria-labelledby="request-text" hidden={v.prompt === null}>
        <p id="request-text">
          <strong id="requester">{v.prompt?.from.name ?? "—"}</strong> requests control{" "}
          <span id="request-left">{v.prompt ? `(${Math.ceil(v.prompt.remainingMs / 1000)} s)` : ""}</span>
        </p>
        <button type="button" id="accept-request" data-testid="accept-request" onClick={() => c.helm.answer(true)}>
          Hand over
        </button>
        <button type="button" id="deny-request" data-testid="deny-request" onClick={() => c.helm.answer(false)}>
          Keep control
        </button>
      </div>
    </Panel>
  );
}

function Segmented<T extends string>(props: {
  name: string;
  options: readonly T[];
  value: T | null;
  disabled?: boolean;
  label: (v: T) => string;
  onSelect: (v: T) => void;
}): preact.JSX.Element {
  return (
    <div class="segmented" role="radiogroup" aria-label={props.name}>
      {props.options.map((o) => (
        <button
          type="button"
          key={o}
          id={`${props.name}-${o}`}
          data-testid={`${props.name}-${o}`}
          role="radio"
          aria-checked={props.value === o}
          disabled={props.disabled}
          onClick={() => props.onSelect(o)}
        >
          {props.label(o)}
        </button>
      ))}
    </div>
  );
}

const INPUT_LABELS: Readonly<Record<InputMode, string>> = {
  keyboard: "Keyboard",
  touch: "Touch",
  gamepad: "Gamepad",
  headset: "Headset",
};

const KEY_NAMES = ["KeyW", "KeyS", "KeyQ", "KeyE", "KeyD", "KeyA"];

function KeyLegend(props: { mode: "motion" | "manual" }): preact.JSX.Element {
  const map = props.mode === "motion" ? MOTION_KEYMAP : MANUAL_KEYMAP;
  return (
    <ul class="key-legend" data-testid="key-legend">
      {KEY_NAMES.map((code) => {
        const b = map[code];
        return (
          <li key={code}>
            <kbd>{code.slice(3)}</kbd> {b ? `${b.target} ${b.sign > 0 ? "+" : "−"}` : ""}
          </li>
        );
      })}
    </ul>
  );
}

export function InputPanel({ s, c }: Props): preact.JSX.Element {
  const mode = stickMode(s.control?.mode ?? "motion");
  const h = s.headset;
  return (
    <Panel title="Input" id="input">
      <Segmented name="input" options={INPUT_MODES} value={s.inputMode} label={(m) => INPUT_LABELS[m]} onSelect={(m) => c.setInputMode(m)} />
      {s.inputMode === "keyboard" && (mode ? <KeyLegend mode={mode} /> : <p class="note">DP mode: keys are ignored.</p>)}
      {s.inputMode === "touch" && <p class="note">Use the sticks on the camera image (several fingers at once).</p>}
      {s.inputMode === "gamepad" && (
        <div class="gamepad" data-testid="gamepad-status" data-connected={s.gamepad !== null}>
          <p>
            {s.gamepad === null
              ? "No gamepad: connect one and press a button."
              : `${s.gamepad.id}${s.gamepad.armed ? "" : " — centre the sticks to arm"}`}
          </p>
          <p class="note">Right stick: surge/yaw (starboard in manual) · left stick: heave (port) · LT/RT: vertical −/+</p>
          <div class="inline-fields">
            <label>
              Deadband
              <input
                type="number"
                min="0"
                max="0.5"
                step="0.01"
                id="gamepad-deadband"
                value={s.gamepadOptions.deadband}
                onChange={(e) => {
                  const v = Number((e.currentTarget as HTMLInputElement).value);
                  if (v >= 0 && v <= 0.5) c.input.setGamepadOptions({ ...s.gamepadOptions, deadband: v });
                }}
              />
            </label>
            <label>
              Expo
              <input
                type="number"
                min="0"
                max="1"
                step="0.05"
                id="gamepad-expo"
                value={s.gamepadOptions.expo}
                onChange={(e) => {
                  const v = Number((e.currentTarget as HTMLInputElement).value);
                  if (v >= 0 && v <= 1) c.input.setGamepadOptions({ ...s.gamepadOptions, expo: v });
                }}
              />
            </label>
          </div>
          <ButtonMapEditor s={s} c={c} />
        </div>
      )}
      {s.inputMode === "headset" && (
        <div class="headset" data-testid="headset-status" data-state={h.status}>
          <p>
            {h.status === "off" ? "Head tracking is off." : h.message}
            {h.angles && ` · yaw ${formatDeg(h.angles.yaw, true)}° pitch ${formatDeg(h.angles.pitch, true)}°`}
          </p>
          <div class="helm-actions">
            <button type="button" id="headset-start" onClick={() => void c.headset.start()}>
              {h.status === "off" || h.status === "error" ? "Start head tracking" : "Restart"}
            </button>
            <button type="button" id="headset-reference" disabled={h.angles === null} onClick={() => c.headset.capture()}>
              Set reference
            </button>
            <button type="button" id="headset-stop" hidden={h.status === "off"} onClick={() => c.headset.stop()}>
              Stop
            </button>
          </div>
          <p class="note">
            Head yaw → heading setpoint{h.lastHeading !== null ? ` (${formatHeading(h.lastHeading)}°)` : ""}, head pitch → camera tilt
            {h.lastTilt !== null ? ` (${formatDeg(h.lastTilt, true)}°)` : ""}. No thrust from the headset.
          </p>
          <FieldStatusText s={s} field="headset" />
        </div>
      )}
    </Panel>
  );
}

/** The gamepad's buttons: what each does, "assign" (then press a button), reset to default. */
function ButtonMapEditor({ s, c }: Props): preact.JSX.Element {
  const m = s.buttonMapping;
  const last = s.lastPress;
  return (
    <details class="button-map" id="button-map" data-testid="button-map">
      <summary>Buttons</summary>
      <p class="note" id="gamepad-last" data-testid="gamepad-last">
        {last === null ? "Press a button: it acts once per press." : `${buttonName(last.button)} → ${last.action === null ? "nothing" : ACTION_LABELS[last.action]}`}
      </p>
      <table class="button-table">
        <tbody>
          {BUTTON_ACTIONS.map((action) => {
            const button = m.actions[action];
            const learning = s.learning === action;
            return (
              <tr key={action} data-action={action} data-learning={String(learning)}>
                <th scope="row">{ACTION_LABELS[action]}</th>
                <td id={`map-${action}`} data-testid={`map-${action}`} data-button={button === undefined ? "" : String(button)}>
                  {learning ? "press a button…" : button === undefined ? "—" : buttonName(button)}
                </td>
                <td class="buttons">
                  <button type="button" id={`assign-${action}`} aria-pressed={learning} onClick={() => c.buttons.learn(action)}>
                    {learning ? "Cancel" : "Assign"}
                  </button>
                  <button type="button" id={`unassign-${action}`} title="No button" disabled={button === undefined} onClick={() => c.buttons.unassign(action)}>
                    ×
                  </button>
                </td>
              </tr>
            );
          })}
        </tbody>
      </table>
      <div class="inline-fields">
        <label>
          Repeat (ms)
          <input
            type="number"
            id="gamepad-repeat"
            min={String(REPEAT_MS.min)}
            max={String(REPEAT_MS.max)}
            step="50"
            value={m.repeatMs}
            onChange={(e) => c.buttons.setRepeatMs(Number((e.currentTarget as HTMLInputElement).value))}
          />
        </label>
        <button type="button" id="mapping-reset" data-testid="mapping-reset" onClick={() => c.buttons.reset()}>
          Reset to default
        </button>
      </div>
      <output class="field-status" id="mapping-status" data-testid="mapping-status" data-state={s.mappingStatus.state} aria-live="polite">
        {s.mappingStatus.text}
      </output>
    </details>
  );
}

function FieldStatusText({ s, field }: { s: OperatorState; field: FieldName }): preact.JSX.Element {
  const f = s.fields[field];
  return (
    <output class="field-status" id={`${field}-status`} data-testid={`${field}-status`} data-state={f?.state ?? "none"} aria-live="polite">
      {f?.text ?? ""}
    </output>
  );
}

function ValueField(props: {
  s: OperatorState;
  field: "gain" | "lights" | "laser" | "tilt";
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

const CONTROL_LABELS: Readonly<Record<ControlMode, string>> = { motion: "Motion", manual: "Manual", dp: "DP" };
const RUN_LABELS: Readonly<Record<RunMode, string>> = { normal: "Normal", simulator: "Simulator" };

function isControlMode(v: string | undefined): v is ControlMode {
  return (CONTROL_MODES as readonly string[]).includes(v ?? "");
}
function isRunMode(v: string | null | undefined): v is RunMode {
  return (RUN_MODES as readonly string[]).includes(v ?? "");
}

export function SettingsPanel({ s, c }: Props): preact.JSX.Element {
  const ctl = s.control;
  const pilot = s.helm.me === "pilot";
  const off = !pilot || s.status !== "connected";
  const ap = ctl?.autopilot ?? null;
  return (
    <Panel title="Vehicle" id="settings" class="settings">
      {!pilot && <p class="note">Request control to change these.</p>}
      <div class="setting-row">
        <span class="setting-label">Control mode</span>
        <Segmented
          name="control-mode"
          options={CONTROL_MODES}
          value={isControlMode(ctl?.mode) ? ctl.mode : null}
          disabled={off}
          label={(m) => CONTROL_LABELS[m]}
          onSelect={(m) => c.fields.setControlMode(m)}
        />
        <FieldStatusText s={s} field="control_mode" />
        {dpNote(ctl) !== null && (
          <p class="note" data-testid="dp-note">
            {dpNote(ctl)}
          </p>
        )}
      </div>
      <div class="setting-row">
        <span class="setting-label">Run mode</span>
        <Segmented
          name="run-mode"
          options={RUN_MODES}
          value={isRunMode(ctl?.run_mode) ? ctl.run_mode : null}
          disabled={off}
          label={(m) => RUN_LABELS[m]}
          onSelect={(m) => c.fields.setRunMode(m)}
        />
        <FieldStatusText s={s} field="run_mode" />
      </div>
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
