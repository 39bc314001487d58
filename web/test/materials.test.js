// Material models from an OpenAPI document shaped like the server's (contract/brdfs.py through pydantic).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { modelsFromOpenapi, specFor } from '../src/materials.js';

const openapi = { components: { schemas: {
  PhongSpec: { properties: { kind: { type: 'string', const: 'phong' }, s: { type: 'number', minimum: 0, maximum: 1e5 } },
    required: ['kind', 's'] },
  LambertSpec: { properties: { kind: { const: 'lambert' }, albedo: { anyOf: [{ type: 'number', minimum: 0, maximum: 1 },
    { type: 'array' }], default: 1 } }, required: ['kind'] },
  GGXSpec: { properties: { kind: { const: 'ggx' }, alpha: { type: 'number', exclusiveMinimum: 0, maximum: 10 },
    fresnel: { type: 'string', enum: ['none', 'schlick'], default: 'none' },
    f0: { anyOf: [{ type: 'number' }, { type: 'null' }] } }, required: ['kind', 'alpha'] },
  Lobe1DSpec: { properties: { kind: { const: 'lobe1d' }, t: { type: 'array' } }, required: ['kind', 't'] },
  SumSpec: { properties: { kind: { const: 'sum' }, lobes: { type: 'array' } }, required: ['kind', 'lobes'] },
  PlanCreate: { properties: { envmap: { type: 'string' } } },
} } };

test('models: scalar and enum parameters, presets for required numbers, optional nulls left out', () => {
  const models = modelsFromOpenapi(openapi);
  assert.deepEqual(models.map((m) => m.kind), ['ggx', 'lambert', 'phong']);
  const phong = models.find((m) => m.kind === 'phong');
  assert.equal(phong.params[0].value, 32);
  assert.ok(phong.params[0].log && phong.params[0].min === 10 && phong.params[0].max === 1e5);
  const ggx = models.find((m) => m.kind === 'ggx');
  assert.deepEqual(ggx.params.map((p) => p.name), ['alpha', 'fresnel']);
  assert.equal(ggx.params[0].value, 0.3);
  assert.equal(ggx.params[1].type, 'enum');
  const lambert = models.find((m) => m.kind === 'lambert');
  assert.equal(lambert.params[0].value, 1);
  assert.ok(!lambert.params[0].log);
});

test('specFor: values, defaults, and a diffuse lobe as a sum', () => {
  const phong = modelsFromOpenapi(openapi).find((m) => m.kind === 'phong');
  assert.deepEqual(specFor(phong, { s: 64 }), { kind: 'phong', s: 64 });
  assert.deepEqual(specFor(phong, {}, 0.25), { kind: 'sum', lobes: [{ kind: 'lambert', albedo: 0.25 },
    { kind: 'phong', s: 32 }] });
});
