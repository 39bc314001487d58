// The In-out PRT panel (seed 004: Mahajan, Tseng & Ramamoorthi 2008), built here and registered by main.js with one
// line: a service mesh drawn with in-out factorized PRT (inout_object.js) from an inout_prt job (POST /jobs), a K
// slider that sums fewer terms of the same data (whole pairs; captured energy shown), and the analysis charts
// (factor_chart.js) from factorization jobs: K vs Phong exponent (Fig. 3A), singular values against F_l (Figs. 2,
// 5), K vs (l*)^2 with the Torrance-Sparrow line and the measured materials named by id (Fig. 7C; the service
// lists no BRDFs, so "every registered" means every id typed in or in state.measuredBrdfIds).
// window.relight.inout is the InOutObject, .inoutJobId the last job, .inoutCharts the charts' data (tests).
import { singularValues, repeatedTransfer, termsVsLStar, termsVsPhong } from './factor_chart.js';
import { InOutObject } from './inout_object.js';

export const PHONG_EXPONENTS = [5, 10, 20, 30, 50];
export const TS_ALPHAS = [0.15, 0.2, 0.3, 0.4];

const HTML = `
  <h2>In-out PRT (seed 004)</h2>
  <label>Mesh <select id="inout-mesh" aria-label="in-out mesh"></select></label>
  <label>BRDF <input id="inout-brdf" value="phong:s=8" aria-label="in-out BRDF"></label>
  <div class="row">energy <input id="inout-energy" type="number" min="0.5" max="0.9999" step="0.01" value="0.99"
      aria-label="captured energy">
    F <input id="inout-order" type="number" min="0" max="8" value="4" aria-label="lighting order F"></div>
  <div class="row">rays <input id="inout-rays" type="number" min="16" max="16384" value="256" aria-label="rays">
    <label><input id="inout-shadows" type="checkbox" checked> shadows</label></div>
  <div class="row"><button id="inout-compute" type="button">Compute in-out PRT</button>
    <button id="inout-charts-show" type="button">Charts</button></div>
  <label>Measured BRDF ids <input id="inout-measured" placeholder="ids from POST /brdfs/measured, comma-separated"
      aria-label="measured BRDF ids"></label>
  <label>K <input id="inout-terms" type="range" min="1" max="1" value="1" aria-label="terms K"></label>
  <div id="inout-terms-label" class="status"></div>
  <progress id="inout-progress" max="1" value="0"></progress>
  <div id="inout-status" class="status"></div>
  <div id="inout-charts"></div>
  <p id="inout-error" class="error" role="alert"></p>`;

async function runJob(api, kind, request, onProgress = () => {}) {
  const job = await api.request('POST', '/jobs', { json: { kind, request } });
  const final = ['succeeded', 'failed', 'cancelled'].includes(job.state) ? job
    : await api.follow(job.id, (j) => onProgress(j.progress));
  if (final.state !== 'succeeded') {
    throw new Error(`the ${kind} job ${final.state}: ${final.failure_reason || ''}`);
  }
  return { id: final.id, result: await api.request('GET', `/jobs/${final.id}/result`) };
}

const analysis = async (api, brdf, domain = 'hemisphere') => (await runJob(api, 'factorization',
  { brdf, domain, resolution: 40, factors: 0, convergence: false })).result.analysis;

export function initInOut(state, $, showError) {
  const section = document.createElement('section');
  section.id = 'inout-panel';
  section.innerHTML = HTML;
  const panel = document.getElementById('panel');
  panel.insertBefore(section, panel.querySelector('section:last-of-type'));
  const status = (text) => { $('inout-status').textContent = text; };

  async function refresh() {
    const list = await state.api.request('GET', '/meshes');
    const sel = $('inout-mesh');
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
  }

  function showTerms() {
    const o = state.inout;
    $('inout-terms-label').textContent = `K = ${o.terms} of ${o.manifest.terms} stored: `
      + `${(100 * o.captured()).toFixed(2)} % of the BRDF's energy (predicted error `
      + `${(100 * Math.sqrt(Math.max(0, 1 - o.captured()))).toPrecision(3)} %)`;
  }

  async function load(jobId, result) {
    const meshId = $('inout-mesh').value;
    const info = await state.api.request('GET', `/meshes/${meshId}`);
    const geometry = await state.api.request('GET', `/meshes/${meshId}/geometry.bin`, { as: 'arrayBuffer' });
    const buffers = {};
    for (const name of ['transport.bin', 'factors.bin']) {
      buffers[name] = await state.api.request('GET', `/jobs/${jobId}/files/${name}`, { as: 'arrayBuffer' });
    }
    state.inout?.dispose();
    const o = new InOutObject(state.viewer);
    await o.loadShaders();
    o.setMesh(info, geometry);
    o.setData(result, buffers);
    state.inout = o;
    state.viewer.setPrt(o);
    const slider = $('inout-terms');
    slider.max = String(result.terms);
    slider.value = String(result.terms);
    showTerms();
    state.inoutJobId = jobId;
  }

  async function compute() {
    showError('inout-error', null);
    $('inout-compute').disabled = true;
    try {
      const request = { mesh: $('inout-mesh').value, brdf: $('inout-brdf').value,
        energy: Number($('inout-energy').value), order: Number($('inout-order').value),
        rays: Number($('inout-rays').value), shadows: $('inout-shadows').checked };
      const { id, result } = await runJob(state.api, 'inout_prt', request, (p) => { $('inout-progress').value = p; });
      $('inout-progress').value = 1;
      await load(id, result);
      status(`${result.terms} terms (${(100 * result.captured).toFixed(2)} % of the energy), order ${result.order}, `
        + `${result.rays} rays/vertex, Monte Carlo error (RMS) ${result.monte_carlo_error_rms.toPrecision(2)}`);
    } catch (err) {
      showError('inout-error', err);
    } finally {
      $('inout-compute').disabled = false;
    }
  }

  async function charts() {
    showError('inout-error', null);
    $('inout-charts-show').disabled = true;
    try {
      const api = state.api;
      const spec = $('inout-brdf').value;
      const current = await analysis(api, spec);
      const phong = [];
      for (const s of PHONG_EXPONENTS) {
        const hemi = await analysis(api, `phong:s=${s}`);
        const sph = await analysis(api, `phong:s=${s}`, 'sphere');
        phong.push({ s, hemisphere: hemi.terms['0.99'], sphere: sph.terms['0.99'] });
      }
      const point = (a, label) => ({ label, K: a.terms['0.99'], lStar: a.prediction?.l_star?.['0.99'] });
      const ts = [];
      for (const alpha of TS_ALPHAS) {
        ts.push(point(await analysis(api, `torrance-sparrow:alpha=${alpha},fresnel=none`), `TS ${alpha}`));
      }
      // the service has no BRDF listing: the measured materials are the ids given (and those this page uploaded)
      const ids = new Set([...$('inout-measured').value.split(',').map((x) => x.trim()).filter(Boolean),
        ...(state.measuredBrdfIds || [])]);
      const measured = [];
      for (const id of ids) {
        measured.push(point(await analysis(api, id), id.slice(0, 12)));
      }
      const cs = current.brdf?.kind === 'phong' ? current.brdf.s : null;
      const lstar = current.prediction?.l_star?.['0.99'];
      const fl = current.radial_transfer ? repeatedTransfer(current.radial_transfer, current.domain)
        .slice(0, current.singular_values.length) : null;
      state.inoutCharts = { phong, ts, measured, current };
      $('inout-charts').innerHTML = [
        termsVsPhong(phong, cs === null ? null : { s: cs, K: current.terms['0.99'] }),
        singularValues(current.singular_values.slice(0, 200), fl),
        termsVsLStar(ts.filter((p) => Number.isFinite(p.lStar)), measured.filter((p) => Number.isFinite(p.lStar)),
          Number.isFinite(lstar) ? { lStar: lstar, K: current.terms['0.99'] } : null),
      ].join('');
    } catch (err) {
      showError('inout-error', err);
    } finally {
      $('inout-charts-show').disabled = false;
    }
  }

  $('inout-compute').addEventListener('click', compute);
  $('inout-charts-show').addEventListener('click', charts);
  $('inout-terms').addEventListener('input', () => {
    if (state.inout) {
      state.inout.setTerms(Number($('inout-terms').value));
      showTerms();
    }
  });
  state.refreshInOut = refresh;
  state.computeInOut = compute;
  state.inOutCharts = charts;
  return refresh().catch((err) => showError('inout-error', err));
}
