// Percentiles for the benches' figures.

/** Delivery latency histogram: 0.1 ms bins up to 10 s (the last bin: beyond). */
export const BINS = 100_000;

/** The p-th percentile (ms) of a BINS + 1 histogram of 0.1 ms bins; NaN when empty. */
export function histPct(hist, p) {
  let n = 0; for (let b = 0; b <= BINS; b++) n += hist[b];
  if (n === 0) return NaN;
  const want = Math.ceil((p / 100) * n);
  let c = 0;
  for (let b = 0; b <= BINS; b++) { c += hist[b]; if (c >= want) return (b + 1) / 10; }
  return NaN;
}

/** The p-th percentile (nearest rank) of samples `xs`; NaN when empty. */
export function pct(xs, p) {
  if (!xs.length) return NaN;
  const s = [...xs].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.max(0, Math.ceil((p / 100) * s.length) - 1))];
}
