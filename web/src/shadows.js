// The Shadows panel (web/index.html): a mesh of the service (GET /meshes, the preloaded samples included) drawn
// with diffuse PRT (prt_object.js), and its visibility job (POST /visibility, kind diffuse_transfer) followed to
// the end; the shading modes switch between unshadowed irradiance, ambient occlusion x irradiance and the
// SH-transfer shadows. window.relight.prt is the PrtObject (tests), window.relight.prtJobId the last job.
// "Compare with Mitsuba" (mesh_compare.js) puts Mitsuba's image of the same view beside the current mode's, with a
// false-colour difference; window.relight.lastMeshComparison holds its numbers (tests).
import { compareMesh } from './mesh_compare.js';
import { PrtObject } from './prt_object.js';

const percent = (x) => (Number.isFinite(x) ? `${(100 * x).toPrecision(3)} %` : '—');

export function initShadows(state, $, showError) {
  const status = (text) => { $('prt-status').textContent = text; };

  async function refreshMeshes() {
    const list = await state.api.request('GET', '/meshes');
    const sel = $('prt-mesh');
    const keep = sel.value;
    sel.textContent = '';
    for (const m of list.items) {
      const opt = document.createElement('option');
      opt.value = m.id;
      opt.textContent = `${m.name || m.id.slice(0, 12)} (${m.vertices} vertices)`;
      sel.append(opt);
    }
    if (keep) {
      sel.value = keep;
    }
    return list.items;
  }

  async function showMesh(id = $('prt-mesh').value) {
    showError('prt-error', null);
    if (!id) {
      throw new Error('no mesh: upload one or wait for the samples');
    }
    const info = await state.api.request('GET', `/meshes/${id}`);
    const buffer = await state.api.request('GET', `/meshes/${id}/geometry.bin`, { as: 'arrayBuffer' });
    const prt = state.prt && state.prt.meshInfo?.id === id ? state.prt : new PrtObject(state.viewer);
    if (prt !== state.prt) {
      state.prt?.dispose();
      prt.setMesh(info, buffer);
    }
    prt.setMode($('prt-mode').value);
    state.prt = prt;
    state.viewer.setPrt(prt);
    status(`${info.name || id.slice(0, 12)}: ${info.vertices} vertices, ${info.faces} triangles`);
    return prt;
  }

  async function loadVisibility(jobId) {
    const manifest = await state.api.request('GET', `/visibility/${jobId}`);
    const buffers = {};
    for (const name of ['transfer.bin', 'ao.bin']) {
      if (manifest.files[name]) {
        buffers[name] = await state.api.request('GET', `/visibility/${jobId}/files/${name}`, { as: 'arrayBuffer' });
      }
    }
    const prt = await showMesh(manifest.mesh);
    prt.setVisibility(manifest, buffers);
    state.prtJobId = jobId;
    const err = manifest.monte_carlo_error_rms.transfer_error;
    status(`shadows: order ${manifest.order}, ${manifest.rays} rays/vertex, Monte Carlo error (RMS) `
      + `${err?.toPrecision(2) ?? '—'}`);
    return manifest;
  }

  async function computeShadows() {
    showError('prt-error', null);
    $('prt-compute').disabled = true;
    try {
      const body = { mesh: $('prt-mesh').value, order: Number($('prt-order').value),
        rays: Number($('prt-rays').value), kind: 'diffuse_transfer' };
      const job = await state.api.request('POST', '/visibility', { json: body });
      const pred = job.predicted;
      status(`job ${job.id.slice(0, 12)}: predicted ${pred?.seconds?.toFixed(1) ?? '?'} s, Monte Carlo error `
        + `< ${pred?.rms_error?.toPrecision(2) ?? '?'}`);
      const final = ['succeeded', 'failed', 'cancelled'].includes(job.state) ? job
        : await state.api.follow(job.id, (j) => { $('prt-progress').value = j.progress; });
      if (final.state !== 'succeeded') {
        throw new Error(`the visibility job ${final.state}: ${final.failure_reason || ''}`);
      }
      $('prt-progress').value = 1;
      $('prt-mode').value = 'transfer';
      await loadVisibility(final.id);
      state.prt.setMode('transfer');
    } catch (err) {
      showError('prt-error', err);
    } finally {
      $('prt-compute').disabled = false;
    }
  }

  async function compareWithMitsuba() {
    showError('prt-error', null);
    $('prt-compare').disabled = true;
    $('comparison').hidden = false;
    $('cmp-ours-caption').textContent = `PRT (WebGL, ${state.prt?.mode ?? '—'})`;
    $('cmp-ref-caption').textContent = 'Mitsuba 3 (path traced, direct light, exact shadows)';
    $('cmp-err-caption').textContent = 'rendering with Mitsuba…';
    try {
      const result = await compareMesh({
        viewer: state.viewer, api: state.api, envmapId: state.envmapId, size: Number($('compare-size').value),
        spp: Number($('prt-spp').value),
        canvases: { ours: $('cmp-shrm'), reference: $('cmp-ref'), error: $('cmp-err') },
      });
      state.lastMeshComparison = result;
      $('cmp-err-caption').textContent = `${result.mode}: ${percent(result.rms)} relative RMS, max `
        + `${percent(result.max)}; Mitsuba's noise ${percent(result.noise)} (${result.spp} spp; |ΔY| / max Y, log `
        + `colour 1e-4…1e-1, silhouettes excluded)`;
      return result;
    } catch (err) {
      $('cmp-err-caption').textContent = 'error';
      showError('prt-error', err);
      throw err;
    } finally {
      $('prt-compare').disabled = false;
    }
  }

  $('prt-compare').addEventListener('click', () => compareWithMitsuba().catch(() => {}));
  $('prt-show').addEventListener('click', () => showMesh().catch((err) => showError('prt-error', err)));
  $('prt-compute').addEventListener('click', computeShadows);
  $('prt-mode').addEventListener('change', () => state.prt?.setMode($('prt-mode').value));
  state.refreshMeshes = refreshMeshes;
  state.showMesh = showMesh;
  state.loadVisibility = loadVisibility;
  state.compareWithMitsuba = compareWithMitsuba;
  return refreshMeshes().catch((err) => showError('prt-error', err));
}
