// ApiError.display (web/src/api.js): the line the viewer's panels show for an API problem (RFC 9457): title,
// status, the server's own detail, and a validation error's per-field messages unless the detail holds them.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { ApiError } from '../src/api.js';

test('a problem shows its title, status and detail', () => {
  const err = new ApiError(404, { title: 'Not Found', detail: "scene s1 has no file 'a.bin'" });
  assert.equal(err.display(), "Not Found (404) — scene s1 has no file 'a.bin'");
  assert.equal(err.message, "scene s1 has no file 'a.bin'");
});

test('relight\'s validation problem (errors: field, message) is not repeated after its detail', () => {
  const err = new ApiError(422, { title: 'Unprocessable Content', detail: 'objects.0.size: must be > 0 (got -1)',
    errors: [{ field: 'objects.0.size', message: 'must be > 0', type: 'greater_than', value: -1 }] });
  assert.equal(err.display(), 'Unprocessable Content (422) — objects.0.size: must be > 0 (got -1)');
});

test('field messages the detail lacks are added (pydantic loc / msg too); no title: the status', () => {
  const err = new ApiError(422, { detail: 'invalid request', errors: [{ loc: ['body', 'epsilon'], msg: 'too big' },
    { field: 'size', message: 'too small' }] });
  assert.equal(err.display(), 'HTTP 422 — invalid request — body.epsilon: too big; size: too small');
});
