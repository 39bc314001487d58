// Api.events / Api.follow (web/src/api.js): the viewer follows every kind of job through its server-sent event
// stream, with a timeout and a fallback, instead of polling. fetch is replaced by a stub serving scripted streams.
import assert from 'node:assert/strict';
import { afterEach, test } from 'node:test';

import { Api, ApiError } from '../src/api.js';

const realFetch = globalThis.fetch;
afterEach(() => { globalThis.fetch = realFetch; });

const job = (state, progress = 0, stage = null) => ({ id: 'a'.repeat(64), kind: 'tradeoff', state, progress, stage });
const block = (event, data) => `event: ${event}\r\ndata: ${JSON.stringify(data)}\r\nid: 1\r\n\r\n`;

/** A Response whose body sends `chunks` (strings) one by one, then ends, or stays open when `hang` (until the
 * request's signal aborts it, as fetch does). */
function streamResponse(chunks, { hang = false } = {}, signal = null) {
  const enc = new TextEncoder();
  const body = new ReadableStream({
    start(ctrl) {
      signal?.addEventListener('abort', () => ctrl.error(new DOMException('aborted', 'AbortError')));
      for (const c of chunks) {
        ctrl.enqueue(enc.encode(c));
      }
      if (!hang) {
        ctrl.close();
      }
    },
  });
  return new Response(body, { status: 200, headers: { 'Content-Type': 'text/event-stream' } });
}

/** Install a fetch stub answering each path from a queue of responses; returns the paths requested. */
function stub(routes) {
  const calls = [];
  globalThis.fetch = async (url, init) => {
    calls.push(url);
    const queue = routes[url];
    assert.ok(queue && queue.length, `unexpected request ${url}`);
    init?.signal?.throwIfAborted();
    return queue.shift()(init?.signal);
  };
  return calls;
}

test('events: every job event in order (split across chunks, with keep-alive comments), resolves at end', async () => {
  const id = 'a'.repeat(64);
  const text = block('job', job('queued')) + ': ping\n\n' + block('job', job('running', 0.25, 'sweeping'))
    + block('job', job('succeeded', 1)) + block('end', job('succeeded', 1));
  const cut = 37; // an event split across two network reads
  stub({ [`/jobs/${id}/events`]: [() => streamResponse([text.slice(0, cut), text.slice(cut)])] });
  const seen = [];
  const final = await new Api('').events(id, (j) => seen.push([j.state, j.progress]));
  assert.deepEqual(seen, [['queued', 0], ['running', 0.25], ['succeeded', 1]]);
  assert.equal(final.state, 'succeeded');
});

test('events: a stream that goes silent is abandoned after idleMs with a clear error', async () => {
  const id = 'b'.repeat(64);
  stub({ [`/jobs/${id}/events`]: [(sig) => streamResponse([block('job', job('running', 0.1))], { hang: true }, sig)] });
  await assert.rejects(new Api('').events(id, () => {}, { idleMs: 50 }), /no news of job b{12} .*event stream was lost/);
});

test('follow: a stream closing before its end falls back to the job, then opens the stream again', async () => {
  const id = 'c'.repeat(64);
  const calls = stub({
    [`/jobs/${id}/events`]: [() => streamResponse([block('job', job('running', 0.5))]),
      () => streamResponse([block('job', job('running', 0.7)), block('end', job('cancelled', 0.7))])],
    [`/jobs/${id}`]: [() => Response.json(job('running', 0.6))],
  });
  const seen = [];
  const final = await new Api('').follow(id, (j) => seen.push(j.progress));
  assert.equal(final.state, 'cancelled');
  assert.deepEqual(seen, [0.5, 0.6, 0.7]);
  assert.deepEqual(calls, [`/jobs/${id}/events`, `/jobs/${id}`, `/jobs/${id}/events`]);
});

test('follow: gives up after its attempts with the stream error; an API error (404) is not retried', async () => {
  const id = 'd'.repeat(64);
  const silent = (sig) => streamResponse([], { hang: true }, sig);
  stub({ [`/jobs/${id}/events`]: [silent, silent], [`/jobs/${id}`]: [() => Response.json(job('running')),
    () => Response.json(job('running'))] });
  await assert.rejects(new Api('').follow(id, () => {}, { attempts: 2, idleMs: 30 }), /event stream was lost/);

  const gone = 'e'.repeat(64);
  const calls = stub({ [`/jobs/${gone}/events`]: [() => Response.json({ title: 'Not Found', status: 404,
    detail: `no job with id '${gone}'` }, { status: 404 })] });
  await assert.rejects(new Api('').follow(gone, () => {}), (err) => err instanceof ApiError && err.status === 404);
  assert.equal(calls.length, 1);
});
