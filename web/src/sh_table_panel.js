// The SH-table panel (seed 003, Kautz, Sloan & Snyder 2002, §3, Fig. 2 bottom row): a per-view SH table of any
// BRDF (brushed metal by default) computed by the service (POST /jobs, kind sh_table, followed to the end), then
// inspected: the directional albedo sqrt(4 pi) c_0(v) and the energy per band l, sum_m c_lm(v)^2, over the view
// map, each as a false-colour image of the R x R texels (texels outside the parabolic disk are grey), with the
// fraction of the table's energy in each band. The panel builds its own DOM (one registration line in main.js);
// window.relight.shTable holds the last table and its inspection (tests).

import { halfToFloat } from './half.js';

const DEFAULT_BRDF = 'ashikhmin-shirley:nu=48,nv=16,rs=0.05,rd=0';

/**
 * Per-texel albedo and band energies of a table.bin (float16 [(F+1)^2, R, R, C], docs/conventions.md).
 * @param {Uint16Array} half
 * @param {number} order F
 * @param {number} resolution R
 * @param {number} channels C
 * @returns {{albedo: Float32Array, bands: Float32Array[], share: number[]}} albedo (R R, channel mean), bands[l]
 *   (R R, summed over m and averaged over channels), share[l] = band l's part of the summed energy
 */
export function inspectTable(half, order, resolution, channels) {
  const n = (order + 1) * (order + 1);
  const texels = resolution * resolution;
  if (half.length !== n * texels * channels) {
    throw new Error(`table.bin holds ${half.length} values, expected ${n * texels * channels}`);
  }
  const albedo = new Float32Array(texels);
  const bands = Array.from({ length: order + 1 }, () => new Float32Array(texels));
  for (let i = 0; i < n; i += 1) {
    const l = Math.floor(Math.sqrt(i));
    for (let p = 0; p < texels; p += 1) {
      let sq = 0;
      for (let c = 0; c < channels; c += 1) {
        const v = halfToFloat(half[(i * texels + p) * channels + c]);
        sq += v * v;
        if (i === 0) {
          albedo[p] += Math.sqrt(4 * Math.PI) * v / channels;
        }
      }
      bands[l][p] += sq / channels;
    }
  }
  const sums = bands.map((b) => b.reduce((a, x) => a + x, 0));
  const total = sums.reduce((a, x) => a + x, 0);
  return { albedo, bands, share: sums.map((s) => (total > 0 ? s / total : 0)) };
}

/** Texel (row i, column j) lies on the parabolic map's disk (relight.view_maps; all texels of hemi-octahedral). */
function insideMap(layout, resolution, i, j) {
  if (layout !== 'parabolic') {
    return true;
  }
  const x = (2 * (j + 0.5)) / resolution - 1;
  const y = (2 * (i + 0.5)) / resolution - 1;
  return x * x + y * y <= 1;
}

/** A false-colour canvas (black - red - yellow - white, scaled to the image's maximum) of R x R values. */
export function falseColour(values, resolution, layout, scale = 3) {
  const canvas = document.createElement('canvas');
  canvas.width = resolution;
  canvas.height = resolution;
  canvas.style.width = `${resolution * scale}px`;
  canvas.style.imageRendering = 'pixelated';
  const ctx = canvas.getContext('2d');
  const img = ctx.createImageData(resolution, resolution);
  let top = 0;
  values.forEach((v) => { top = Math.max(top, Math.abs(v)); });
  for (let i = 0; i < resolution; i += 1) {
    for (let j = 0; j < resolution; j += 1) {
      // texture row i is local y = 2 (i + 1/2) / R - 1: draw +y up
      const p = i * resolution + j;
      const q = ((resolution - 1 - i) * resolution + j) * 4;
      if (!insideMap(layout, resolution, i, j)) {
        img.data.set([96, 96, 96, 255], q);
        continue;
      }
      const t = top > 0 ? Math.min(1, Math.abs(values[p]) / top) : 0;
      img.data.set([255 * Math.min(1, 3 * t), 255 * Math.min(1, Math.max(0, 3 * t - 1)),
        255 * Math.max(0, 3 * t - 2), 255], q);
    }
  }
  ctx.putImageData(img, 0, 0);
  return canvas;
}

function figure(canvas, caption) {
  const fig = document.createElement('figure');
  fig.style.display = 'inline-block';
  fig.style.margin = '2px';
  const cap = document.createElement('figcaption');
  cap.textContent = caption;
  fig.append(canvas, cap);
  return fig;
}

/** Register the panel: a <section> appended to the side bar (the first <aside> or <main>, else <body>). */
export function initShTables(state, $, showError) {
  const section = document.createElement('section');
  section.id = 'shtable-panel';
  section.innerHTML = `<h2>SH table (seed 003)</h2>
    <label>BRDF <input id="shtable-brdf" size="40"></label>
    <label>order F <select id="shtable-order"><option>2</option><option selected>4</option><option>6</option>
      <option>8</option></select></label>
    <label>R <input id="shtable-resolution" type="number" min="8" max="256" value="64"></label>
    <button id="shtable-compute" type="button">Compute table</button>
    <progress id="shtable-progress" max="1" value="0"></progress>
    <div id="shtable-status"></div><div id="shtable-error" class="error"></div>
    <div id="shtable-maps"></div>`;
  (document.querySelector('aside') || document.querySelector('main') || document.body).append(section);
  $('shtable-brdf').value = DEFAULT_BRDF;

  async function show(jobId) {
    const result = await state.api.request('GET', `/jobs/${jobId}/result`);
    const man = result.manifest;
    const buffer = await state.api.request('GET', `/jobs/${jobId}/files/table.bin`, { as: 'arrayBuffer' });
    const inspection = inspectTable(new Uint16Array(buffer), man.order, man.resolution, man.channels);
    const maps = $('shtable-maps');
    maps.textContent = '';
    maps.append(figure(falseColour(inspection.albedo, man.resolution, man.layout), 'albedo'));
    inspection.bands.forEach((b, l) => {
      maps.append(figure(falseColour(b, man.resolution, man.layout), `l = ${l}: ${(100 * inspection.share[l])
        .toPrecision(3)} %`));
    });
    $('shtable-status').textContent = `${man.coefficients} coefficients, ${man.resolution} x ${man.resolution} `
      + `${man.layout}, ${man.report.seconds.toFixed(2)} s, ${man.float16_clamped} float16 values clamped`;
    state.shTable = { jobId, manifest: man, inspection };  // window.relight is the state
  }

  $('shtable-compute').addEventListener('click', async () => {
    showError('shtable-error', null);
    try {
      const request = { brdf: $('shtable-brdf').value.trim(), order: Number($('shtable-order').value),
        resolution: Number($('shtable-resolution').value) };
      const job = await state.api.request('POST', '/jobs', { json: { kind: 'sh_table', request } });
      $('shtable-status').textContent = `job ${job.id.slice(0, 12)}: ${job.state}`;
      const final = ['succeeded', 'failed', 'cancelled'].includes(job.state) ? job
        : await state.api.follow(job.id, (j) => { $('shtable-progress').value = j.progress; });
      if (final.state !== 'succeeded') {
        throw new Error(`the table job ${final.state}: ${final.error?.detail || final.error || ''}`);
      }
      $('shtable-progress').value = 1;
      await show(job.id);
    } catch (err) {
      showError('shtable-error', err);
    }
  });
}
