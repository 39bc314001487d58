// The JavaScript real SH against relight.sh.to_real's basis (fixture written by tests/web/make_js_fixtures.py).
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { realHarmonics, realHarmonicsCartesian, rotateY, shCount, shIndex } from '../src/sh.js';

const fixture = JSON.parse(readFileSync(new URL('./fixtures/sh.json', import.meta.url)));

test('realHarmonics equals relight.sh real basis to 1e-12 up to order 8', () => {
  const { order, directions, values } = fixture;
  let worst = 0;
  directions.forEach((d, i) => {
    const y = realHarmonics(order, d);
    assert.equal(y.length, shCount(order));
    y.forEach((v, k) => {
      worst = Math.max(worst, Math.abs(v - values[i][k]));
    });
  });
  assert.ok(worst < 1e-12, `worst difference ${worst}`);
});

test('lower orders are prefixes of higher ones', () => {
  const d = fixture.directions[3];
  const y8 = realHarmonics(8, d);
  const y3 = realHarmonics(3, d);
  y3.forEach((v, k) => assert.equal(v, y8[k]));
});

test('index and known closed forms: Yr_1,1 is proportional to +x (SH frame: world X)', () => {
  assert.equal(shIndex(1, 1), 3);
  assert.equal(shIndex(2, -2), 4);
  const c1 = Math.sqrt(3 / (4 * Math.PI));
  const y = realHarmonicsCartesian(1, [0.6, 0.0, 0.8]);
  assert.ok(Math.abs(y[shIndex(1, 1)] - c1 * 0.6) < 1e-15);
  assert.ok(Math.abs(y[shIndex(1, 0)] - c1 * 0.8) < 1e-15);
  assert.ok(Math.abs(y[shIndex(1, -1)]) < 1e-15);
  // world +Y is the pole
  const w = realHarmonics(1, [0, 2, 0]);
  assert.ok(Math.abs(w[shIndex(1, 0)] - c1) < 1e-15);
});

test('orthonormality by quadrature (Fibonacci sphere, order 4)', () => {
  const n = 20000;
  const order = 4;
  const count = shCount(order);
  const gram = new Float64Array(count * count);
  for (let i = 0; i < n; i += 1) {
    const z = 1 - (2 * (i + 0.5)) / n;
    const r = Math.sqrt(1 - z * z);
    const phi = i * Math.PI * (3 - Math.sqrt(5));
    const y = realHarmonicsCartesian(order, [r * Math.cos(phi), r * Math.sin(phi), z]);
    for (let a = 0; a < count; a += 1) {
      for (let b = 0; b < count; b += 1) {
        gram[a * count + b] += (y[a] * y[b] * 4 * Math.PI) / n;
      }
    }
  }
  for (let a = 0; a < count; a += 1) {
    for (let b = 0; b < count; b += 1) {
      assert.ok(Math.abs(gram[a * count + b] - (a === b ? 1 : 0)) < 1e-3, `gram[${a},${b}]`);
    }
  }
});

test('rotateY: +Z goes to +X for a = pi/2; a zero direction is refused', () => {
  const r = rotateY([0, 0, 1], Math.PI / 2);
  assert.ok(Math.abs(r[0] - 1) < 1e-15 && Math.abs(r[2]) < 1e-15);
  assert.throws(() => realHarmonics(2, [0, 0, 0]), RangeError);
  assert.throws(() => realHarmonicsCartesian(-1, [0, 0, 1]), RangeError);
});
