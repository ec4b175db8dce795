/** The developer page's autopilot tuning panel: gains form, step-response preview, apply. */

import { useStore } from "../lib/use_store";
import type { TuningController } from "./tuning";
import { AXES, GAIN_KEYS, figures, polylines } from "./tuning_model";

const W = 360;
const H = 140;

export function TuningPanel({ c }: { c: TuningController }): preact.JSX.Element {
  const s = useStore(c.store);
  const lines = s.preview === null ? null : polylines(s.preview, W, H);
  const unit = s.axis === "depth" ? "m" : "rad";
  return (
    <details class="tuning" id="tuning" data-testid="tuning" onToggle={(e) => (e.currentTarget as HTMLDetailsElement).open && s.info === null && void c.load()}>
      <summary>Autopilot tuning</summary>
      {s.form === null ? (
        <p class="note">{s.busy === "loading" ? "Reading the gains…" : s.message || "Open to read the gains in force."}</p>
      ) : (
        <form
          onSubmit={(e) => {
            e.preventDefault();
            void c.preview();
          }}
        >
          <table class="gains">
            <thead>
              <tr>
                <th />
                {GAIN_KEYS.map((k) => (
                  <th key={k}>{k}</th>
                ))}
              </tr>
            </thead>
            <tbody>
              {AXES.map((axis) => (
                <tr key={axis}>
                  <th>{axis}</th>
                  {GAIN_KEYS.map((k) => (
                    <td key={k}>
                      <input
                        type="text"
                        inputMode="decimal"
                        size={6}
                        id={`gain-${axis}-${k}`}
                        data-testid={`gain-${axis}-${k}`}
                        value={s.form?.[axis][k] ?? ""}
                        onInput={(e) => c.setField(axis, k, (e.currentTarget as HTMLInputElement).value)}
                      />
                    </td>
                  ))}
                </tr>
              ))}
            </tbody>
          </table>
          <div class="toolbar">
            <label>
              Step{" "}
              <select id="tuning-axis" data-testid="tuning-axis" value={s.axis} onChange={(e) => c.setAxis((e.currentTarget as HTMLSelectElement).value === "heading" ? "heading" : "depth")}>
                <option value="depth">depth 1 m</option>
                <option value="heading">heading 90°</option>
              </select>
            </label>
            <button type="submit" id="tuning-preview" data-testid="tuning-preview" disabled={s.busy !== null}>
              Preview step
            </button>
            <button type="button" id="tuning-apply" data-testid="tuning-apply" disabled={s.busy !== null} onClick={() => void c.apply()}>
              Apply to the vehicle
            </button>
            <button type="button" id="tuning-defaults" onClick={() => c.resetToDefaults()}>
              Defaults
            </button>
          </div>
        </form>
      )}
      {s.message !== "" && (
        <p class="field-status" data-testid="tuning-message" data-state={s.error ? "error" : "ok"} role={s.error ? "alert" : "status"}>
          {s.message}
        </p>
      )}
      {s.preview !== null && lines !== null && (
        <figure class="step-preview" data-testid="step-preview">
          <svg viewBox={`0 0 ${W} ${H}`} width={W} height={H} role="img" aria-label={`step response of ${s.preview.axis}`}>
            <polyline points={lines.setpoint} fill="none" stroke="#888" stroke-dasharray="4 3" />
            <polyline points={lines.reference} fill="none" stroke="#e0a030" />
            <polyline points={lines.value} fill="none" stroke="#3080e0" stroke-width="2" />
          </svg>
          <figcaption data-testid="step-figures">
            {s.preview.axis} step on the simulator model: {figures(s.preview)} · setpoint (dashed), reference (orange), vehicle (blue); {lines.min.toFixed(2)}–{lines.max.toFixed(2)} {unit}
          </figcaption>
        </figure>
      )}
    </details>
  );
}
