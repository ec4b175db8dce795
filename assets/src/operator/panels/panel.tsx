/**
 * What the operator page's panels are built of: the panel frame (`Panel`), a segmented choice
 * (`Segmented`), a readout (`Readout`) and a field's status (`FieldStatusText`). Every panel
 * is a function of the page's state `s` (state.ts) and, when it sends commands, the page's
 * controller `c` (controller.ts: its parts carry the commands).
 */

import type { ComponentChildren } from "preact";
import type { OperatorController } from "../controller";
import type { FieldName, OperatorState } from "../state";

/** What a panel gets: the page's state, and the controller whose parts send commands. */
export interface PanelProps {
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

export function Segmented<T extends string>(props: {
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

export function Readout(props: { label: string; id: string; value: string; unit?: string }): preact.JSX.Element {
  return (
    <div>
      <dt>{props.label}</dt>
      <dd>
        <span id={props.id} data-testid={props.id}>
          {props.value}
        </span>
        {props.unit !== undefined && <span class={props.unit === "°" ? "unit deg" : "unit"}>{props.unit}</span>}
      </dd>
    </div>
  );
}

export function FieldStatusText({ s, field }: { s: OperatorState; field: FieldName }): preact.JSX.Element {
  const f = s.fields[field];
  return (
    <output class="field-status" id={`${field}-status`} data-testid={`${field}-status`} data-state={f?.state ?? "none"} aria-live="polite">
      {f?.text ?? ""}
    </output>
  );
}
