// Layout rules of web/src/layout.js against relight.gl.layout (fixture written by tests/web/make_js_fixtures.py).
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import {
  LayoutError, defines, fromManifest, halfArray, numLayers, rgbaLayers, textureOrder, uniformWeights,
} from '../src/layout.js';

const fixture = JSON.parse(readFileSync(new URL('./fixtures/layout.json', import.meta.url)));

for (const [name, c] of Object.entries(fixture.cases)) {
  test(`layout ${name} equals relight.gl.layout`, () => {
    const lay = fromManifest(c.manifest);
    assert.deepEqual(textureOrder(lay), c.texture_order);
    assert.deepEqual(Object.entries(defines(lay)), c.defines);
    assert.deepEqual(
      lay.components.map((k) => ({ center: k.center, frame: k.frame, P: k.P, layers: k.layers.map((l) => [l.index, l.p, l.q]) })),
      c.components,
    );
    const w = uniformWeights(lay, fixture.view);
    assert.equal(w.length, c.weights.length);
    w.forEach((v, i) => assert.ok(Math.abs(v - c.weights[i]) <= 1e-7 * Math.max(1, Math.abs(c.weights[i]))));
  });
}

for (const [name, manifest] of Object.entries(fixture.bad)) {
  test(`bad manifest ${name} is refused`, () => {
    assert.throws(() => fromManifest(manifest), LayoutError);
  });
}

test('rgbaLayers reorders layers to texture order and adds alpha = 1 (half 0x3c00)', () => {
  const lay = fromManifest(fixture.cases.shrm_components.manifest);
  const n = numLayers(lay);
  const texels = lay.height * lay.width;
  const rgb = new Uint16Array(n * texels * 3);
  for (let k = 0; k < n; k += 1) {
    rgb.fill(k + 1, k * texels * 3, (k + 1) * texels * 3); // layer k holds the value k + 1
  }
  const rgba = rgbaLayers(lay, rgb);
  textureOrder(lay).forEach((src, dst) => {
    const base = dst * texels * 4;
    assert.deepEqual([...rgba.slice(base, base + 4)], [src + 1, src + 1, src + 1, 0x3c00]);
  });
  assert.throws(() => rgbaLayers(lay, new Uint16Array(5)), LayoutError);
});

test('halfArray reads little-endian halves', () => {
  const bytes = new Uint8Array([0x00, 0x3c, 0x00, 0xc0]); // 1.0, -2.0
  assert.deepEqual([...halfArray(bytes.buffer)], [0x3c00, 0xc000]);
});
