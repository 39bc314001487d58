// Eq. 8 in the browser (web/src/global.js) against relight.gl.layout.global_layers / relight.wigner.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { globalLayers, wignerSmallD } from '../src/global.js';
import { floatToHalf, halfToFloat } from '../src/half.js';
import { fromManifest } from '../src/layout.js';

const fixture = JSON.parse(readFileSync(new URL('./fixtures/global.json', import.meta.url)));

test('wignerSmallD equals relight.wigner (Edmonds, Condon-Shortley)', () => {
  const { p, beta, d } = fixture.wigner;
  const got = wignerSmallD(p, beta);
  got.forEach((v, i) => assert.ok(Math.abs(v - d[i]) < 1e-13, `entry ${i}: ${v} vs ${d[i]}`));
});

test('globalLayers equals relight.gl.layout.global_layers (to float16 rounding of the output)', () => {
  const lay = fromManifest(fixture.manifest);
  const halves = Uint16Array.from(fixture.local, floatToHalf);
  const { layout, rgba } = globalLayers(lay, halves);
  assert.deepEqual(layout.components.map((c) => ({ center: c.center, frame: c.frame, P: c.P,
    layers: c.layers.map((l) => [l.p, l.q]) })), fixture.components);
  const want = fixture.global;
  const texels = want.length / 3;
  for (let i = 0; i < texels; i += 1) {
    for (let c = 0; c < 3; c += 1) {
      const got = halfToFloat(rgba[4 * i + c]);
      const w = want[3 * i + c];
      assert.ok(Math.abs(got - w) <= 2 ** -11 * Math.abs(w) + 1e-7, `texel ${i} channel ${c}: ${got} vs ${w}`);
    }
    assert.equal(rgba[4 * i + 3], 0x3c00);
  }
});

test('half conversion: exact round trips, rounding to nearest even, clamping like the server', () => {
  for (const x of [0, 1, -2, 0.5, 65504, -65504, 2 ** -24, 2 ** -14, 1.5 * 2 ** -15, 3.140625]) {
    assert.equal(halfToFloat(floatToHalf(x)), x);
  }
  assert.equal(halfToFloat(floatToHalf(1e9)), 65504);
  assert.equal(halfToFloat(floatToHalf(1 + 2 ** -11)), 1); // tie: to even
  assert.equal(halfToFloat(floatToHalf(1 + 3 * 2 ** -11)), 1 + 2 ** -9);
  assert.equal(halfToFloat(floatToHalf(2 ** -26)), 0);
  assert.ok(Number.isNaN(halfToFloat(floatToHalf(Number.NaN))));
});
