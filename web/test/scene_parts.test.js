// web/src/scene_parts.js tableRgba: a scene sh_table job's float16 table ([(F+1)^2, R, R, C], issue 16 item 4) as
// the RGBA layers ShTablePart uploads: each texel's channels in place (C = 3) or its one value repeated (C = 1).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { DATA_WIDTH } from '../src/sh_table.js';
import { tableRgba } from '../src/scene_parts.js';
import { matrixTexels } from '../src/scene_table_parts.js';

const manifest = (shape) => ({ files: { 'table.bin': { shape } } });

test('an RGB table keeps each texel\'s channels, alpha zero, layer-major', () => {
  const half = Uint16Array.from({ length: 4 * 1 * 2 * 3 }, (_, k) => k + 1);
  const out = tableRgba(half, manifest([4, 1, 2, 3]));
  assert.equal(out.length, 4 * 2 * 4);
  assert.deepEqual(Array.from(out.subarray(0, 8)), [1, 2, 3, 0, 4, 5, 6, 0]);
  assert.deepEqual(Array.from(out.subarray(28, 32)), [22, 23, 24, 0]);
});

test('a one-channel table repeats its value in R, G and B', () => {
  const out = tableRgba(Uint16Array.from([5, 6]), manifest([1, 1, 2, 1]));
  assert.deepEqual(Array.from(out), [5, 5, 5, 0, 6, 6, 6, 0]);
});

test('data of the wrong size or channel count is refused', () => {
  assert.throws(() => tableRgba(new Uint16Array(5), manifest([1, 1, 2, 3])), /expected 1 x 1 x 2/);
  assert.throws(() => tableRgba(new Uint16Array(4), manifest([1, 1, 2, 2])), /1 or 3/);
});

// web/src/scene_table_parts.js matrixTexels: a shadow_matrix job's float16 matrices (relight.vertex_texture:
// ceil(n^2 / 4) texels per vertex) re-packed as MODE_TRANSFER reads them (row i of vertex p from texel
// (p n + i) ceil(n / 4), rows zero-padded), DATA_WIDTH texels wide.
test('transfer matrices are re-packed one padded row per texel group, DATA_WIDTH wide', () => {
  // order 1: n = 4, 16 values = 4 texels per vertex (no padding either way); 2 vertices
  const half = Uint16Array.from({ length: 2 * 16 }, (_, k) => k + 1);
  const texture = { vertices: 2, texels_per_vertex: 4, value_shape: [4, 4] };
  const { data, width, height } = matrixTexels(half, texture, 1);
  assert.equal(width, DATA_WIDTH);
  assert.equal(height, 1);
  assert.deepEqual(Array.from(data.subarray(0, 32)), Array.from(half));
  assert.ok(data.subarray(32).every((x) => x === 0));
});

test('order 2 (n = 9): rows padded to 12 values; a larger matrix gives its leading block', () => {
  const n = 9;
  const m = 16; // an order-3 matrix (16 x 16) read at order 2
  const t = Math.ceil((m * m) / 4);
  const half = new Uint16Array(4 * t);
  for (let i = 0; i < m; i += 1) {
    for (let j = 0; j < m; j += 1) {
      half[i * m + j] = 100 * i + j + 1;
    }
  }
  const { data } = matrixTexels(half, { vertices: 1, texels_per_vertex: t, value_shape: [m, m] }, 2);
  for (let i = 0; i < n; i += 1) {
    assert.deepEqual(Array.from(data.subarray(12 * i, 12 * i + 12)),
      [...Array.from({ length: n }, (_, j) => 100 * i + j + 1), 0, 0, 0]);
  }
  assert.throws(() => matrixTexels(half, { vertices: 1, texels_per_vertex: t, value_shape: [m, m] }, 4),
    /do not fit order 4/);
});
