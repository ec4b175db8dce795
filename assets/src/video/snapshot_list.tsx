/** The developer page's list of the vehicle's camera snapshots on the server, with download links. */

import { useCallback, useEffect, useState } from "preact/hooks";
import { formatBytes } from "../lib/recordings";
import { fetchSnapshots, snapshotUrl } from "./snapshots";
import type { SnapshotInfo } from "./snapshots";

export function SnapshotList(props: { vehicle: string | null; token: string | null }): preact.JSX.Element {
  const { vehicle, token } = props;
  const [list, setList] = useState<readonly SnapshotInfo[] | null>(null);
  const [error, setError] = useState<string | null>(null);
  const load = useCallback(() => {
    if (vehicle === null) return;
    fetchSnapshots(vehicle, token).then(
      (snapshots) => {
        setList(snapshots);
        setError(null);
      },
      (err: unknown) => setError(err instanceof Error ? err.message : String(err)),
    );
  }, [vehicle, token]);
  useEffect(load, [load]);
  const count = list?.length ?? 0;
  return (
    <details class="recordings snapshots" id="snapshots" data-testid="snapshots" onToggle={(e) => e.currentTarget.open && load()}>
      <summary>Snapshots on the server{list === null ? "" : ` (${count})`}</summary>
      <div class="toolbar">
        <button type="button" id="snapshots-refresh" data-testid="snapshots-refresh" onClick={load}>
          Refresh
        </button>
        {error !== null && (
          <span class="field-status" data-state="error" role="alert">
            {error}
          </span>
        )}
      </div>
      {list !== null && count === 0 && <p class="note">No snapshots of this vehicle yet (the operator page's Snapshot button takes one).</p>}
      {count > 0 && (
        <ul class="recording-list" data-testid="snapshot-list">
          {list?.map((s) => (
            <li key={s.name} data-name={s.name}>
              <span class="recording-name">{new Date(s.takenAt).toLocaleString("en-GB")}</span>
              <span class="note">
                {s.name} · {formatBytes(s.bytes)}
              </span>
              <a href={snapshotUrl(s, token)} download={s.name}>
                JPEG
              </a>
            </li>
          ))}
        </ul>
      )}
    </details>
  );
}
