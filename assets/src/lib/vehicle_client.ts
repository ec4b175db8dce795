/**
 * Typed wrapper around the official phoenix client for the Neptunus channels.
 *
 * - `NeptunusClient` owns the Socket (`/socket`, params `{name}` in local mode, `{token}` after
 *   a login — in the query string: yaws has no WebSocket subprotocols).
 * - `fleet()` joins `fleet` and resolves with the vehicle list; `FleetHandlers` get its
 *   updates (`vehicles`, `unreachable`, `reachable`) while joined.
 * - `vehicle(id)` gives a `VehicleChannel` for `vehicle:<id>`: join → snapshot, telemetry,
 *   helm, presence and the helm's events for this connection (`control_request`,
 *   `control_granted`, `control_lost`, `request_denied`), and commands (`thrust`, `stop`,
 *   `heartbeat`, `requestControl`, `answerRequest`, `takeControl`, `releaseControl`) as
 *   Promises that reject with a `CommandError` carrying the server's readable reason.
 *
 * Commands are only sent while the channel is joined: the phoenix client would otherwise buffer
 * them and deliver them up to a push timeout later, and a late thrust command is worse than none.
 */

import { Presence, Socket } from "phoenix";
import type { Channel, Push, SocketConnectOption } from "phoenix";
import type { ClockSample } from "./clock";
import {
  decodeClock,
  decodeControlReply,
  decodeControlUpdate,
  decodeLinkStatus,
  decodeVehicleSettings,
  decodeFleetReply,
  decodeGrant,
  decodeHelm,
  decodeTelemetry,
  decodeThrustReply,
  decodeVehicleSnapshot,
  errorReason,
  presenceEntry,
} from "./protocol";
import * as wire from "./wire.gen";
import type {
  ControlMode,
  ControlReply,
  ControlSettings,
  LinkStatus,
  RunMode,
  ThrusterOutputs,
  FleetReply,
  Grant,
  Helm,
  MotionCommand,
  Party,
  PresenceEntry,
  Telemetry,
  ThrustReply,
  VehicleInfo,
  VehicleSettings,
  VehicleSnapshot,
} from "./protocol";

export type ConnectionStatus = "connecting" | "connected" | "disconnected";

/** The commands of topic `vehicle:<id>` (the wire schema's): the only events a page pushes. */
export type Command = keyof wire.VehicleCommands;

export type CommandErrorKind = "error" | "timeout" | "not_joined" | "bad_reply";

/** A refused or failed command; `reason` is the server's text (e.g. "not_in_control"). */
export class CommandError extends Error {
  readonly reason: string;
  readonly kind: CommandErrorKind;

  constructor(reason: string, kind: CommandErrorKind) {
    super(reason);
    this.name = "CommandError";
    this.reason = reason;
    this.kind = kind;
  }
}

export const DEFAULT_JOIN_TIMEOUT_MS = 5000;
export const DEFAULT_COMMAND_TIMEOUT_MS = 2000;

/** Updates of the fleet's directory (topic `fleet`) after its join reply. */
export interface FleetHandlers {
  /** the whole list, when it changed (at most once a second) */
  readonly vehicles?: (vehicles: readonly VehicleInfo[]) => void;
  /** vehicle `id`'s node was cut off from the server's (`false`) or is back (`true`) */
  readonly reachability?: (id: string, reachable: boolean) => void;
  readonly protocolError?: (what: string, payload: unknown) => void;
}

export interface NeptunusClientOptions {
  /** Socket endpoint; the client appends `/websocket`. Default "/socket". */
  readonly endpoint?: string;
  /** Display name shown in presence (local mode; a login's token names the user). */
  readonly name?: string;
  /** Login token (`POST /api/login`), sent as the `token` query parameter. */
  readonly token?: string;
  /** WebSocket constructor (the `ws` package in Node). Default: the browser's. */
  readonly transport?: SocketConnectOption["transport"];
}

function awaitPush<T>(
  push: Push,
  decode: (response: unknown) => T | null,
  what: string,
): Promise<T> {
  return new Promise<T>((resolve, reject) => {
    push
      .receive("ok", (response: unknown) => {
        const value = decode(response);
        if (value === null) {
          reject(new CommandError(`unexpected ${what} reply: ${JSON.stringify(response)}`, "bad_reply"));
        } else {
          resolve(value);
        }
      })
      .receive("error", (response: unknown) => {
        reject(new CommandError(errorReason(response), "error"));
      })
      .receive("timeout", () => {
        reject(new CommandError(`no reply to ${what} (timeout)`, "timeout"));
      });
  });
}

export class NeptunusClient {
  readonly socket: Socket;
  private fleetChannel: Channel | null = null;

  constructor(options: NeptunusClientOptions = {}) {
    const params: Record<string, string> = {};
    if (options.name !== undefined) params["name"] = options.name;
    if (options.token !== undefined) params["token"] = options.token;
    const opts: Partial<SocketConnectOption> = { params };
    if (options.transport) opts.transport = options.transport;
    this.socket = new Socket(options.endpoint ?? "/socket", opts);
  }

  connect(): void {
    this.socket.connect();
  }

  disconnect(): Promise<void> {
    return new Promise((resolve) => this.socket.disconnect(() => resolve()));
  }

  /**
   * Joins `fleet` (once: a second call leaves the first) and resolves with its join reply;
   * `handlers` get the directory's updates while it stays joined.
   */
  fleet(timeoutMs = DEFAULT_JOIN_TIMEOUT_MS, handlers: FleetHandlers = {}): Promise<FleetReply> {
    if (this.fleetChannel) this.fleetChannel.leave();
    const channel = this.socket.channel("fleet", {});
    this.fleetChannel = channel;
    channel.on("vehicles", (payload: unknown) => {
      const reply = decodeFleetReply(payload);
      if (reply) handlers.vehicles?.(reply.vehicles);
      else handlers.protocolError?.("vehicles", payload);
    });
    for (const [event, decode, reachable] of [
      ["unreachable", wire.decodeUnreachable, false],
      ["reachable", wire.decodeReachable, true],
    ] as const) {
      channel.on(event, (payload: unknown) => {
        const decoded = decode(payload);
        if (decoded) handlers.reachability?.(decoded.id, reachable);
        else handlers.protocolError?.(event, payload);
      });
    }
    return awaitPush(channel.join(timeoutMs), decodeFleetReply, "fleet join").catch(
      (err: unknown) => {
        // A refused join is retried forever by the client; we asked once.
        channel.leave();
        if (this.fleetChannel === channel) this.fleetChannel = null;
        throw err;
      },
    );
  }

  vehicle(id: string, handlers: VehicleHandlers = {}): VehicleChannel {
    return new VehicleChannel(this.socket, id, handlers);
  }

  /** The developer log of vehicle `id` (topic `log:<id>`); `entry` gets every `log` payload. */
  log(id: string, entry: (payload: unknown) => void): LogTopic {
    return new LogTopic(this.socket, id, entry);
  }

  /**
   * Round trip of the socket's own heartbeat (topic `phoenix`), in ms; rejects when not
   * connected or after `timeoutMs`.
   */
  ping(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<number> {
    return new Promise<number>((resolve, reject) => {
      const timer = setTimeout(() => reject(new CommandError("no reply to ping (timeout)", "timeout")), timeoutMs);
      const sent = this.socket.ping((latency: number) => {
        clearTimeout(timer);
        resolve(latency);
      });
      if (!sent) {
        clearTimeout(timer);
        reject(new CommandError("not connected", "not_joined"));
      }
    });
  }
}

/** Topic `log:<id>` (read-only): the server's log entries for the developer logger. */
export class LogTopic {
  readonly topic: string;
  private readonly channel: Channel;

  constructor(socket: Socket, id: string, entry: (payload: unknown) => void) {
    this.topic = `log:${id}`;
    this.channel = socket.channel(this.topic, {});
    this.channel.on("log", (payload: unknown) => entry(payload));
  }

  /** Joins; rejects with the server's reason (e.g. a server without the log topic). */
  join(timeoutMs = DEFAULT_JOIN_TIMEOUT_MS): Promise<void> {
    return awaitPush(this.channel.join(timeoutMs), () => true, `join ${this.topic}`).then(
      () => undefined,
      (err: unknown) => {
        if (err instanceof CommandError && err.kind === "error") this.channel.leave();
        throw err;
      },
    );
  }

  leave(): void {
    this.channel.leave();
  }
}

/** A mavlink vehicle's answer to `arm`, `disarm` or `autopilot`. */
export interface VehicleAnswer {
  readonly command: string;
  readonly ok: boolean;
  readonly reason: string | null;
}

/** `arm`/`disarm` reply: the vehicle answered (`ok`) or its answer follows (`pending`). */
export type ArmReply = "ok" | "pending";

export interface VehicleHandlers {
  /** Every successful (re)join, with the server's snapshot. */
  readonly snapshot?: (snapshot: VehicleSnapshot) => void;
  readonly telemetry?: (telemetry: Telemetry) => void;
  /** The helm changed (who pilots, requests, takeover countdown, epoch). */
  readonly helm?: (helm: Helm) => void;
  /** We pilot and `from` asks for control: answer with `answerRequest`. */
  readonly controlRequest?: (from: Party) => void;
  /** We got the helm (also after a `granted` reply). */
  readonly controlGranted?: (grant: Grant) => void;
  /** We lost the helm, and why (`released`, `control_transferred`, `main_station_takeover`…). */
  readonly controlLost?: (reason: string) => void;
  /** Our request was refused: `denied`, `request_timeout`, `main_station_takeover`. */
  readonly requestDenied?: (reason: string) => void;
  /** The thrusters were driven neutral (safety or by request), with the server's reason. */
  readonly stopped?: (reason: string) => void;
  /** The board link came up or went down (serial boards). */
  readonly link?: (link: LinkStatus) => void;
  /** A mavlink vehicle's late answer to `arm`/`disarm`/`autopilot` (the reply said pending). */
  readonly vehicleAnswer?: (answer: VehicleAnswer) => void;
  /**
   * The vehicle's node of the fleet was cut off from ours (`false`: no telemetry, commands
   * refused, a pilot here lost control) or is back (`true`); `node` names it.
   */
  readonly reachability?: (reachable: boolean, node: string) => void;
  /** Who is connected to this vehicle (after every presence sync). */
  readonly presence?: (entries: readonly PresenceEntry[]) => void;
  readonly status?: (status: ConnectionStatus) => void;
  /** The vehicle's settings changed (camera rotation): every page applies them. */
  readonly vehicleSettings?: (settings: VehicleSettings) => void;
  /** A payload that does not have the documented shape (ignored otherwise). */
  readonly protocolError?: (what: string, payload: unknown) => void;
}

export class VehicleChannel {
  readonly id: string;
  readonly topic: string;
  private readonly socket: Socket;
  private readonly channel: Channel;
  private readonly handlers: VehicleHandlers;
  private readonly socketRefs: string[];
  private socketOpen: boolean;
  private joinedOnce = false;
  private currentStatus: ConnectionStatus = "connecting";

  constructor(socket: Socket, id: string, handlers: VehicleHandlers) {
    this.id = id;
    this.topic = `vehicle:${id}`;
    this.socket = socket;
    this.handlers = handlers;
    this.socketOpen = socket.isConnected();
    this.channel = socket.channel(this.topic, {});

    this.channel.on("telemetry", (payload: unknown) => {
      const telemetry = decodeTelemetry(payload);
      if (telemetry) handlers.telemetry?.(telemetry);
      else handlers.protocolError?.("telemetry", payload);
    });
    this.channel.on("helm", (payload: unknown) => {
      const helm = decodeHelm(payload);
      if (helm) handlers.helm?.(helm);
      else handlers.protocolError?.("helm", payload);
    });
    this.channel.on("control_request", (payload: unknown) => {
      const request = wire.decodeControlRequest(payload);
      if (request) handlers.controlRequest?.(request.from);
      else handlers.protocolError?.("control_request", payload);
    });
    this.channel.on("control_granted", (payload: unknown) => {
      const grant = decodeGrant(payload);
      if (grant) handlers.controlGranted?.(grant);
      else handlers.protocolError?.("control_granted", payload);
    });
    this.channel.on("control_lost", (payload: unknown) => {
      handlers.controlLost?.(errorReason(payload));
    });
    this.channel.on("request_denied", (payload: unknown) => {
      handlers.requestDenied?.(errorReason(payload));
    });
    this.channel.on("stopped", (payload: unknown) => {
      handlers.stopped?.(errorReason(payload));
    });
    this.channel.on("vehicle_settings", (payload: unknown) => {
      const settings = decodeVehicleSettings(payload);
      if (settings) handlers.vehicleSettings?.(settings);
      else handlers.protocolError?.("vehicle_settings", payload);
    });
    this.channel.on("vehicle_answer", (payload: unknown) => {
      const answer = wire.decodeVehicleAnswer(payload);
      if (answer) handlers.vehicleAnswer?.(answer);
      else handlers.protocolError?.("vehicle_answer", payload);
    });
    for (const [event, decode, reachable] of [
      ["unreachable", wire.decodeUnreachable, false],
      ["reachable", wire.decodeReachable, true],
    ] as const) {
      this.channel.on(event, (payload: unknown) => {
        const decoded = decode(payload);
        if (decoded) handlers.reachability?.(reachable, decoded.node);
        else handlers.protocolError?.(event, payload);
      });
    }
    this.channel.on("link", (payload: unknown) => {
      const link = decodeLinkStatus(payload);
      if (link) handlers.link?.(link);
      else handlers.protocolError?.("link", payload);
    });

    const presence = new Presence(this.channel);
    presence.onSync(() => {
      handlers.presence?.(presence.list((key: string, p: unknown) => presenceEntry(key, p)));
    });

    this.channel.onError(() => this.setStatus(this.socketOpen ? "connecting" : "disconnected"));
    this.channel.onClose(() => this.setStatus("disconnected"));
    this.socketRefs = [
      socket.onOpen(() => {
        this.socketOpen = true;
        this.setStatus(this.joined ? "connected" : "connecting");
      }),
      socket.onClose(() => {
        this.socketOpen = false;
        this.setStatus("disconnected");
      }),
      socket.onError(() => {
        this.socketOpen = false;
        this.setStatus("disconnected");
      }),
    ];
  }

  get status(): ConnectionStatus {
    return this.currentStatus;
  }

  /** True while commands can be sent: socket open and channel joined. */
  get joined(): boolean {
    return this.channel.state === "joined" && this.socket.isConnected();
  }

  /**
   * Joins; resolves with the first snapshot, rejects with a CommandError if the first attempt
   * is refused or times out (the client keeps retrying; later snapshots go to `handlers`).
   */
  join(timeoutMs = DEFAULT_JOIN_TIMEOUT_MS): Promise<VehicleSnapshot> {
    return new Promise<VehicleSnapshot>((resolve, reject) => {
      let settled = false;
      const settle = (f: () => void): void => {
        if (!settled) {
          settled = true;
          f();
        }
      };
      this.channel
        .join(timeoutMs)
        .receive("ok", (response: unknown) => {
          const snapshot = decodeVehicleSnapshot(response);
          if (!snapshot) {
            this.handlers.protocolError?.("join reply", response);
            settle(() => reject(new CommandError("unexpected join reply", "bad_reply")));
            return;
          }
          this.joinedOnce = true;
          this.setStatus("connected");
          this.handlers.snapshot?.(snapshot);
          settle(() => resolve(snapshot));
        })
        .receive("error", (response: unknown) => {
          settle(() => reject(new CommandError(errorReason(response), "error")));
        })
        .receive("timeout", () => {
          settle(() => reject(new CommandError(`no reply to join ${this.topic}`, "timeout")));
        });
    });
  }

  /** Has the channel been joined at least once. */
  get everJoined(): boolean {
    return this.joinedOnce;
  }

  /**
   * Motion command with absolute axes in [-1, 1], stamped with the helm `epoch` of our grant
   * (the server refuses other epochs with `stale_command`).
   */
  thrust(
    command: MotionCommand,
    epoch: number,
    timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS,
  ): Promise<ThrustReply> {
    return this.command(
      "thrust",
      { mode: "motion", surge: command.surge, heave: command.heave, yaw: command.yaw, epoch },
      decodeThrustReply,
      timeoutMs,
    );
  }

  /** Manual-mode thrust: each thruster in [-1, 1], stamped like `thrust`. */
  thrustManual(
    thrusters: ThrusterOutputs,
    epoch: number,
    timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS,
  ): Promise<ThrustReply> {
    const { port, vertical, starboard } = thrusters;
    return this.command(
      "thrust",
      { mode: "manual", port, vertical, starboard, epoch },
      decodeThrustReply,
      timeoutMs,
    );
  }

  /**
   * The pilot's heartbeat (every `heartbeat_ms` while piloting; feeds the deadman). Resolves
   * with the round trip in ms.
   */
  heartbeat(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<number> {
    const sent = performance.now();
    return this.command("heartbeat", {}, () => true, timeoutMs).then(() => performance.now() - sent);
  }

  /**
   * `clock`: the server's wall clock (the clock of telemetry's `sent_at`), with this
   * computer's `Date.now()` before and after, for `ClockOffset` (lib/clock.ts). Anyone joined.
   */
  clock(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<ClockSample> {
    const sentAt = Date.now();
    return this.command("clock", {}, decodeClock, timeoutMs).then((serverNow) => ({ sentAt, serverNow, receivedAt: Date.now() }));
  }

  /** `set_control_mode {mode}`: motion, manual or dp. */
  setControlMode(mode: ControlMode): Promise<ControlSettings> {
    return this.setting("set_control_mode", { mode });
  }

  /** `set_run_mode {mode}`: normal or simulator. */
  setRunMode(mode: RunMode): Promise<ControlSettings> {
    return this.setting("set_run_mode", { mode });
  }

  /**
   * `set_gain`, `set_lights`, `set_laser`, `set_tilt` with `{value}`. The value goes as typed
   * (a number, or the text when it is not one) so the server's reason names what is wrong.
   */
  setValue(event: "set_gain" | "set_lights" | "set_laser" | "set_tilt", value: number | string): Promise<ControlSettings> {
    return this.setting(event, { value });
  }

  /** `autopilot {depth?, heading?}`: m / rad, "hold" (the current value) or null (off). */
  autopilot(setpoints: {
    readonly depth?: number | string | null;
    readonly heading?: number | string | null;
  }): Promise<ControlSettings> {
    return this.setting("autopilot", setpoints);
  }

  /** Asks for control: granted at once on a free helm, else pending the pilot's answer. */
  requestControl(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<ControlReply> {
    return this.command("request_control", {}, decodeControlReply, timeoutMs).then((reply) => {
      if (reply.status === "granted") this.handlers.controlGranted?.(reply.grant);
      return reply;
    });
  }

  /** The main station takes control (after the server's warning countdown). */
  takeControl(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<ControlReply> {
    return this.command("take_control", {}, decodeControlReply, timeoutMs).then((reply) => {
      if (reply.status === "granted") this.handlers.controlGranted?.(reply.grant);
      return reply;
    });
  }

  /** The pilot answers a control request. */
  answerRequest(accept: boolean, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<void> {
    return this.command("answer_request", { accept }, () => true, timeoutMs).then(() => undefined);
  }

  /** Gives the helm up (or withdraws our request / cancels our takeover). */
  releaseControl(timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<void> {
    return this.command("release_control", {}, () => true, timeoutMs).then(() => undefined);
  }

  /** All thrusters neutral; `reason` (1..100 bytes) is shown to everyone watching. */
  stop(reason?: string, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<void> {
    const payload = reason === undefined ? {} : { reason };
    return this.command("stop", payload, () => true, timeoutMs).then(() => undefined);
  }

  /**
   * Arms (`true`) or disarms a mavlink vehicle (pilot only). Resolves `ok` when the vehicle
   * accepted, `pending` when its answer follows as `vehicleAnswer`; rejects with its reason.
   */
  arm(arm: boolean, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<ArmReply> {
    const decode = (r: unknown): ArmReply | null => wire.decodeVehicleRequest(r)?.status ?? null;
    return this.command(arm ? "arm" : "disarm", {}, decode, timeoutMs);
  }

  /** Leaves the channel and forgets the socket callbacks. */
  leave(timeoutMs = 1000): Promise<void> {
    this.socket.off(this.socketRefs);
    return new Promise((resolve) => {
      this.channel
        .leave(timeoutMs)
        .receive("ok", () => resolve())
        .receive("timeout", () => resolve());
    });
  }

  /** The camera rotation of this vehicle, for every page (the pilot or the main station). */
  setCameraRotation(degrees: number): Promise<VehicleSettings> {
    return this.command("set_camera_rotation", { value: degrees }, decodeVehicleSettings, DEFAULT_COMMAND_TIMEOUT_MS);
  }

  /**
   * A request on the vehicle's topic whose reply `decode` reads (null: unexpected reply):
   * the autopilot tuning events `get_tuning`, `step_response`, `set_tuning`.
   */
  request<T>(event: Command, payload: object, decode: (response: unknown) => T | null, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<T> {
    return this.command(event, payload, decode, timeoutMs);
  }

  private setting(event: Command, payload: object): Promise<ControlSettings> {
    return this.command(event, payload, decodeControlUpdate, DEFAULT_COMMAND_TIMEOUT_MS);
  }

  private command<T>(
    event: Command,
    payload: object,
    decode: (response: unknown) => T | null,
    timeoutMs: number,
  ): Promise<T> {
    if (!this.joined) {
      return Promise.reject(new CommandError("not connected", "not_joined"));
    }
    return awaitPush(this.channel.push(event, payload, timeoutMs), decode, event);
  }

  private setStatus(status: ConnectionStatus): void {
    if (status === this.currentStatus) return;
    this.currentStatus = status;
    this.handlers.status?.(status);
  }
}
