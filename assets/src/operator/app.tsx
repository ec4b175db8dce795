/** The operator page (Preact): header, camera with HUD and touch sticks, side panels, readouts. */

import { stickMode } from "../input/demand";
import type { Thrusters } from "../lib/protocol";
import { ageText } from "../lib/clock";
import { PLACEHOLDER, formatFixed, formatHeading } from "../lib/units";
import { useStore } from "../lib/use_store";
import type { OperatorController, OperatorState } from "./controller";
import { overviewRows } from "./fleet";
import { barGeometry, downFor, fmt, formatDeg, vehicleHref, vehicleLabel } from "./format";
import { Camera, Hud } from "./hud";
import { HelmPanel, InputPanel, Panel, SettingsPanel } from "./panels";
import { TouchPad } from "./touchpad";
import { VideoHealthLine, VideoLatency } from "../video/view";

const THRUSTERS = ["port", "vertical", "starboard"] as const;

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

/**
 * Every vehicle of the fleet with depth, heading, pilot, link, REC, node and status, live;
 * a click or a tap opens it (`?vehicle=ID`). Rows are links: big enough for a finger.
 */
function FleetOverview({ s }: { s: OperatorState }): preact.JSX.Element {
  const rows = overviewRows(s.fleet, s.vehicleId, window.location.search);
  return (
    <Panel title="Fleet" id="fleet">
      <ul class="fleet-list" id="fleet-overview" data-testid="fleet-overview">
        {rows.map((r) => (
          <li key={r.id}>
            <a
              class="fleet-row"
              href={r.href}
              data-vehicle={r.id}
              data-status={r.status}
              aria-current={r.current ? "page" : undefined}
              title={r.summary}
            >
              <span class="fleet-name">
                <strong>{r.id}</strong> <small class="fleet-node">{r.node}</small>
                {r.rec ? (
                  <span class="fleet-rec" data-testid="fleet-rec">
                    {" "}
                    REC
                  </span>
                ) : null}
              </span>
              {r.status === "unreachable" ? (
                <span class="fleet-status" data-field="status">
                  unreachable
                </span>
              ) : (
                <span class="fleet-fields">
                  <span data-field="depth">{r.depth}</span>
                  <span data-field="heading">{r.heading}</span>
                  <span data-field="pilot">{r.pilot}</span>
                  <span data-field="link" data-up={r.linkUp === null ? undefined : String(r.linkUp)}>
                    link {r.link}
                  </span>
                </span>
              )}
            </a>
          </li>
        ))}
      </ul>
    </Panel>
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

function Readout(props: { label: string; id: string; value: string; unit?: string }): preact.JSX.Element {
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

function Navigation({ s }: { s: OperatorState }): preact.JSX.Element {
  const t = s.telemetry;
  const est = t?.estimate ?? null;
  const age = ageText(s.telemetryState, s.telemetryAgeMs);
  return (
    <Panel title="Navigation" id="nav">
      <dl class="readouts">
        <Readout label="Heading" id="heading" value={t ? formatHeading(t.measurement.heading) : PLACEHOLDER} unit="°" />
        <Readout label="Depth" id="depth" value={t ? formatFixed(t.measurement.depth, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Roll" id="roll" value={formatDeg(t?.measurement.roll, true)} unit="°" />
        <Readout label="Pitch" id="pitch" value={formatDeg(t?.measurement.pitch, true)} unit="°" />
        <Readout label="Position x" id="x" value={t?.sim ? formatFixed(t.sim.x, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Position y" id="y" value={t?.sim ? formatFixed(t.sim.y, 2) : PLACEHOLDER} unit="m" />
        <Readout label="Speed u" id="speed-u" value={t?.sim ? formatFixed(t.sim.u, 2) : PLACEHOLDER} unit="m/s" />
        <Readout label="Voltage" id="voltage" value={fmt(t?.measurement.voltage, 1)} unit="V" />
        <Readout label="Current" id="current" value={fmt(t?.measurement.current, 2)} unit="A" />
        {est && <Readout label="Est. depth rate" id="depth-rate" value={fmt(est.depth_rate, 2, true)} unit="m/s" />}
        {t?.wild_points && <Readout label="Wild points" id="wild-points" value={String(t.wild_points.total)} />}
        <div>
          <dt>Telemetry</dt>
          <dd>
            <span id="telemetry-age" data-testid="telemetry-age" data-state={s.telemetryState}>
              {age}
            </span>
          </dd>
        </div>
      </dl>
    </Panel>
  );
}

function ThrusterPanel({ thrusters }: { thrusters: Thrusters | null }): preact.JSX.Element {
  return (
    <Panel title="Thrusters" id="thr">
      <ul class="thrusters">
        {THRUSTERS.map((name) => {
          const value = thrusters ? thrusters[name] : Number.NaN;
          const us = thrusters ? thrusters[`${name}_us`] : Number.NaN;
          const g = barGeometry(Number.isFinite(value) ? value : 0);
          return (
            <li key={name}>
              <span class="label">{name[0]?.toUpperCase() + name.slice(1)}</span>
              <span class="meter" aria-hidden="true">
                <span class={g.reverse ? "fill reverse" : "fill"} id={`bar-${name}`} style={{ left: `${g.left}%`, width: `${g.width}%` }} />
              </span>
              <span class="value" id={`thr-${name}`} data-testid={`thr-${name}`} data-value={String(value)} title={`${Math.round(us)} µs`}>
                {formatFixed(value, 2, true)}
              </span>
            </li>
          );
        })}
      </ul>
    </Panel>
  );
}

function CommandPanel({ s }: { s: OperatorState }): preact.JSX.Element {
  const t = s.telemetry;
  const cmd = t?.command ?? null;
  const manual = t?.manual ?? null;
  return (
    <Panel title="Command" id="cmd">
      <dl class="readouts">
        <Readout label="Surge" id="cmd-surge" value={cmd ? formatFixed(cmd.surge, 2, true) : PLACEHOLDER} />
        <Readout label="Heave" id="cmd-heave" value={cmd ? formatFixed(cmd.heave, 2, true) : PLACEHOLDER} />
        <Readout label="Yaw" id="cmd-yaw" value={cmd ? formatFixed(cmd.yaw, 2, true) : PLACEHOLDER} />
        {manual && <Readout label="Manual" id="cmd-manual" value={`P ${fmt(manual.port, 2, true)} V ${fmt(manual.vertical, 2, true)} S ${fmt(manual.starboard, 2, true)}`} />}
        <Readout label="Mode" id="control-mode" value={s.control?.mode ?? "motion"} />
      </dl>
    </Panel>
  );
}

function Crew({ s }: { s: OperatorState }): preact.JSX.Element {
  return (
    <Panel title="Crew" id="crew">
      <ul class="crew-list" data-testid="crew-list">
        {s.presence.map((e) => (
          <li key={e.key} data-pilot={e.pilot}>
            <span class="crew-mark" aria-hidden="true">{e.pilot ? "● " : "○ "}</span>
            {e.name}
            {e.role ? <small> {e.role.replace("_", " ")}</small> : null}
            {e.connections > 1 ? <small> ×{e.connections}</small> : null}
          </li>
        ))}
      </ul>
    </Panel>
  );
}

/** A mavlink (ArduSub) vehicle's own state — link, armed, flight mode — and, for the pilot, Arm / Disarm. */
function VehiclePanel({ s, c }: { s: OperatorState; c: OperatorController }): preact.JSX.Element | null {
  const m = s.link?.mavlink;
  if (!s.link || !m) return null;
  const pilot = s.helm.me === "pilot";
  return (
    <Panel title="ArduSub" id="ardusub">
      <dl class="readouts">
        <Readout label="Link" id="vehicle-link" value={s.link.up ? "up" : `down${s.link.reason ? ` (${s.link.reason})` : ""}`} />
        <div>
          <dt>State</dt>
          <dd>
            <strong id="armed" data-testid="armed" data-armed={String(m.armed)}>
              {m.armed ? "ARMED" : "disarmed"}
            </strong>
          </dd>
        </div>
        <Readout label="Mode" id="vehicle-mode" value={m.mode ?? PLACEHOLDER} />
      </dl>
      <div class="helm-actions" hidden={!pilot}>
        <button type="button" id="arm" data-testid="arm" disabled={m.armed || !s.link.up} onClick={() => c.arm(true)}>
          Arm
        </button>
        <button type="button" id="disarm" data-testid="disarm" disabled={!m.armed} onClick={() => c.arm(false)}>
          Disarm
        </button>
      </div>
    </Panel>
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
      <main class="layout">
        <div class="view-column">
          <Camera camera={s.camera} rotation={s.rotation} status={s.telemetry?.camera_status ?? null} video={controller.video}>
            <Hud s={s} video={<VideoLatency player={controller.video} />} />
            <StopBanner s={s} />
            {s.inputMode === "touch" && <TouchPad controller={controller} touch={s.touch} mode={mode} />}
          </Camera>
          {s.camera?.video != null && <VideoHealthLine player={controller.video} onSnapshot={() => controller.snapshot()} />}
          <div class="readout-grid">
            <Navigation s={s} />
            <ThrusterPanel thrusters={s.telemetry?.thrusters ?? null} />
            <CommandPanel s={s} />
            <Crew s={s} />
          </div>
        </div>
        <aside class="side-column">
          {s.fleet.length > 1 ? <FleetOverview s={s} /> : null}
          <HelmPanel s={s} c={controller} />
          <VehiclePanel s={s} c={controller} />
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
