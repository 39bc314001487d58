// The comparison panel's error metric and mask.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { falseColour, relativeError, sphereMask } from '../src/metrics.js';

test('sphereMask covers pi/4 of the square and is symmetric', () => {
  const n = 200;
  const m = sphereMask(n);
  const frac = m.reduce((a, b) => a + b, 0) / (n * n);
  assert.ok(Math.abs(frac - Math.PI / 4) < 5e-3);
  assert.equal(m[0], 0);
  assert.equal(m[(n / 2) * n + n / 2], 1);
  assert.equal(m[5 * n + 100], m[(n - 1 - 5) * n + 100]);
});

test('relativeError: a uniform 1 % error is 1 % relative RMS; identical images give 0', () => {
  const n = 16;
  const mask = sphereMask(n);
  const ref = new Float32Array(n * n * 3).fill(2);
  const test1 = ref.map((v) => v * 1.01);
  const e = relativeError(test1, ref, mask);
  assert.ok(Math.abs(e.rms - 0.01) < 1e-6, String(e.rms));
  assert.ok(Math.abs(e.max - 0.01) < 1e-6);
  assert.equal(relativeError(ref, ref, mask).rms, 0);
  const img = falseColour(test1, ref, mask);
  assert.equal(img.length, n * n * 4);
  assert.deepEqual([...img.slice(0, 4)], [0, 0, 0, 255]);
});
