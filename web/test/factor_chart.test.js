import assert from 'node:assert/strict';
import { test } from 'node:test';

import { linScale, repeatedTransfer, singularValues, termsVsLStar, termsVsPhong } from '../src/factor_chart.js';
import { wholePairs } from '../src/inout_object.js';

const count = (svg, cls) => (svg.match(new RegExp(`class="${cls}"`, 'g')) || []).length;

test('repeatedTransfer repeats F_l l + 1 times on the hemisphere and 2l + 1 on the sphere, descending', () => {
  assert.deepEqual(repeatedTransfer([1, 0.5, -0.25], 'hemisphere'), [1, 0.5, 0.5, 0.25, 0.25, 0.25]);
  assert.equal(repeatedTransfer([1, 0.5, 0.25], 'sphere').length, 9);
});

test('linScale maps the ends', () => {
  const s = linScale([0, 10], [100, 0]);
  assert.equal(s(0), 100);
  assert.equal(s(10), 0);
  assert.equal(s(5), 50);
});

test('termsVsPhong draws both lines, every point and the current material', () => {
  const svg = termsVsPhong([{ s: 10, hemisphere: 27, sphere: 49 }, { s: 30, hemisphere: 75, sphere: 141 }],
    { s: 20, K: 51 });
  assert.equal(count(svg, 'measured-hemisphere'), 2);
  assert.equal(count(svg, 'measured-sphere'), 2);
  assert.equal(count(svg, 'current'), 1);
  assert.equal(count(svg, 'paper-hemisphere'), 1);
  assert.equal(count(termsVsPhong([], null), 'current'), 0);
});

test('singularValues plots positive values and the F_l line; termsVsLStar the TS line and measured points', () => {
  const svg = singularValues([1, 0.5, 0.5, 0, 0.1], [1, 0.5, 0.5, 0.1]);
  assert.equal(count(svg, 'sigma'), 4);
  assert.equal(count(svg, 'f-l'), 1);
  const c = termsVsLStar([{ lStar: 15, K: 64 }, { lStar: 7, K: 23 }], [{ lStar: 10, K: 40, label: 'm' }],
    { lStar: 12, K: 49 });
  assert.equal(count(c, 'ts'), 2);
  assert.equal(count(c, 'measured'), 1);
  assert.equal(count(c, 'current'), 1);
  assert.ok(!c.includes('NaN'));
});

test('wholePairs never splits a (cos, sin) pair', () => {
  const m = [0, 1, 1, 0, 2, 2];
  const parity = [0, 0, 1, 0, 0, 1];
  assert.equal(wholePairs(m, parity, 2), 3);
  assert.equal(wholePairs(m, parity, 3), 3);
  assert.equal(wholePairs(m, parity, 4), 4);
  assert.equal(wholePairs(m, parity, 5), 6);
  assert.equal(wholePairs(m, parity, 99), 6);
});
