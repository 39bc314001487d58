// web/src/gaussian.js's lobe table is relight.gl.gaussian.LobeTable's (fixture from make_js_fixtures.py): the same
// rows, grid, shader defines and RGBA32UI words from the same float16 material.
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { gaussianDefines, lobeGrid, lobeTable, lobeTexels, MAX_GRID_ROWS } from '../src/gaussian.js';

const fixture = JSON.parse(readFileSync(new URL('./fixtures/gaussian.json', import.meta.url)));

for (const c of fixture.cases) {
  test(`lobeTable: K = ${c.lobes}, ${c.elevations.length} elevations -> ${c.rows} rows`, () => {
    const table = lobeTable({ lobes: c.lobes, elevations: c.elevations, shape: Uint16Array.from(c.shape),
      weight: Uint16Array.from(c.weight) });
    assert.equal(table.rows, c.rows);
    assert.equal(table.grid === null, c.grid === null);
    if (c.grid) {
      table.grid.forEach((x, i) => assert.ok(Math.abs(x - c.grid[i]) <= 1e-12 * Math.abs(c.grid[i]) + 1e-15));
    }
    assert.equal(table.words.length, c.rows * lobeTexels(c.lobes) * 4);
    assert.deepEqual(Array.from(table.words), c.words);
    const defines = gaussianDefines({ table, levels: 3, linear: false });
    delete defines.GAUSSIAN_LEVELS;
    assert.deepEqual(defines, c.defines);
  });
}

test('lobeGrid: rows on an even grid, none when it would exceed MAX_GRID_ROWS', () => {
  assert.deepEqual(lobeGrid([0, 0.5, 0.75, 1.5]), [0, 0.25, 7]);
  assert.equal(lobeGrid([0.2]), null);
  assert.equal(lobeGrid([0, 1e-4, 1]), null); // 10001 rows
  assert.ok(MAX_GRID_ROWS >= 2 * 14 * 16 + 1); // relight fit: 15 elevations bisected 4 levels deep, with margin
});
