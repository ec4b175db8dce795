/**
 * Typed wrapper around the official phoenix client for the Neptunus channels.
 *
 * - `NeptunusClient` owns the Socket (`/socket`, params `{name}`).
 * - `fleet()` joins `fleet` and resolves with the vehicle list.
 * - `vehicle(id)` gives a `VehicleChannel` for `vehicle:<id>`: join → snapshot, telemetry,
 *   pilot and presence callbacks, and commands (`thrust`, `stop`) as Promises that reject with
 *   a `CommandError` carrying the server's readable reason.
 *
 * Commands are only sent while the channel is joined: the phoenix client would otherwise buffer
 * them and deliver them up to a push timeout later, and a late thrust command is worse than none.
 */

import { Presence, Socket } from "phoenix";
import type { Channel, Push, SocketConnectOption } from "phoenix";
import {
  decodeFleetReply,
  decodePilot,
  decodeTelemetry,
  decodeThrustReply,
  decodeVehicleSnapshot,
  errorReason,
  isRecord,
  presenceEntry,
} from "./protocol";
import type {
  FleetReply,
  MotionCommand,
  Pilot,
  PresenceEntry,
  Telemetry,
  ThrustReply,
  VehicleSnapshot,
} from "./protocol";

export type ConnectionStatus = "connecting" | "connected" | "disconnected";

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

export interface NeptunusClientOptions {
  /** Socket endpoint; the client appends `/websocket`. Default "/socket". */
  readonly endpoint?: string;
  /** Display name shown in presence. */
  readonly name?: string;
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
    const opts: Partial<SocketConnectOption> = {
      params: options.name === undefined ? {} : { name: options.name },
    };
    if (options.transport) opts.transport = options.transport;
    this.socket = new Socket(options.endpoint ?? "/socket", opts);
  }

  connect(): void {
    this.socket.connect();
  }

  disconnect(): Promise<void> {
    return new Promise((resolve) => this.socket.disconnect(() => resolve()));
  }

  /** Joins `fleet` (once) and resolves with its join reply. */
  fleet(timeoutMs = DEFAULT_JOIN_TIMEOUT_MS): Promise<FleetReply> {
    if (this.fleetChannel) this.fleetChannel.leave();
    const channel = this.socket.channel("fleet", {});
    this.fleetChannel = channel;
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
}

export interface VehicleHandlers {
  /** Every successful (re)join, with the server's snapshot. */
  readonly snapshot?: (snapshot: VehicleSnapshot) => void;
  readonly telemetry?: (telemetry: Telemetry) => void;
  readonly pilot?: (pilot: Pilot | null) => void;
  /** The thrusters were driven neutral (safety or by request), with the server's reason. */
  readonly stopped?: (reason: string) => void;
  /** Who is connected to this vehicle (after every presence sync). */
  readonly presence?: (entries: readonly PresenceEntry[]) => void;
  readonly status?: (status: ConnectionStatus) => void;
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
    this.channel.on("pilot", (payload: unknown) => {
      const pilot = isRecord(payload) ? decodePilot(payload["pilot"]) : undefined;
      if (pilot === undefined) handlers.protocolError?.("pilot", payload);
      else handlers.pilot?.(pilot);
    });
    this.channel.on("stopped", (payload: unknown) => {
      handlers.stopped?.(errorReason(payload));
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

  /** Motion command with absolute axes in [-1, 1]. */
  thrust(command: MotionCommand, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<ThrustReply> {
    return this.command(
      "thrust",
      { mode: "motion", surge: command.surge, heave: command.heave, yaw: command.yaw },
      decodeThrustReply,
      timeoutMs,
    );
  }

  /** All thrusters neutral; `reason` (1..100 bytes) is shown to everyone watching. */
  stop(reason?: string, timeoutMs = DEFAULT_COMMAND_TIMEOUT_MS): Promise<void> {
    const payload = reason === undefined ? {} : { reason };
    return this.command("stop", payload, () => true, timeoutMs).then(() => undefined);
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

  private command<T>(
    event: string,
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
