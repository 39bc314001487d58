// The viewer page: wires the panel (web/index.html) to the API (api.js) and the 3-D view (viewer.js).
// window.relight exposes the state for tests and the benchmark (tests/web, bench/viewer.py).
import { Api, ApiError, TERMINAL } from './api.js';
import { compare } from './compare.js';
import { initInOut } from './inout_panel.js';
import { modelsFromOpenapi, specFor } from './materials.js';
import { loadFile, loadSample } from './objects.js';
import { exampleScene, parseScene, sceneItems, showScene, showSceneErrors } from './scene.js';
import { chainFromLevels } from './gaussian.js';
import { initGaussianPanel, materialFromLobes } from './gaussian_panel.js';
import { initShadows } from './shadows.js';
import { initShTables } from './sh_table_panel.js';
import { initBrushed } from './brushed_panel.js';
import { initOrderGrid } from './sh_order_grid.js';
import { initExports } from './exports_panel.js';
import { chartModel, renderSvg } from './tradeoff.js';
import { ShrmViewer } from './viewer.js';

const $ = (id) => document.getElementById(id);
const state = {
  api: new Api('', localStorage.getItem('relight.apiKey') || ''),
  viewer: null,
  models: [],
  envmapId: null,
  brdf: null, // the spec object, or a measured BRDF's id
  shrmId: null,
  plan: null,
  job: null,
  planSeq: 0,
  ready: false,
  lastComparison: null,
  progressLog: [], // [state, progress] of every job update shown (tests)
  tradeoff: null, // the last GET /tradeoffs/{id} answer
  tradeoffKey: null, // JSON of the material and map it was run for
  scene: null, // the last GET /scenes/{id} answer
  sceneShown: null, // id of the scene drawn in the 3-D view (null: the single object)
  sceneErrors: [], // objects of that scene not drawn: {name, message} (a representation the viewer lacks)
};
window.relight = state;

function showError(id, err) {
  $(id).textContent = err ? (err instanceof ApiError ? err.display() : String(err.message || err)) : '';
}

function fmtSeconds(s) {
  return s < 1 ? `${(1000 * s).toFixed(0)} ms` : `${s.toFixed(1)} s`;
}

function fmtPercent(x) {
  return x === null || x === undefined ? '—' : `${(100 * x).toPrecision(2)} %`;
}

// ------------------------------------------------------------------------------------------------ materials
const FALLBACK_MODELS = [
  { kind: 'phong', params: [{ name: 's', type: 'number', min: 10, max: 1e5, value: 32, log: true }] },
  { kind: 'lambert', params: [] },
];

function numberControl(p, onChange) {
  const input = document.createElement('input');
  input.type = 'range';
  if (p.log) {
    input.min = Math.log10(p.min);
    input.max = Math.log10(p.max);
    input.step = 0.001;
    input.value = Math.log10(p.value);
  } else {
    input.min = p.min;
    input.max = p.max;
    input.step = p.integer ? 1 : (p.max - p.min) / 200;
    input.value = p.value;
  }
  input.readValue = () => {
    const v = p.log ? 10 ** Number(input.value) : Number(input.value);
    return p.integer ? Math.round(v) : Number(v.toPrecision(3));
  };
  input.addEventListener('input', onChange);
  return input;
}

function enumControl(p, onChange) {
  const select = document.createElement('select');
  for (const o of p.options) {
    const opt = document.createElement('option');
    opt.value = o;
    opt.textContent = o;
    select.append(opt);
  }
  select.value = p.value;
  select.readValue = () => select.value;
  select.addEventListener('change', onChange);
  return select;
}

function renderParams() {
  const model = state.models.find((m) => m.kind === $('brdf-kind').value);
  const box = $('brdf-params');
  box.textContent = '';
  const params = [...(model?.params || [])];
  if (model && model.kind !== 'lambert') {
    params.push({ name: 'diffuse', type: 'number', min: 0, max: 1, value: 0, log: false, extra: true,
      description: 'adds a Lambert lobe of this albedo (a sum of lobes: an N-centred component)' });
  }
  for (const p of params) {
    const label = document.createElement('label');
    label.className = 'param';
    label.textContent = p.name;
    label.title = p.description || '';
    const out = document.createElement('output');
    const control = p.type === 'enum' ? enumControl(p, () => changed()) : numberControl(p, () => changed());
    const changed = () => {
      out.textContent = control.readValue();
      materialChanged();
    };
    control.dataset.param = p.name;
    if (p.extra) {
      control.dataset.extra = '1';
    }
    control.setAttribute('aria-label', p.name);
    out.textContent = control.readValue();
    label.append(out, control);
    box.append(label);
  }
}

function currentBrdf() {
  const kind = $('brdf-kind').value;
  if (kind.startsWith('measured:')) {
    return kind.slice('measured:'.length);
  }
  const model = state.models.find((m) => m.kind === kind);
  const values = {};
  let diffuse = 0;
  for (const control of $('brdf-params').querySelectorAll('[data-param]')) {
    if (control.dataset.extra) {
      diffuse = control.readValue();
    } else {
      values[control.dataset.param] = control.readValue();
    }
  }
  return specFor(model, values, diffuse);
}

function requestBody() {
  const body = { envmap: state.envmapId, brdf: currentBrdf() };
  if (document.querySelector('input[name=accuracy]:checked').value === 'epsilon') {
    body.epsilon = Number((10 ** Number($('epsilon').value)).toPrecision(3));
  } else {
    body.order = Number($('order-f').value);
    body.p_order = Number($('order-p').value);
  }
  return body;
}

// ------------------------------------------------------------------------------------------------ plan
let planTimer = null;

function materialChanged() {
  clearTimeout(planTimer);
  planTimer = setTimeout(updatePlan, 200);
}

// One band of predicted_error.by_view (issue 18): its predicted error and, when the tolerance is enforced there but
// cannot be met within the caps, that it is not and the smallest BRDF error the band can reach.
function viewBandText(b) {
  const text = `N·V ${b.ndotv[0]}–${b.ndotv[1]}: ${fmtPercent(b.rms)}`;
  if (b.enforced && b.met === false) {
    const best = b.achievable_epsilon_brdf;
    return `${text} (ε not met${best != null ? `; reaches ε ${Number(best).toPrecision(2)}` : ''})`;
  }
  return text;
}

function showPlan(plan) {
  const o = plan.orders;
  const e = plan.predicted_error;
  $('plan').innerHTML = '';
  const dl = document.createElement('dl');
  const rows = [
    ['representation', plan.representation],
    ['orders', `F_B = ${o.F_B}, P_B = ${o.P_B}`],
    ['predicted time', fmtSeconds(plan.predicted_seconds)],
    ['predicted error', `${fmtPercent(e.rms_min_of_errors)} RMS (bound ${fmtPercent(e.rms_appendix_b)})`],
    ...(e.by_view ? [['error by view', e.by_view.map(viewBandText).join(', ')]] : []),
    ['output', `${plan.output.height} × ${plan.output.width} × ${plan.output.layers} layers`],
    ['cached', plan.cached ? 'yes — appears instantly' : 'no'],
  ];
  for (const [k, v] of rows) {
    const dt = document.createElement('dt');
    dt.textContent = k;
    const dd = document.createElement('dd');
    dd.textContent = v;
    dd.dataset.field = k.replace(/ /g, '-');
    dl.append(dt, dd);
  }
  $('plan').append(dl);
  $('plan').title = plan.reason || '';
}

async function updatePlan() {
  if (!state.envmapId) {
    $('plan').textContent = 'choose or upload an environment map';
    return;
  }
  const seq = ++state.planSeq;
  try {
    const plan = await state.api.plan(requestBody());
    if (seq !== state.planSeq) {
      return;
    }
    state.plan = plan;
    showPlan(plan);
    showError('plan-error', null);
    drawTradeoff();
  } catch (err) {
    if (seq === state.planSeq) {
      state.plan = null;
      $('plan').textContent = '—';
      showError('plan-error', err);
    }
  }
}

// ------------------------------------------------------------------------------------------------ jobs
function showJob(job) {
  state.job = job;
  state.progressLog.push([job.state, job.progress]);
  $('progress').value = job.state === 'succeeded' ? 1 : job.progress || 0;
  $('job-status').textContent = `${job.state}${job.stage ? ` — ${job.stage}` : ''}`
    + (job.failure_reason ? `: ${job.failure_reason}` : '');
}

async function compute() {
  showError('plan-error', null);
  $('compute').disabled = true;
  try {
    const { job, cached } = await state.api.submit(requestBody());
    showJob(job);
    let final = job;
    if (!cached && !TERMINAL.includes(job.state)) {
      final = await state.api.follow(job.id, showJob);
      showJob(final);
    }
    if (final.state === 'succeeded') {
      await loadResult(job.id);
      updatePlan(); // now "cached"
    }
  } catch (err) {
    showError('plan-error', err);
  } finally {
    $('compute').disabled = false;
  }
}

async function loadResult(id) {
  const [manifest, coefficients] = await Promise.all([state.api.manifest(id), state.api.coefficients(id)]);
  leaveScene();
  state.viewer.setShrm(manifest, coefficients);
  state.shrmId = id;
  $('progress').value = 1;
  const layers = manifest.layers.length;
  $('overlay').textContent = `${manifest.representation}: ${manifest.height} × ${manifest.width}, ${layers} `
    + `layer${layers > 1 ? 's' : ''}`;
  state.loaded = (state.loaded || 0) + 1;
}

// ------------------------------------------------------------------------------------------------ tradeoff

function tradeoffKey() {
  return JSON.stringify([state.envmapId, currentBrdf()]);
}

function drawTradeoff() {
  const t = state.tradeoff;
  if (!t || t.state !== 'succeeded') {
    return;
  }
  const stale = state.tradeoffKey !== tradeoffKey();
  // the marker is the current plan's prediction; it only belongs on the chart of the same material and map
  const model = chartModel(t.points || [], stale ? null : state.plan, { width: 276, height: 200, meta: t.meta });
  $('tradeoff-chart').innerHTML = renderSvg(model);
  const n = (m) => (t.points || []).filter((p) => p.method === m).length;
  const ms = t.meta?.mitsuba;
  $('tradeoff-status').textContent = `${n('frequency')} frequency, ${n('angular')} angular points on a `
    + `${t.params?.rows ?? '?'}-row map; ◆ = current choice (predicted)`
    + (ms?.computed ? `; □ = error against Mitsuba 3 (noise floor ${Number(ms.noise).toPrecision(2)}, dotted)`
      : (ms?.reason ? `; no Mitsuba comparison: ${ms.reason}` : ''))
    + (stale ? ' — chart is for a previous material or map: run again' : '');
}

async function runTradeoff() {
  showError('tradeoff-error', null);
  if (!state.envmapId) {
    showError('tradeoff-error', 'choose or upload an environment map first');
    return;
  }
  $('tradeoff-run').disabled = true;
  const key = tradeoffKey();
  try {
    const { tradeoff } = await state.api.tradeoff({ envmap: state.envmapId, brdf: currentBrdf(), rows: 16 });
    let t = tradeoff;
    if (!TERMINAL.includes(t.state)) {
      const started = performance.now();
      await state.api.follow(t.id, (job) => {
        $('tradeoff-status').textContent = `${job.state}${job.stage ? ` — ${job.stage}` : ''} `
          + `${Math.round(100 * (job.progress || 0))} % — ${((performance.now() - started) / 1000).toFixed(0)} s`;
      });
      t = await state.api.getTradeoff(t.id);
    }
    if (t.state !== 'succeeded') {
      throw new Error(`the sweep ${t.state}${t.failure_reason ? `: ${t.failure_reason}` : ''}`);
    }
    state.tradeoff = t;
    state.tradeoffKey = key;
    drawTradeoff();
  } catch (err) {
    $('tradeoff-status').textContent = '';
    showError('tradeoff-error', err);
  } finally {
    $('tradeoff-run').disabled = false;
  }
}

// ------------------------------------------------------------------------------------------------ scene
async function runScene() {
  showError('scene-error', null);
  $('scene-run').disabled = true;
  try {
    const body = parseScene($('scene-json').value, state.envmapId);
    let pub = await state.api.scene(body);
    state.scene = pub;
    await showScene($('scene-plan'), pub, state.api);
    if (!TERMINAL.includes(pub.state)) {
      await state.api.follow(pub.id, (job) => {
        $('scene-status').textContent = `${job.state}${job.stage ? ` — ${job.stage}` : ''} `
          + `${Math.round(100 * (job.progress || 0))} %`;
      });
      pub = await state.api.getScene(pub.id);
      state.scene = pub;
      $('scene-status').textContent = '';
    }
    await showScene($('scene-plan'), pub, state.api);
    if (pub.state !== 'succeeded') {
      showError('scene-error', `the scene ${pub.state}${pub.failure_reason ? `: ${pub.failure_reason}` : ''}`);
    } else {
      await showSceneIn3d(pub);
    }
  } catch (err) {
    showError('scene-error', err);
  } finally {
    $('scene-run').disabled = false;
  }
}

/** Every object of a finished scene in the 3-D view, each with its own SHRM and planned viewer. */
async function showSceneIn3d(pub) {
  const shape = (name) => (name === 'sphere' ? 'sphere' : loadSample(name));
  const { items, errors } = await sceneItems(pub, state.api, shape, { material: materialFromLobes,
    chain: chainFromLevels });
  showSceneErrors($('scene-plan'), errors);
  state.sceneErrors = errors;
  state.viewer.setSceneObjects(items);
  state.sceneShown = pub.id;
  $('scene-single').hidden = false;
  const drawn = new Set(items.map((it) => it.name)).size;
  $('overlay').textContent = `scene ${pub.scene?.name || pub.id.slice(0, 10)}: ${drawn} objects, each with its `
    + `chosen representation${errors.length ? ` (${errors.length} not drawn: see the Scene panel)` : ''}`;
}

/** Back to the current material on one object. */
function leaveScene() {
  if (state.sceneShown) {
    state.viewer.clearScene();
    state.sceneShown = null;
    $('scene-single').hidden = true;
  }
}

// ------------------------------------------------------------------------------------------------ environment
async function refreshEnvmaps(select) {
  const list = await state.api.listEnvmaps();
  const sel = $('envmap');
  sel.textContent = '';
  for (const env of list.items) {
    const opt = document.createElement('option');
    opt.value = env.id;
    opt.textContent = `${env.name || env.id.slice(0, 12)} (${env.width} × ${env.height})`;
    sel.append(opt);
  }
  if (select) {
    sel.value = select;
  }
  if (sel.value) {
    await selectEnvmap(sel.value);
  } else {
    $('plan').textContent = 'upload an environment map';
  }
}

async function selectEnvmap(id) {
  state.envmapId = id;
  state.exportsPanel?.refresh(); // its download buttons export the selected map from now on
  materialChanged();
  try {
    const tex = await state.api.envmapTexture(id, 256);
    if (state.envmapId !== id) {
      return; // another map was selected while this texture loaded: the later choice wins
    }
    const halves = new Uint16Array(tex.data);
    state.viewer.setEnvironment(halves, tex.height, tex.width);
    state.environmentId = id; // the map the viewer lights with (tests wait for it)
    showError('envmap-error', null);
  } catch (err) {
    showError('envmap-error', err);
  }
}

async function uploadEnvmap(file) {
  showError('envmap-error', null);
  try {
    const env = await state.api.uploadEnvmap(file);
    await refreshEnvmaps(env.id);
  } catch (err) {
    showError('envmap-error', err);
  }
}

async function uploadBrdf(file) {
  showError('brdf-error', null);
  try {
    const brdf = await state.api.uploadMeasuredBrdf(file);
    const opt = document.createElement('option');
    opt.value = `measured:${brdf.id}`;
    opt.textContent = `measured ${brdf.id.slice(0, 10)}`;
    $('brdf-kind').append(opt);
    $('brdf-kind').value = opt.value;
    renderParams();
    materialChanged();
  } catch (err) {
    showError('brdf-error', err);
  }
}

// ------------------------------------------------------------------------------------------------ display
async function setObject(name) {
  showError('mesh-error', null);
  leaveScene();
  try {
    if (name === 'sphere') {
      state.viewer.setObject('sphere');
    } else {
      state.viewer.setObject(await loadSample(name), name);
    }
  } catch (err) {
    showError('mesh-error', err);
  }
}

async function uploadMesh(file) {
  showError('mesh-error', null);
  leaveScene();
  try {
    state.viewer.setObject(await loadFile(file), file.name);
  } catch (err) {
    showError('mesh-error', err);
  }
}

function displayOptions() {
  const rotation = Number($('rotation').value);
  const exposure = Number($('exposure').value);
  $('rotation-value').textContent = `${rotation}°`;
  $('exposure-value').textContent = `${exposure} EV`;
  state.viewer.setOptions({
    mode: $('mode').value,
    rotation: (rotation * Math.PI) / 180,
    exposure,
    tonemap: $('tonemap').value,
    background: $('background').checked,
  });
}

async function runCompare() {
  showError('compare-error', null);
  if (!state.shrmId) {
    showError('compare-error', 'compute or load an SHRM first');
    return;
  }
  $('compare').disabled = true;
  $('cmp-err-caption').textContent = 'computing the reference…';
  $('cmp-ours-caption').textContent = 'SHRM (WebGL)';
  $('cmp-ref-caption').textContent = 'reference (angular brute force, slow)';
  $('comparison').hidden = false;
  try {
    const result = await compare({
      viewer: state.viewer, api: state.api, shrmId: state.shrmId, size: Number($('compare-size').value),
      canvases: { shrm: $('cmp-shrm'), reference: $('cmp-ref'), error: $('cmp-err') },
    });
    state.lastComparison = result;
    $('cmp-err-caption').textContent = `error: ${fmtPercent(result.rms)} relative RMS, max ${fmtPercent(result.max)}`
      + ` (|ΔY| / max Y, log colour 1e-4…1e-1; reference on the map at ${result.envRows ?? '?'} rows)`;
  } catch (err) {
    $('cmp-err-caption').textContent = 'error';
    showError('compare-error', err);
  } finally {
    $('compare').disabled = false;
  }
}

// ------------------------------------------------------------------------------------------------ start
function resize() {
  const canvas = $('view');
  state.viewer?.resize(canvas.clientWidth, canvas.clientHeight);
}

async function main() {
  state.viewer = await new ShrmViewer($('view')).init();
  resize();
  window.addEventListener('resize', resize);
  state.viewer.start();

  $('api-key').value = state.api.apiKey;
  $('api-key').addEventListener('change', () => {
    state.api.apiKey = $('api-key').value;
    localStorage.setItem('relight.apiKey', state.api.apiKey);
    refreshEnvmaps().catch((err) => showError('envmap-error', err));
  });
  try {
    state.models = modelsFromOpenapi(await state.api.openapi());
  } catch {
    state.models = [];
  }
  if (!state.models.length) {
    state.models = FALLBACK_MODELS;
  }
  for (const m of state.models) {
    const opt = document.createElement('option');
    opt.value = m.kind;
    opt.textContent = m.kind;
    $('brdf-kind').append(opt);
  }
  $('brdf-kind').value = state.models.some((m) => m.kind === 'phong') ? 'phong' : state.models[0].kind;
  renderParams();
  $('brdf-kind').addEventListener('change', () => {
    renderParams();
    materialChanged();
  });
  $('envmap').addEventListener('change', () => selectEnvmap($('envmap').value));
  $('envmap-file').addEventListener('change', (e) => e.target.files[0] && uploadEnvmap(e.target.files[0]));
  $('brdf-file').addEventListener('change', (e) => e.target.files[0] && uploadBrdf(e.target.files[0]));
  $('mesh-file').addEventListener('change', (e) => e.target.files[0] && uploadMesh(e.target.files[0]));
  $('epsilon').addEventListener('input', () => {
    $('epsilon-value').textContent = (10 ** Number($('epsilon').value)).toPrecision(2);
    materialChanged();
  });
  for (const id of ['order-f', 'order-p']) {
    $(id).addEventListener('input', materialChanged);
  }
  for (const radio of document.querySelectorAll('input[name=accuracy]')) {
    radio.addEventListener('change', () => {
      const eps = document.querySelector('input[name=accuracy]:checked').value === 'epsilon';
      $('accuracy-epsilon').hidden = !eps;
      $('accuracy-orders').hidden = eps;
      materialChanged();
    });
  }
  $('compute').addEventListener('click', compute);
  $('object').addEventListener('change', () => setObject($('object').value));
  for (const id of ['mode', 'rotation', 'exposure', 'tonemap', 'background']) {
    $(id).addEventListener('input', displayOptions);
    $(id).addEventListener('change', displayOptions);
  }
  displayOptions();
  $('tradeoff-run').addEventListener('click', runTradeoff);
  $('scene-run').addEventListener('click', runScene);
  $('scene-single').addEventListener('click', leaveScene);
  $('scene-example').addEventListener('click', () => {
    $('scene-json').value = JSON.stringify(exampleScene(state.envmapId, currentBrdf()), null, 1);
  });
  $('scene-file').addEventListener('change', async (e) => {
    if (e.target.files[0]) {
      $('scene-json').value = await e.target.files[0].text();
    }
  });
  $('compare').addEventListener('click', runCompare);
  $('compare-close').addEventListener('click', () => {
    $('comparison').hidden = true;
  });
  try {
    await refreshEnvmaps();
  } catch (err) {
    showError('envmap-error', err);
  }
  await initShadows(state, $, showError);
  initGaussianPanel(state, $, showError);
  await initInOut(state, $, showError);
  initShTables(state, $, showError);
  initBrushed(state, $, showError);
  initOrderGrid(state, $, showError);
  state.currentBrdf = currentBrdf; // the exports panel offers the chains of the current material too
  initExports(state, $, showError);
  const fromUrl = new URLSearchParams(window.location.search).get('shrm');
  if (fromUrl) {
    await loadResult(fromUrl).catch((err) => showError('plan-error', err));
  }
  state.ready = true;
}

state.loadResult = loadResult;
state.setObject = setObject;
main().catch((err) => {
  document.body.dataset.error = String(err);
  $('overlay').textContent = `viewer failed to start: ${err.message || err}`;
  console.error(err);
});
