/**
 * The camera area and the head-up display over it: compass tape (heading and the autopilot's
 * heading bug), depth with its setpoint, attitude (roll/pitch), power and link.
 */

import type { ComponentChildren } from "preact";
import { useEffect, useState } from "preact/hooks";
import { bugPosition, compassTicks } from "../lib/compass";
import { formatMs } from "../lib/latency";
import type { Rotation } from "../lib/prefs";
import type { BoardLinkDetails, CameraInfo, CameraStatus, RecordingStatus } from "../lib/protocol";
import { formatHeading, headingDeg, radToDeg } from "../lib/units";
import type { OperatorState } from "./controller";
import { DEPTH_TOLERANCE, HEADING_TOLERANCE, movingReference } from "./reference";
import type { MeasurementState } from "../lib/protocol";
import {
  CAMERA_RETRY_MS,
  barGeometry,
  boardLinkText,
  cameraElement,
  fmt,
  measurementDeg,
  measurementHeading,
  measurementText,
  retryUrl,
  showsUnit,
} from "./format";

const TAPE_SPAN = 120;
/**
 * Degrees at each edge of the tape without labels: 8° of 120 is 6.7 % of the tape, at least
 * 20 px on the narrowest tape (min(36rem, 70 %) of a tablet's camera), more than half the
 * widest label ("345", "NW" at 0.7rem).
 */
const LABEL_MARGIN = 8;

export function CompassTape(props: {
  heading: number | null;
  setpoint: number | null;
  state?: MeasurementState | undefined;
}): preact.JSX.Element {
  const heading = props.heading === null ? Number.NaN : headingDeg(props.heading);
  const setpoint = props.setpoint === null ? null : headingDeg(props.setpoint);
  const ticks = compassTicks(heading, TAPE_SPAN, 5, LABEL_MARGIN);
  const bug = bugPosition(heading, setpoint, TAPE_SPAN);
  const pos = (offset: number): string => `${50 + (offset / TAPE_SPAN) * 100}%`;
  return (
    <div class="compass" data-testid="compass" role="img" aria-label={`heading ${formatHeading(props.heading ?? Number.NaN)} degrees`}>
      {ticks.map((t) => (
        <span key={t.deg} class={t.major ? "tick major" : "tick"} style={{ left: pos(t.offset) }}>
          {t.label !== null && <span class="tick-label">{t.label}</span>}
        </span>
      ))}
      {bug && (
        <span
          class={bug.clamped ? "bug clamped" : "bug"}
          data-testid="heading-bug"
          style={{ left: pos(bug.offset) }}
          title={`heading setpoint ${setpoint?.toFixed(1) ?? ""}°`}
        />
      )}
      <span class="lubber" aria-hidden="true" />
      <span class="compass-readout" id="hud-heading" data-testid="hud-heading" data-state={props.state ?? "valid"}>
        {measurementHeading(props.heading, props.state)}
        {showsUnit(props.state) ? "°" : ""}
      </span>
    </div>
  );
}

export function Attitude(props: {
  roll: number;
  pitch: number;
  rollState?: MeasurementState | undefined;
  pitchState?: MeasurementState | undefined;
}): preact.JSX.Element {
  const roll = Number.isFinite(props.roll) ? radToDeg(props.roll) : 0;
  const pitch = Number.isFinite(props.pitch) ? radToDeg(props.pitch) : 0;
  // the horizon moves opposite to the vehicle: 1° of pitch = 1.5 % of the gauge
  const shift = Math.max(-45, Math.min(45, pitch * 1.5));
  return (
    <div class="attitude" title="attitude (roll, pitch)">
      <div class="horizon" style={{ transform: `rotate(${-roll}deg) translateY(${shift}%)` }} />
      <span class="wings" aria-hidden="true" />
      <div class="attitude-text">
        <span>
          roll <b id="hud-roll" data-testid="hud-roll">{measurementDeg(props.roll, props.rollState, true)}</b>
          {showsUnit(props.rollState) ? "°" : ""}
        </span>
        <span>
          pitch <b id="hud-pitch" data-testid="hud-pitch">{measurementDeg(props.pitch, props.pitchState, true)}</b>
          {showsUnit(props.pitchState) ? "°" : ""}
        </span>
      </div>
    </div>
  );
}

function HudBox(props: { title: string; children: ComponentChildren; class?: string }): preact.JSX.Element {
  return (
    <div class={`hud-box ${props.class ?? ""}`}>
      <span class="hud-title">{props.title}</span>
      {props.children}
    </div>
  );
}

export function Camera(props: {
  camera: CameraInfo | null;
  rotation: Rotation;
  /** the server's word on the camera (from telemetry) */
  status?: CameraStatus | null;
  children?: ComponentChildren;
}): preact.JSX.Element {
  const { camera, rotation } = props;
  const down = props.status && !props.status.running && props.status.error !== null ? props.status.error : null;
  const style = { transform: `rotate(${rotation}deg)` };
  return (
    <div class="camera" data-testid="camera" data-rotation={rotation} data-camera={camera ? "on" : "none"}>
      {camera === null ? (
        <div class="no-camera" data-testid="no-camera">
          <strong>No camera</strong>
          <span>This vehicle publishes no video stream.</span>
        </div>
      ) : camera.url === null ? (
        <div class="no-camera" data-testid="no-camera">
          <strong>No picture</strong>
          <span>This page cannot show the camera's {camera.codec === "h264" ? "H.264" : camera.codec} stream.</span>
        </div>
      ) : cameraElement(camera.url) === "video" ? (
        <video class="feed" src={camera.url} style={style} autoplay muted playsInline />
      ) : (
        <ImageFeed key={camera.url} url={camera.url} style={style} />
      )}
      {camera !== null && down !== null && (
        <div class="camera-lost camera-down" data-testid="camera-down" role="status">
          Camera: {down}
        </div>
      )}
      {props.children}
    </div>
  );
}

/** An MJPEG/JPEG feed that says so when the stream breaks and asks for it again every 3 s. */
function ImageFeed(props: { url: string; style: { transform: string } }): preact.JSX.Element {
  const [attempt, setAttempt] = useState(0);
  const [failed, setFailed] = useState(false);
  useEffect(() => {
    if (!failed) return undefined;
    const timer = window.setTimeout(() => {
      setFailed(false);
      setAttempt((a) => a + 1);
    }, CAMERA_RETRY_MS);
    return () => window.clearTimeout(timer);
  }, [failed]);
  return (
    <>
      <img
        class="feed"
        src={retryUrl(props.url, attempt)}
        style={props.style}
        alt="camera image"
        draggable={false}
        onError={() => setFailed(true)}
      />
      {failed && (
        <div class="camera-lost" data-testid="camera-lost" role="status">
          Camera stream interrupted — retrying…
        </div>
      )}
    </>
  );
}

/** "● REC" while the server records the vehicle, "not recording" (and why) when it does not; the camera's frame rate. */
function RecCamera(props: { recording: RecordingStatus | null; camera: CameraStatus | null }): preact.JSX.Element | null {
  const { recording, camera } = props;
  if (recording === null && camera === null) return null;
  return (
    <span class="hud-rec">
      {recording !== null && (
        <span
          data-testid="hud-recording"
          data-state={recording.on ? "on" : recording.error !== null ? "error" : "off"}
          title={recording.error ?? (recording.on ? "the server records everything this vehicle sends" : "recording is off on this server")}
        >
          {recording.on ? "● REC" : recording.error !== null ? "⚠ not recording" : "not recording"}
        </span>
      )}
      {camera !== null && (
        <span data-testid="hud-camera" data-state={camera.running && camera.fps > 0 ? "on" : "off"} title={camera.error ?? ""}>
          {recording !== null ? " · " : ""}
          {camera.running && camera.fps > 0 ? `cam ${camera.fps} fps` : "cam ✗"}
        </span>
      )}
    </span>
  );
}

/** The board link's liveness and warnings (see boardLinkText). */
function BoardLink(props: { details: BoardLinkDetails }): preact.JSX.Element {
  const { summary, warnings } = boardLinkText(props.details);
  return (
    <>
      <span data-testid="hud-board-link">{summary}</span>
      {warnings.map((w) => (
        <span key={w} class="hud-warn" data-testid="hud-board-warning">
          {w}
        </span>
      ))}
    </>
  );
}

export function Hud(props: { s: OperatorState }): preact.JSX.Element {
  const { s } = props;
  const t = s.telemetry;
  const m = t?.measurement;
  const ms = t?.measurement_state ?? null;
  const ap = s.control?.autopilot ?? null;
  const apStatus = t?.autopilot ?? null;
  const headingSp = ap?.heading ?? apStatus?.heading?.setpoint ?? null;
  const depthSp = ap?.depth ?? apStatus?.depth?.setpoint ?? null;
  // the reference the autopilot tracks, shown while it is on its way to the setpoint
  const depthRef = movingReference(apStatus?.depth ?? null, DEPTH_TOLERANCE, false);
  const headingRef = movingReference(apStatus?.heading ?? null, HEADING_TOLERANCE, true);
  const link = s.link;
  return (
    <div class="hud" data-stale={s.telemetryState !== "live"}>
      <CompassTape heading={m ? m.heading : null} setpoint={headingSp} state={ms?.heading} />
      <div class="hud-left">
        <Attitude roll={m?.roll ?? Number.NaN} pitch={m?.pitch ?? Number.NaN} rollState={ms?.roll} pitchState={ms?.pitch} />
        <HudBox title="Crew">
          <span data-testid="hud-pilot">pilot {s.pilotName ?? "nobody"}</span>
          <span>{s.presence.reduce((n, e) => n + e.connections, 0)} watching</span>
        </HudBox>
        <HudBox title="Power">
          <span>
            <b data-testid="hud-voltage">{measurementText(m?.voltage, ms?.voltage, 1)}</b>
            {showsUnit(ms?.voltage) ? " V" : ""} · <b data-testid="hud-current">{measurementText(m?.current, ms?.current, 2)}</b>
            {showsUnit(ms?.current) ? " A" : ""}
          </span>
        </HudBox>
      </div>
      <div class="hud-right">
        <HudBox title="Depth" class="depth-box">
          <span class="big">
            <b data-testid="hud-depth" data-state={ms?.depth ?? "valid"}>
              {measurementText(m?.depth, ms?.depth, 2)}
            </b>
            {showsUnit(ms?.depth) ? " m" : ""}
          </span>
          <span class="setpoint" data-testid="hud-depth-setpoint">
            {depthSp === null ? "autopilot off" : `set ${fmt(depthSp, 2)} m`}
          </span>
          {depthRef !== null ? (
            <span class="setpoint" data-testid="hud-depth-reference">
              → now {fmt(depthRef, 2)} m
            </span>
          ) : null}
          {apStatus?.depth?.waiting ? (
            <span class="setpoint warn" data-testid="hud-depth-waiting">
              {apStatus.depth.waiting}
            </span>
          ) : null}
        </HudBox>
        <HudBox title="Heading autopilot">
          <span class="setpoint" data-testid="hud-heading-setpoint">
            {headingSp === null ? "off" : `set ${formatHeading(headingSp)}°`}
          </span>
          {headingRef !== null ? (
            <span class="setpoint" data-testid="hud-heading-reference">
              → now {formatHeading(headingRef)}°
            </span>
          ) : null}
          {apStatus?.heading?.waiting ? (
            <span class="setpoint warn" data-testid="hud-heading-waiting">
              {apStatus.heading.waiting}
            </span>
          ) : null}
        </HudBox>
        <HudBox title="Link">
          <span data-testid="hud-link" data-state={s.status === "connected" ? (link && !link.up ? "down" : "up") : "down"}>
            {s.status === "connected" ? "server ✓" : `server ${s.status}`}
            {link ? ` · board ${link.up ? "✓" : `✗ ${link.reason ?? ""}`}` : ""}
          </span>
          {link?.up && link.board ? <BoardLink details={link.board} /> : null}
          <span>
            RTT <b id="rtt" data-testid="rtt">{formatMs(s.latency.mean)}</b>
            <small> (max {formatMs(s.latency.max)})</small>
          </span>
          <RecCamera recording={t?.recording ?? null} camera={t?.camera_status ?? null} />
        </HudBox>
        <HudBox title="Thrusters">
          <span class="hud-thrusters" data-testid="hud-thrusters">
            {(["port", "vertical", "starboard"] as const).map((k) => {
              const v = t?.thrusters[k] ?? Number.NaN;
              const g = barGeometry(Number.isFinite(v) ? v : 0);
              return (
                <span key={k} class="hud-thr">
                  <span class="hud-thr-name">{k[0]?.toUpperCase()}</span>
                  <span class="meter">
                    <span class={g.reverse ? "fill reverse" : "fill"} style={{ left: `${g.left}%`, width: `${g.width}%` }} />
                  </span>
                  <span class="hud-thr-value">{fmt(v, 2, true)}</span>
                </span>
              );
            })}
          </span>
        </HudBox>
      </div>
      {s.telemetryState === "stale" && (
        <div class="hud-stale" role="status">
          telemetry stale ({(s.telemetryAgeMs / 1000).toFixed(1)} s)
        </div>
      )}
    </div>
  );
}
