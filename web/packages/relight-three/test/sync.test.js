// The package's copies of the viewer's modules and GLSL are current (scripts/sync.mjs).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { stale } from '../scripts/sync.mjs';

test('copies of the viewer code are current', () => {
  assert.deepEqual(stale(), [], 'run `node scripts/sync.mjs` in web/packages/relight-three');
});
