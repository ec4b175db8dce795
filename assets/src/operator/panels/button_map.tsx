/** The gamepad's button mapping editor (in the input panel): what each button does, assign, reset. */

import { ACTION_LABELS, BUTTON_ACTIONS, REPEAT_MS, buttonName } from "../../input/buttons";
import type { PanelProps } from "./panel";

/** The gamepad's buttons: what each does, "assign" (then press a button), reset to default. */
export function ButtonMapEditor({ s, c }: PanelProps): preact.JSX.Element {
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
