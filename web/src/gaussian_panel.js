// The Gaussian lobes panel (seed 002: Green, Kautz & Durand 2007): several fitted materials on one Gaussian chain,
// switched instantly (the chain's texture stays on the GPU; a material is two K x N float16 textures, ~1 KB), lobes
// edited live (the paper's run-time editing: mu, sigma, weight of one lobe at one elevation, re-uploaded and
// redrawn), and the fit's charts: relative L2 error against theta_o with the interpolated mid-elevations (Fig. 4),
// and mu, sigma, w of every lobe against theta_o (Fig. 3).
//
// Data come from the job system: POST /jobs kind gaussian_fit (result: the gaussian-lobes material and the error
// table; lobes.bin = float16 (N, K, 8): mu, sigma, 0, 0, w_r, w_g, w_b, 0) and kind gaussian_chain (uniform_size
// levels, level_JJ.bin = float16 RGB lat-long). The sphere is drawn with web/shaders/gaussian*.glsl (gaussian.js) into
// a float target, read back as linear radiance and shown through the CPU display transform (tonemap.js).
// window.relight.gaussian exposes the state for tests: materials, current, edits, pixels(), requests.
import {
  bindGaussian, cameraBasis, chainFromLevels, gaussianDefines, gaussianProgram, lobeSampling, lobeTable, tableKey,
  uploadChain, uploadLobes,
} from './gaussian.js';
import { floatToHalf, halfToFloat } from './half.js';
import { tonemapImage } from './tonemap.js';

const SIZE = 160;
const VIEW = [0.3, 0.4, 1.0];
const deg = (r) => (180 * r) / Math.PI;

const HTML = `
  <h2>Gaussian lobes</h2>
  <label>BRDF <input id="sg-brdf" value="torrance-sparrow:alpha=0.2,fresnel=none" aria-label="BRDF to fit"></label>
  <div class="row">K <input id="sg-lobes" type="number" min="1" max="8" value="3" aria-label="lobes">
    N <input id="sg-elevations" type="number" min="2" max="64" value="15" aria-label="elevations">
    <button id="sg-fit" type="button">Fit</button>
    <button id="sg-chain" type="button">Chain for this map</button></div>
  <div id="sg-materials" class="row" style="flex-wrap: wrap" role="group" aria-label="fitted materials"></div>
  <canvas id="sg-canvas" width="${SIZE}" height="${SIZE}" aria-label="Gaussian-lobe sphere"></canvas>
  <div class="row">elevation <select id="sg-elev" aria-label="elevation"></select>
    lobe <select id="sg-lobe" aria-label="lobe"></select></div>
  <label>mu (deg) <input id="sg-mu" type="range" min="-30" max="30" step="0.1"></label>
  <label>sigma (deg) <input id="sg-sigma" type="range" min="0.5" max="60" step="0.1"></label>
  <label>weight x <input id="sg-weight" type="range" min="0" max="2" step="0.01" value="1"></label>
  <div id="sg-charts"></div>
  <div id="sg-status" class="status"></div>
  <p id="sg-error" class="error" role="alert"></p>`;

/** A material from a gaussian_fit result and its lobes.bin: float16 bits for the two K x N RGBA textures. */
export function materialFromLobes(result, buffer) {
  const n = result.elevations;
  const k = result.lobes;
  const raw = new Uint16Array(buffer);
  if (raw.length !== n * k * 8) {
    throw new Error(`lobes.bin holds ${raw.length} values; N = ${n}, K = ${k} need ${n * k * 8}`);
  }
  const shape = new Uint16Array(n * k * 4);
  const weight = new Uint16Array(n * k * 4);
  for (let t = 0; t < n * k; t += 1) {
    shape.set(raw.subarray(8 * t, 8 * t + 4), 4 * t);
    weight.set(raw.subarray(8 * t + 4, 8 * t + 8), 4 * t);
  }
  const elevations = result.material.elevations.map((e) => e.theta_o);
  return { lobes: k, elevations, shape, weight, errors: result.errors, midErrors: result.mid_errors };
}

/** One lobe's parameters at elevation i: mu, sigma (radians), weight [r, g, b]. */
export function lobeAt(material, i, k) {
  const t = 4 * (i * material.lobes + k);
  return { mu: halfToFloat(material.shape[t]), sigma: halfToFloat(material.shape[t + 1]),
    weight: [0, 1, 2].map((c) => halfToFloat(material.weight[t + c])) };
}

/** Edit one lobe in place (float16 rounding as the textures hold it). */
export function setLobe(material, i, k, { mu, sigma, weight }) {
  const t = 4 * (i * material.lobes + k);
  if (mu !== undefined) material.shape[t] = floatToHalf(mu);
  if (sigma !== undefined) material.shape[t + 1] = floatToHalf(Math.max(sigma, 1e-3));
  if (weight !== undefined) weight.forEach((w, c) => { material.weight[t + c] = floatToHalf(Math.max(w, 0)); });
}

/** SVG line chart: series [{name, points [[x, y]], dash}] over x in degrees. */
export function lineChart(series, { title, yLabel, width = 260, height = 130 }) {
  const all = series.flatMap((s) => s.points);
  const xs = all.map((p) => p[0]);
  const ys = all.map((p) => p[1]);
  const [x0, x1] = [Math.min(...xs), Math.max(...xs) || 1];
  const [y0, y1] = [Math.min(0, ...ys), Math.max(...ys) || 1];
  const px = (x) => 34 + ((x - x0) / (x1 - x0 || 1)) * (width - 44);
  const py = (y) => height - 20 - ((y - y0) / (y1 - y0 || 1)) * (height - 34);
  const colours = ['#d62728', '#1f77b4', '#2ca02c', '#9467bd', '#ff7f0e', '#8c564b', '#e377c2', '#7f7f7f'];
  const lines = series.map((s, j) => {
    const pts = s.points.map(([x, y]) => `${px(x).toFixed(1)},${py(y).toFixed(1)}`).join(' ');
    const dots = s.points.map(([x, y]) => `<circle class="pt" cx="${px(x).toFixed(1)}" cy="${py(y).toFixed(1)}" r="1.8"`
      + ` fill="${colours[j % 8]}"><title>${s.name}: ${x.toFixed(1)} deg, ${y.toPrecision(3)}</title></circle>`);
    return `<polyline class="series" data-name="${s.name}" fill="none" stroke="${colours[j % 8]}" `
      + `stroke-dasharray="${s.dash ? '3,2' : ''}" points="${pts}"/>${dots.join('')}`;
  });
  return `<svg class="sg-chart" width="${width}" height="${height}" role="img" aria-label="${title}">`
    + `<text x="34" y="10" font-size="10">${title}</text>`
    + `<text x="2" y="${height / 2}" font-size="9">${yLabel}</text>`
    + `<text x="${width - 60}" y="${height - 4}" font-size="9">theta_o (deg)</text>`
    + `<text x="2" y="${py(y1) + 3}" font-size="8">${y1.toPrecision(2)}</text>${lines.join('')}</svg>`;
}

class GaussianView {
  constructor() {
    this.canvas = document.createElement('canvas');
    this.canvas.width = SIZE;
    this.canvas.height = SIZE;
    this.gl = this.canvas.getContext('webgl2');
    if (!this.gl || !this.gl.getExtension('EXT_color_buffer_float')) {
      throw new Error('WebGL2 with EXT_color_buffer_float is needed for the Gaussian-lobe view');
    }
    const gl = this.gl;
    this.programs = new Map();
    this.target = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.target);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, SIZE, SIZE);
    this.fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.target, 0);
    this.quad = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, this.quad);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 0, 3, -1, 0, -1, 3, 0]), gl.STATIC_DRAW);
    this.lobes = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.lobes);
    lobeSampling(gl);
  }

  /** The chain's levels (uniform size) as one RGBA16F 3-D texture, uploaded once per chain. */
  setChain(chain) {
    const gl = this.gl;
    if (this.chainTex) gl.deleteTexture(this.chainTex);
    this.chainTex = uploadChain(gl, chain);
    this.chain = chain;
  }

  /** Linear radiance of the sphere (Float32Array SIZE * SIZE * 4, row 0 at the bottom). */
  async draw(material) {
    const gl = this.gl;
    const table = lobeTable(material); // an edit changes the values, never the program
    const key = `${tableKey(table)}/${this.chain.levels.length}`;
    if (!this.programs.has(key)) {
      this.programs.set(key, await gaussianProgram(gl, gaussianDefines({
        table, levels: this.chain.levels.length, sphere: true })));
    }
    const prog = this.programs.get(key);
    gl.bindTexture(gl.TEXTURE_2D, this.lobes);
    uploadLobes(gl, table);
    bindGaussian(gl, prog, { lobes: this.lobes, chain: this.chainTex, table, chainInfo: this.chain });
    const len = Math.hypot(...VIEW);
    const v = VIEW.map((x) => x / len);
    const [right, up] = cameraBasis(v);
    gl.uniform3fv(gl.getUniformLocation(prog, 'u_view_direction'), v);
    gl.uniform3fv(gl.getUniformLocation(prog, 'u_right'), right);
    gl.uniform3fv(gl.getUniformLocation(prog, 'u_up'), up);
    gl.uniform2f(gl.getUniformLocation(prog, 'u_viewport'), SIZE, SIZE);
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.fbo);
    gl.viewport(0, 0, SIZE, SIZE);
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.quad);
    const loc = gl.getAttribLocation(prog, 'a_position');
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    const out = new Float32Array(SIZE * SIZE * 4);
    gl.readPixels(0, 0, SIZE, SIZE, gl.RGBA, gl.FLOAT, out);
    return out;
  }
}

function show(canvas, rgba) {
  const rgb = new Float32Array(SIZE * SIZE * 3);
  for (let y = 0; y < SIZE; y += 1) { // GL rows bottom-up -> image rows top-down
    for (let x = 0; x < SIZE; x += 1) {
      const s = 4 * ((SIZE - 1 - y) * SIZE + x);
      rgb.set(rgba.subarray(s, s + 3), 3 * (y * SIZE + x));
    }
  }
  const ctx = canvas.getContext('2d');
  ctx.putImageData(new ImageData(tonemapImage(rgb), SIZE, SIZE), 0, 0);
}

export function initGaussianPanel(state, $, showError) {
  $('gaussian-panel').innerHTML = HTML;
  const sg = { materials: new Map(), current: null, chain: null, requests: 0, view: null, last: null, draws: 0,
    edits: 0 };
  state.gaussian = sg;
  const status = (text) => { $('sg-status').textContent = text; };
  const request = (...args) => { sg.requests += 1; return state.api.request(...args); };

  // the job's event stream (no polling): progress as it comes, the final job at its end
  async function waitJob(job) {
    const show = (p) => status(`${p.kind}: ${p.stage || p.state} ${Math.round(100 * (p.progress || 0))} %`);
    const pub = ['succeeded', 'failed', 'cancelled'].includes(job.state) ? job
      : await state.api.follow(job.id, show);
    if (pub.state !== 'succeeded') throw new Error(`${pub.kind} job ${pub.state}: ${pub.failure_reason || ''}`);
    return pub;
  }

  async function redraw() {
    const mat = sg.materials.get(sg.current);
    if (!mat || !sg.chain) return;
    sg.last = await sg.view.draw(mat);
    sg.draws += 1;
    show($('sg-canvas'), sg.last);
  }

  function charts(mat) {
    const th = mat.elevations.map(deg);
    const mids = th.slice(1).map((t, i) => (t + th[i]) / 2);
    const err = [{ name: 'fitted', points: th.map((t, i) => [t, 100 * mat.errors[i]]) },
      { name: 'interpolated (mid)', dash: true, points: mids.map((t, i) => [t, 100 * mat.midErrors[i]]) }];
    const lobes = [...Array(mat.lobes).keys()];
    const param = (fn, label) => lineChart(lobes.map((k) => ({ name: `lobe ${k + 1}`,
      points: th.map((t, i) => [t, fn(lobeAt(mat, i, k))]) })), { title: label, yLabel: '' });
    $('sg-charts').innerHTML = lineChart(err, { title: 'relative L2 error (%) vs theta_o (Fig. 4)', yLabel: '%' })
      + param((l) => deg(l.mu), 'mu (deg)') + param((l) => deg(l.sigma), 'sigma (deg)')
      + param((l) => l.weight[1], 'weight (green)');
  }

  function fillEditor(mat) {
    const elev = $('sg-elev');
    const lobe = $('sg-lobe');
    elev.innerHTML = mat.elevations.map((t, i) => `<option value="${i}">${deg(t).toFixed(1)} deg</option>`).join('');
    lobe.innerHTML = [...Array(mat.lobes).keys()].map((k) => `<option value="${k}">${k + 1}</option>`).join('');
    syncSliders();
  }

  function syncSliders() {
    const mat = sg.materials.get(sg.current);
    if (!mat) return;
    const l = lobeAt(mat, Number($('sg-elev').value), Number($('sg-lobe').value));
    $('sg-mu').value = deg(l.mu);
    $('sg-sigma').value = deg(l.sigma);
    $('sg-weight').value = 1;
    sg.editBase = l;
  }

  /** Switch to a fitted material: no request, only the two lobe textures change. */
  async function select(id) {
    sg.current = id;
    for (const b of $('sg-materials').querySelectorAll('button')) b.setAttribute('aria-pressed', b.dataset.id === id);
    const mat = sg.materials.get(id);
    fillEditor(mat);
    charts(mat);
    await redraw();
  }

  async function addFit(job) {
    const result = await request('GET', `/jobs/${job.id}/result`);
    const buffer = await request('GET', `/jobs/${job.id}/files/lobes.bin`, { as: 'arrayBuffer' });
    const mat = materialFromLobes(result, buffer);
    const spec = job.request.brdf_spec || {};
    const params = Object.entries(spec).filter(([key]) => key !== 'kind').map(([key, v]) => `${key}=${v}`);
    mat.label = `${spec.kind || job.id.slice(0, 8)} ${params.join(',')} (K ${mat.lobes})`;
    sg.materials.set(job.id, mat);
    const b = document.createElement('button');
    b.type = 'button';
    b.dataset.id = job.id;
    b.textContent = mat.label;
    b.addEventListener('click', () => select(job.id).catch((err) => showError('sg-error', err)));
    $('sg-materials').append(b);
    await select(job.id);
  }

  async function fit() {
    showError('sg-error', null);
    const body = { brdf: $('sg-brdf').value, lobes: Number($('sg-lobes').value),
      elevations: Number($('sg-elevations').value), theta_max_deg: 87 };
    const job = await waitJob(await request('POST', '/jobs', { json: { kind: 'gaussian_fit', request: body } }));
    await addFit(job);
    status(`fitted ${body.brdf}: ${sg.materials.get(job.id).elevations.length} elevations`);
  }

  async function chain() {
    showError('sg-error', null);
    if (!state.envmapId) throw new Error('pick an environment map first');
    const body = { envmap: state.envmapId, ratio: 'sqrt2', epsilon: 1e-3, uniform_size: true };
    const job = await waitJob(await request('POST', '/jobs', { json: { kind: 'gaussian_chain', request: body } }));
    const result = await request('GET', `/jobs/${job.id}/result`);
    const buffers = [];
    for (const lv of result.levels) {
      buffers.push(await request('GET', `/jobs/${job.id}/files/${lv.file}`, { as: 'arrayBuffer' }));
    }
    const chainData = chainFromLevels(result, buffers);
    sg.view = sg.view || new GaussianView();
    sg.view.setChain(chainData);
    sg.chain = job.id;
    status(`chain: ${chainData.levels.length} levels of ${chainData.height} rows`);
    await redraw();
  }

  /** Apply the slider that moved (only that parameter changes) to the selected lobe and elevation, redraw. */
  async function edit(id) {
    const mat = sg.materials.get(sg.current);
    if (!mat || !sg.editBase) return;
    const value = Number($(id).value);
    const change = id === 'sg-weight' ? { weight: sg.editBase.weight.map((w) => w * value) }
      : { [id === 'sg-mu' ? 'mu' : 'sigma']: (value * Math.PI) / 180 };
    setLobe(mat, Number($('sg-elev').value), Number($('sg-lobe').value), change);
    sg.edits += 1;
    charts(mat);
    await redraw();
  }

  const guard = (fn) => () => fn().catch((err) => showError('sg-error', err));
  $('sg-fit').addEventListener('click', guard(fit));
  $('sg-chain').addEventListener('click', guard(chain));
  $('sg-elev').addEventListener('change', syncSliders);
  $('sg-lobe').addEventListener('change', syncSliders);
  for (const id of ['sg-mu', 'sg-sigma', 'sg-weight']) $(id).addEventListener('input', guard(() => edit(id)));
  sg.select = select;
  sg.pixels = () => sg.last;
  sg.redraw = redraw;
}
