// Charts of the in-out factorization analysis (Mahajan, Tseng & Ramamoorthi 2008; factorization jobs,
// relight/factor_analysis.py). Pure functions (no DOM): the panel (inout_panel.js) inserts the SVG strings;
// web/test/factor_chart.test.js tests them under node.
//   termsVsPhong: K (99 %) against the Phong exponent, measured hemisphere and sphere points with the paper's
//     lines K = 2.5 s and 5 s (Fig. 3A), the current material marked;
//   singularValues: sigma_k against k (log y) with F_l, each repeated l + 1 times on the hemisphere (2l + 1 on the
//     sphere) for radial lobes (Figs. 2 and 5);
//   termsVsLStar: K (99 %) against (l*)^2 with the Torrance-Sparrow line and measured materials (Fig. 7C).

import { COLORS } from './tradeoff.js';

const W = 360;
const H = 220;
const PAD = { l: 48, r: 12, t: 14, b: 34 };

const esc = (s) => String(s).replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]));
const fmt = (v) => (Math.abs(v) >= 100 || Number.isInteger(v) ? String(Math.round(v)) : v.toPrecision(2));

/** A linear scale [lo, hi] -> [a, b]. */
export function linScale([lo, hi], [a, b]) {
  const span = hi - lo || 1;
  return (v) => a + ((v - lo) / span) * (b - a);
}

/** F_l repeated l + 1 (hemisphere) or 2l + 1 (sphere) times, descending: the predicted singular values. */
export function repeatedTransfer(transfer, domain) {
  const out = [];
  transfer.forEach((f, l) => {
    const n = domain === 'sphere' ? 2 * l + 1 : l + 1;
    for (let i = 0; i < n; i += 1) {
      out.push(Math.abs(f));
    }
  });
  return out.sort((a, b) => b - a);
}

function frame(title, xLabel, yLabel, xTicks, yTicks, body, id) {
  const axes = [
    `<line x1="${PAD.l}" y1="${H - PAD.b}" x2="${W - PAD.r}" y2="${H - PAD.b}" stroke="#888"/>`,
    `<line x1="${PAD.l}" y1="${PAD.t}" x2="${PAD.l}" y2="${H - PAD.b}" stroke="#888"/>`,
    ...xTicks.map(([x, t]) => `<text x="${x}" y="${H - PAD.b + 13}" font-size="10" fill="#ccc" `
      + `text-anchor="middle">${esc(t)}</text>`),
    ...yTicks.map(([y, t]) => `<text x="${PAD.l - 4}" y="${y + 3}" font-size="10" fill="#ccc" `
      + `text-anchor="end">${esc(t)}</text>`),
    `<text x="${(PAD.l + W - PAD.r) / 2}" y="${H - 4}" font-size="11" fill="#ddd" text-anchor="middle">`
      + `${esc(xLabel)}</text>`,
    `<text x="12" y="${(PAD.t + H - PAD.b) / 2}" font-size="11" fill="#ddd" text-anchor="middle" `
      + `transform="rotate(-90 12 ${(PAD.t + H - PAD.b) / 2})">${esc(yLabel)}</text>`,
    `<text x="${PAD.l + 4}" y="${PAD.t + 10}" font-size="11" fill="#fff">${esc(title)}</text>`,
  ];
  return `<svg xmlns="http://www.w3.org/2000/svg" id="${id}" width="${W}" height="${H}" viewBox="0 0 ${W} ${H}">`
    + `${axes.join('')}${body.join('')}</svg>`;
}

const ticks = (lo, hi, n, scale) => Array.from({ length: n + 1 }, (_, i) => lo + (i * (hi - lo)) / n)
  .map((v) => [scale(v), fmt(v)]);
const dot = (x, y, color, cls, r = 3.5) => `<circle class="${cls}" cx="${x.toFixed(1)}" cy="${y.toFixed(1)}" `
  + `r="${r}" fill="${color}"/>`;
const line = (pts, color, cls, dash = '') => `<polyline class="${cls}" fill="none" stroke="${color}" `
  + `${dash ? `stroke-dasharray="${dash}" ` : ''}points="${pts.map(([x, y]) => `${x.toFixed(1)},${y.toFixed(1)}`)
    .join(' ')}"/>`;

/**
 * Fig. 3A. `points`: [{s, hemisphere, sphere}] (K at 99 %); `current`: {s, K} or null.
 */
export function termsVsPhong(points, current = null) {
  const sMax = Math.max(50, ...points.map((p) => p.s), current?.s ?? 0);
  const kMax = Math.max(5 * sMax, ...points.map((p) => p.sphere ?? 0), current?.K ?? 0);
  const x = linScale([0, sMax], [PAD.l, W - PAD.r]);
  const y = linScale([0, kMax], [H - PAD.b, PAD.t]);
  const body = [
    line([[x(0), y(0)], [x(sMax), y(2.5 * sMax)]], COLORS.frequency, 'paper-hemisphere', '4 3'),
    line([[x(0), y(0)], [x(sMax), y(5 * sMax)]], COLORS.angular, 'paper-sphere', '4 3'),
    ...points.filter((p) => Number.isFinite(p.hemisphere)).map((p) => dot(x(p.s), y(p.hemisphere),
      COLORS.frequency, 'measured-hemisphere')),
    ...points.filter((p) => Number.isFinite(p.sphere)).map((p) => dot(x(p.s), y(p.sphere), COLORS.angular,
      'measured-sphere')),
  ];
  if (current && Number.isFinite(current.s) && Number.isFinite(current.K)) {
    body.push(dot(x(current.s), y(current.K), COLORS.current, 'current', 5));
  }
  return frame('K (99 %) vs Phong s: hemisphere (blue, 2.5 s), sphere (orange, 5 s)', 'Phong exponent s',
    'terms K', ticks(0, sMax, 5, x), ticks(0, kMax, 4, y), body, 'chart-phong');
}

/** Figs. 2 and 5: singular values (log) against their index, with the predicted F_l when given. */
export function singularValues(values, predicted = null) {
  const pos = values.filter((v) => v > 0);
  const n = Math.max(pos.length, predicted?.length ?? 0, 2);
  const all = [...pos, ...(predicted || []).filter((v) => v > 0)];
  const lo = Math.log10(Math.min(...all, 1) * 0.9);
  const hi = Math.log10(Math.max(...all, 1e-300) * 1.1);
  const x = linScale([1, n], [PAD.l, W - PAD.r]);
  const ly = linScale([lo, hi], [H - PAD.b, PAD.t]);
  const y = (v) => ly(Math.log10(v));
  const body = pos.map((v, i) => dot(x(i + 1), y(v), COLORS.frequency, 'sigma', 2));
  if (predicted?.length) {
    body.push(line(predicted.filter((v) => v > 0).map((v, i) => [x(i + 1), y(v)]), COLORS.current, 'f-l'));
  }
  const yTicks = [];
  for (let e = Math.ceil(lo); e <= Math.floor(hi); e += 1) {
    yTicks.push([ly(e), `1e${e}`]);
  }
  return frame('singular values (dots) and F_l (line)', 'k', 'sigma_k', ticks(1, n, 4, x), yTicks, body,
    'chart-sigma');
}

/** Fig. 7C. `ts`: [{label, lStar, K}] (Torrance-Sparrow line); `measured`, `current`: points alike. */
export function termsVsLStar(ts, measured = [], current = null) {
  const pts = [...ts, ...measured, ...(current ? [current] : [])];
  const xMax = Math.max(1, ...pts.map((p) => p.lStar ** 2));
  const kMax = Math.max(1, ...pts.map((p) => p.K));
  const x = linScale([0, xMax], [PAD.l, W - PAD.r]);
  const y = linScale([0, kMax], [H - PAD.b, PAD.t]);
  const sorted = [...ts].sort((a, b) => a.lStar - b.lStar);
  const body = [
    line(sorted.map((p) => [x(p.lStar ** 2), y(p.K)]), COLORS.angular, 'ts-line'),
    ...sorted.map((p) => dot(x(p.lStar ** 2), y(p.K), COLORS.angular, 'ts')),
    ...measured.map((p) => dot(x(p.lStar ** 2), y(p.K), COLORS.mitsuba, 'measured')),
  ];
  if (current) {
    body.push(dot(x(current.lStar ** 2), y(current.K), COLORS.current, 'current', 5));
  }
  return frame('K (99 %) vs (l*)^2: Torrance-Sparrow (line), measured (grey)', '(l*)^2', 'terms K',
    ticks(0, xMax, 4, x), ticks(0, kMax, 4, y), body, 'chart-lstar');
}
