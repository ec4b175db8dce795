/** The operator page (Preact): header, camera with HUD and touch sticks, the panels (panels/), the message bar. */

import { useEffect, useState } from "preact/hooks";
import { stickMode } from "../input/demand";
import { fetchRollbackNotice } from "../lib/firmware";
import { useStore } from "../lib/use_store";
import type { OperatorController, OperatorState } from "./controller";
import { downFor, vehicleHref, vehicleLabel } from "./format";
import { Camera, Hud } from "./hud";
import { ArduSubPanel } from "./panels/ardusub";
import { CommandPanel } from "./panels/command";
import { CrewPanel } from "./panels/crew";
import { FleetPanel } from "./panels/fleet";
import { HelmPanel } from "./panels/helm";
import { InputPanel } from "./panels/input";
import { NavigationPanel } from "./panels/navigation";
import { SettingsPanel } from "./panels/settings";
import { ThrusterPanel } from "./panels/thrusters";
import { TouchPad } from "./touchpad";

function statusText(s: OperatorState): string {
  if (s.status === "connected") return "connected";
  if (s.status === "connecting") return "connecting";
  const since = s.disconnectedAt === null ? "" : ` ${downFor(performance.now() - s.disconnectedAt)}`;
  return `disconnected${since} — reconnecting`;
}

/** The fleet's vehicles (every node's): choosing one opens it (`?vehicle=ID`). */
function VehiclePicker({ s }: { s: OperatorState }): preact.JSX.Element {
  return (
    <select
      id="vehicle-picker"
      data-testid="vehicle-picker"
      aria-label="Vehicle"
      value={s.vehicleId ?? ""}
      onChange={(e) => {
        const id = e.currentTarget.value;
        if (id !== s.vehicleId) window.location.assign(vehicleHref(window.location.search, id));
      }}
    >
      {s.fleet.map((v) => (
        <option key={v.id} value={v.id}>
          {vehicleLabel(v)}
        </option>
      ))}
    </select>
  );
}

function Header({ s }: { s: OperatorState }): preact.JSX.Element {
  const watching = s.presence.reduce((n, e) => n + e.connections, 0);
  const devHref = s.vehicleId === null ? "/dev.html" : `/dev.html?vehicle=${encodeURIComponent(s.vehicleId)}`;
  return (
    <header class="bar">
      <h1>Neptunus</h1>
      <span class="vehicle">
        Vehicle{" "}
        <strong id="vehicle-id" data-testid="vehicle-id">
          {s.vehicleId ?? "—"}
        </strong>
        {s.fleet.length > 1 ? <VehiclePicker s={s} /> : null}
      </span>
      <span id="status" class="status" data-testid="status" data-state={s.status} role="status">
        {statusText(s)}
      </span>
      <span class="crew">
        Pilot{" "}
        <strong id="pilot" data-testid="pilot">
          {s.pilotName ?? "nobody"}
        </strong>{" "}
        · Watching{" "}
        <strong id="observers" data-testid="observers" title={s.presence.map((e) => e.name).join(", ")}>
          {String(watching)}
        </strong>
      </span>
      <a class="dev-link" id="dev-link" href={devHref} target="_blank" rel="noopener">
        Developer page
      </a>
    </header>
  );
}

function Banner({ s, c }: { s: OperatorState; c: OperatorController }): preact.JSX.Element {
  const b = s.banner;
  const text =
    b === null
      ? ""
      : b.mode === "local"
        ? "Local mode: no login — anyone on this computer may pilot."
        : b.user
          ? `Signed in as ${b.user.name} (${b.user.role.replace("_", " ")})`
          : "Watching without login";
  return (
    <p id="mode-banner" class="banner" data-testid="mode-banner" data-mode={b?.mode ?? "unknown"} hidden={b === null}>
      <span id="mode-text">{text}</span>{" "}
      <a id="sign-out" href="/login.html" hidden={b === null || b.mode === "local"} onClick={() => c.signOut()}>
        {b?.user ? "Sign out" : "Log in"}
      </a>
    </p>
  );
}

/** On an SD-card image whose last update was rolled back: what happened and why. */
function FirmwareNotice(): preact.JSX.Element | null {
  const [notice, setNotice] = useState<string | null>(null);
  useEffect(() => {
    void fetchRollbackNotice().then(setNotice);
  }, []);
  if (notice === null) return null;
  return (
    <p id="firmware-notice" class="banner firmware-notice" data-testid="firmware-notice" role="alert">
      {notice}
    </p>
  );
}

function StopBanner({ s }: { s: OperatorState }): preact.JSX.Element | null {
  if (s.lastStop === null) return null;
  const age = Date.now() - s.lastStop.at;
  if (age > 5000) return null;
  return (
    <div class="stop-banner" data-testid="stop-banner" role="alert">
      Stopped: {s.lastStop.reason}
    </div>
  );
}

export function App({ controller }: { controller: OperatorController }): preact.JSX.Element {
  const s = useStore(controller.store);
  const mode = stickMode(s.control?.mode ?? "motion");
  return (
    <div class="page" data-input={s.inputMode}>
      <Header s={s} />
      <Banner s={s} c={controller} />
      <FirmwareNotice />
      <main class="layout">
        <div class="view-column">
          <Camera camera={s.camera} rotation={s.rotation} status={s.telemetry?.camera_status ?? null}>
            <Hud s={s} />
            <StopBanner s={s} />
            {s.inputMode === "touch" && <TouchPad controller={controller} touch={s.touch} mode={mode} />}
          </Camera>
          <div class="readout-grid">
            <NavigationPanel s={s} />
            <ThrusterPanel thrusters={s.telemetry?.thrusters ?? null} />
            <CommandPanel s={s} />
            <CrewPanel s={s} />
          </div>
        </div>
        <aside class="side-column">
          {s.fleet.length > 1 ? <FleetPanel s={s} /> : null}
          <HelmPanel s={s} c={controller} />
          <ArduSubPanel s={s} c={controller} />
          <InputPanel s={s} c={controller} />
          <SettingsPanel s={s} c={controller} />
        </aside>
      </main>
      <footer class="bar bottom">
        <p id="message" class="message" data-testid="message" role="alert" data-kind={s.message.kind}>
          {s.message.text}
        </p>
        <p class="help">
          Request control, then fly with the selected input. Leaving the window, hiding the page or changing the input mode stops the vehicle.
        </p>
      </footer>
    </div>
  );
}
