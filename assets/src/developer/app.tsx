/** The developer page (Preact): plots on the left, the logger on the right. */

import { useEffect, useRef, useState } from "preact/hooks";
import { CATEGORIES, categoryLabel, clockTime, formatLog } from "../logger/model";
import { ageText } from "../lib/clock";
import { downloadText, fileStamp } from "../lib/download";
import { formatBytes, recordingUrl } from "../lib/recordings";
import { useStore } from "../lib/use_store";
import { Plot } from "../plots/plot";
import { sortSeries } from "../plots/series";
import { MAX_PLOTS } from "./controller";
import type { DevController, DevState } from "./controller";
import { TuningPanel } from "./tuning_panel";
import { SnapshotList } from "../video/snapshot_list";

/** Entries rendered at most (the download has all the matching ones). */
const SHOWN = 400;

function Header({ s }: { s: DevState }): preact.JSX.Element {
  const back = s.vehicleId === null ? "/" : `/?vehicle=${encodeURIComponent(s.vehicleId)}`;
  return (
    <header class="bar">
      <h1>Neptunus</h1>
      <span class="vehicle">
        Developer · vehicle{" "}
        <strong id="vehicle-id" data-testid="vehicle-id">
          {s.vehicleId ?? "—"}
        </strong>
      </span>
      <span id="status" class="status" data-testid="status" data-state={s.status} role="status">
        {s.status === "disconnected" ? "disconnected — reconnecting" : s.status}
      </span>
      <span class="telemetry">
        Telemetry{" "}
        <strong id="telemetry-age" data-testid="telemetry-age" data-state={s.telemetryState}>
          {ageText(s.telemetryState, s.telemetryAgeMs)}
        </strong>
      </span>
      <a class="dev-link" href={back}>
        Operator page
      </a>
    </header>
  );
}

function Recordings({ s, c }: { s: DevState; c: DevController }): preact.JSX.Element {
  const list = s.recordings;
  const count = list?.recordings.length ?? 0;
  return (
    <details class="recordings" id="recordings" data-testid="recordings">
      <summary>
        Recordings on the server{list === null ? "" : list.recording ? ` (${count})` : " (recording is off)"}
      </summary>
      <div class="toolbar">
        <button type="button" id="recordings-refresh" data-testid="recordings-refresh" onClick={() => void c.loadRecordings()}>
          Refresh
        </button>
        {s.recordingsError !== null && (
          <span class="field-status" data-state="error" role="alert">
            {s.recordingsError}
          </span>
        )}
      </div>
      {list !== null && list.recording && count === 0 && <p class="note">No recordings of this vehicle yet.</p>}
      {list !== null && !list.recording && <p class="note">This server does not record (NEPTUNUS_RECORDINGS=off).</p>}
      {count > 0 && (
        <ul class="recording-list" data-testid="recording-list">
          {list?.recordings.map((r) => (
            <li key={r.name} data-name={r.name}>
              <span class="recording-name">{r.startedAt !== null ? new Date(r.startedAt).toLocaleString("en-GB") : r.name}</span>
              <span class="note">
                {formatBytes(r.bytes)} · last written {new Date(r.modifiedAt).toLocaleTimeString("en-GB")}
              </span>
              <a href={recordingUrl(r, "csv", c.tokenForLinks())} download>
                CSV
              </a>
              <button type="button" class="replay" disabled={s.replay?.loading === true} onClick={() => void c.replay(r)}>
                Show in plots
              </button>
              <button
                type="button"
                class="delete-recording danger"
                onClick={() => {
                  if (window.confirm(`Delete the recording ${r.name} (${formatBytes(r.bytes)}) from the server? This cannot be undone.`)) void c.deleteRecording(r);
                }}
              >
                Delete
              </button>
            </li>
          ))}
        </ul>
      )}
    </details>
  );
}

function ReplayBar({ s, c }: { s: DevState; c: DevController }): preact.JSX.Element | null {
  const r = s.replay;
  if (r === null) return null;
  const text = r.loading
    ? `Loading recording ${r.name}…`
    : r.error !== null
      ? `Cannot show recording ${r.name}: ${r.error}`
      : `Showing recording ${r.name}: ${r.samples.toLocaleString("en")} samples, ${r.events} ${r.events === 1 ? "event" : "events"}. Live telemetry is not plotted meanwhile.`;
  return (
    <p class="replay-bar" id="replay" data-testid="replay" data-state={r.loading ? "loading" : r.error !== null ? "error" : "shown"} role="status">
      {text}{" "}
      <button type="button" id="back-to-live" data-testid="back-to-live" onClick={() => c.live()}>
        Back to live
      </button>
    </p>
  );
}

function Plots({ s, c }: { s: DevState; c: DevController }): preact.JSX.Element {
  const all = sortSeries(s.series);
  const seconds = Math.round(c.recorder.capacity / 20);
  const download = (): void => {
    const name = `neptunus-${s.vehicleId ?? "vehicle"}-${fileStamp(new Date())}.csv`;
    downloadText(name, c.recorder.toCsv(sortSeries(c.recorder.series)), "text/csv");
  };
  return (
    <section class="panel plots-panel" aria-labelledby="plots-title">
      <h2 id="plots-title">Plots</h2>
      <div class="toolbar">
        <button type="button" id="add-plot" data-testid="add-plot" disabled={s.plots.length >= MAX_PLOTS} onClick={() => c.addPlot()}>
          Add plot
        </button>
        <button type="button" id="reset-graphs" data-testid="reset-graphs" onClick={() => c.resetGraphs()}>
          Reset graphs
        </button>
        <button type="button" id="remove-plots" data-testid="remove-plots" disabled={s.plots.length === 0} onClick={() => c.removeAllPlots()}>
          Remove plots
        </button>
        <button type="button" id="reset-plots" data-testid="reset-plots" onClick={() => c.resetPlots()}>
          Reset to defaults
        </button>
        <button type="button" id="download-csv" data-testid="download-csv" onClick={download}>
          Download CSV
        </button>
        <span class="buffer" id="buffer" data-testid="buffer" data-samples={c.recorder.size}>
          {s.plots.length}/{MAX_PLOTS} plots · buffer {c.recorder.size.toLocaleString("en")} / {c.recorder.capacity.toLocaleString("en")} samples (≈ {Math.round(seconds / 60)} min at 20 Hz),{" "}
          {s.replay === null ? "recording since this page connected" : `from recording ${s.replay.name}`}
          {c.recorder.dropped > 0 ? ` · ${c.recorder.dropped.toLocaleString("en")} oldest dropped` : ""} · {all.length} series
        </span>
      </div>
      <output class="field-status" id="plots-status" data-testid="plots-status" data-state={s.plotsStatus.state} aria-live="polite">
        {s.plotsStatus.text}
      </output>
      <ReplayBar s={s} c={c} />
      <Recordings s={s} c={c} />
      <SnapshotList vehicle={s.vehicleId} token={c.tokenForLinks()} />
      <TuningPanel c={c.tuning} />
      {s.plots.length === 0 && <p class="note">No plots: “Add plot” shows one (up to {MAX_PLOTS}); each overlays any series.</p>}
      <div class="plot-list">
        {s.plots.map((p) => (
          <Plot
            key={p.id}
            id={p.id}
            series={p.series}
            allSeries={all}
            recorder={c.recorder}
            dataVersion={s.dataVersion}
            onSeries={(series) => c.setPlotSeries(p.id, series)}
            onRemove={() => c.removePlot(p.id)}
          />
        ))}
      </div>
    </section>
  );
}

function Logger({ s, c }: { s: DevState; c: DevController }): preact.JSX.Element {
  const [selected, setSelected] = useState<ReadonlySet<string>>(() => new Set(CATEGORIES.map((x) => x.id)));
  const [filter, setFilter] = useState("");
  const list = useRef<HTMLOListElement>(null);
  const stick = useRef(true);
  // categories the server used that are not in our list
  const extra = Array.from(new Set(c.log.all.map((e) => e.category))).filter((id) => !CATEGORIES.some((x) => x.id === id));
  const categories = [...CATEGORIES.map((x) => x.id), ...extra];
  const visible = c.log.visible(selected, filter);
  const shown = visible.slice(-SHOWN);

  useEffect(() => {
    const el = list.current;
    if (el && stick.current) el.scrollTop = el.scrollHeight;
  }, [s.logVersion, shown.length]);

  const toggle = (id: string, on: boolean): void => {
    const next = new Set(selected);
    if (on) next.add(id);
    else next.delete(id);
    setSelected(next);
  };
  const download = (): void => {
    const name = `neptunus-${s.vehicleId ?? "vehicle"}-log-${fileStamp(new Date())}.txt`;
    downloadText(name, formatLog(visible));
  };

  return (
    <section class="panel logger" aria-labelledby="logger-title" data-testid="logger">
      <h2 id="logger-title">Logger</h2>
      <p class="note" data-testid="log-topic" data-state={s.logJoined}>
        {s.logJoined === "joined" ? "log topic joined" : s.logJoined === "joining" ? "joining the log topic…" : `no log topic: ${s.logError ?? ""}`}
      </p>
      <fieldset class="categories" data-testid="categories">
        <legend>Categories</legend>
        <div class="cat-actions">
          <button type="button" id="cat-all" onClick={() => setSelected(new Set(categories))}>
            All
          </button>
          <button type="button" id="cat-none" onClick={() => setSelected(new Set())}>
            None
          </button>
        </div>
        {categories.map((id) => (
          <label key={id} class="cat">
            <input type="checkbox" data-testid={`cat-${id}`} id={`cat-${id}`} checked={selected.has(id)} onChange={(e) => toggle(id, (e.currentTarget as HTMLInputElement).checked)} />
            {categoryLabel(id)}
          </label>
        ))}
      </fieldset>
      <div class="toolbar">
        <input
          type="search"
          id="log-filter"
          data-testid="log-filter"
          placeholder="filter text"
          value={filter}
          onInput={(e) => setFilter((e.currentTarget as HTMLInputElement).value)}
        />
        <button
          type="button"
          id="log-pause"
          data-testid="log-pause"
          aria-pressed={c.log.paused}
          onClick={() => {
            if (c.log.paused) c.log.resume();
            else c.log.pause();
            c.bumpLog();
          }}
        >
          {c.log.paused ? `Resume (${c.log.pending} new)` : "Pause"}
        </button>
        <button
          type="button"
          id="log-clear"
          data-testid="log-clear"
          onClick={() => {
            c.log.clear();
            c.bumpLog();
          }}
        >
          Clear
        </button>
        <button type="button" id="log-download" data-testid="log-download" onClick={download}>
          Download
        </button>
      </div>
      <p class="note">
        {visible.length} shown{visible.length > SHOWN ? ` (the last ${SHOWN} on screen)` : ""} · {c.log.all.length} kept (last {c.log.capacity})
      </p>
      <ol
        class="log-list"
        ref={list}
        data-testid="log-list"
        onScroll={(e) => {
          const el = e.currentTarget as HTMLOListElement;
          stick.current = el.scrollTop + el.clientHeight >= el.scrollHeight - 8;
        }}
      >
        {shown.map((e) => (
          <li key={e.seq} data-category={e.category} data-level={e.level}>
            <time dateTime={new Date(e.at).toISOString()}>{clockTime(e.at)}</time>
            <span class="log-cat">{categoryLabel(e.category)}</span>
            <span class="log-msg">{e.message}</span>
          </li>
        ))}
      </ol>
    </section>
  );
}

export function DevApp({ controller }: { controller: DevController }): preact.JSX.Element {
  const s = useStore(controller.store);
  return (
    <div class="page dev">
      <Header s={s} />
      {s.message !== "" && (
        <p class="banner" role="alert" data-testid="message">
          {s.message}
        </p>
      )}
      <main class="dev-layout">
        <Plots s={s} c={controller} />
        <Logger s={s} c={controller} />
      </main>
    </div>
  );
}
