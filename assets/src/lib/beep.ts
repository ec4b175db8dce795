/**
 * Audible warnings (Web Audio): the main station's takeover and a control request must be
 * heard, not only seen. Browsers allow sound only after the user has interacted with the page;
 * until then (and where there is no audio) a beep is silently skipped.
 */

let context: AudioContext | null = null;

/** `count` short tones of `hz` Hz, `ms` long, `gapMs` apart. */
export function beep(count = 1, hz = 880, ms = 150, gapMs = 120): void {
  try {
    context ??= new AudioContext();
    const ctx = context;
    if (ctx.state === "suspended") void ctx.resume().catch(() => undefined);
    for (let i = 0; i < count; i++) {
      const start = ctx.currentTime + (i * (ms + gapMs)) / 1000;
      const osc = ctx.createOscillator();
      const gain = ctx.createGain();
      osc.frequency.value = hz;
      gain.gain.value = 0.2;
      osc.connect(gain).connect(ctx.destination);
      osc.start(start);
      osc.stop(start + ms / 1000);
    }
  } catch {
    // no audio here: the on-screen warning has to do
  }
}
