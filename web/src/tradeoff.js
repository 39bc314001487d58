// Accuracy against time (POST /tradeoffs, relight/tradeoff.py): a log-log chart of measured error vs measured
// seconds for both methods, their Pareto fronts, the current choice (the last /plan: predicted error and time) and,
// when the material has a Mitsuba 3 twin, each point's error against Mitsuba (hollow squares) with the render's
// Monte Carlo noise floor (dotted): below the floor Mitsuba cannot tell the points apart.
// Pure functions (no DOM): the page inserts the SVG string; web/test/tradeoff.test.js tests them under node.

export const METHODS = ['frequency', 'angular'];
export const COLORS = { frequency: '#6cb4ff', angular: '#ffb347', current: '#ff5c8a', mitsuba: '#e0e0e0' };

/** A log10 scale from [lo, hi] (positive) onto [a, b] (pixels; b < a flips the axis). */
export function logScale([lo, hi], [a, b]) {
  const l0 = Math.log10(lo);
  const l1 = Math.log10(hi);
  const span = l1 - l0 || 1;
  const f = (v) => a + ((Math.log10(v) - l0) / span) * (b - a);
  f.domain = [lo, hi];
  f.range = [a, b];
  return f;
}

/** [lo, hi] of the positive finite values, widened to whole decades (at least one decade wide). */
export function logExtent(values) {
  const v = values.filter((x) => Number.isFinite(x) && x > 0);
  if (!v.length) {
    return [0.1, 1];
  }
  let lo = Math.floor(Math.log10(Math.min(...v)));
  let hi = Math.ceil(Math.log10(Math.max(...v)));
  if (hi <= lo) {
    hi = lo + 1;
  }
  return [10 ** lo, 10 ** hi];
}

/** Powers of ten inside [lo, hi] (the tick marks of a log axis). */
export function decades([lo, hi]) {
  const out = [];
  for (let e = Math.round(Math.log10(lo)); e <= Math.round(Math.log10(hi)); e += 1) {
    out.push(10 ** e);
  }
  return out;
}

/** True for each point no other beats in both error and time (ties in both keep both): relight.tradeoff.pareto_flags. */
export function paretoFlags(errors, seconds) {
  return errors.map((e, i) => !errors.some((e2, j) => e2 <= e && seconds[j] <= seconds[i]
    && (e2 < e || seconds[j] < seconds[i])));
}

/** Points usable on a log-log chart (positive, finite measured error and seconds). */
export function plottable(points) {
  return (points || []).filter((p) => Number.isFinite(p.measured_error) && p.measured_error > 0
    && Number.isFinite(p.measured_seconds) && p.measured_seconds > 0);
}

/** The Pareto front of one method, ordered by time: the server's `pareto` flags, or computed when absent. */
export function paretoFront(points, method) {
  const mine = plottable(points).filter((p) => p.method === method);
  const flags = mine.every((p) => typeof p.pareto === 'boolean')
    ? mine.map((p) => p.pareto)
    : paretoFlags(mine.map((p) => p.measured_error), mine.map((p) => p.measured_seconds));
  return mine.filter((_, i) => flags[i]).sort((a, b) => a.measured_seconds - b.measured_seconds
    || b.measured_error - a.measured_error);
}

/** The current choice from a POST /plan answer: {error, seconds}, or null when the plan has neither. */
export function currentChoice(plan) {
  if (!plan) {
    return null;
  }
  const e = plan.predicted_error;
  const error = typeof e === 'number' ? e : e?.rms_min_of_errors ?? e?.rms_appendix_b;
  const seconds = plan.predicted_seconds;
  if (!(Number.isFinite(error) && error > 0 && Number.isFinite(seconds) && seconds > 0)) {
    return null;
  }
  return { error, seconds, orders: plan.orders || null };
}

/** Marker position; a value outside the axes is clamped to the edge and flagged (drawn hollow). */
export function placeMarker(choice, x, y) {
  if (!choice) {
    return null;
  }
  const clamp = (v, r) => Math.min(Math.max(v, Math.min(...r)), Math.max(...r));
  const px = x(choice.seconds);
  const py = y(choice.error);
  const cx = clamp(px, x.range);
  const cy = clamp(py, y.range);
  return { x: cx, y: cy, clamped: cx !== px || cy !== py };
}

const positive = (v) => Number.isFinite(v) && v > 0;

/** The Mitsuba comparison of a sweep's meta (`meta.mitsuba`): {noise, reference} when computed, else null. */
export function mitsubaFloor(meta) {
  const m = meta?.mitsuba;
  return m && m.computed ? { noise: m.noise, reference: m.reference_error } : null;
}

/** Everything the chart draws, in pixels. `meta` (the sweep's) adds the Mitsuba errors and the noise floor. */
export function chartModel(points, plan, { width = 280, height = 200, margin = { l: 40, r: 8, t: 20, b: 30 },
  meta = null } = {}) {
  const pts = plottable(points);
  const choice = currentChoice(plan);
  const floor = mitsubaFloor(meta);
  const vsMitsuba = floor ? pts.filter((p) => positive(p.mitsuba_error)) : [];
  const xs = pts.map((p) => p.measured_seconds);
  const ys = pts.map((p) => p.measured_error).concat(vsMitsuba.map((p) => p.mitsuba_error));
  if (choice) {
    xs.push(choice.seconds);
    ys.push(choice.error);
  }
  if (floor && positive(floor.noise)) {
    ys.push(floor.noise);
  }
  const x = logScale(logExtent(xs), [margin.l, width - margin.r]);
  const y = logScale(logExtent(ys), [height - margin.b, margin.t]);
  const series = METHODS.map((method) => ({
    method,
    points: pts.filter((p) => p.method === method).map((p) => ({ x: x(p.measured_seconds), y: y(p.measured_error),
      pareto: Boolean(p.pareto), point: p })),
    front: paretoFront(pts, method).map((p) => [x(p.measured_seconds), y(p.measured_error)]),
  }));
  const mitsuba = floor ? {
    points: vsMitsuba.map((p) => ({ x: x(p.measured_seconds), y: y(p.mitsuba_error), point: p })),
    noise: positive(floor.noise) ? { y: y(floor.noise), value: floor.noise } : null,
  } : null;
  return { width, height, margin, x, y, series, mitsuba, marker: placeMarker(choice, x, y), choice,
    xticks: decades(x.domain), yticks: decades(y.domain) };
}

const fmt = (v) => (v >= 1e-2 && v < 1e3 ? String(Number(v.toPrecision(2))) : v.toExponential(0).replace('+', ''));

/** The chart as an SVG string (class names / data attributes are what the tests read). */
export function renderSvg(m) {
  const { width: w, height: h, margin: g } = m;
  const out = [`<svg xmlns="http://www.w3.org/2000/svg" class="tradeoff-chart" viewBox="0 0 ${w} ${h}" `
    + `width="${w}" height="${h}" role="img" aria-label="measured error against measured time, log-log">`];
  out.push(`<rect x="${g.l}" y="${g.t}" width="${w - g.l - g.r}" height="${h - g.t - g.b}" fill="#1b1d21" `
    + 'stroke="#555"/>');
  for (const t of m.xticks) {
    const px = m.x(t).toFixed(1);
    out.push(`<line x1="${px}" x2="${px}" y1="${g.t}" y2="${h - g.b}" stroke="#333"/>`
      + `<text x="${px}" y="${h - g.b + 12}" text-anchor="middle" font-size="9" fill="#999">${fmt(t)}</text>`);
  }
  for (const t of m.yticks) {
    const py = m.y(t).toFixed(1);
    out.push(`<line x1="${g.l}" x2="${w - g.r}" y1="${py}" y2="${py}" stroke="#333"/>`
      + `<text x="${g.l - 3}" y="${py}" text-anchor="end" dominant-baseline="middle" font-size="9" fill="#999">`
      + `${fmt(t)}</text>`);
  }
  out.push(`<text x="${(g.l + w - g.r) / 2}" y="${h - 3}" text-anchor="middle" font-size="10" fill="#bbb">`
    + 'measured seconds</text>');
  out.push(`<text transform="translate(10 ${(g.t + h - g.b) / 2}) rotate(-90)" text-anchor="middle" font-size="10" `
    + 'fill="#bbb">relative RMS error</text>');
  for (const s of m.series) {
    const c = COLORS[s.method];
    if (s.front.length) {
      out.push(`<polyline class="front" data-method="${s.method}" fill="none" stroke="${c}" stroke-width="1.5" `
        + `points="${s.front.map(([px, py]) => `${px.toFixed(1)},${py.toFixed(1)}`).join(' ')}"/>`);
    }
    for (const p of s.points) {
      const o = p.point.orders ? JSON.stringify(p.point.orders).replace(/"/g, '') : '';
      out.push(`<circle class="point" data-method="${s.method}" cx="${p.x.toFixed(1)}" cy="${p.y.toFixed(1)}" `
        + `r="3" fill="${p.pareto ? c : 'none'}" stroke="${c}"><title>${s.method} ${o}: error `
        + `${p.point.measured_error.toPrecision(3)}, ${p.point.measured_seconds.toPrecision(3)} s</title></circle>`);
    }
  }
  if (m.mitsuba) {
    const c = COLORS.mitsuba;
    if (m.mitsuba.noise) {
      const py = m.mitsuba.noise.y.toFixed(1);
      out.push(`<line class="mitsuba-noise" x1="${g.l}" x2="${w - g.r}" y1="${py}" y2="${py}" stroke="${c}" `
        + `stroke-dasharray="2 3"><title>Mitsuba 3 Monte Carlo noise floor: ${m.mitsuba.noise.value.toPrecision(2)}`
        + '</title></line>');
    }
    for (const p of m.mitsuba.points) {
      out.push(`<rect class="mitsuba-point" data-method="${p.point.method}" x="${(p.x - 3).toFixed(1)}" `
        + `y="${(p.y - 3).toFixed(1)}" width="6" height="6" fill="none" stroke="${c}"><title>${p.point.method}: `
        + `error vs Mitsuba 3 ${p.point.mitsuba_error.toPrecision(3)}</title></rect>`);
    }
  }
  if (m.marker) {
    const { x: mx, y: my, clamped } = m.marker;
    const d = 6;
    out.push(`<path class="current" d="M${mx} ${my - d}L${mx + d} ${my}L${mx} ${my + d}L${mx - d} ${my}Z" `
      + `fill="${clamped ? 'none' : COLORS.current}" stroke="#fff" stroke-width="1"><title>current choice `
      + `(predicted): error ${m.choice.error.toPrecision(3)}, ${m.choice.seconds.toPrecision(3)} s`
      + `${clamped ? ' (off the axes)' : ''}</title></path>`);
  }
  let lx = g.l; // legend: one row above the plot, clear of the data
  const legend = [['frequency', COLORS.frequency], ['angular', COLORS.angular], ['current', COLORS.current]];
  if (m.mitsuba?.points.length) {
    legend.push(['vs Mitsuba', COLORS.mitsuba]);
  }
  for (const [label, c] of legend) {
    out.push(`<circle cx="${lx + 3}" cy="8" r="3" fill="${c}"/><text x="${lx + 9}" y="11" font-size="9" `
      + `fill="#ddd">${label}</text>`);
    lx += 14 + 5 * label.length;
  }
  out.push('</svg>');
  return out.join('');
}
