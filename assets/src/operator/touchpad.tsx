/**
 * The on-screen sticks and buttons (touch input mode), over the camera image. Pointer Events
 * with pointer capture: every finger is tracked by its id, so both sticks (and a button) work
 * at once. `touch-action: none` (app.css) keeps the browser from scrolling or zooming.
 */

import type { StickMode } from "../input/demand";
import type { StickVector, TouchControl, TouchState } from "../input/touch";
import type { OperatorController } from "./controller";

interface PadProps {
  readonly controller: OperatorController;
  readonly touch: TouchState;
  readonly mode: StickMode | null;
}

function handlers(controller: OperatorController, control: TouchControl): Record<string, (e: PointerEvent) => void> {
  const release = (e: PointerEvent): void => controller.input.touchUp(e.pointerId);
  return {
    onPointerDown: (e: PointerEvent) => {
      e.preventDefault();
      const el = e.currentTarget as HTMLElement;
      try {
        el.setPointerCapture(e.pointerId);
      } catch {
        // capture is best effort (synthetic events in some browsers)
      }
      const r = el.getBoundingClientRect();
      controller.input.touchDown(e.pointerId, control, e.clientX, e.clientY, r.left + r.width / 2, r.top + r.height / 2, r.width / 2);
    },
    onPointerMove: (e: PointerEvent) => controller.input.touchMove(e.pointerId, e.clientX, e.clientY),
    onPointerUp: release,
    onPointerCancel: release,
    onLostPointerCapture: release,
  };
}

function Stick(props: { controller: OperatorController; id: "left" | "right"; value: StickVector; label: string }): preact.JSX.Element {
  const { value } = props;
  const knob = { left: `${50 + value.x * 35}%`, top: `${50 - value.y * 35}%` };
  return (
    <div
      class="stick"
      id={`stick-${props.id}`}
      data-testid={`stick-${props.id}`}
      data-x={value.x.toFixed(2)}
      data-y={value.y.toFixed(2)}
      role="slider"
      aria-label={props.label}
      aria-valuetext={`x ${value.x.toFixed(2)}, y ${value.y.toFixed(2)}`}
      onContextMenu={(e) => e.preventDefault()}
      {...handlers(props.controller, props.id)}
    >
      <span class="stick-label">{props.label}</span>
      <span class="knob" style={knob} />
    </div>
  );
}

function PadButton(props: { controller: OperatorController; id: "up" | "down"; held: boolean; label: string }): preact.JSX.Element {
  return (
    <div
      class="pad-button"
      id={`pad-${props.id}`}
      data-testid={`pad-${props.id}`}
      data-held={props.held}
      role="button"
      aria-pressed={props.held}
      onContextMenu={(e) => e.preventDefault()}
      {...handlers(props.controller, props.id)}
    >
      {props.label}
    </div>
  );
}

export function TouchPad({ controller, touch, mode }: PadProps): preact.JSX.Element {
  if (mode === null) {
    return (
      <div class="touchpad disabled" data-testid="touchpad">
        <p>DP mode: the sticks are off.</p>
      </div>
    );
  }
  const left = mode === "motion" ? "heave ↕" : "port ↕";
  const right = mode === "motion" ? "surge ↕ · yaw ↔" : "starboard ↕";
  return (
    <div class="touchpad" data-testid="touchpad" data-mode={mode}>
      <Stick controller={controller} id="left" value={touch.left} label={left} />
      {mode === "manual" && (
        <div class="pad-buttons">
          <PadButton controller={controller} id="up" held={touch.up} label="vertical +" />
          <PadButton controller={controller} id="down" held={touch.down} label="vertical −" />
        </div>
      )}
      <Stick controller={controller} id="right" value={touch.right} label={right} />
    </div>
  );
}
