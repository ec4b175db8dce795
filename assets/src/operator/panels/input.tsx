/**
 * The input panel: which input drives (keyboard, touch, gamepad, headset) and each one's
 * settings — the keys of the control mode, the gamepad's pad and options and its button
 * mapping, head tracking.
 */

import { INPUT_MODES, stickMode } from "../../input/demand";
import type { InputMode } from "../../input/demand";
import type { GamepadOptions } from "../../input/gamepad";
import { MANUAL_KEYMAP, MOTION_KEYMAP } from "../../input/keyboard";
import { formatHeading } from "../../lib/units";
import { formatDeg } from "../format";
import { ButtonMapEditor } from "./button_map";
import type { PanelProps } from "./panel";
import { FieldStatusText, Panel, Segmented } from "./panel";

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

export function InputPanel({ s, c }: PanelProps): preact.JSX.Element {
  const mode = stickMode(s.control?.mode ?? "motion");
  return (
    <Panel title="Input" id="input">
      <Segmented name="input" options={INPUT_MODES} value={s.inputMode} label={(m) => INPUT_LABELS[m]} onSelect={(m) => c.setInputMode(m)} />
      {s.inputMode === "keyboard" && (mode ? <KeyLegend mode={mode} /> : <p class="note">DP mode: keys are ignored.</p>)}
      {s.inputMode === "touch" && <p class="note">Use the sticks on the camera image (several fingers at once).</p>}
      {s.inputMode === "gamepad" && <GamepadSettings s={s} c={c} />}
      {s.inputMode === "headset" && <HeadsetControls s={s} c={c} />}
    </Panel>
  );
}

/** One of the pad's options (deadband, expo), within its range. */
function PadOption(props: PanelProps & { option: keyof GamepadOptions; label: string; max: number; step: number }): preact.JSX.Element {
  const { s, c, option } = props;
  return (
    <label>
      {props.label}
      <input
        type="number"
        min="0"
        max={String(props.max)}
        step={String(props.step)}
        id={`gamepad-${option}`}
        value={s.gamepadOptions[option]}
        onChange={(e) => {
          const v = Number((e.currentTarget as HTMLInputElement).value);
          if (v >= 0 && v <= props.max) c.input.setGamepadOptions({ ...s.gamepadOptions, [option]: v });
        }}
      />
    </label>
  );
}

/** The gamepad: which pad is read (and whether it is armed), its options, its buttons. */
function GamepadSettings({ s, c }: PanelProps): preact.JSX.Element {
  return (
    <div class="gamepad" data-testid="gamepad-status" data-connected={s.gamepad !== null}>
      <p>{s.gamepad === null ? "No gamepad: connect one and press a button." : `${s.gamepad.id}${s.gamepad.armed ? "" : " — centre the sticks to arm"}`}</p>
      <p class="note">Right stick: surge/yaw (starboard in manual) · left stick: heave (port) · LT/RT: vertical −/+</p>
      <div class="inline-fields">
        <PadOption s={s} c={c} option="deadband" label="Deadband" max={0.5} step={0.01} />
        <PadOption s={s} c={c} option="expo" label="Expo" max={1} step={0.05} />
      </div>
      <ButtonMapEditor s={s} c={c} />
    </div>
  );
}

/** Head tracking: its state, start / reference / stop, and what it steers. */
function HeadsetControls({ s, c }: PanelProps): preact.JSX.Element {
  const h = s.headset;
  return (
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
  );
}
