/**
 * The live edge of a <video> fed by Media Source Extensions (pure). The video plays what is
 * buffered at the camera's nominal rate; when frames come faster than it plays (a camera a
 * little faster than its nominal rate, a page that was busy) the lag grows. Kept small by:
 * a slightly faster playback while it lags a few frames, a jump to the newest frame when it
 * lags more than JUMP_S, and trimming what lies behind the playhead beyond KEEP_S.
 */

/** lag (s) past which the video jumps to the newest frame */
export const JUMP_S = 0.3;
/** buffer (s) kept behind the playhead; older is removed once it exceeds TRIM_AFTER_S */
export const KEEP_S = 2;
export const TRIM_AFTER_S = 10;
/** frames of lag played at normal speed (the newest frame is always one frame ahead) */
const SLACK_FRAMES = 2;

export interface EdgeDecision {
  /** where to move the playhead (null: stay) */
  readonly seekTo: number | null;
  readonly rate: number;
  /** remove the buffer from its start to here (null: nothing to trim) */
  readonly trimTo: number | null;
  /** frames jumped over (never shown) */
  readonly skipped: number;
}

/**
 * What to do given the buffered range (s), the playhead (s) and the frame duration (s).
 */
export function liveEdge(buffered: { readonly start: number; readonly end: number } | null, currentTime: number, frameS: number): EdgeDecision {
  if (buffered === null || !(frameS > 0)) return { seekTo: null, rate: 1, trimTo: null, skipped: 0 };
  const lag = buffered.end - currentTime;
  const trimTo = currentTime - buffered.start > TRIM_AFTER_S ? currentTime - KEEP_S : null;
  if (currentTime < buffered.start || lag > JUMP_S) {
    // the newest frame's middle: it is shown at once, and the next one follows it
    const seekTo = Math.max(buffered.start, buffered.end - frameS / 2);
    const skipped = currentTime < buffered.start ? 0 : Math.max(0, Math.round((seekTo - currentTime) / frameS) - 1);
    return { seekTo, rate: 1, trimTo, skipped };
  }
  const lagFrames = lag / frameS;
  // 5 % faster per frame of lag beyond the slack, up to 25 %: catches up within a second or two
  const rate = lagFrames <= SLACK_FRAMES ? 1 : Math.min(1.25, 1 + (lagFrames - SLACK_FRAMES) * 0.05);
  return { seekTo: null, rate: Math.round(rate * 100) / 100, trimTo, skipped: 0 };
}
