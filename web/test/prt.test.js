// web/src/prt.js: the lighting projection, its rotation about +Y, the clamped cosine's zonal factors and the
// service's binary layouts, against closed forms and the Python twins' rules (relight/gl/prt.py).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { floatToHalf } from '../src/half.js';
import { cosineZonal, parseGeometry, projectLatlongHalf, rotateLightingY, vertexValue } from '../src/prt.js';

function map(height, width, f) {
  const bits = new Uint16Array(height * width * 3);
  for (let i = 0; i < height; i += 1) {
    for (let j = 0; j < width; j += 1) {
      const [r, g, b] = f(i, j);
      bits.set([floatToHalf(r), floatToHalf(g), floatToHalf(b)], 3 * (i * width + j));
    }
  }
  return bits;
}

test('a constant map projects to L_00 = sqrt(4 pi) c (exact solid angles), odd and m != 0 terms vanish', () => {
  const c = projectLatlongHalf(map(16, 32, () => [1, 2, 0.5]), 16, 32, 3);
  assert.ok(Math.abs(c[0] - Math.sqrt(4 * Math.PI)) < 1e-12 && Math.abs(c[1] - 2 * Math.sqrt(4 * Math.PI)) < 1e-12);
  for (let k = 3; k < c.length; k += 1) {
    // Y_20 sees the midpoint rule's error in cos^2 theta per ring (O(1 / H^2): 0.4 % of L_00 at H = 16)
    const bound = Math.floor(k / 3) === 6 ? 0.01 * c[k % 3] : 1e-12;
    assert.ok(Math.abs(c[k]) < bound, `coefficient ${Math.floor(k / 3)} is ${c[k]}`);
  }
});

test('rotating the lighting by 2 pi k / W is projecting the map rolled by k columns', () => {
  const h = 16;
  const w = 32;
  const f = (i, j) => [1 + Math.sin(0.3 * i) * Math.cos((2 * Math.PI * j) / w + 0.4), 0.5 + 0.02 * j, i === 3 ? 4 : 0];
  const k = 5;
  const base = projectLatlongHalf(map(h, w, f), h, w, 4);
  const rolled = projectLatlongHalf(map(h, w, (i, j) => f(i, (j + k) % w)), h, w, 4);
  const rotated = rotateLightingY(base, 4, (2 * Math.PI * k) / w);
  rotated.forEach((v, n) => assert.ok(Math.abs(v - rolled[n]) < 1e-9, `${n}: ${v} vs ${rolled[n]}`));
  const back = rotateLightingY(rotated, 4, (-2 * Math.PI * k) / w);
  back.forEach((v, n) => assert.ok(Math.abs(v - base[n]) < 1e-12));
});

test('cosine zonal factors: 2 I_l = 1, 2/3, 1/4, 0, -1/24, 0, 1/64', () => {
  const z = cosineZonal(6);
  [1, 2 / 3, 1 / 4, 0, -1 / 24, 0, 1 / 64].forEach((v, l) => assert.ok(Math.abs(z[l] - v) < 1e-15, `l = ${l}`));
});

test('geometry.bin sections and vertex-texture values', () => {
  const geometry = { bytes: 3 * 40 + 12, sections: {
    positions: { offset: 0, shape: [3, 3], dtype: 'float32' }, normals: { offset: 36, shape: [3, 3], dtype: 'float32' },
    tangents: { offset: 72, shape: [3, 4], dtype: 'float32' }, indices: { offset: 120, shape: [1, 3], dtype: 'uint32' } } };
  const buf = new ArrayBuffer(geometry.bytes);
  new Float32Array(buf, 0, 9).set([0, 0, 0, 1, 0, 0, 0, 1, 0]);
  new Uint32Array(buf, 120, 3).set([0, 1, 2]);
  const g = parseGeometry(buf, geometry);
  assert.deepEqual(Array.from(g.indices), [0, 1, 2]);
  assert.equal(g.positions[3], 1);
  assert.throws(() => parseGeometry(new ArrayBuffer(8), geometry), /bytes/);
  // 5 values per vertex: 2 texels each; vertex 1's value 4 sits in texel 3, channel 0
  const bits = new Uint16Array(4 * 4).fill(floatToHalf(0));
  bits[12] = floatToHalf(0.75);
  assert.equal(vertexValue(bits, { texels_per_vertex: 2 }, 1, 4), 0.75);
});
