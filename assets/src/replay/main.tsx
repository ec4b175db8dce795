/**
 * The replay page (`/replay.html[?vehicle=ID][&dive=NAME]`): pick a recorded dive (listed with
 * its summary), play its video with the HUD over it and plots of its telemetry below, in sync
 * (core.ts: the clock, the events, the shortcuts; video.ts: the picture). It only reads the
 * recordings API (docs/API.md): it never joins a vehicle, so an observer may replay and a
 * replay never touches the live vehicle.
 */

import { render } from "preact";
import { useEffect, useMemo, useRef, useState } from "preact/hooks";
import uPlot from "uplot";
import { parseRecordingLines, recordingUrl } from "../lib/recordings";
import type { ExportFormat, ParsedRecording, RecordedEntry } from "../lib/recordings";
import { PageSession, browserSessionEnv } from "../lib/session";
import { formatFixed, formatHeading } from "../lib/units";
import { CompassTape } from "../operator/hud";
import { flattenNumeric, seriesLabel } from "../plots/series";
import { RATES, formatOffset, indexAt, keyAction, nextEvent, previousEvent, replayEvents } from "./core";
import type { Rate, ReplayClock, ReplayEvent } from "./core";
import { decodeDiveList, mayEditNotes, notesChanges, withNotes } from "./dives";
import type { DiveInfo } from "./dives";
import { NO_FOOTAGE, display, newSync, react } from "./sync";
import type { Footage, SyncEvent, SyncState } from "./sync";
import { ReplayVideo } from "./video";

/** telemetry samples asked for: the server thins a long dive to this many */
const MAX_SAMPLES = 12_000;
const PLOTTED = ["estimate.depth", "measurement.heading", "thrusters.port", "thrusters.vertical", "thrusters.starboard"] as const;

interface Loaded {
  readonly dive: DiveInfo;
  readonly recording: ParsedRecording;
  readonly times: Float64Array;
  readonly events: readonly ReplayEvent[];
  readonly start: number;
  readonly end: number;
}

function headers(token: string | null): Record<string, string> {
  return token !== null ? { authorization: `Bearer ${token}` } : {};
}

async function errorOf(response: Response): Promise<string> {
  try {
    const body: unknown = await response.json();
    if (typeof body === "object" && body !== null && "error" in body) return String((body as { error: unknown }).error);
  } catch {
    // not JSON
  }
  return `HTTP ${response.status}`;
}

function diveUrl(dive: DiveInfo, suffix: string, query: Record<string, string>): string {
  return `/api/recordings/${encodeURIComponent(dive.vehicle)}/${encodeURIComponent(dive.name)}${suffix}?${new URLSearchParams(query).toString()}`;
}

function num(payload: Readonly<Record<string, unknown>> | undefined, path: string): number | null {
  let v: unknown = payload;
  for (const part of path.split(".")) {
    if (typeof v !== "object" || v === null) return null;
    v = (v as Record<string, unknown>)[part];
  }
  return typeof v === "number" ? v : null;
}

function DiveList(props: { dives: readonly DiveInfo[]; onPick: (d: DiveInfo) => void; selected: string | null }): preact.JSX.Element {
  if (props.dives.length === 0) return <p data-testid="replay-empty">No recorded dives.</p>;
  return (
    <ul class="replay-dives" data-testid="replay-dives">
      {props.dives.map((d) => (
        <li key={`${d.vehicle}/${d.name}`}>
          <button
            type="button"
            class={props.selected === `${d.vehicle}/${d.name}` ? "replay-dive selected" : "replay-dive"}
            data-testid="replay-dive"
            data-name={d.name}
            onClick={() => props.onPick(d)}
          >
            <b>{d.title ?? `${d.vehicle} · ${d.startedAt !== null ? new Date(d.startedAt).toISOString().replace("T", " ").slice(0, 19) : d.name}`}</b>
            <span>
              {formatOffset(d.durationMs ?? 0)} · max {formatFixed(d.maxDepth ?? Number.NaN, 1)} m · {d.pilots.length > 0 ? d.pilots.join(", ") : "no pilot"} · {d.stops} stops ·{" "}
              {d.snapshots} snapshots · {d.video !== null ? `video ${d.video.codec}` : "no video"}
              {d.recording ? " · recording now" : ""}
            </span>
            {d.problems.length > 0 ? <span class="replay-problems">{d.problems.join("; ")}</span> : null}
          </button>
        </li>
      ))}
    </ul>
  );
}

function Plots(props: { loaded: Loaded; cursorRef: { current: ((pos: number) => void) | null }; onSeek: (pos: number) => void }): preact.JSX.Element {
  const host = useRef<HTMLDivElement>(null);
  const { loaded } = props;
  useEffect(() => {
    const el = host.current;
    if (el === null) return undefined;
    const t = Array.from(loaded.times, (ms) => ms / 1000);
    const columns = PLOTTED.map((key) => loaded.recording.telemetry.map((e) => flattenNumeric(e.payload).get(key) ?? null));
    const axis: uPlot.Axis = { stroke: "#8fa9b8", grid: { stroke: "#24445a", width: 1 }, ticks: { stroke: "#24445a", width: 1 } };
    const colors = ["#4fc3f7", "#ffb74d", "#66bb6a", "#ef5350", "#ba68c8"];
    const u = new uPlot(
      {
        width: Math.max(200, el.clientWidth),
        height: 180,
        scales: { x: { time: true } },
        series: [{ label: "time" }, ...PLOTTED.map((k, i) => ({ label: seriesLabel(k), stroke: colors[i] ?? "#fff", width: 1.5 }))],
        axes: [axis, axis],
        cursor: { drag: { x: false, y: false } },
        legend: { live: false },
      },
      [t, ...columns],
      el,
    );
    const line = document.createElement("div");
    line.className = "replay-cursor";
    line.dataset["testid"] = "replay-plot-cursor";
    u.over.appendChild(line);
    props.cursorRef.current = (pos: number) => {
      line.style.left = `${u.valToPos(pos / 1000, "x")}px`;
      line.dataset["ms"] = String(pos);
    };
    const seekTo = (e: PointerEvent): void => {
      const rect = u.over.getBoundingClientRect();
      props.onSeek(u.posToVal(e.clientX - rect.left, "x") * 1000);
    };
    const down = (e: PointerEvent): void => {
      seekTo(e);
      u.over.setPointerCapture(e.pointerId);
    };
    const move = (e: PointerEvent): void => {
      if (u.over.hasPointerCapture(e.pointerId)) seekTo(e);
    };
    u.over.addEventListener("pointerdown", down);
    u.over.addEventListener("pointermove", move);
    const resize = new ResizeObserver(() => u.setSize({ width: Math.max(200, el.clientWidth), height: 180 }));
    resize.observe(el);
    return () => {
      resize.disconnect();
      props.cursorRef.current = null;
      u.destroy();
    };
  }, [loaded]);
  return <div class="replay-plot" ref={host} data-testid="replay-plot" />;
}

function Player(props: { loaded: Loaded; token: string | null; editable: boolean; onNotes: (d: DiveInfo) => void }): preact.JSX.Element {
  const { loaded } = props;
  const canvas = useRef<HTMLCanvasElement>(null);
  const player = useRef<HTMLDivElement>(null);
  const video = useRef<ReplayVideo | null>(null);
  const cursor = useRef<((pos: number) => void) | null>(null);
  const footage = (): Footage => video.current?.footage ?? NO_FOOTAGE;
  // the clock and the picture's hold (sync.ts); the page re-renders when what it shows changes
  const sync = useRef<SyncState>(newSync(loaded.start, loaded.end, performance.now(), loaded.dive.video !== null ? { kind: "loading" } : NO_FOOTAGE));
  const [clock, setClock] = useState<ReplayClock>(sync.current.clock);
  const [pos, setPos] = useState(loaded.start);
  const [problem, setProblem] = useState<string | null>(null);

  const send = (e: SyncEvent): void => {
    const next = react(sync.current, e, footage());
    sync.current = next;
    setClock(next.clock);
  };
  const shownPos = (): number => display(sync.current, performance.now(), footage()).pos;

  useEffect(() => {
    const el = canvas.current;
    if (el === null || loaded.dive.video === null) return undefined;
    const v = new ReplayVideo(
      el,
      (from, to) => diveUrl(loaded.dive, "/video", { from: String(from), to: String(to) }),
      headers(props.token),
      { start: loaded.start, end: loaded.end },
      () => setProblem(v.problem),
    );
    video.current = v;
    return () => {
      v.close();
      video.current = null;
    };
  }, [loaded]);

  // one loop draws everything at one position, in one step: the picture, the plots' cursor,
  // the HUD (sync.ts: the cursor and the HUD never run ahead of the picture)
  useEffect(() => {
    let frame = 0;
    let lastShown = Number.NaN;
    const draw = (): void => {
      const now = performance.now();
      const f = footage();
      let s = react(sync.current, { type: "tick", now }, f);
      video.current?.want(display(s, now, f).want);
      const us = video.current?.present() ?? null;
      if (us !== null && us !== s.shownUs) s = react(s, { type: "picture", us, now }, f);
      if (s !== sync.current) {
        sync.current = s;
        setClock(s.clock);
      }
      const d = display(s, now, f);
      cursor.current?.(d.pos);
      const el = player.current;
      if (el !== null) {
        el.dataset["stale"] = String(d.stale);
        el.dataset["holds"] = String(s.holds);
        el.dataset["settled"] = String(s.settled);
      }
      if (d.pos !== lastShown) {
        lastShown = d.pos;
        setPos(d.pos);
      }
      frame = requestAnimationFrame(draw);
    };
    frame = requestAnimationFrame(draw);
    return () => cancelAnimationFrame(frame);
  }, [loaded]);

  const jump = (dir: 1 | -1): void => {
    const p = shownPos();
    const e = dir === 1 ? nextEvent(loaded.events, p) : previousEvent(loaded.events, p);
    if (e !== null) send({ type: "seek", pos: e.at, now: performance.now() });
  };
  const seekTo = (to: number): void => send({ type: "seek", pos: to, now: performance.now() });

  useEffect(() => {
    const onKey = (e: KeyboardEvent): void => {
      if (e.ctrlKey || e.metaKey || e.altKey) return;
      if (e.target instanceof HTMLInputElement && e.target.type !== "range") return;
      if (e.target instanceof HTMLTextAreaElement) return;
      // a focused button (reached by Tab) is pressed by space or Enter, as everywhere
      if (e.target instanceof HTMLButtonElement && (e.key === " " || e.key === "Enter")) return;
      const action = keyAction(e.key);
      if (action === null) return;
      e.preventDefault();
      const now = performance.now();
      switch (action.type) {
        case "toggle":
          send({ type: "toggle", now });
          break;
        case "seekBy":
          send({ type: "seekBy", ms: action.ms, now });
          break;
        case "frame":
          send({ type: "step", dir: action.dir, now });
          break;
        case "rate":
          send({ type: "stepRate", dir: action.dir, now });
          break;
        case "event":
          jump(action.dir);
          break;
        case "home":
          seekTo(loaded.start);
          break;
        case "end":
          seekTo(loaded.end);
          break;
      }
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [loaded]);

  const sample: RecordedEntry | undefined = loaded.recording.telemetry[indexAt(loaded.times, pos)];
  const p = sample?.payload;
  const depth = num(p, "estimate.depth") ?? num(p, "measurement.depth");
  const heading = num(p, "estimate.heading") ?? num(p, "measurement.heading");
  const helm = [...loaded.recording.events].reverse().find((e) => e.event === "helm" && e.at <= pos);
  const pilotPayload = helm?.payload["pilot"];
  const pilot = typeof pilotPayload === "object" && pilotPayload !== null && "name" in pilotPayload ? String((pilotPayload as { name: unknown }).name) : null;
  const current = [...loaded.events].reverse().find((e) => e.at <= pos && pos - e.at < 3_000);

  return (
    <div class="replay-player" ref={player} data-testid="replay-player" data-playing={String(clock.playing)} data-rate={String(clock.rate)}>
      <div class="replay-stage">
        {loaded.dive.video !== null ? (
          <canvas ref={canvas} class="replay-video" data-testid="replay-video" width={640} height={360} />
        ) : (
          <div class="replay-novideo">This dive has no video.</div>
        )}
        <div class="replay-hud" data-testid="replay-hud">
          <CompassTape heading={heading} setpoint={null} />
          <span class="replay-hud-box">
            depth <b data-testid="replay-depth">{formatFixed(depth ?? Number.NaN, 2)}</b> m
          </span>
          <span class="replay-hud-box">heading {heading !== null ? `${formatHeading(heading)}°` : "—"}</span>
          <span class="replay-hud-box">{pilot !== null ? `pilot ${pilot}` : "helm free"}</span>
          {current !== undefined ? (
            <span class={`replay-hud-box replay-event ${current.kind}`} data-testid="replay-current-event">
              {current.label}
            </span>
          ) : null}
        </div>
        {problem !== null ? (
          <div class="replay-problem" data-testid="replay-problem">
            {problem}
          </div>
        ) : null}
      </div>
      {/* a click or tap does not leave the focus on a button, so space keeps playing and pausing */}
      <div class="replay-controls" onMouseDown={(e) => e.preventDefault()}>
        <button type="button" data-testid="replay-prev-event" title="previous event (p)" onClick={() => jump(-1)}>
          ⏮
        </button>
        <button type="button" data-testid="replay-frame-back" title="one frame back (,)" onClick={() => send({ type: "step", dir: -1, now: performance.now() })}>
          ◀|
        </button>
        <button type="button" class="replay-play" data-testid="replay-play" title="play / pause (space, k)" onClick={() => send({ type: "toggle", now: performance.now() })}>
          {clock.playing ? "❚❚" : "▶"}
        </button>
        <button type="button" data-testid="replay-frame-forward" title="one frame on (.)" onClick={() => send({ type: "step", dir: 1, now: performance.now() })}>
          |▶
        </button>
        <button type="button" data-testid="replay-next-event" title="next event (n)" onClick={() => jump(1)}>
          ⏭
        </button>
        <span class="replay-time" data-testid="replay-time">
          {formatOffset(pos - loaded.start)} / {formatOffset(loaded.end - loaded.start)}
        </span>
        <span class="replay-rates">
          {RATES.map((r: Rate) => (
            <button
              key={r}
              type="button"
              class={clock.rate === r ? "selected" : ""}
              data-testid={`replay-rate-${r}`}
              onClick={() => send({ type: "rate", rate: r, now: performance.now() })}
            >
              {r}×
            </button>
          ))}
        </span>
      </div>
      <input
        type="range"
        class="replay-seek"
        data-testid="replay-seek"
        aria-label="position in the dive"
        min={loaded.start}
        max={loaded.end}
        step={1}
        value={pos}
        onInput={(e) => {
          seekTo(Number((e.target as HTMLInputElement).value));
        }}
      />
      <ul class="replay-events" data-testid="replay-events">
        {loaded.events.map((e) => (
          <li key={`${e.at}-${e.label}`}>
            <button type="button" class={`replay-event ${e.kind}`} onClick={() => seekTo(e.at)}>
              {formatOffset(e.at - loaded.start)} {e.label}
            </button>
          </li>
        ))}
      </ul>
      <Plots loaded={loaded} cursorRef={cursor} onSeek={seekTo} />
      <Exports dive={loaded.dive} token={props.token} />
      <DiveNotes dive={loaded.dive} token={props.token} editable={props.editable} onSaved={props.onNotes} />
    </div>
  );
}

/**
 * The dive's title and notes (an inspection's findings, what went wrong): edited by who may
 * pilot (local mode, a pilot, the main station), read by everyone else.
 */
function DiveNotes(props: { dive: DiveInfo; token: string | null; editable: boolean; onSaved: (d: DiveInfo) => void }): preact.JSX.Element {
  // the dive as last saved (the page's `loaded` keeps the dive as it was loaded)
  const [saved, setSaved] = useState(props.dive);
  const [title, setTitle] = useState(props.dive.title ?? "");
  const [notes, setNotes] = useState(props.dive.notes ?? "");
  const [status, setStatus] = useState<{ readonly error: boolean; readonly text: string } | null>(null);
  const [saving, setSaving] = useState(false);
  if (!props.editable) {
    return (
      <section class="replay-notes" data-testid="replay-notes">
        <h2>{saved.title ?? "Untitled dive"}</h2>
        <p class="replay-notes-text">{saved.notes ?? "No notes."}</p>
      </section>
    );
  }
  const changes = notesChanges(saved, title, notes);
  const save = async (): Promise<void> => {
    if (changes === null) return;
    setSaving(true);
    try {
      const url = `/api/recordings/${encodeURIComponent(saved.vehicle)}/${encodeURIComponent(saved.name)}`;
      const response = await fetch(url, { method: "PUT", headers: { ...headers(props.token), "content-type": "application/json" }, body: JSON.stringify(changes) });
      if (!response.ok) throw new Error(await errorOf(response));
      const next = withNotes(saved, await response.json());
      if (next === null) throw new Error("unexpected reply");
      setSaved(next);
      setTitle(next.title ?? "");
      setNotes(next.notes ?? "");
      props.onSaved(next);
      setStatus({ error: false, text: "Saved." });
    } catch (err) {
      setStatus({ error: true, text: `Cannot save: ${err instanceof Error ? err.message : String(err)}` });
    } finally {
      setSaving(false);
    }
  };
  return (
    <form
      class="replay-notes"
      data-testid="replay-notes"
      onSubmit={(e) => {
        e.preventDefault();
        void save();
      }}
    >
      <label>
        Title
        <input
          type="text"
          data-testid="replay-title"
          maxLength={200}
          value={title}
          placeholder="e.g. Hull inspection, pier 4"
          onInput={(e) => {
            setTitle((e.target as HTMLInputElement).value);
            setStatus(null);
          }}
        />
      </label>
      <label>
        Notes
        <textarea
          data-testid="replay-notes-text"
          rows={3}
          maxLength={10_000}
          value={notes}
          placeholder="What was found, what went wrong, what to do next"
          onInput={(e) => {
            setNotes((e.target as HTMLTextAreaElement).value);
            setStatus(null);
          }}
        />
      </label>
      <span class="replay-notes-actions">
        <button type="submit" data-testid="replay-notes-save" disabled={changes === null || saving}>
          {saving ? "Saving…" : "Save"}
        </button>
        {status !== null ? (
          <span class={status.error ? "replay-notes-status error" : "replay-notes-status"} data-testid="replay-notes-status">
            {status.text}
          </span>
        ) : null}
      </span>
    </form>
  );
}

/** The dive's exports as downloads (the server makes them; docs/API.md): MP4 only with video. */
function Exports(props: { dive: DiveInfo; token: string | null }): preact.JSX.Element {
  const formats: readonly [ExportFormat, string, string][] = [
    ["mp4", "MP4", "the video with a telemetry subtitle track"],
    ["mcap", "MCAP", "telemetry, events and video for Foxglove"],
    ["csv", "CSV", "the telemetry as a table"],
    ["ass", "ASS", "the telemetry subtitles alone"],
    ["jsonl", "JSON lines", "every entry as recorded"],
  ];
  return (
    <p class="replay-exports" data-testid="replay-exports">
      Export:{" "}
      {formats
        .filter(([format]) => format !== "mp4" || props.dive.video !== null)
        .map(([format, label, title]) => (
          <a key={format} href={recordingUrl(props.dive, format, props.token)} download title={title} data-format={format}>
            {label}
          </a>
        ))}
    </p>
  );
}

function ReplayApp(props: { session: PageSession; params: URLSearchParams }): preact.JSX.Element {
  const [token, setToken] = useState<string | null>(null);
  const [editable, setEditable] = useState(false);
  const [ready, setReady] = useState(false);
  const [dives, setDives] = useState<readonly DiveInfo[] | null>(null);
  const [loaded, setLoaded] = useState<Loaded | null>(null);
  const [message, setMessage] = useState("");
  const vehicle = props.params.get("vehicle");

  useEffect(() => {
    void (async () => {
      const session = await props.session.authenticate();
      if (session === null) return; // leaving for the login page
      const t = props.session.token;
      setToken(t);
      setEditable(mayEditNotes(session));
      setReady(true);
      try {
        const query = vehicle !== null ? `?${new URLSearchParams({ vehicle }).toString()}` : "";
        const response = await fetch(`/api/recordings${query}`, { headers: headers(t), cache: "no-store" });
        if (!response.ok) throw new Error(await errorOf(response));
        const list = decodeDiveList(await response.json());
        if (list === null) throw new Error("unexpected reply to /api/recordings");
        setDives(list);
        const wanted = props.params.get("dive");
        const first = list.find((d) => d.name === wanted);
        if (first !== undefined) void pick(first, t);
      } catch (err) {
        setMessage(`Cannot list the dives: ${err instanceof Error ? err.message : String(err)}`);
      }
    })();
  }, []);

  const pick = async (dive: DiveInfo, t: string | null = token): Promise<void> => {
    setMessage(`Loading ${dive.name}…`);
    try {
      const response = await fetch(diveUrl(dive, "", { format: "jsonl", max: String(MAX_SAMPLES) }), { headers: headers(t), cache: "no-store" });
      if (!response.ok) throw new Error(await errorOf(response));
      const recording = parseRecordingLines(await response.text());
      const times = Float64Array.from(recording.telemetry, (e) => e.at);
      const start = Math.min(dive.startedAt ?? Infinity, times[0] ?? Infinity, recording.events[0]?.at ?? Infinity);
      const lastEvent = recording.events[recording.events.length - 1]?.at ?? -Infinity;
      const end = Math.max(dive.endedAt ?? -Infinity, times[times.length - 1] ?? -Infinity, lastEvent);
      if (!Number.isFinite(start) || !Number.isFinite(end)) throw new Error("this dive holds nothing to replay");
      setLoaded({ dive, recording, times, events: replayEvents(recording.events), start, end });
      setMessage(recording.bad > 0 ? `${recording.bad} lines of the recording could not be read.` : "");
    } catch (err) {
      setMessage(`Cannot load ${dive.name}: ${err instanceof Error ? err.message : String(err)}`);
    }
  };

  const selected = loaded !== null ? `${loaded.dive.vehicle}/${loaded.dive.name}` : null;
  const list = useMemo(() => dives, [dives]);
  return (
    <div class="replay-page" data-testid="replay-page" data-ready={String(ready)}>
      <header class="replay-header">
        <h1>Replay</h1>
        <a href={vehicle !== null ? `/?vehicle=${encodeURIComponent(vehicle)}` : "/"}>operator page</a>
        <a href={vehicle !== null ? `/dev.html?vehicle=${encodeURIComponent(vehicle)}` : "/dev.html"}>developer page</a>
        {message !== "" ? <span class="replay-message" data-testid="replay-message">{message}</span> : null}
      </header>
      <div class="replay-body">
        <aside class="replay-side">{list !== null ? <DiveList dives={list} selected={selected} onPick={(d) => void pick(d)} /> : <p>Listing the dives…</p>}</aside>
        <main class="replay-main">{loaded !== null ? <Player
              key={selected}
              loaded={loaded}
              token={token}
              editable={editable}
              onNotes={(d) => setDives((list) => (list ?? []).map((x) => (x.vehicle === d.vehicle && x.name === d.name ? d : x)))}
            /> : <p>Pick a dive.</p>}</main>
      </div>
    </div>
  );
}

function main(): void {
  const root = document.getElementById("app");
  if (!root) throw new Error("replay page: #app is missing from replay.html");
  const session = new PageSession(browserSessionEnv(() => undefined));
  render(<ReplayApp session={session} params={new URLSearchParams(window.location.search)} />, root);
}

if (document.readyState === "loading") {
  document.addEventListener("DOMContentLoaded", main, { once: true });
} else {
  main();
}
