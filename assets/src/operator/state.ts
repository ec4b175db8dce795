/**
 * The operator page's state and the pure operations on it (the shape of Livebook's
 * `Session.Data`: plain data, and functions that compute the next state from it; here each
 * returns the patch the page's `Store` merges). The page keeps one `OperatorState`; each part
 * of the page (connection.ts, pilot_input.ts, gamepad_buttons.ts, settings_fields.ts,
 * heartbeat.ts, headset.ts) updates its own fields through its host, the reactions
 * (reactions.ts) through the controller's effects, and the panels (panels/) only read it.
 */

import { DEFAULT_MAPPING } from "../input/buttons";
import type { ButtonAction, ButtonMapping } from "../input/buttons";
import type { InputMode, ThrustDemand } from "../input/demand";
import type { GamepadOptions } from "../input/gamepad";
import { TOUCH_REST } from "../input/touch";
import type { TouchState } from "../input/touch";
import type { TelemetryState } from "../lib/clock";
import { seenView } from "../lib/helm";
import type { HelmView } from "../lib/helm";
import { KEPT_LOADING } from "../lib/kept_setting";
import type { KeptStatus } from "../lib/kept_setting";
import type { LatencySummary } from "../lib/latency";
import type { Rotation } from "../lib/prefs";
import type { AuthMode, CameraInfo, ControlSettings, LinkStatus, Mission, PresenceEntry, Role, Telemetry, VehicleInfo } from "../lib/protocol";
import type { ConnectionStatus } from "../lib/vehicle_client";
import { HEADSET_OFF } from "./headset";
import { NO_TRACK } from "./map";
import type { MapPoint, Track } from "./map";
import type { HeadsetState } from "./headset";
import { INITIAL_REACTIONS } from "./reactions";
import type { MessageKind } from "./reactions";

export type { TelemetryState };

/** The fields of the settings panel (and the headset's), each with a status beside it. */
export type FieldName =
  | "control_mode"
  | "run_mode"
  | "depth"
  | "heading"
  | "gain"
  | "lights"
  | "laser"
  | "tilt"
  | "rotation"
  | "headset";

export interface FieldStatus {
  readonly state: "busy" | "ok" | "error";
  readonly text: string;
}

export interface Message {
  readonly text: string;
  readonly kind: MessageKind;
  /** who said it (`helm`, `command`, `session`…): a later success clears only its own kind */
  readonly source: string | null;
}

export interface OperatorState {
  readonly status: ConnectionStatus;
  /** when the connection was lost (ms, performance clock), for "reconnecting for N s" */
  readonly disconnectedAt: number | null;
  readonly vehicleId: string | null;
  /**
   * the body-frame axes the vehicle can be commanded in (its snapshot's, then telemetry's
   * `axes`): the inputs offer these and the page shows them; null until joined (then: surge,
   * heave, yaw)
   */
  readonly axes: readonly string[] | null;
  /** every vehicle of the fleet, for the picker (empty until listed) */
  readonly fleet: readonly VehicleInfo[];
  readonly banner: { readonly mode: AuthMode; readonly user: { readonly name: string; readonly role: Role } | null } | null;
  readonly helm: HelmView;
  readonly pilotName: string | null;
  readonly presence: readonly PresenceEntry[];
  readonly telemetry: Telemetry | null;
  readonly telemetryState: TelemetryState;
  readonly telemetryAgeMs: number;
  readonly control: ControlSettings | null;
  readonly link: LinkStatus | null;
  readonly latency: LatencySummary;
  readonly camera: CameraInfo | null;
  readonly rotation: Rotation;
  readonly inputMode: InputMode;
  readonly gamepad: { readonly id: string; readonly armed: boolean } | null;
  readonly gamepadOptions: GamepadOptions;
  readonly buttonMapping: ButtonMapping;
  /** where the button mapping stands: read from the server, saved, or why not */
  readonly mappingStatus: KeptStatus;
  /** the action the editor assigns to the next button pressed (null: none) */
  readonly learning: ButtonAction | null;
  /** the last button pressed and what it did */
  readonly lastPress: { readonly button: number; readonly action: ButtonAction | null } | null;
  readonly touch: TouchState;
  readonly headset: HeadsetState;
  /** the last demand this page sent */
  readonly sent: ThrustDemand | null;
  readonly message: Message;
  readonly fields: Readonly<Partial<Record<FieldName, FieldStatus>>>;
  /** the last stop the vehicle made (reason, ms since the epoch) */
  readonly lastStop: { readonly reason: string; readonly at: number } | null;
  /** the mission in dp with its waypoints (the `mission` event, the snapshot); null: none */
  readonly mission: Mission | null;
  /** where the vehicle has been, in its position's frame (map.ts) */
  readonly track: Track;
  /** the waypoints the pilot is planning on the map, not yet sent */
  readonly plan: readonly MapPoint[];
}

/** No round trip measured yet. */
export const NO_LATENCY: LatencySummary = Object.freeze({ last: null, mean: null, max: null, samples: 0 });

const NO_MESSAGE: Message = Object.freeze({ text: "", kind: "info", source: null });

/** The page before it has connected: the operator's input mode and pad options come from the browser. */
export function initialState(inputMode: InputMode, gamepadOptions: GamepadOptions): OperatorState {
  return {
    status: "connecting",
    disconnectedAt: null,
    vehicleId: null,
    axes: null,
    fleet: [],
    banner: null,
    helm: seenView(INITIAL_REACTIONS.helm, 0),
    pilotName: null,
    presence: [],
    telemetry: null,
    telemetryState: "none",
    telemetryAgeMs: 0,
    control: null,
    link: null,
    latency: NO_LATENCY,
    camera: null,
    rotation: 0,
    inputMode,
    gamepad: null,
    gamepadOptions,
    buttonMapping: DEFAULT_MAPPING,
    mappingStatus: KEPT_LOADING,
    learning: null,
    lastPress: null,
    touch: TOUCH_REST,
    headset: HEADSET_OFF,
    sent: null,
    message: NO_MESSAGE,
    fields: {},
    lastStop: null,
    mission: null,
    track: NO_TRACK,
    plan: [],
  };
}

/** The control mode the vehicle is in: its telemetry's, else its settings', else motion. */
export function controlModeOf(s: Pick<OperatorState, "telemetry" | "control">): string {
  return s.telemetry?.control?.mode ?? s.control?.mode ?? "motion";
}

/**
 * The connection's status at `nowMs` (monotonic): `disconnectedAt` is when it was last lost,
 * kept while it stays lost (reconnecting attempts do not restart the count).
 */
export function withStatus(s: Pick<OperatorState, "status" | "disconnectedAt">, status: ConnectionStatus, nowMs: number): Pick<OperatorState, "status" | "disconnectedAt"> {
  const lostNow = s.status === "connected" || s.disconnectedAt === null;
  return { status, disconnectedAt: status === "connected" ? null : lostNow ? nowMs : s.disconnectedAt };
}

/** A field's status beside it. */
export function withField(s: Pick<OperatorState, "fields">, field: FieldName, state: FieldStatus["state"], text: string): Pick<OperatorState, "fields"> {
  return { fields: { ...s.fields, [field]: { state, text } } };
}

export function withMessage(text: string, kind: MessageKind, source: string | null = null): Pick<OperatorState, "message"> {
  return { message: { text, kind, source } };
}

/** The message cleared if `source` said it (another's stays). */
export function withoutMessage(s: Pick<OperatorState, "message">, source: string): Partial<Pick<OperatorState, "message">> {
  return s.message.source === source ? { message: NO_MESSAGE } : {};
}

/**
 * A telemetry frame and its freshness: the control settings, the board link and the axes the
 * pilot may command (they change once an ArduSub vehicle's frame is known, and in run mode
 * simulator) it carries replace the page's (an older server's frame without them leaves those
 * as they were).
 */
export function withTelemetry(t: Telemetry, fresh: { readonly telemetryState: TelemetryState; readonly telemetryAgeMs: number }): Partial<OperatorState> {
  return {
    telemetry: t,
    ...fresh,
    ...(t.control ? { control: t.control } : {}),
    ...(t.link ? { link: t.link } : {}),
    ...(t.axes ? { axes: t.axes } : {}),
  };
}
