/**
 * The video's views: the picture (the player's canvas or video, turned by the vehicle's
 * camera rotation), the stream-health line under it, and the latency figure for the HUD.
 */

import { useEffect, useRef } from "preact/hooks";
import type { Rotation } from "../lib/prefs";
import { useStore } from "../lib/use_store";
import { formatBitrate, formatLatency } from "./health";
import { PATH_CHOICES, PATH_LABELS, parsePathChoice } from "./path";
import type { VideoPlayer, VideoView } from "./player";

/** What the picture area says while there is no picture (null: the picture is showing). */
export function waitingText(v: VideoView): string | null {
  if (v.note !== null && v.path === null && v.stream !== null) return v.note;
  if (v.camera !== null && v.camera.state !== "running") {
    const why = v.camera.reason !== null ? `: ${v.camera.reason}` : "";
    switch (v.camera.state) {
      case "starting":
        return "Camera starting…";
      case "restarting":
        return `Camera restarting${why}`;
      case "failed":
        return `Camera failed${why}`;
      case "idle":
        return "Camera idle — waking it up…";
      case "none":
        return "This vehicle publishes no video stream.";
    }
  }
  if (v.socket === "closed") return v.failures > 1 ? "Video stream refused or unreachable — retrying…" : "Video stream interrupted — reconnecting…";
  if (v.socket === "connecting" || v.socket === "off") return "Connecting to the camera…";
  if (v.health?.frozen === true && v.showing) return "Picture frozen — waiting for the camera…";
  if (!v.showing) return "Waiting for the first picture…";
  return null;
}

/** The picture, turned by `rotation`, with what it waits for said over it. */
export function VideoFeed(props: { player: VideoPlayer; rotation: Rotation }): preact.JSX.Element {
  const { player, rotation } = props;
  const v = useStore(player.store);
  const box = useRef<HTMLDivElement>(null);
  useEffect(() => {
    player.attach(box.current);
    return () => player.attach(null);
  }, [player]);
  const waiting = waitingText(v);
  return (
    <>
      <div
        ref={box}
        class="feed video-feed"
        data-testid="video-feed"
        data-path={v.path ?? "none"}
        data-showing={String(v.showing)}
        style={{ transform: `rotate(${rotation}deg)` }}
      />
      {waiting !== null && (
        <div class="camera-lost video-waiting" data-testid="video-waiting" role="status">
          {waiting}
        </div>
      )}
    </>
  );
}

const CODEC_LABELS = { h264: "H.264", mjpeg: "MJPEG" } as const;

/**
 * Codec, size, frames shown per second, bitrate, frames dropped, freezes and the latency
 * (server→display; render→display for the sim camera), and the decode path with its selector.
 */
export function VideoHealthLine(props: { player: VideoPlayer; onSnapshot?: () => void }): preact.JSX.Element {
  const { player, onSnapshot } = props;
  const v = useStore(player.store);
  const h = v.health;
  const s = v.stream;
  const render = h?.renderToDisplay.p50 ?? null;
  return (
    <p class="video-health" data-testid="video-health" data-frozen={String(h?.frozen ?? false)}>
      <span data-field="codec">{s ? `${CODEC_LABELS[s.codec]} ${s.width}×${s.height}` : "no stream"}</span>
      <span data-field="fps">{h ? `${h.fps.toFixed(0)} fps` : "— fps"}</span>
      <span data-field="bitrate">{h ? formatBitrate(h.bitrate) : "—"}</span>
      <span data-field="dropped">dropped {h?.dropped ?? 0}</span>
      <span data-field="freezes" class={h?.frozen ? "warn" : undefined}>
        freezes {h?.freezes ?? 0}
      </span>
      <span data-field="latency" title="server → display (median of the last 2 s)">
        latency {formatLatency(h?.serverToDisplay.p50 ?? null)}
      </span>
      {render !== null && (
        <span data-field="render-latency" title="rendered → displayed, read from the picture's corner (median of the last 2 s)">
          render→display {formatLatency(render)} (p99 {formatLatency(h?.renderToDisplay.p99 ?? null)})
        </span>
      )}
      {onSnapshot !== undefined && (
        <button type="button" class="snapshot" data-testid="snapshot" title="Save the current picture on the server (full resolution JPEG)" onClick={onSnapshot}>
          Snapshot
        </button>
      )}
      <label class="video-path">
        <span>{v.path !== null ? PATH_LABELS[v.path] : "decoder"}</span>
        <select
          data-testid="video-path"
          aria-label="Video decode path"
          value={v.choice}
          onChange={(e) => {
            const choice = parsePathChoice(e.currentTarget.value);
            if (choice !== null) player.setChoice(choice);
          }}
        >
          {PATH_CHOICES.map((c) => (
            <option key={c} value={c}>
              {c === "auto" ? "auto" : PATH_LABELS[c]}
            </option>
          ))}
        </select>
      </label>
      {v.note !== null && (
        <span class="note" data-field="note">
          {v.note}
        </span>
      )}
    </p>
  );
}

/** The picture's latency for the HUD: render→display when the picture says, else server→display. */
export function VideoLatency(props: { player: VideoPlayer }): preact.JSX.Element | null {
  const v = useStore(props.player.store);
  const h = v.health;
  if (v.socket === "off") return null;
  const render = h?.renderToDisplay.p50 ?? null;
  const value = render ?? h?.serverToDisplay.p50 ?? null;
  return (
    <span data-testid="hud-video-latency" data-kind={render !== null ? "render" : "server"} title={render !== null ? "video: rendered → displayed" : "video: server → displayed"}>
      video <b>{formatLatency(value)}</b>
      {h?.frozen ? " (frozen)" : ""}
    </span>
  );
}
