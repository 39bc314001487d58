// web/src/shaders.js builds byte-identical sources to relight/gl/shaders.py (fixture from make_js_fixtures.py).
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { test } from 'node:test';

import { build, formatDefine, loadSources } from '../src/shaders.js';

const fixture = JSON.parse(readFileSync(new URL('./fixtures/shaders.json', import.meta.url)));
const read = (name) => fixture.files[name];

for (const b of fixture.builds) {
  const defines = Object.fromEntries(b.defines);
  test(`build ${b.name} (${Object.keys(defines).filter((k) => !k.startsWith('SH')).join(' ') || 'no switches'})`, () => {
    assert.equal(build(b.name, { target: '300 es', defines, read }), b.text);
  });
}

test('the shader files on disk are the ones the fixture was made from', () => {
  for (const [name, text] of Object.entries(fixture.files)) {
    assert.equal(readFileSync(new URL(`../shaders/${name}`, import.meta.url), 'utf8'), text, name);
  }
});

test('defines: switches, numbers, lists; bad names and values are refused', () => {
  assert.equal(formatDefine('A', null), '#define A');
  assert.equal(formatDefine('A', 3), '#define A 3');
  assert.equal(formatDefine('A', 0.5), '#define A 0.5');
  assert.equal(formatDefine('A', [1, 2, 3]), '#define A 1, 2, 3');
  assert.throws(() => formatDefine('1A', 1));
  assert.throws(() => formatDefine('A', false));
  assert.throws(() => formatDefine('A', 'x\ny'));
});

test('includes expand once; a missing file is an error', () => {
  const files = { 'a.glsl': '#include "b.glsl"\n#include "b.glsl"\nA\n', 'b.glsl': 'B' };
  assert.equal(build('a.glsl', { target: '330', read: (n) => files[n] }), '#version 330\nB\n\nA\n');
  assert.throws(() => build('a.glsl', { read: () => undefined }), /not found/);
});

test('loadSources fetches a shader and everything it includes', async () => {
  const fetched = [];
  const fakeFetch = async (url) => {
    fetched.push(url);
    const name = url.slice('base/'.length);
    return { ok: name in fixture.files, status: 404, text: async () => fixture.files[name] };
  };
  const readFetched = await loadSources(['view_map.frag.glsl'], 'base/', fakeFetch);
  const b = fixture.builds.find((x) => x.name === 'view_map.frag.glsl');
  assert.equal(build(b.name, { defines: Object.fromEntries(b.defines), read: readFetched }), b.text);
  assert.ok(fetched.includes('base/generated/constants.glsl'));
  await assert.rejects(loadSources(['missing.glsl'], 'base/', fakeFetch), /HTTP 404/);
});
