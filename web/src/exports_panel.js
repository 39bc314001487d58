// Engine exports of the current map and material (issue 17, item 9): download buttons for every export the API
// serves (GET /envmaps/{id}/ibl: the KTX2 prefiltered cube chain per target engine, the glTF lighting GLB, the
// same two with the current material's lobe per level (relight export --brdf SPEC), the SH9 document with every
// engine convention; GET /dfg: the split-sum DFG table as relight dfg writes it), and a side-by-side of relight's
// chain against three.js' own MeshStandardMaterial + PMREMGenerator on the same map (engine_compare.js, through
// @relight/three).
import * as THREE from 'three';

import { drawSideBySide, ROUGHNESS } from './engine_compare.js';
import { exportList, MEDIA, specString } from './export_list.js';

export { CONVENTIONS, DFG_TABLES, exportList, specString, TARGETS } from './export_list.js';

/** One convention's document from the API's sh.json bytes. */
export function conventionDocument(shJsonBytes, convention) {
  const doc = JSON.parse(new TextDecoder().decode(shJsonBytes));
  const entry = doc.sh9?.[convention];
  if (!entry) {
    throw new Error(`sh.json has no ${convention} coefficients`);
  }
  return { convention, quantity: entry.quantity, coefficients: entry.coefficients, source: doc.source ?? null,
    sun: doc.sun ?? null };
}

/** GET an export (an API path), waiting while its job runs (202 + Retry-After); the file's bytes. */
export async function fetchExport(api, path, onWait = () => {}) {
  for (;;) {
    const resp = await api.request('GET', path, { as: 'response' });
    if (resp.status === 200) {
      return new Uint8Array(await resp.arrayBuffer());
    }
    onWait(await resp.json());
    const wait = Number(resp.headers.get('Retry-After') || 1);
    await new Promise((r) => setTimeout(r, 1000 * wait));
  }
}

function saveAs(bytes, name, type) {
  const url = URL.createObjectURL(new Blob([bytes], { type }));
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

export function initExports(state, $, showError) {
  const section = document.createElement('section');
  section.id = 'exports-panel';
  section.innerHTML = `<h2>Engine exports</h2>
    <div id="exports-buttons"></div>
    <button id="exports-compare" type="button">relight vs three's PMREM</button>
    <div id="exports-status"></div><div id="exports-error" class="error"></div>
    <canvas id="exports-canvas" width="${ROUGHNESS.length * 64}" height="128" style="width:100%"></canvas>
    <div id="exports-rms"></div>`;
  (document.querySelector('aside') || document.querySelector('main') || document.body).append(section);
  const panel = { downloads: 0, rms: null, busy: false };
  state.exportsPanel = panel;
  let renderer = null;

  const status = (text) => {
    $('exports-status').textContent = text;
  };

  const material = () => specString(state.currentBrdf?.() ?? null);

  function refresh() {
    const box = $('exports-buttons');
    box.textContent = '';
    const id = state.envmapId;
    panel.shownFor = id;
    panel.material = material();
    box.dataset.envmap = id || ''; // the map these buttons export (tests wait for it)
    box.dataset.brdf = panel.material || '';
    if (!id) {
      box.textContent = 'upload an environment map';
      return;
    }
    for (const [label, name, path, convention, query] of exportList(id, panel.material)) {
      const b = document.createElement('button');
      b.type = 'button';
      b.textContent = label;
      b.dataset.url = path;
      if (query !== null) {
        b.dataset.export = convention ? `${query}&convention=${convention}` : query;
      }
      b.addEventListener('click', async () => {
        showError('exports-error', null);
        try {
          status(`${label}: computing`);
          let bytes = await fetchExport(state.api, path, (job) => status(`${label}: ${job.state}`));
          if (convention) {
            bytes = new TextEncoder().encode(`${JSON.stringify(conventionDocument(bytes, convention), null, 2)}\n`);
          }
          saveAs(bytes, name, MEDIA[name.split('.').pop()]);
          panel.downloads += 1;
          status(`${label}: ${bytes.length} bytes`);
        } catch (err) {
          showError('exports-error', err);
        }
      });
      box.append(b);
    }
  }

  $('exports-compare').addEventListener('click', async () => {
    const env = state.viewer?.environment;
    const id = state.envmapId;
    if (!env || !id || panel.busy) {
      return;
    }
    panel.busy = true;
    showError('exports-error', null);
    try {
      status('three chain: computing');
      // three's own layout: faces 256^2 down to 8^2 (LOD_MIN = 3), as PMREMGenerator writes them
      const chainPath = `/envmaps/${id}/ibl?target=three&format=ktx2&size=256&levels=6`;
      const chainBytes = await fetchExport(state.api, chainPath, (job) => status(`three chain: ${job.state}`));
      renderer ??= new THREE.WebGLRenderer({ canvas: $('exports-canvas'), antialias: false,
        preserveDrawingBuffer: true });
      panel.rms = drawSideBySide(renderer, { chainBytes, halfRgb: env.halfRgb, height: env.height,
        width: env.width });
      $('exports-rms').textContent = `top: relight's chain, bottom: three's PMREM; relative RMS by roughness: ${
        ROUGHNESS.map((r, i) => `r ${r}: ${(100 * panel.rms[i]).toPrecision(2)} %`).join(', ')}`;
      status('compared');
    } catch (err) {
      showError('exports-error', err);
    } finally {
      panel.busy = false;
    }
  });

  panel.refresh = refresh;
  refresh();
  // selectEnvmap calls panel.refresh() when the map changes; the poll catches any other change of state.envmapId
  // and every change of the material
  const timer = setInterval(() => {
    if (panel.shownFor !== state.envmapId || panel.material !== material()) {
      refresh();
    }
  }, 500);
  panel.stop = () => clearInterval(timer);
}
