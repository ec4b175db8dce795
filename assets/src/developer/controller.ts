/**
 * The developer page's logic: connects like the operator page (watching only, it never asks
 * for control; the session is `PageSession`, lib/session.ts, as on the operator page),
 * records every telemetry sample from the moment it connects (plots), shows how old the
 * telemetry is (as the operator page does, lib/clock.ts), and feeds the logger from the
 * vehicle topic and the `log:<id>` topic.
 *
 * The plots open with the user's set, kept on the server (`developer.plots`, plot_set.ts),
 * or the default set (with position for a vehicle with a position source, once its telemetry
 * says so); every change of the plots is saved, "reset to defaults" deletes it.
 */

import { LogBook, entryFromRecordedEvent, entryFromServerLog, linkEntry, recorded, stopEntry, telemetryChanges, telemetryFacts } from "../logger/model";
import type { NewEntry, TelemetryFacts } from "../logger/model";
import { SeriesRecorder } from "../plots/recorder";
import { flattenNumeric, wrapPeriod } from "../plots/series";
import { deleteRecording, fetchRecording, fetchRecordings } from "../lib/recordings";
import type { ParsedRecording, RecordingInfo, RecordingList } from "../lib/recordings";
import { decodeTelemetry } from "../lib/protocol";
import type { Helm, Telemetry } from "../lib/protocol";
import { TelemetryClock } from "../lib/clock";
import type { TelemetryState } from "../lib/clock";
import { chooseVehicle } from "../lib/choose_vehicle";
import { PageSession, browserSessionEnv } from "../lib/session";
import { KEPT_LOADING, KeptSetting } from "../lib/kept_setting";
import type { KeptStatus } from "../lib/kept_setting";
import { DEVELOPER_PLOTS_KEY, SettingsClient } from "../lib/settings";
import { Store } from "../lib/store";
import { CommandError, NeptunusClient } from "../lib/vehicle_client";
import type { ConnectionStatus, VehicleChannel } from "../lib/vehicle_client";
import { DEFAULT_PLOT_SET, MAX_PLOTS, adaptDefaultPlots, defaultPlotSet, encodePlotSet, hasPositionSource, parsePlotSet } from "./plot_set";
import type { PlotSet } from "./plot_set";
import { TuningController } from "./tuning";

export { MAX_PLOTS };

/** how often the page reads the server's clock (to tell how old telemetry is on arrival) */
const CLOCK_MS = 10_000;

export interface PlotSpec {
  readonly id: number;
  readonly series: readonly string[];
}

export interface DevState {
  readonly status: ConnectionStatus;
  readonly vehicleId: string | null;
  readonly logJoined: "joining" | "joined" | "error";
  readonly logError: string | null;
  /** changes when the logger has new entries (or was cleared / paused) */
  readonly logVersion: number;
  /** changes when the recording changed (throttled) */
  readonly dataVersion: number;
  /** series known so far, in arrival order */
  readonly series: readonly string[];
  readonly plots: readonly PlotSpec[];
  /** where the user's plot set stands: read from the server, saved, or why not */
  readonly plotsStatus: KeptStatus;
  readonly telemetryState: TelemetryState;
  readonly telemetryAgeMs: number;
  readonly message: string;
  /** the server's recordings of this vehicle (null until listed) */
  readonly recordings: RecordingList | null;
  readonly recordingsError: string | null;
  /** what the plots show: live telemetry, or a recording being loaded / loaded */
  readonly replay: ReplayState | null;
}

export interface ReplayState {
  readonly name: string;
  readonly loading: boolean;
  /** telemetry samples loaded, of the recording's (the server thins long ones) */
  readonly samples: number;
  readonly events: number;
  readonly error: string | null;
}

/** Series a new plot starts with (thesis table 7.3), taken in turn. */
const STARTERS = [
  ["measurement.depth"],
  ["command.surge", "command.heave", "command.yaw"],
  ["thrusters.port", "thrusters.vertical", "thrusters.starboard"],
  ["measurement.heading"],
  ["measurement.roll", "measurement.pitch"],
  ["sim.x", "sim.y", "sim.z"],
  ["sim.u", "sim.w", "sim.r"],
  ["measurement.voltage"],
  ["measurement.current"],
  ["sim.psi"],
];

function reasonOf(err: unknown): string {
  if (err instanceof CommandError) return err.reason;
  if (err instanceof Error) return err.message;
  return String(err);
}

export class DevController {
  readonly store: Store<DevState>;
  readonly recorder: SeriesRecorder;
  readonly log = new LogBook();
  /** the autopilot tuning panel's logic */
  readonly tuning = new TuningController();
  private readonly params: URLSearchParams;
  private facts: TelemetryFacts | null = null;
  /** whether the vehicle has a position source (the default plots then include position) */
  private withPosition = false;
  private lastHelm: Helm | null = null;
  private nextPlotId = 1;
  private starter = 0;
  private token: string | null = null;
  private readonly session: PageSession;
  /** the plots, kept on the server */
  private readonly kept: KeptSetting<readonly PlotSpec[]>;
  private vehicle: VehicleChannel | null = null;
  private readonly clock = new TelemetryClock(() => this.vehicle);

  constructor(params: URLSearchParams, capacity?: number) {
    this.params = params;
    // angles that wrap (headings) also get their continuous line, for the plots
    this.recorder = new SeriesRecorder(capacity, wrapPeriod);
    this.store = new Store<DevState>({
      status: "connecting",
      vehicleId: null,
      logJoined: "joining",
      logError: null,
      logVersion: 0,
      dataVersion: 0,
      series: [],
      plots: [],
      plotsStatus: KEPT_LOADING,
      telemetryState: "none",
      telemetryAgeMs: 0,
      message: "",
      recordings: null,
      recordingsError: null,
      replay: null,
    });
    this.store.update({ plots: this.specs(DEFAULT_PLOT_SET) });
    this.session = new PageSession(
      browserSessionEnv((reason) => this.store.update({ message: reason === null ? "" : `Cannot reach the server: ${reason}` })),
    );
    this.kept = new KeptSetting<readonly PlotSpec[]>({
      key: DEVELOPER_PLOTS_KEY,
      client: new SettingsClient(() => this.session.token),
      parse: (stored) => {
        const parsed = parsePlotSet(stored);
        return parsed.ok ? { ok: true, value: this.specs(parsed.plots) } : parsed;
      },
      encode: (plots) => encodePlotSet(plots.map((p) => p.series)),
      texts: {
        default: "Default plots.",
        stored: "Your plots, from the server.",
        unusable: (reason) => `Your stored plots cannot be used (${reason}): the defaults apply.`,
        notKept: "Not kept: log in to keep your plots.",
        notSaved: (reason) => `Plots not saved: ${reason}`,
      },
      get: () => ({ value: this.store.get().plots, status: this.store.get().plotsStatus }),
      set: ({ value, status }) => this.store.update({ ...(value !== undefined ? { plots: value } : {}), plotsStatus: status }),
    });
  }

  async start(): Promise<void> {
    // plots redraw at most 4 times a second, whatever the telemetry rate
    window.setInterval(() => {
      const v = this.recorder.version;
      if (v !== this.store.get().dataVersion) {
        this.store.update({ dataVersion: v, series: [...this.recorder.series] });
      }
    }, 250);

    window.setInterval(() => this.tick(), 250);
    window.setInterval(() => this.clock.read(), CLOCK_MS);

    const session = await this.session.authenticate();
    if (session === null) return; // leaving for the login page
    const token = this.session.token;
    this.token = token;
    void this.kept.load();
    const name = (this.params.get("name") ?? "").trim().slice(0, 40) || "developer";
    const client = new NeptunusClient({ name, ...(token !== null ? { token } : {}) });
    client.socket.onOpen(() => this.store.update({ status: "connected" }));
    // a refused upgrade (expired or revoked token) looks like a network error from here
    client.socket.onError(() => void this.session.recheck());
    client.connect();
    const id = await chooseVehicle(client, this.params.get("vehicle"), (message) => this.store.update({ message }));
    if (id === null) return;
    this.store.update({ vehicleId: id, message: "" });
    document.title = `Neptunus — developer — ${id}`;
    void this.loadRecordings();

    const vehicle = client.vehicle(id, {
      snapshot: (snapshot) => {
        this.lastHelm = snapshot.helm;
        if (snapshot.telemetry) this.onTelemetry(snapshot.telemetry);
        void this.tuning.joined();
      },
      telemetry: (t) => this.onTelemetry(t),
      helm: (h) => this.onHelm(h),
      stopped: (reason) => this.add(stopEntry(reason, Date.now())),
      link: (link) => this.add(linkEntry(link.up, link.reason, Date.now())),
      status: (status) => {
        const was = this.store.get().status;
        this.store.update({ status });
        if (status !== was && (status === "disconnected" || was === "disconnected")) {
          this.add({
            category: "link",
            level: status === "connected" ? "info" : "warning",
            message: `server connection ${status}`,
          });
        }
      },
      protocolError: (what, payload) =>
        this.add({ category: "error", level: "error", message: `unexpected ${what} payload: ${JSON.stringify(payload).slice(0, 200)}` }),
    });
    this.vehicle = vehicle;
    this.tuning.attach(vehicle);
    vehicle.join().catch((err: unknown) => {
      this.add({ category: "error", level: "error", message: `cannot join vehicle ${id}: ${reasonOf(err)}` });
      this.store.update({ message: `Cannot join vehicle ${id}: ${reasonOf(err)}` });
    });

    const log = client.log(id, (payload) => {
      const entry = entryFromServerLog(payload, Date.now());
      if (entry) this.add(entry);
      else this.add({ category: "error", level: "error", message: `unexpected log payload: ${JSON.stringify(payload).slice(0, 200)}` });
    });
    log.join().then(
      () => this.store.update({ logJoined: "joined", logError: null }),
      (err: unknown) => {
        const reason = reasonOf(err);
        this.store.update({ logJoined: "error", logError: reason });
        this.add({ category: "error", level: "error", message: `cannot join log:${id}: ${reason}` });
      },
    );
  }

  private onTelemetry(t: Telemetry): void {
    this.store.update(this.clock.received(t.sent_at, performance.now(), Date.now()));
    // while a recording is shown, live samples are not mixed into it
    if (this.store.get().replay === null) this.recorder.add(t.sent_at / 1000, flattenNumeric(t.raw));
    const facts = telemetryFacts(t);
    for (const e of telemetryChanges(this.facts, facts, t.sent_at)) this.add(e);
    this.facts = facts;
    this.positionPlots(hasPositionSource(t.position));
  }

  // while the page shows the default plots, they follow whether the vehicle has a position
  // source (a reset meanwhile included); the user's own set is never changed
  private positionPlots(withPosition: boolean): void {
    this.withPosition = withPosition;
    const { plots, plotsStatus } = this.store.get();
    const next = adaptDefaultPlots(
      plots.map((p) => p.series),
      plotsStatus.state,
      withPosition,
    );
    if (next !== null) this.store.update({ plots: this.specs(next) });
  }

  private tick(): void {
    // stale telemetry ages on screen; the clock is read as soon as the vehicle is joined
    const stale = this.clock.tick(performance.now());
    if (stale !== null) this.store.update(stale);
  }

  private onHelm(h: Helm): void {
    const prev = this.lastHelm;
    this.lastHelm = h;
    const pilot = h.pilot?.name ?? null;
    const changed =
      prev === null ||
      prev.state !== h.state ||
      (prev.pilot?.id ?? null) !== (h.pilot?.id ?? null) ||
      (prev.request?.from.id ?? null) !== (h.request?.from.id ?? null) ||
      (prev.takeover?.by.id ?? null) !== (h.takeover?.by.id ?? null);
    if (changed) {
      let message: string;
      switch (h.state) {
        case "free":
          message = "helm free";
          break;
        case "piloted":
          message = `${pilot ?? "?"} pilots`;
          break;
        case "requested":
          message = `${h.request?.from.name ?? "?"} requests control from ${pilot ?? "?"}`;
          break;
        case "takeover":
          message = `main station ${h.takeover?.by.name ?? "?"} takes control from ${pilot ?? "?"} in ${Math.ceil((h.takeover?.countdown_ms ?? 0) / 1000)} s`;
          break;
      }
      this.add({ category: "transfer", level: h.state === "takeover" ? "warning" : "info", message: `${message} (epoch ${h.epoch})` });
    } else if (prev.epoch !== h.epoch) {
      this.add({ category: "safety", level: "warning", message: `new epoch ${h.epoch} (deadman stop?)` });
    }
  }

  add(entry: Omit<NewEntry, "at"> & { at?: number }): void {
    this.log.add({ ...entry, at: entry.at ?? Date.now() });
    this.bumpLog();
  }

  bumpLog(): void {
    this.store.update((s) => ({ logVersion: s.logVersion + 1 }));
  }

  // Plots

  addPlot(): void {
    const plots = this.store.get().plots;
    if (plots.length >= MAX_PLOTS) return;
    const known = new Set(this.recorder.series);
    let series: string[] = [];
    for (let i = 0; i < STARTERS.length && series.length === 0; i++) {
      const candidate = STARTERS[(this.starter + i) % STARTERS.length] ?? [];
      series = candidate.filter((k) => known.has(k));
      if (series.length > 0) this.starter = (this.starter + i + 1) % STARTERS.length;
    }
    this.savePlots([...plots, { id: this.nextPlotId++, series }]);
  }

  removePlot(id: number): void {
    this.savePlots(this.store.get().plots.filter((p) => p.id !== id));
  }

  removeAllPlots(): void {
    this.savePlots([]);
  }

  setPlotSeries(id: number, series: readonly string[]): void {
    this.savePlots(this.store.get().plots.map((p) => (p.id === id ? { ...p, series } : p)));
  }

  /** Back to the default plots (the user's stored set is deleted on the server). */
  resetPlots(): void {
    this.kept.reset(this.specs(defaultPlotSet(this.withPosition)));
  }

  private specs(set: PlotSet): PlotSpec[] {
    return set.map((series) => ({ id: this.nextPlotId++, series: [...series] }));
  }

  private savePlots(plots: readonly PlotSpec[]): void {
    this.kept.save(plots);
  }

  // Recordings on the server

  /** The token to put in download links (null in local mode or as an anonymous observer). */
  tokenForLinks(): string | null {
    return this.token;
  }

  /** Lists the server's recordings of this vehicle. */
  async loadRecordings(): Promise<void> {
    const id = this.store.get().vehicleId;
    if (id === null) return;
    try {
      const recordings = await fetchRecordings(id, this.token);
      this.store.update({ recordings, recordingsError: null });
    } catch (err) {
      this.store.update({ recordingsError: reasonOf(err) });
    }
  }

  /**
   * Shows a recording in the plots instead of live telemetry (the server thins it to the
   * buffer's capacity); `live()` goes back.
   */
  async replay(info: RecordingInfo): Promise<void> {
    this.store.update({ replay: { name: info.name, loading: true, samples: 0, events: 0, error: null } });
    try {
      const recording = await fetchRecording(info, this.token, this.recorder.capacity);
      if (this.store.get().replay?.name !== info.name) return; // "live" was pressed meanwhile
      this.recorder.clear();
      let samples = 0;
      for (const entry of recording.telemetry) if (this.recorder.add(entry.at / 1000, flattenNumeric(entry.payload))) samples += 1;
      this.store.update({
        replay: { name: info.name, loading: false, samples, events: recording.events.length, error: null },
        dataVersion: this.recorder.version,
        series: [...this.recorder.series],
      });
      this.logRecording(recording);
      const skipped = recording.bad > 0 ? `, ${recording.bad} unreadable lines skipped` : "";
      this.add({ category: "recording", level: recording.bad > 0 ? "warning" : "info", message: `showing recording ${info.name}: ${samples} samples, ${recording.events.length} events${skipped}` });
    } catch (err) {
      this.store.update({ replay: { name: info.name, loading: false, samples: 0, events: 0, error: reasonOf(err) } });
    }
  }

  /**
   * The recording's history in the logger, marked "[recorded]": its events (stops, link,
   * helm, recording) and what changed in its telemetry (commands, gain, autopilots), in time
   * order, at most the logger's capacity (the newest).
   */
  private logRecording(recording: ParsedRecording): void {
    const entries: NewEntry[] = [];
    for (const e of recording.events) {
      const entry = entryFromRecordedEvent(e.event, e.payload, e.at);
      if (entry) entries.push(entry);
    }
    let facts: TelemetryFacts | null = null;
    for (const e of recording.telemetry) {
      const t = decodeTelemetry(e.payload);
      if (t === null) continue;
      const next = telemetryFacts(t);
      for (const change of telemetryChanges(facts, next, e.at)) entries.push(recorded(change));
      facts = next;
    }
    entries.sort((a, b) => a.at - b.at);
    for (const entry of entries.slice(-this.log.capacity)) this.log.add(entry);
    this.bumpLog();
  }

  /** Deletes a recording on the server (after the page asked), then lists them again. */
  async deleteRecording(info: RecordingInfo): Promise<void> {
    try {
      await deleteRecording(info, this.token);
      this.add({ category: "recording", level: "info", message: `deleted recording ${info.name}` });
      this.store.update({ recordingsError: null });
    } catch (err) {
      this.store.update({ recordingsError: `cannot delete ${info.name}: ${reasonOf(err)}` });
    }
    await this.loadRecordings();
  }

  /** Back to live telemetry (the buffer starts afresh). */
  live(): void {
    if (this.store.get().replay === null) return;
    this.recorder.clear();
    this.store.update({ replay: null, dataVersion: this.recorder.version });
  }

  /** Clears the recorded data; the plots stay with their series. */
  resetGraphs(): void {
    this.recorder.clear();
    this.store.update({ dataVersion: this.recorder.version });
  }
}
