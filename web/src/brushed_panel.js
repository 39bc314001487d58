// The brushed-metal panel (seed 003, Kautz, Sloan & Snyder 2002, §4-§6): an object (sphere, or a service mesh:
// bunny, teapot, an uploaded mesh) in any BRDF's per-view SH table (an sh_table job; Ashikhmin–Shirley (48, 16) by
// default) under the viewer's environment turning about +Y and up to two movable circular area lights (direction,
// solid angle, colour; sh_lights.capLight), with view and lighting both changing every frame. The rotation of the
// lighting into every vertex's frame runs on the GPU (web/src/sh_table.js, sh_rotation.glsl). A mode switch
// (general / fixed lighting / fixed view / PRT transfer) shows the measured frame time, and "Time modes" measures
// all of them in one run as the paper's Table 1 (ratios to the general mode). Windowing (none / Hann / Lanczos)
// states its cost (the relative L2 change of the lighting); a tangent-field overlay draws the brushing direction;
// PRT shadows come from a visibility job (kind shadow_matrix: world T_p, rotated on the GPU, TRANSFER_WORLD).
// The panel builds its own DOM and canvas (one registration line in main.js); window.relight.brushed exposes the
// state and probes for tests/web/test_brushed_browser.py.
import { parseGeometry, projectLatlongHalf, rotateLightingY } from './prt.js';
import { loadSources } from './shaders.js';
import { capLight, addLighting, sphereGeometry, tangentField, tangentLines, windowLighting } from './sh_lights.js';
import { LineOverlay } from './line_overlay.js';
import { SHADER_FILES, SHTableGL } from './sh_table.js';
import { tableRgb, transferLayout, viewProjection } from './sh_table_data.js';

const DEFAULT_BRDF = 'ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0';
const TIMED_FRAMES = 20;
function controls() {
  const cap = (k, on, az, el, sr, colour) => `<fieldset><legend>area light ${k + 1}</legend>
    <label><input type="checkbox" id="brushed-cap${k}-on"${on ? ' checked' : ''}> on</label>
    <label>azimuth <input type="range" id="brushed-cap${k}-az" min="-180" max="180" value="${az}"></label>
    <label>elevation <input type="range" id="brushed-cap${k}-el" min="-90" max="90" value="${el}"></label>
    <label>solid angle (sr) <input type="number" id="brushed-cap${k}-sr" min="0.01" max="12.5" step="0.01"
      value="${sr}"></label>
    <label>colour <input type="color" id="brushed-cap${k}-colour" value="${colour}"></label>
    <label>radiance <input type="number" id="brushed-cap${k}-radiance" min="0" max="1000" value="8"></label>
    </fieldset>`;
  return `<h2>Brushed metal (seed 003)</h2>
    <canvas id="brushed-view" width="320" height="320"></canvas>
    <div id="brushed-frame"></div>
    <label>object <select id="brushed-object"><option value="sphere">sphere</option></select></label>
    <label>BRDF <input id="brushed-brdf" size="36"></label>
    <label>order F <select id="brushed-order"><option>2</option><option selected>4</option><option>6</option>
      <option>8</option></select></label>
    <label>R <input id="brushed-resolution" type="number" min="8" max="256" value="64"></label>
    <label>tangent <select id="brushed-tangent"><option value="project">projected direction (§6)</option>
      <option value="azimuthal">azimuthal about +Y</option><option value="mesh">mesh TANGENT</option></select></label>
    <label>direction <input id="brushed-direction" value="1,0.3,0.2" size="10"></label>
    <button id="brushed-load" type="button">Load</button>
    <label>mode <select id="brushed-mode"><option value="general">general (view and light change)</option>
      <option value="fixed-light">fixed lighting</option><option value="fixed-view">fixed view</option>
      <option value="transfer">PRT transfer</option></select></label>
    <label><input type="checkbox" id="brushed-spin-light" checked> rotate environment</label>
    <label><input type="checkbox" id="brushed-spin-view" checked> orbit view</label>
    <label>environment <input type="range" id="brushed-env" min="0" max="2" step="0.05" value="1"></label>
    ${cap(0, true, 40, 35, 0.3, '#ffd9a0')}${cap(1, false, -120, 10, 1.0, '#a0c8ff')}
    <label>window <select id="brushed-window"><option>none</option><option>hann</option><option>lanczos</option>
      </select></label> <span id="brushed-window-cost"></span>
    <label><input type="checkbox" id="brushed-tangents"> tangent field</label>
    <label>shadows <select id="brushed-prt"><option value="off">off</option><option value="shadows">PRT shadows
      </option><option value="interreflections">shadows + interreflections</option></select></label>
    <label>bounces <input id="brushed-bounces" type="number" min="1" max="4" value="1"></label>
    <label>rays <input id="brushed-rays" type="number" min="16" max="4096" value="256"></label>
    <button id="brushed-time" type="button">Time modes (Table 1)</button>
    <div id="brushed-table1"></div>
    <progress id="brushed-progress" max="1" value="0"></progress>
    <div id="brushed-status"></div><div id="brushed-error" class="error"></div>`;
}

export function initBrushed(state, $, showError) {
  const section = document.createElement('section');
  section.id = 'brushed-panel';
  section.innerHTML = controls();
  (document.querySelector('aside') || document.querySelector('main') || document.body).append(section);
  $('brushed-brdf').value = DEFAULT_BRDF;
  const canvas = $('brushed-view');
  const gl = canvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
  const status = (text) => { $('brushed-status').textContent = text; };
  const panel = {
    gl, table: null, object: null, lightingKey: null, light: null, envCoeffs: null, envKey: null,
    rotation: 0, viewAz: 0.6, viewEl: 0.35, mode: 'general', frameMs: {}, samples: {}, prepared: null,
    windowCost: 0, transferJob: null, table1: null, read: null, lines: null,
  };
  state.brushed = panel;

  const job = async (kind, request, url = '/jobs') => {
    const body = kind ? { kind, request } : request;
    const j = await state.api.request('POST', url, { json: body });
    const final = ['succeeded', 'failed', 'cancelled'].includes(j.state) ? j
      : await state.api.follow(j.id, (u) => { $('brushed-progress').value = u.progress || 0; });
    if (final.state !== 'succeeded') {
      throw new Error(`the ${kind || 'visibility'} job ${final.state}: ${final.failure_reason || ''}`);
    }
    $('brushed-progress').value = 1;
    return j.id;
  };

  async function refreshObjects() {
    const list = await state.api.request('GET', '/meshes');
    const sel = $('brushed-object');
    for (const m of list.items) {
      if (![...sel.options].some((o) => o.value === m.id)) {
        const opt = document.createElement('option');
        opt.value = m.id;
        opt.textContent = `${m.name || m.id.slice(0, 12)} (${m.vertices} vertices)`;
        sel.append(opt);
      }
    }
  }

  /** The chosen tangent field as a job's request names it (sh_transfer's tangent). */
  function tangentSpec() {
    const kind = $('brushed-tangent').value;
    return kind === 'project' ? { kind, direction: $('brushed-direction').value.split(',').map(Number) } : { kind };
  }

  /** The object's geometry normalised into the unit ball, with the chosen tangent field. */
  async function loadObject() {
    const id = $('brushed-object').value;
    let g;
    if (id === 'sphere') {
      g = { ...sphereGeometry(), meshTangents: null, id };
    } else {
      const info = await state.api.request('GET', `/meshes/${id}`);
      const buffer = await state.api.request('GET', `/meshes/${id}/geometry.bin`, { as: 'arrayBuffer' });
      const raw = parseGeometry(buffer, info.geometry);
      const [lo, hi] = [info.bounds.min, info.bounds.max];
      const s = 1 / (info.bounding_radius > 0 ? info.bounding_radius : 1);
      const positions = Float32Array.from(raw.positions, (x, k) => (x - 0.5 * (lo[k % 3] + hi[k % 3])) * s);
      g = { positions, normals: raw.normals, indices: raw.indices, meshTangents: raw.tangents, id };
    }
    const spec = tangentSpec();
    g.tangents = tangentField(g.normals, spec.kind === 'mesh' ? (g.meshTangents ? { kind: 'mesh',
      tangents: g.meshTangents } : { kind: 'azimuthal' }) : spec);
    const count = g.normals.length / 3;
    g.count = count;
    g.vertices = new Float32Array(10 * count);
    for (let k = 0; k < count; k += 1) {
      g.vertices.set(g.positions.subarray(3 * k, 3 * k + 3), 10 * k);
      g.vertices.set(g.normals.subarray(3 * k, 3 * k + 3), 10 * k + 3);
      g.vertices.set(g.tangents.subarray(4 * k, 4 * k + 4), 10 * k + 6);
    }
    const lines = tangentLines(g.positions, g.normals, g.tangents, { stride: Math.max(1, Math.floor(count / 3000)) });
    if (panel.object && panel.table) {
      panel.table.releaseMesh(panel.object);
    }
    panel.object = g;
    panel.lines = lines;
    panel.prepared = null;
    return g;
  }

  /** The sh_table job of the current BRDF and order, its table.bin on the GPU. */
  async function loadTable() {
    const request = { brdf: $('brushed-brdf').value.trim(), order: Number($('brushed-order').value),
      resolution: Number($('brushed-resolution').value) };
    const id = await job('sh_table', request);
    const man = (await state.api.request('GET', `/jobs/${id}/result`)).manifest;
    const buffer = await state.api.request('GET', `/jobs/${id}/files/table.bin`, { as: 'arrayBuffer' });
    panel.read = panel.read || await loadSources(SHADER_FILES, '/shaders/');
    if (panel.table && panel.object) {
      panel.table.releaseMesh(panel.object);
    }
    panel.table = new SHTableGL(gl, panel.read, { order: man.order, layout: man.layout, resolution: man.resolution,
      half: tableRgb(new Uint16Array(buffer), man.channels) });
    panel.tableJob = id;
    panel.brdfRequest = request.brdf;
    panel.manifest = man;
    panel.envKey = null;
    panel.prepared = null;
  }

  /** World lighting (Float64Array n x 3): the environment turned by `rotation`, the area lights, windowed. */
  function lighting() {
    const order = panel.table.order;
    const env = state.viewer?.environment;
    const key = `${state.environmentId}/${order}`;
    if (env && panel.envKey !== key) {
      panel.envCoeffs = projectLatlongHalf(env.halfRgb, env.height, env.width, order);
      panel.envKey = key;
    }
    const n = (order + 1) ** 2;
    const scale = Number($('brushed-env').value);
    const envPart = panel.envCoeffs ? rotateLightingY(panel.envCoeffs, order, panel.rotation).map((x) => x * scale)
      : new Float64Array(3 * n);
    const parts = [envPart];
    for (const k of [0, 1]) {
      if ($(`brushed-cap${k}-on`).checked) {
        const az = (Number($(`brushed-cap${k}-az`).value) * Math.PI) / 180;
        const el = (Number($(`brushed-cap${k}-el`).value) * Math.PI) / 180;
        const hex = $(`brushed-cap${k}-colour`).value;
        const radiance = Number($(`brushed-cap${k}-radiance`).value);
        const colour = [1, 3, 5].map((i) => (radiance * parseInt(hex.slice(i, i + 2), 16)) / 255);
        parts.push(capLight([Math.cos(el) * Math.sin(az), Math.sin(el), Math.cos(el) * Math.cos(az)],
          Number($(`brushed-cap${k}-sr`).value), colour, order));
      }
    }
    const { coeffs, cost } = windowLighting(addLighting(...parts), order, $('brushed-window').value);
    panel.windowCost = cost;
    return coeffs;
  }

  const viewDir = () => [Math.cos(panel.viewEl) * Math.sin(panel.viewAz), Math.sin(panel.viewEl),
    Math.cos(panel.viewEl) * Math.cos(panel.viewAz)];

  /** One frame in the current mode; returns its milliseconds (draw and a one-texel read-back). */
  function frame(mode = panel.mode) {
    const t = panel.table;
    const g = panel.object;
    const view = viewDir();
    const light = Float32Array.from(lighting());
    panel.light = light;
    const t0 = performance.now();
    // the fixed modes keep per-vertex data: prepared again only when what they fix changed (§4)
    const fixedKey = mode === 'fixed-light' ? `L${light.join()}` : mode === 'fixed-view' ? `V${view.join()}` : null;
    if (fixedKey && panel.prepared !== `${mode}/${fixedKey}`) {
      t.prepare(mode, g.vertices, g.count, view, light);
      panel.prepared = `${mode}/${fixedKey}`;
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.enable(gl.DEPTH_TEST);
    gl.clearColor(0.08, 0.08, 0.1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const vp = viewProjection(view);
    t.draw(mode, g, vp, view, light, { exposure: Number(document.getElementById('exposure')?.value || 0) });
    if ($('brushed-tangents').checked) {
      drawLines(vp);
    }
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));  // wait for the GPU
    return performance.now() - t0;
  }

  const overlay = new LineOverlay(gl);
  const drawLines = (vp) => overlay.draw(vp, panel.lines);

  function record(mode, ms) {
    const s = (panel.samples[mode] = panel.samples[mode] || []);
    s.push(ms);
    if (s.length > 30) {
      s.shift();
    }
    panel.frameMs[mode] = s.reduce((a, x) => a + x, 0) / s.length;
  }

  let last = null;
  function loop(now) {
    requestAnimationFrame(loop);
    if (!panel.table || !panel.object || panel.busy) {
      return;
    }
    const dt = last === null ? 0 : Math.min(0.1, (now - last) / 1000);
    last = now;
    const mode = panel.mode;
    if ($('brushed-spin-light').checked && mode !== 'fixed-light') {
      panel.rotation += 0.5 * dt;
    }
    if ($('brushed-spin-view').checked && mode !== 'fixed-view') {
      panel.viewAz += 0.3 * dt;
    }
    record(mode, frame(mode));
    $('brushed-frame').textContent = `${mode}: ${panel.frameMs[mode].toFixed(2)} ms per frame (mean of `
      + `${panel.samples[mode].length}), ${panel.object.count} vertices`;
    $('brushed-window-cost').textContent = `window cost ${(100 * panel.windowCost).toPrecision(3)} % of the `
      + 'lighting (relative L2 change)';
  }

  /** Every available mode for TIMED_FRAMES frames, each changing what it does not fix (Table 1's columns). */
  function timeModes(frames = TIMED_FRAMES) {
    panel.busy = true;
    const keep = [panel.rotation, panel.viewAz, panel.mode];
    const modes = ['general', 'fixed-light', 'fixed-view', ...(panel.transferJob ? ['transfer'] : [])];
    const ms = {};
    try {
      for (const mode of modes) {
        frame(mode);  // compile and prepare outside the timing
        let sum = 0;
        for (let f = 0; f < frames; f += 1) {
          if (mode !== 'fixed-light') {
            panel.rotation += 0.01;
          }
          if (mode !== 'fixed-view') {
            panel.viewAz += 0.01;
          }
          sum += frame(mode);
        }
        ms[mode] = sum / frames;
      }
    } finally {
      [panel.rotation, panel.viewAz, panel.mode] = keep;
      panel.busy = false;
    }
    panel.table1 = { vertices: panel.object.count, frames, ms,
      speedup: Object.fromEntries(modes.map((m) => [m, ms.general / ms[m]])) };
    $('brushed-table1').textContent = modes.map((m) => `${m} ${ms[m].toFixed(2)} ms (${(ms.general / ms[m])
      .toFixed(2)}x)`).join(' · ') + ` — ${panel.object.count} vertices; paper: fixed light 3.8–4.8x, fixed view `
      + '21–31x the general mode';
    return panel.table1;
  }

  async function loadShadows() {
    if ($('brushed-prt').value === 'off') {
      panel.transferJob = null;
      if (panel.mode === 'transfer') {
        panel.mode = 'general';
        $('brushed-mode').value = 'general';
      }
      return;
    }
    const mesh = $('brushed-object').value;
    if (mesh === 'sphere') {
      throw new Error('PRT transfer needs a service mesh (the sphere is convex: nothing to shadow or reflect)');
    }
    const n = (panel.table.order + 1) ** 2;
    const rays = Number($('brushed-rays').value);
    let half;
    let texture;
    let id;
    if ($('brushed-prt').value === 'interreflections') {
      // the BRDF is fixed into the bounces (§5): an sh_transfer job of this table's BRDF, order and tangent field
      id = await job('sh_transfer', { mesh, brdf: panel.brdfRequest, order: panel.table.order,
        resolution: panel.manifest.resolution, tangent: tangentSpec(), bounces: Number($('brushed-bounces').value),
        rays });
      const result = await state.api.request('GET', `/jobs/${id}/result`);
      half = new Uint16Array(await state.api.request('GET', `/jobs/${id}/files/transfer.bin`, { as: 'arrayBuffer' }));
      texture = result.textures['transfer.bin'];
      status(`PRT shadows and ${result.bounces} bounce(s): order ${result.order}, ${result.rays} rays per vertex`);
    } else {
      id = await job(null, { mesh, order: panel.table.order, rays, kind: 'shadow_matrix' }, '/visibility');
      const man = await state.api.request('GET', `/visibility/${id}`);
      half = new Uint16Array(await state.api.request('GET', `/visibility/${id}/files/shadow_matrix.bin`,
        { as: 'arrayBuffer' }));
      texture = man.files['shadow_matrix.bin'].texture;
      status(`PRT shadows: order ${man.order}, ${man.rays} rays per vertex`);
    }
    panel.table.setTransfer(transferLayout(half, texture, n), panel.object.count, { world: true });
    panel.transferJob = id;
    panel.mode = 'transfer';
    $('brushed-mode').value = 'transfer';
  }

  async function load() {
    showError('brushed-error', null);
    $('brushed-load').disabled = true;
    try {
      await loadTable();
      await loadObject();
      await loadShadows();
      status(`${panel.manifest.coefficients} coefficients, ${panel.manifest.resolution}² ${panel.manifest.layout}; `
        + `${panel.object.count} vertices` + (panel.transferJob ? ', PRT shadows' : ''));
      panel.ready = true;
    } catch (err) {
      showError('brushed-error', err);
    } finally {
      $('brushed-load').disabled = false;
    }
  }

  $('brushed-load').addEventListener('click', load);
  $('brushed-mode').addEventListener('change', () => {
    const mode = $('brushed-mode').value;
    if (mode === 'transfer' && !panel.transferJob) {
      showError('brushed-error', 'choose PRT shadows and Load first');
      $('brushed-mode').value = panel.mode;
      return;
    }
    panel.mode = mode;
  });
  $('brushed-time').addEventListener('click', () => panel.table && panel.object && timeModes());
  panel.load = load;
  panel.refreshObjects = refreshObjects;
  panel.lighting = () => (panel.table ? lighting() : null);
  panel.view = viewDir;
  panel.frame = frame;
  panel.timeModes = timeModes;
  /** Q per vertex (count x 3) through `mode`'s shader at the current view and lighting (tests). */
  panel.probe = (mode) => {
    panel.prepared = null;  // probe() prepares the fixed modes' data itself
    return panel.table.probe(mode, panel.object.normals, panel.object.tangents, viewDir(),
      Float32Array.from(lighting()));
  };
  requestAnimationFrame(loop);
  refreshObjects().catch((err) => showError('brushed-error', err));
  return panel;
}
