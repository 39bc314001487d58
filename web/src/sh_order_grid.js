// The order / window grid of seed 003's Fig. 6 (Kautz, Sloan & Snyder 2002): rows = materials from diffuse to
// specular (Ashikhmin–Shirley (12, 4), (24, 8), (48, 16) by default), columns = SH order F = 2, 4*, 6, 8 (n = 9,
// 25, 49, 81 coefficients, for lighting and table alike) and F = 8 windowed; the top row is the projected lighting
// environment at each column's order. The paper's last two columns are n = 225 (offline); sh_table jobs stop at
// F = 8, so 81 is the highest order here. Each material is one sh_table job at F = 8; a column of order F uses its
// first (F+1)^2 layers (the projection of a coefficient does not depend on the order it is truncated at). The
// spheres (azimuthal tangents about +Y, seen from +Z) are drawn per vertex by SHTableGL on one offscreen WebGL2
// canvas and copied into the grid; the windowed column states its cost (the relative L2 change of the lighting).
// window.relight.orderGrid holds the cells and a probe per cell (tests/web/test_brushed_browser.py).
import { projectLatlongHalf } from './prt.js';
import { realHarmonics } from './sh.js';
import { loadSources } from './shaders.js';
import { sphereGeometry, tangentField, windowLighting } from './sh_lights.js';
import { SHADER_FILES, SHTableGL } from './sh_table.js';
import { tableRgb, viewProjection } from './sh_table_data.js';
import { tonemapImage } from './tonemap.js';

const MATERIALS = ['ashikhmin-shirley:nu=12,nv=4,rs=0.05,rd=0', 'ashikhmin-shirley:nu=24,nv=8,rs=0.05,rd=0',
  'ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0'];
export const COLUMNS = [[2, 'none'], [4, 'none'], [6, 'none'], [8, 'none'], [8, 'hann']];
const CELL = 96;
const VIEW = [0, 0, 1];

/** The first (F+1)^2 coefficients (RGB interleaved) of higher-order lighting. */
export function truncate(coeffs, order) {
  return coeffs.slice(0, 3 * (order + 1) ** 2);
}

/** Linear RGB of SH lighting on an h x 2h lat-long grid (row 0 = +Y; docs/conventions.md), row-major. */
export function lightingImage(coeffs, order, h = 48) {
  const w = 2 * h;
  const out = new Float32Array(3 * h * w);
  const n = (order + 1) ** 2;
  for (let i = 0; i < h; i += 1) {
    const th = ((i + 0.5) * Math.PI) / h;
    for (let j = 0; j < w; j += 1) {
      const ph = ((j + 0.5) / w - 0.5) * 2 * Math.PI;
      const y = realHarmonics(order, [Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)]);
      for (let k = 0; k < n; k += 1) {
        for (let c = 0; c < 3; c += 1) {
          out[3 * (i * w + j) + c] += coeffs[3 * k + c] * y[k];
        }
      }
    }
  }
  return out;
}

function caption(text) {
  const div = document.createElement('div');
  div.textContent = text;
  div.style.fontSize = '11px';
  return div;
}

export function initOrderGrid(state, $, showError) {
  const section = document.createElement('section');
  section.id = 'order-grid-panel';
  section.innerHTML = `<h2>SH order and windowing (seed 003 Fig. 6)</h2>
    <label>materials (one per line) <textarea id="order-grid-materials" rows="3" cols="40"></textarea></label>
    <label>R <input id="order-grid-resolution" type="number" min="8" max="256" value="32"></label>
    <button id="order-grid-run" type="button">Draw the grid</button>
    <progress id="order-grid-progress" max="1" value="0"></progress>
    <div id="order-grid-status"></div><div id="order-grid-error" class="error"></div>
    <div id="order-grid" style="overflow-x:auto;display:grid;grid-template-columns:repeat(${COLUMNS.length + 1},auto);gap:2px"></div>`;
  (document.querySelector('aside') || document.querySelector('main') || document.body).append(section);
  $('order-grid-materials').value = MATERIALS.join('\n');
  const glCanvas = document.createElement('canvas');
  glCanvas.width = CELL;
  glCanvas.height = CELL;
  const gl = glCanvas.getContext('webgl2', { antialias: false, preserveDrawingBuffer: true });
  const sphere = sphereGeometry(32, 64);
  sphere.tangents = tangentField(sphere.normals, { kind: 'azimuthal' });
  const count = sphere.normals.length / 3;
  sphere.vertices = new Float32Array(10 * count);
  for (let k = 0; k < count; k += 1) {
    sphere.vertices.set(sphere.positions.subarray(3 * k, 3 * k + 3), 10 * k);
    sphere.vertices.set(sphere.normals.subarray(3 * k, 3 * k + 3), 10 * k + 3);
    sphere.vertices.set(sphere.tangents.subarray(4 * k, 4 * k + 4), 10 * k + 6);
  }
  const grid = { cells: [], columns: COLUMNS, lighting: null, costs: [] };
  state.orderGrid = grid;
  let read = null;

  async function tableOf(brdf, resolution) {
    const j = await state.api.request('POST', '/jobs', { json: { kind: 'sh_table',
      request: { brdf, order: 8, resolution } } });
    const final = ['succeeded', 'failed', 'cancelled'].includes(j.state) ? j : await state.api.follow(j.id, () => {});
    if (final.state !== 'succeeded') {
      throw new Error(`the table job for ${brdf} ${final.state}: ${final.failure_reason || ''}`);
    }
    const man = (await state.api.request('GET', `/jobs/${j.id}/result`)).manifest;
    const buffer = await state.api.request('GET', `/jobs/${j.id}/files/table.bin`, { as: 'arrayBuffer' });
    return { id: j.id, man, rgb: tableRgb(new Uint16Array(buffer), man.channels) };
  }

  function image(rgb, width, height) {
    const c = document.createElement('canvas');
    c.width = width;
    c.height = height;
    const exposure = Number(document.getElementById('exposure')?.value || 0);
    c.getContext('2d').putImageData(new ImageData(tonemapImage(rgb, exposure, 'aces'), width, height), 0, 0);
    return c;
  }

  async function run() {
    showError('order-grid-error', null);
    $('order-grid-run').disabled = true;
    try {
      const env = state.viewer?.environment;
      if (!env) {
        throw new Error('choose an environment map first');
      }
      const materials = $('order-grid-materials').value.split('\n').map((s) => s.trim()).filter(Boolean);
      const resolution = Number($('order-grid-resolution').value);
      read = read || await loadSources(SHADER_FILES, '/shaders/');
      const full = projectLatlongHalf(env.halfRgb, env.height, env.width, 8);
      grid.lighting = full;
      const lights = COLUMNS.map(([order, win]) => windowLighting(truncate(full, order), order, win));
      grid.costs = lights.map((l) => l.cost);
      const box = $('order-grid');
      box.textContent = '';
      box.append(caption(''));
      COLUMNS.forEach(([order, win], c) => box.append(caption(`n = ${(order + 1) ** 2}${order === 4 ? '*' : ''}`
        + (win !== 'none' ? `, ${win} (cost ${(100 * grid.costs[c]).toPrecision(3)} %)` : ', unwindowed'))));
      box.append(caption('lighting'));
      COLUMNS.forEach(([order], c) => box.append(image(lightingImage(lights[c].coeffs, order), 96, 48)));
      grid.cells.forEach((cell) => cell.table.releaseMesh(sphere));
      grid.cells = [];
      for (const [row, brdf] of materials.entries()) {
        const t = await tableOf(brdf, resolution);
        $('order-grid-progress').value = (row + 1) / materials.length;
        box.append(caption(brdf.replace('ashikhmin-shirley:', 'AS ')));
        for (const [c, [order]] of COLUMNS.entries()) {
          const n = (order + 1) ** 2;
          const table = new SHTableGL(gl, read, { order, layout: t.man.layout, resolution: t.man.resolution,
            half: t.rgb.subarray(0, n * t.man.resolution * t.man.resolution * 3) });
          const light = Float32Array.from(lights[c].coeffs);
          gl.bindFramebuffer(gl.FRAMEBUFFER, null);
          gl.viewport(0, 0, CELL, CELL);
          gl.enable(gl.DEPTH_TEST);
          gl.clearColor(0.08, 0.08, 0.1, 1);
          gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
          table.draw('general', sphere, viewProjection(VIEW, 1.05), VIEW, light,
            { exposure: Number(document.getElementById('exposure')?.value || 0) });
          const cell = document.createElement('canvas');
          cell.width = CELL;
          cell.height = CELL;
          cell.getContext('2d').drawImage(glCanvas, 0, 0);
          box.append(cell);
          grid.cells.push({ row, column: c, brdf, order, window: COLUMNS[c][1], job: t.id, table, light });
        }
      }
      $('order-grid-status').textContent = `${materials.length} materials x ${COLUMNS.length} columns; lighting and `
        + 'table at the same order; n = 225 (the paper\'s last columns) is beyond the table jobs\' F = 8';
      grid.ready = true;
    } catch (err) {
      showError('order-grid-error', err);
    } finally {
      $('order-grid-run').disabled = false;
    }
  }

  $('order-grid-run').addEventListener('click', run);
  grid.run = run;
  grid.sphere = sphere;
  grid.view = VIEW;
  /** Q per sphere vertex (count x 3) of cell k, through the shader that drew it. */
  grid.probe = (k) => {
    const cell = grid.cells[k];
    return cell.table.probe('general', sphere.normals, sphere.tangents, VIEW, cell.light);
  };
  return grid;
}
