// The relight HTTP API from the browser: JSON in and out, RFC 9457 problem details turned into ApiError (with
// the server's own detail text), server-sent job events read with fetch (so the API key header can be sent).

export class ApiError extends Error {
  constructor(status, problem) {
    const detail = problem?.detail || problem?.title || `HTTP ${status}`;
    super(detail);
    this.status = status;
    this.problem = problem || {};
  }

  /** One line for the page: "Title: detail" and the per-field messages of a validation error. */
  display() {
    const p = this.problem;
    const fields = (p.errors || []).map((e) => `${(e.loc || []).join('.')}: ${e.msg}`).join('; ');
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

  /** Calls onJob(job) for every `job` event until `end`; resolves with the last job. */
  async events(id, onJob, signal) {
    const resp = await this.request('GET', `/jobs/${id}/events`, { as: 'response', signal,
      headers: { Accept: 'text/event-stream' } });
    const reader = resp.body.pipeThrough(new TextDecoderStream()).getReader();
    let buffer = '';
    let last = null;
    for (;;) {
      const { value, done } = await reader.read();
      if (done) {
        return last;
      }
      buffer += value;
      let cut;
      while ((cut = buffer.search(/\r?\n\r?\n/)) >= 0) {
        const block = buffer.slice(0, cut);
        buffer = buffer.slice(cut).replace(/^\r?\n\r?\n/, '');
        const event = { event: 'message', data: [] };
        for (const line of block.split(/\r?\n/)) {
          if (line.startsWith('event:')) {
            event.event = line.slice(6).trim();
          } else if (line.startsWith('data:')) {
            event.data.push(line.slice(5).replace(/^ /, ''));
          }
        }
        const data = event.data.join('\n');
        if (event.event === 'job' && data) {
          last = JSON.parse(data);
          onJob(last);
        } else if (event.event === 'end') {
          reader.cancel().catch(() => {});
          return last;
        }
      }
    }
  }
}
