// web/src/scene_parts.js tableRgba: a scene sh_table job's float16 table ([(F+1)^2, R, R, C], issue 16 item 4) as
// the RGBA layers ShTablePart uploads: each texel's channels in place (C = 3) or its one value repeated (C = 1).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { tableRgba } from '../src/scene_parts.js';

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
