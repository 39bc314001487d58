// The export panel's list (issue 17, item 9): the viewer's spec objects as relight spec strings, and one button
// per export of the map, the material and the DFG table, each naming its API path.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { DFG_TABLES, exportList, specString } from '../src/export_list.js';

test('spec objects become relight spec strings', () => {
  assert.equal(specString({ kind: 'phong', s: 32 }), 'phong:s=32');
  assert.equal(specString({ kind: 'sum', lobes: [{ kind: 'lambert', albedo: 0.2 }, { kind: 'ggx', alpha: 0.1,
    f0: [0.9, 0.6, 0.2], fresnel: 'schlick' }] }), 'lambert:albedo=0.2+ggx:alpha=0.1,f0=0.9/0.6/0.2,fresnel=schlick');
  assert.equal(specString({ kind: 'lambert' }), 'lambert');
  assert.equal(specString('a'.repeat(64)), null); // a measured BRDF's id has no spec string
  assert.equal(specString({ kind: 'sum', lobes: [] }), null);
});

test('every export of a map and material has a button with its API path', () => {
  const id = 'ab'.repeat(32);
  const plain = exportList(id);
  const withMaterial = exportList(id, 'phong:s=32');
  assert.equal(plain.length, 4 + 1 + 1 + 5 + DFG_TABLES.length);
  assert.equal(withMaterial.length, plain.length + 5);
  const paths = withMaterial.map((e) => e[2]);
  assert.ok(paths.includes(`/envmaps/${id}/ibl?target=gltf&format=gltf`));
  assert.ok(paths.includes(`/envmaps/${id}/ibl?target=babylon&format=ktx2&brdf=phong%3As%3D32`));
  assert.ok(paths.includes('/dfg?size=128&multiscatter=true&format=ktx2'));
  const names = withMaterial.map((e) => e[1]);
  assert.equal(new Set(names.filter((n) => !n.includes('sh9-'))).size, names.filter((n) => !n.includes('sh9-')).length);
  assert.ok(names.includes(`${id.slice(0, 12)}-phong_s=32-three.ktx2`));
  for (const [, name, path, , query] of withMaterial) {
    assert.equal(query === null, path.startsWith('/dfg?'), name);
  }
});
