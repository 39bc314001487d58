// The comparison panel's error metric and mask.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { falseColour, interior, relativeError, sphereMask } from '../src/metrics.js';

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

test('interior: a covered square loses its one-pixel rim; a hole removes its 3 x 3 neighbourhood', () => {
  const n = 10;
  const cov = new Uint8Array(n * n);
  for (let y = 2; y < 8; y += 1) {
    for (let x = 2; x < 8; x += 1) {
      cov[y * n + x] = 1;
    }
  }
  const inner = interior(cov, n);
  assert.equal(inner.reduce((a, b) => a + b, 0), 16); // 4 x 4 of the 6 x 6 square
  assert.equal(inner[2 * n + 2], 0);
  assert.equal(inner[3 * n + 3], 1);
  cov[5 * n + 5] = 0;
  const holed = interior(cov, n);
  assert.equal(holed.reduce((a, b) => a + b, 0), 16 - 9 + 0); // the hole's 3 x 3 block is within the 4 x 4
  assert.equal(interior(new Uint8Array(n * n).fill(1), n)[0], 0); // the image border is never interior
});
