// web/src/sh_lights.js (cap lights, windows, tangent fields) and the layout helpers of web/src/sh_table_data.js,
// against references that share none of their formulas: quadrature of the cap's indicator, the windows' defining
// values, orthonormality and the fallback at the tangent fields' singular points.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { tableRgb, transferLayout, viewProjection } from '../src/sh_table_data.js';
import { realHarmonics, shCount } from '../src/sh.js';
import { capLight, legendre, tangentField, windowFactors, windowLighting } from '../src/sh_lights.js';

test('a cap light equals the quadrature of its indicator times Yr (closed form vs a 400 x 800 midpoint rule)', () => {
  const order = 6;
  const dir = [0.3, 0.8, -0.52];
  const nd = Math.hypot(...dir);
  const omega = 0.7;
  const cosA = 1 - omega / (2 * Math.PI);
  const got = capLight(dir, omega, [2, 1, 0.5], order);
  const want = new Float64Array(shCount(order));
  const [h, w] = [400, 800];
  for (let i = 0; i < h; i += 1) {
    const th = ((i + 0.5) * Math.PI) / h;
    for (let j = 0; j < w; j += 1) {
      const ph = ((j + 0.5) * 2 * Math.PI) / w;
      const d = [Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)];
      if ((d[0] * dir[0] + d[1] * dir[1] + d[2] * dir[2]) / nd >= cosA) {
        const y = realHarmonics(order, d);
        const da = Math.sin(th) * (Math.PI / h) * ((2 * Math.PI) / w);
        y.forEach((v, k) => { want[k] += v * da; });
      }
    }
  }
  // the rule's error is the cap boundary cut through cells: ~ perimeter x cell size ~ 2 pi sin(a) (pi / 400) times
  // max |Yr| ~ 1.4 at l = 6, about 0.01 relative to L_00 = sqrt(4 pi) Omega / (4 pi); allow 2e-3 absolute
  for (let k = 0; k < want.length; k += 1) {
    assert.ok(Math.abs(got[3 * k] - 2 * want[k]) < 2e-3, `${k}: ${got[3 * k]} vs ${2 * want[k]}`);
    assert.ok(Math.abs(got[3 * k + 2] - 0.25 * got[3 * k]) < 1e-15);
  }
  // the whole sphere is a constant: L_00 = sqrt(4 pi), nothing else
  const all = capLight([0, 1, 0], 4 * Math.PI, [1, 1, 1], 4);
  assert.ok(Math.abs(all[0] - Math.sqrt(4 * Math.PI)) < 1e-12);
  all.slice(3).forEach((v) => assert.ok(Math.abs(v) < 1e-12));
  assert.throws(() => capLight([0, 0, 0], 1, [1, 1, 1], 2), /direction/);
  assert.throws(() => capLight([0, 1, 0], 0, [1, 1, 1], 2), /solid angle/);
});

test('Legendre polynomials: P_2, P_3 in closed form', () => {
  const p = legendre(0.3, 3);
  assert.ok(Math.abs(p[2] - 0.5 * (3 * 0.09 - 1)) < 1e-15 && Math.abs(p[3] - 0.5 * (5 * 0.027 - 0.9)) < 1e-15);
});

test('windows: Hann and Lanczos values; the cost is the relative L2 change of the lighting', () => {
  const hann = windowFactors(3, 'hann');
  assert.deepEqual([...hann].map((x) => Number(x.toFixed(12))), [1, 0.853553390593, 0.5, 0.146446609407]);
  const lz = windowFactors(1, 'lanczos');
  assert.ok(lz[0] === 1 && Math.abs(lz[1] - 2 / Math.PI) < 1e-15);
  const c = new Float64Array(3 * 4).fill(1);
  const { coeffs, cost } = windowLighting(c, 1, 'hann');
  assert.ok(Math.abs(coeffs[3] - 0.5) < 1e-15);
  assert.ok(Math.abs(cost - Math.sqrt((3 * 3 * 0.25) / 12)) < 1e-15);
  assert.equal(windowLighting(c, 1, 'none').cost, 0);
  assert.throws(() => windowFactors(2, 'box'), /window/);
});

test('tangent fields: orthonormal to the normal, no NaN at and next to the singular points', () => {
  const normals = new Float32Array([0, 1, 0, 0, -1, 0, 1e-8, 1, 0, 0.6, 0, 0.8, 1, 0.3, 0.2]);
  for (const spec of [{ kind: 'azimuthal' }, { kind: 'project', direction: [0, 1, 0] },
    { kind: 'project', direction: [1, 0.3, 0.2] }]) {
    const t = tangentField(normals, spec);
    for (let k = 0; k < 5; k += 1) {
      const n = [...normals.subarray(3 * k, 3 * k + 3)];
      const nn = Math.hypot(...n);
      const tv = [...t.subarray(4 * k, 4 * k + 3)];
      assert.ok(tv.every(Number.isFinite), `${spec.kind} ${k}`);
      assert.ok(Math.abs(Math.hypot(...tv) - 1) < 1e-6);
      assert.ok(Math.abs(tv[0] * n[0] + tv[1] * n[1] + tv[2] * n[2]) / nn < 1e-6);
      assert.equal(t[4 * k + 3], 1);
    }
  }
  // at n = +Y the azimuthal field about +Y falls back to +X (relight.shrm.tangent_field)
  const t = tangentField(new Float32Array([0, 1, 0]), { kind: 'azimuthal' });
  assert.deepEqual([...t], [1, 0, 0, 1]);
  // mesh tangents keep their handedness
  const m = tangentField(new Float32Array([0, 0, 1]), { kind: 'mesh', tangents: [1, 0, 0.5, -1] });
  assert.deepEqual([...m], [1, 0, 0, -1]);
});

test('the view-projection looks along -V: the origin at the centre, V toward the viewer (smaller depth)', () => {
  const v = [0.3, 0.4, 0.866];
  const m = viewProjection(v);
  const apply = (p) => [0, 1, 2, 3].map((r) => m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r]);
  const o = apply([0, 0, 0]);
  assert.ok(Math.abs(o[0]) < 1e-6 && Math.abs(o[1]) < 1e-6);
  assert.ok(apply(v)[2] < o[2]);
  const up = apply([0, 1, 0]);
  assert.ok(up[1] > 0);
});

test('layouts: grey tables repeated in RGB; shadow matrices re-packed with padded rows', () => {
  assert.deepEqual([...tableRgb(new Uint16Array([7, 9]), 1)], [7, 7, 7, 9, 9, 9]);
  const n = 2;
  // two vertices, n^2 = 4 values in ceil(4 / 4) = 1 texel each
  const half = new Uint16Array([1, 2, 3, 4, 5, 6, 7, 8]);
  const out = transferLayout(half, { vertices: 2, texels_per_vertex: 1 }, n);
  assert.deepEqual([...out], [1, 2, 0, 0, 3, 4, 0, 0, 5, 6, 0, 0, 7, 8, 0, 0]);
});
