import assert from 'node:assert/strict';
import { test } from 'node:test';

import {
  chartModel, currentChoice, decades, logExtent, logScale, paretoFlags, paretoFront, placeMarker, plottable,
  renderSvg,
} from '../src/tradeoff.js';

const POINTS = [
  { method: 'frequency', measured_error: 0.1, measured_seconds: 0.01, pareto: true },
  { method: 'frequency', measured_error: 0.01, measured_seconds: 0.1, pareto: true },
  { method: 'frequency', measured_error: 0.05, measured_seconds: 0.2, pareto: false },
  { method: 'angular', measured_error: 0.2, measured_seconds: 0.5, pareto: true },
  { method: 'angular', measured_error: 0.02, measured_seconds: 3, pareto: true },
  { method: 'angular', measured_error: 0, measured_seconds: 4, pareto: true }, // not plottable on a log axis
];
const PLAN = { predicted_error: { rms_min_of_errors: 0.03, rms_appendix_b: 0.05 }, predicted_seconds: 0.05,
  orders: { F_B: 8, P_B: 0 } };

test('logScale maps decades linearly and can flip', () => {
  const x = logScale([0.01, 10], [0, 300]);
  assert.equal(x(0.01), 0);
  assert.equal(x(10), 300);
  assert.ok(Math.abs(x(0.1) - 100) < 1e-9);
  const y = logScale([1e-3, 1], [200, 0]);
  assert.equal(y(1e-3), 200);
  assert.ok(Math.abs(y(0.1) - 200 / 3) < 1e-9);
});

test('logExtent widens to whole decades and ignores non-positive values', () => {
  assert.deepEqual(logExtent([0.02, 0.3, 0, -1, NaN]), [0.01, 1]);
  assert.deepEqual(logExtent([1, 1]), [1, 10]);
  assert.deepEqual(logExtent([]), [0.1, 1]);
  assert.deepEqual(decades([0.01, 1]).map((v) => Number(v.toPrecision(3))), [0.01, 0.1, 1]);
});

test('paretoFlags matches relight.tradeoff.pareto_flags (ties in both keep both)', () => {
  assert.deepEqual(paretoFlags([1, 2, 0.5, 1], [1, 0.5, 2, 1]), [true, true, true, true]);
  assert.deepEqual(paretoFlags([1, 2, 3], [1, 2, 0.5]), [true, false, true]);
});

test('paretoFront: server flags when present, sorted by time; computed otherwise', () => {
  const f = paretoFront(POINTS, 'frequency');
  assert.deepEqual(f.map((p) => p.measured_seconds), [0.01, 0.1]);
  const unflagged = POINTS.map((p) => {
    const copy = { ...p };
    delete copy.pareto;
    return copy;
  });
  assert.deepEqual(paretoFront(unflagged, 'frequency').map((p) => p.measured_seconds), [0.01, 0.1]);
  assert.equal(paretoFront(POINTS, 'angular').length, 2);
  assert.equal(plottable(POINTS).length, 5);
});

test('currentChoice reads the /plan answer', () => {
  assert.deepEqual(currentChoice(PLAN), { error: 0.03, seconds: 0.05, orders: { F_B: 8, P_B: 0 } });
  assert.equal(currentChoice(null), null);
  assert.equal(currentChoice({ predicted_error: {}, predicted_seconds: 1 }), null);
});

test('placeMarker clamps to the axes and says so', () => {
  const x = logScale([0.01, 1], [40, 240]);
  const y = logScale([0.01, 1], [170, 10]);
  const inside = placeMarker({ error: 0.1, seconds: 0.1 }, x, y);
  assert.deepEqual(inside, { x: 140, y: 90, clamped: false });
  const out = placeMarker({ error: 1e-4, seconds: 100 }, x, y);
  assert.deepEqual(out, { x: 240, y: 170, clamped: true });
});

test('chartModel and renderSvg: both methods, their fronts and the current choice', () => {
  const m = chartModel(POINTS, PLAN, { width: 300, height: 200 });
  assert.equal(m.series.find((s) => s.method === 'frequency').points.length, 3);
  assert.equal(m.series.find((s) => s.method === 'angular').points.length, 2);
  assert.ok(m.marker && !m.marker.clamped);
  assert.ok(m.x.domain[0] <= 0.01 && m.x.domain[1] >= 3);
  const svg = renderSvg(m);
  assert.equal((svg.match(/class="point" data-method="frequency"/g) || []).length, 3);
  assert.equal((svg.match(/class="point" data-method="angular"/g) || []).length, 2);
  assert.equal((svg.match(/class="front"/g) || []).length, 2);
  assert.equal((svg.match(/class="current"/g) || []).length, 1);
  assert.ok(svg.startsWith('<svg') && svg.endsWith('</svg>'));
  assert.ok(!renderSvg(chartModel(POINTS, null)).includes('class="current"'));
});

test('chartModel and renderSvg: errors against Mitsuba 3 and its noise floor, only when computed', () => {
  const pts = POINTS.map((p, k) => ({ ...p, mitsuba_error: p.method === 'frequency' ? 2e-4 * (k + 1) : null }));
  const meta = { mitsuba: { computed: true, noise: 1e-4, reference_error: 1.5e-4 } };
  const m = chartModel(pts, PLAN, { width: 300, height: 200, meta });
  assert.equal(m.mitsuba.points.length, 3);
  assert.ok(m.y.domain[0] <= 1e-4, 'the axis reaches down to the noise floor');
  const expected = m.y(1e-4);
  assert.equal(m.mitsuba.noise.y, expected);
  const svg = renderSvg(m);
  assert.equal((svg.match(/class="mitsuba-point" data-method="frequency"/g) || []).length, 3);
  assert.equal((svg.match(/class="mitsuba-noise"/g) || []).length, 1);
  assert.ok(svg.includes('vs Mitsuba'));
  const off = renderSvg(chartModel(pts, PLAN, { meta: { mitsuba: { computed: false, reason: 'no twin' } } }));
  assert.ok(!off.includes('mitsuba-point') && !off.includes('mitsuba-noise') && !off.includes('vs Mitsuba'));
});
