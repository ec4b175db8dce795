/** The helm panel: who pilots, request / take / release control, stop, and a request to answer. */

import type { PanelProps } from "./panel";
import { Panel } from "./panel";

export function HelmPanel({ s, c }: PanelProps): preact.JSX.Element {
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
