// The SHRM material is the viewer's shader: its sources equal what the viewer builds from web/shaders (its own
// loader over the files on disk), with the layout's defines and the mode's; bad options are refused.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { defines as layoutDefines, fromManifest, numLayers } from '../../../src/layout.js';
import { build } from '../../../src/shaders.js';
import { ShrmMaterial } from '../src/index.js';

const fixture = JSON.parse(readFileSync(new URL('../../../test/fixtures/layout.json', import.meta.url)));
const readShader = (n) => readFileSync(new URL(`../../../shaders/${n}`, import.meta.url), 'utf8');
const viewer = (name, defs) => build(name, { defines: defs, read: readShader }).replace(/^#version 300 es\n/, '');

function coefficientsFor(manifest) {
  const layout = fromManifest(manifest);
  return new Uint16Array(numLayers(layout) * layout.height * layout.width * 3).fill(0x3c00).buffer;
}

test('near and distant materials build the viewer shader', () => {
  for (const [name, c] of Object.entries(fixture.cases)) {
    const layout = fromManifest(c.manifest);
    for (const [mode, define] of [['near', 'SHADING_LOCAL'], ['distant', 'SHADING_VIEW_MAP']]) {
      const m = new ShrmMaterial({ manifest: c.manifest, coefficients: coefficientsFor(c.manifest), mode });
      assert.equal(m.fragmentShader, viewer('object.frag.glsl', { ...layoutDefines(layout), [define]: null }), name);
      assert.equal(m.vertexShader, viewer('object.vert.glsl', {}), name);
      assert.equal(m.uniforms.u_layer_weight.value.length, c.texture_order.length);
      if (mode === 'distant') {
        assert.equal(m.viewMapTarget.width, 2 * layout.height);
      }
      m.dispose();
    }
  }
});

test('linear output and bad options', () => {
  const c = Object.values(fixture.cases)[0];
  const m = new ShrmMaterial({ manifest: c.manifest, coefficients: coefficientsFor(c.manifest), output: 'linear' });
  assert.match(m.fragmentShader, /#define OUTPUT_LINEAR\n/);
  assert.throws(() => new ShrmMaterial({ manifest: c.manifest, coefficients: coefficientsFor(c.manifest),
    mode: 'far' }), /mode must be/);
  assert.throws(() => new ShrmMaterial({ manifest: c.manifest, coefficients: new ArrayBuffer(2) }),
    /coefficients.bin holds/);
});
