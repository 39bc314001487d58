// The relight HTTP API from the browser: JSON in and out, RFC 9457 problem details turned into ApiError (with
// the server's own detail text), server-sent job events read with fetch (so the API key header can be sent), for
// every kind of job.

/** Job states after which nothing changes. */
export const TERMINAL = ['succeeded', 'failed', 'cancelled'];
/** Silence on a job's event stream after which it counts as lost (the server pings every 15 s). */
export const EVENTS_IDLE_MS = 45000;

export class ApiError extends Error {
  constructor(status, problem) {
    const detail = problem?.detail || problem?.title || `HTTP ${status}`;
    super(detail);
    this.status = status;
    this.problem = problem || {};
  }

  /**
   * One line for the page: "Title (status) — detail" and the per-field messages of a validation error that the
   * detail does not already hold (relight.server.problems writes each field's `field` and `message` into the
   * detail too; other servers' entries may be pydantic's `loc` and `msg`).
   */
  display() {
    const p = this.problem;
    const fields = (p.errors || []).map((e) => `${e.field ?? (e.loc || []).join('.')}: ${e.message ?? e.msg}`)
      .filter((f) => !String(p.detail || '').includes(f)).join('; ');
    const head = p.title ? `${p.title} (${this.status})` : `HTTP ${this.status}`;
    return [head, p.detail, fields].filter(Boolean).join(' — ');
  }
}

export class Api {
  constructor(base = '', apiKey = '') {
    this.base = base;
    this.apiKey = apiKey;
  }

  headers(extra = {}) {
    return this.apiKey ? { Authorization: `Bearer ${this.apiKey}`, ...extra } : extra;
  }

  async request(method, path, { json, body, headers = {}, as = 'json', signal } = {}) {
    const init = { method, headers: this.headers(headers), signal };
    if (json !== undefined) {
      init.body = JSON.stringify(json);
      init.headers['Content-Type'] = 'application/json';
    } else if (body !== undefined) {
      init.body = body;
      init.headers['Content-Type'] = 'application/octet-stream';
    }
    const resp = await fetch(this.base + path, init);
    if (!resp.ok) {
      let problem;
      try {
        problem = await resp.json();
      } catch {
        problem = { title: resp.statusText };
      }
      throw new ApiError(resp.status, problem);
    }
    if (as === 'response') {
      return resp;
    }
    return as === 'json' ? resp.json() : resp.arrayBuffer();
  }

  listEnvmaps() {
    return this.request('GET', '/envmaps?limit=200');
  }

  uploadEnvmap(file) {
    return this.request('POST', `/envmaps?name=${encodeURIComponent(file.name)}`, { body: file });
  }

  async envmapTexture(id, rows = 256) {
    const resp = await this.request('GET', `/envmaps/${id}/texture.bin?rows=${rows}`, { as: 'response' });
    const shape = (resp.headers.get('X-Texture-Shape') || '').split(',').map(Number);
    return { data: await resp.arrayBuffer(), height: shape[0], width: shape[1] };
  }

  uploadMeasuredBrdf(file) {
    return this.request('POST', '/brdfs/measured', { body: file });
  }

  plan(body, signal) {
    return this.request('POST', '/plan', { json: body, signal });
  }

  /** POST /shrms: {job, cached} (200 = the result exists already, 202 = a job runs). */
  async submit(body) {
    const resp = await this.request('POST', '/shrms', { json: body, as: 'response' });
    return { job: await resp.json(), cached: resp.status === 200 };
  }

  job(id) {
    return this.request('GET', `/jobs/${id}`);
  }

  manifest(id) {
    return this.request('GET', `/shrms/${id}`);
  }

  coefficients(id) {
    return this.request('GET', `/shrms/${id}/coefficients.bin`, { as: 'arrayBuffer' });
  }

  /** The brute-force sphere image (EXR bytes) and the map rows it was computed on. */
  async reference(id, view, size, envRows) {
    const v = view.map((x) => x.toFixed(6)).join(',');
    const rows = envRows ? `&env_rows=${envRows}` : '';
    const resp = await this.request('GET', `/shrms/${id}/reference.exr?view=${v}&size=${size}${rows}`,
      { as: 'response' });
    return { data: await resp.arrayBuffer(), envRows: Number(resp.headers.get('X-Reference-Env-Rows')) || null };
  }

  /**
   * GET /meshes/{id}/reference.exr: Mitsuba's image of the mesh (`rotation` in degrees about +Y);
   * {data: ArrayBuffer, noise: relative Monte Carlo standard deviation of the image's luminance}.
   */
  async meshReference(id, { envmap, view, size, spp = 64, rotation = 0, albedo = 0.8, maxDepth = 2 }) {
    const q = new URLSearchParams({ envmap, view: view.map((x) => x.toFixed(6)).join(','), size: String(size),
      spp: String(spp), rotation: rotation.toFixed(6), albedo: albedo.toFixed(6), max_depth: String(maxDepth) });
    const resp = await this.request('GET', `/meshes/${id}/reference.exr?${q}`, { as: 'response' });
    return { data: await resp.arrayBuffer(), noise: Number(resp.headers.get('X-Reference-Noise')) };
  }

  openapi() {
    return this.request('GET', '/openapi.json');
  }

  /** POST /tradeoffs: {tradeoff, done} (200 = the sweep had finished already, 202 = it runs). */
  async tradeoff(body) {
    const resp = await this.request('POST', '/tradeoffs', { json: body, as: 'response' });
    return { tradeoff: await resp.json(), done: resp.status === 200 };
  }

  getTradeoff(id) {
    return this.request('GET', `/tradeoffs/${id}`);
  }

  scene(body) {
    return this.request('POST', '/scenes', { json: body });
  }

  getScene(id) {
    return this.request('GET', `/scenes/${id}`);
  }

  sceneFile(id, name) {
    return this.request('GET', `/scenes/${id}/files/${encodeURIComponent(name)}`, { as: 'arrayBuffer' });
  }

  /**
   * GET /jobs/{id}/events (any kind of job: SHRM, sweep, scene): calls onJob(job) for every `job` event and
   * resolves with the final job at `end`, or with null when the stream closes before its end.
   *
   * Read with fetch rather than EventSource because EventSource cannot send the Authorization header a keyed
   * server needs. Rejects with ApiError for an error answer, and with a timeout Error when nothing arrives for
   * `idleMs` (the server sends a keep-alive comment every 15 s on an idle stream, so silence means it is gone).
   */
  async events(id, onJob, { signal, idleMs = EVENTS_IDLE_MS } = {}) {
    const ctrl = new AbortController();
    const onAbort = () => ctrl.abort(signal.reason);
    signal?.addEventListener('abort', onAbort);
    let timer = null;
    let idle = false;
    let reader = null;
    const lost = () => new Error(`no news of job ${id.slice(0, 12)} for ${Math.round(idleMs / 1000)} s: the event `
      + 'stream was lost');
    const arm = () => {
      clearTimeout(timer);
      timer = setTimeout(() => {
        idle = true;
        ctrl.abort();
        reader?.cancel().catch(() => {}); // a pending read ends at once
      }, idleMs);
    };
    arm();
    try {
      const resp = await this.request('GET', `/jobs/${id}/events`, { as: 'response', signal: ctrl.signal,
        headers: { Accept: 'text/event-stream' } });
      reader = resp.body.pipeThrough(new TextDecoderStream()).getReader();
      let buffer = '';
      for (;;) {
        const { value, done } = await reader.read();
        if (idle) {
          throw lost();
        }
        if (done) {
          return null;
        }
        arm();
        buffer += value;
        let cut;
        while ((cut = buffer.search(/\r?\n\r?\n/)) >= 0) {
          const event = parseEvent(buffer.slice(0, cut));
          buffer = buffer.slice(cut).replace(/^\r?\n\r?\n/, '');
          if (event.data && (event.event === 'job' || event.event === 'end')) {
            const job = JSON.parse(event.data);
            if (event.event === 'end') {
              reader.cancel().catch(() => {});
              return job;
            }
            onJob(job);
          }
        }
      }
    } catch (err) {
      throw idle ? lost() : err;
    } finally {
      clearTimeout(timer);
      signal?.removeEventListener('abort', onAbort);
    }
  }

  /**
   * Follow a job to its end: its event stream, opened again (after reading the job once) when it breaks or goes
   * silent, up to `attempts` times; resolves with the final job (its state may be failed or cancelled).
   */
  async follow(id, onJob, { attempts = 3, idleMs = EVENTS_IDLE_MS } = {}) {
    let lastError = null;
    for (let i = 0; i < attempts; i += 1) {
      try {
        const final = await this.events(id, onJob, { idleMs });
        if (final) {
          return final;
        }
      } catch (err) {
        if (err instanceof ApiError) {
          throw err;
        }
        lastError = err;
      }
      const job = await this.job(id);
      onJob(job);
      if (TERMINAL.includes(job.state)) {
        return job;
      }
    }
    throw lastError || new Error(`the event stream of job ${id.slice(0, 12)} kept closing before the job ended`);
  }
}

/** One server-sent event block: its `event` name and joined `data` lines (comments and ids ignored). */
function parseEvent(block) {
  const event = { event: 'message', data: [] };
  for (const line of block.split(/\r?\n/)) {
    if (line.startsWith('event:')) {
      event.event = line.slice(6).trim();
    } else if (line.startsWith('data:')) {
      event.data.push(line.slice(5).replace(/^ /, ''));
    }
  }
  return { event: event.event, data: event.data.join('\n') };
}
