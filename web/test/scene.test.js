// web/src/scene.js sceneItems: each object of a finished scene dispatched on its lobes' representations (issue 16
// item 4), with the files each kind reads; an object the viewer cannot draw is an error of its own, not of the scene.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ApiError } from '../src/api.js';
import { chainFromLevels } from '../src/gaussian.js';
import { sceneItems } from '../src/scene.js';

const enc = (v) => new TextEncoder().encode(JSON.stringify(v)).buffer;

/** A finished scene: `objects` as [name, representations, files]; jobs and files as the run writes them. */
function scene(objects) {
  const files = {
    'ball.texture.json': enc({ representation: 'shrm' }), 'ball.coefficients.bin': new ArrayBuffer(8),
    'job00-gaussian_fit.json': enc({ kind: 'gaussian-lobes', elevations: [{ theta_o: 0 }, { theta_o: 1 }] }),
    'job00-gaussian_fit.lobes.bin': new Uint16Array(2 * 1 * 8).buffer,
    'job01-gaussian_chain.level_00.bin': new Uint16Array(2 * 4 * 3).fill(7).buffer,
    'job01-gaussian_chain.level_01.bin': new Uint16Array(2 * 4 * 3).fill(9).buffer,
    'bunny.prt.json': enc({ geometry: { name: 'bunny.geometry.bin' }, files: { 'transfer.bin': { name: 'bunny.transfer.bin' } } }),
    'bunny.geometry.bin': new ArrayBuffer(4), 'bunny.transfer.bin': new ArrayBuffer(4),
    'job02-inout_transport.inout.json': enc({ terms: 4, geometry: { name: 'job02-inout_transport.geometry.bin' },
      transport_texture: { name: 'job02-inout_transport.transport.bin' },
      factors_texture: { name: 'job02-inout_transport.factors.bin' } }),
    'job02-inout_transport.geometry.bin': new ArrayBuffer(12), 'job02-inout_transport.transport.bin': new ArrayBuffer(16),
    'job02-inout_transport.factors.bin': new ArrayBuffer(20),
    'job03-sh_table.table.json': enc({ order: 2, files: { 'table.bin': { name: 'job03-sh_table.table.bin' } } }),
    'job03-sh_table.table.bin': new ArrayBuffer(24),
    'job04-shadow_matrix.prt_matrix.json': enc({ order: 2, geometry: { name: 'job04-shadow_matrix.geometry.bin' },
      files: { 'shadow_matrix.bin': { name: 'job04-shadow_matrix.shadow_matrix.bin' } } }),
    'job04-shadow_matrix.geometry.bin': new ArrayBuffer(28), 'job04-shadow_matrix.shadow_matrix.bin': new ArrayBuffer(32),
  };
  const fileOf = { ball: { texture: 'ball.texture.json', coefficients_bin: 'ball.coefficients.bin' },
    bunny: { prt: 'bunny.prt.json', texture: 'ball.texture.json', coefficients_bin: 'ball.coefficients.bin' } };
  const pub = {
    id: 's1', state: 'succeeded',
    scene: { objects: objects.map(([name]) => ({ name, shape: name === 'bunny' ? 'bunny' : 'sphere', size: 1,
      distance: 4, view: [0, 0, 1], ...(name === 'brushed' ? { tangent: { kind: 'project', direction: [1, 0, 0] } }
        : {}) })) },
    plan: { objects: objects.map(([name, reps]) => ({ name, viewer: 'distant', representations: reps.map((r) => ({
      kind: r === 'diffuse_transfer' ? 'lambert' : 'phong', representation: r, seed: '000',
      lobe: { kind: 'lambert', albedo: 0.5 },
      jobs: { gaussian_lobes: ['fit', 'chain'], inout_prt: ['inout'], sh_table: ['table'],
        prt_matrix: ['table', 'matrix'] }[r] ?? [] })) })) },
    result: {
      objects: objects.map(([name, , own]) => ({ name, files: own ?? fileOf[name] ?? {} })),
      jobs: [
        { id: 'fit', kind: 'gaussian_fit', executed: true, files: ['job00-gaussian_fit.json',
          'job00-gaussian_fit.lobes.bin'], summary: { lobes: 1, elevations: 2, errors: [0, 0] } },
        { id: 'chain', kind: 'gaussian_chain', executed: true, files: ['job01-gaussian_chain.json',
          'job01-gaussian_chain.level_00.bin', 'job01-gaussian_chain.level_01.bin'],
        summary: { sigma0: 0.1, ratio: Math.SQRT2, levels: [{ file: 'level_00.bin', height: 2, width: 4 },
          { file: 'level_01.bin', height: 2, width: 4 }] } },
        { id: 'inout', kind: 'inout_transport', executed: true, files: ['job02-inout_transport.npz',
          'job02-inout_transport.inout.json', 'job02-inout_transport.geometry.bin',
          'job02-inout_transport.transport.bin', 'job02-inout_transport.factors.bin'], summary: {} },
        { id: 'table', kind: 'sh_table', executed: true, files: ['job03-sh_table.npz', 'job03-sh_table.table.bin',
          'job03-sh_table.table.json'], summary: {} },
        { id: 'matrix', kind: 'shadow_matrix', executed: true, files: ['job04-shadow_matrix.npz',
          'job04-shadow_matrix.geometry.bin', 'job04-shadow_matrix.shadow_matrix.bin',
          'job04-shadow_matrix.prt_matrix.json'], summary: {} },
      ],
    },
  };
  const fetched = [];
  const refused = new Set();
  const api = { sceneFile: async (id, name) => {
    assert.equal(id, 's1');
    fetched.push(name);
    if (refused.has(name)) {
      throw new ApiError(404, { title: 'Not Found', detail: `scene s1 has no file '${name}'` });
    }
    if (!(name in files)) throw new Error(`no file ${name}`);
    return files[name];
  } };
  const loaders = { material: (result, buffer) => ({ result, bytes: buffer.byteLength }), chain: chainFromLevels };
  return { pub, api, loaders, fetched, refused };
}

const shape = async (name) => `geometry:${name}`;

test('every representation is dispatched to its part, with the files it reads', async () => {
  const s = scene([['ball', ['reflection_map']], ['edited', ['gaussian_lobes']], ['bunny', ['diffuse_transfer']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(errors, []);
  assert.deepEqual(items.map((it) => [it.name, it.kind, it.added]), [['ball', 'shrm', false],
    ['edited', 'gaussian_lobes', false], ['bunny', 'diffuse_transfer', false]]);
  const [ball, edited, bunny] = items;
  assert.deepEqual(ball.manifest, { representation: 'shrm' });
  assert.equal(ball.geometry, 'geometry:sphere');
  assert.deepEqual(edited.material.result.material.elevations, [{ theta_o: 0 }, { theta_o: 1 }]);
  assert.equal(edited.material.bytes, 2 * 8 * 2);
  // the chain's RGB levels padded to RGBA, one size, the summary's sigma0 and ratio
  assert.equal(edited.chain.levels.length, 2);
  assert.deepEqual(Array.from(edited.chain.levels[1].subarray(0, 8)), [9, 9, 9, 0, 9, 9, 9, 0]);
  assert.equal(edited.chain.sigma0, 0.1);
  assert.equal(bunny.albedo, 0.5);
  assert.equal(bunny.geometryBuffer.byteLength, 4);
  assert.ok(!s.fetched.includes('bunny.coefficients.bin')); // the transfer replaces the unshadowed SHRM
});

test('an in-out PRT lobe reads its inout_transport job\'s viewer files', async () => {
  const s = scene([['teapot', ['inout_prt']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(errors, []);
  assert.deepEqual(items.map((it) => [it.name, it.kind]), [['teapot', 'inout_prt']]);
  assert.equal(items[0].inout.terms, 4);
  assert.deepEqual([items[0].geometryBuffer, items[0].transportBuffer, items[0].factorsBuffer]
    .map((b) => b.byteLength), [12, 16, 20]);
});

test('an SH-table lobe reads its sh_table job\'s viewer files and the object\'s tangent field', async () => {
  const s = scene([['brushed', ['sh_table']], ['plain', ['sh_table']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(errors, []);
  assert.deepEqual(items.map((it) => [it.name, it.kind, it.added]), [['brushed', 'sh_table', false],
    ['plain', 'sh_table', false]]);
  assert.equal(items[0].table.order, 2);
  assert.equal(items[0].tableBuffer.byteLength, 24);
  assert.deepEqual(items[0].tangent, { kind: 'project', direction: [1, 0, 0] });
  assert.equal(items[1].tangent, null); // the part's default: azimuthal about +Y, as the CPU's
});

test('a PRT lobe (prt_matrix) reads its sh_table and shadow_matrix jobs\' viewer files', async () => {
  const s = scene([['brushed', ['prt_matrix']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(errors, []);
  assert.deepEqual(items.map((it) => [it.name, it.kind]), [['brushed', 'prt_matrix']]);
  const [it] = items;
  assert.equal(it.table.order, 2);
  assert.equal(it.matrices.order, 2);
  assert.deepEqual([it.tableBuffer, it.geometryBuffer, it.matrixBuffer].map((b) => b.byteLength), [24, 28, 32]);
  assert.deepEqual(it.tangent, { kind: 'project', direction: [1, 0, 0] });
});

test('a representation the viewer cannot draw is that object\'s error; the others are drawn', async () => {
  const s = scene([['ball', ['shrm']], ['teapot', ['photon_map']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(items.map((it) => it.name), ['ball']);
  assert.deepEqual(errors.map((e) => e.name), ['teapot']);
  assert.match(errors[0].message, /cannot draw representation photon_map/);
});

test('a file the API refuses is the object\'s error, with the problem\'s title, status and detail', async () => {
  const s = scene([['ball', ['shrm']], ['brushed', ['prt_matrix']]]);
  s.refused.add('job04-shadow_matrix.shadow_matrix.bin');
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(items.map((it) => it.name), ['ball']);
  assert.deepEqual(errors, [{ name: 'brushed',
    message: "Not Found (404) — scene s1 has no file 'job04-shadow_matrix.shadow_matrix.bin'" }]);
});

test('an SH-table job without its viewer form is the object\'s error', async () => {
  const s = scene([['brushed', ['sh_table']]]);
  s.pub.result.jobs = s.pub.result.jobs.map((j) => (j.id === 'table' ? { ...j, files: ['job03-sh_table.npz'] } : j));
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(items, []);
  assert.match(errors[0].message, /no sh_table job run with a viewer form/);
});

test('missing files are the object\'s error; a plan without representations is one SHRM per object', async () => {
  const s = scene([['ball', []], ['bunny', ['diffuse_transfer'], {}]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(items.map((it) => [it.name, it.kind]), [['ball', 'shrm']]);
  assert.deepEqual(errors.map((e) => e.name), ['bunny']);
  assert.match(errors[0].message, /no viewer form of its diffuse transfer/);
});

test('an object with several representations: the SHRM first, the others added, on one tessellated sphere', async () => {
  const s = scene([['ball', ['irradiance', 'gaussian_lobes']]]);
  const { items, errors } = await sceneItems(s.pub, s.api, shape, s.loaders);
  assert.deepEqual(errors, []);
  assert.deepEqual(items.map((it) => [it.kind, it.added, it.geometry]), [['shrm', false, 'sphere-mesh'],
    ['gaussian_lobes', true, 'sphere-mesh']]);
});

test('a scene that has not finished is refused', async () => {
  const s = scene([['ball', ['shrm']]]);
  await assert.rejects(sceneItems({ ...s.pub, state: 'running' }, s.api, shape, s.loaders), /only a finished scene/);
});
