// The JavaScript display transform (comparison panel) matches relight.envmap.tonemap's definition.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { srgbOetf, tonemapImage, tonemapValue } from '../src/tonemap.js';

test('ACES (Narkowicz) maps 1 to about 0.8 before the OETF; Reinhard x / (1 + x); none clamps', () => {
  const aces1 = (1 * (2.51 + 0.03)) / (1 * (2.43 + 0.59) + 0.14);
  assert.ok(Math.abs(tonemapValue(1, 0, 'aces') - srgbOetf(aces1)) < 1e-15);
  assert.ok(Math.abs(tonemapValue(1, 1, 'reinhard') - srgbOetf(2 / 3)) < 1e-15);
  assert.ok(Math.abs(tonemapValue(7, 0, 'none') - 1) < 1e-15);
  assert.equal(tonemapValue(-1, 0, 'none'), 0);
  assert.equal(tonemapValue(Number.NaN, 0, 'aces'), 0);
  assert.throws(() => tonemapValue(1, 0, 'filmic'));
});

test('tonemapImage writes RGBA8 with alpha 255', () => {
  const out = tonemapImage(new Float32Array([0, 0.5, 1e9]), 0, 'none');
  assert.deepEqual([...out], [0, Math.round(srgbOetf(0.5) * 255), 255, 255]);
});
