// Scenes (POST /scenes, relight/planning/): the plan per object (what is simulated, what is skipped and why), a
// top view of where the objects are (from each object's distance and view direction; the viewer at the origin),
// per object the server's render of that object's own SHRM (`{name}.sphere.png`, asked for with preview_size),
// and the scene itself in the 3-D view: every object at its place, lit by its own SHRM (the float16 texture
// `{name}.coefficients.bin` with its manifest `{name}.texture.json`), with the viewer (distant: eq. 12, near:
// eq. 6) its plan chose, or with the representation its plan chose for its lobes (sceneItems, scene_parts.js).

/** Parse the textarea: a SceneCreate object; asks for sphere previews unless the scene says otherwise. */
export function parseScene(text, envmapId) {
  let scene;
  try {
    scene = JSON.parse(text);
  } catch (err) {
    throw new Error(`the scene is not JSON: ${err.message}`, { cause: err });
  }
  if (!scene || typeof scene !== 'object' || !Array.isArray(scene.objects)) {
    throw new Error('the scene must be an object with an "objects" list (SceneCreate)');
  }
  if (!scene.environment && envmapId) {
    scene.environment = envmapId;
  }
  if (scene.preview_size === undefined) {
    scene.preview_size = 64;
  }
  return scene;
}

/** An example scene for the current map and material: a near glossy sphere and a distant bunny. */
export function exampleScene(envmapId, material) {
  return {
    name: 'two-objects', environment: envmapId, epsilon: 0.05, size: 16, preview_size: 64,
    objects: [
      { name: 'ball', shape: 'sphere', size: 1, distance: 3, material, view: [0, 0, 1] },
      { name: 'bunny', shape: 'bunny', size: 0.5, distance: 20, material: { kind: 'lambert' }, view: [0.3, 0, 0.95] },
    ],
  };
}

/** Objects of a scene (GET /scenes/{id}) with their plan entry and result files, by name. */
export function sceneObjects(pub) {
  const planned = pub?.plan?.objects || [];
  const results = Object.fromEntries((pub?.result?.objects || []).map((o) => [o.name, o]));
  const requested = pub?.scene?.objects || [];
  const names = planned.length ? planned.map((o) => o.name) : requested.map((o) => o.name);
  return names.map((name, k) => {
    const plan = planned.find((o) => o.name === name) || {};
    const req = requested.find((o) => o.name === name) || requested[k] || {};
    return { name, ...req, ...plan, effects: plan.effects || [], files: results[name]?.files || {} };
  });
}

/** World position of an object's centre: the viewer at the origin, the object at -distance * view. */
export function objectCenter(o) {
  const v = o.view || [0, 0, 1];
  const n = Math.hypot(...v) || 1;
  return v.map((x) => (-o.distance * x) / n);
}

/** Top-view position of an object (x, z of objectCenter). */
export function objectPosition(o) {
  const [x, , z] = objectCenter(o);
  return { x, z };
}

/** Representations drawn by the object's SHRM (seed 000: the run synthesises their lobes into one SHRM). */
export const SHRM_REPRESENTATIONS = ['irradiance', 'reflection_map', 'shrm_q0', 'shrm'];
/** Representations drawn by a part of their own (scene_parts.js). */
export const PART_REPRESENTATIONS = ['gaussian_lobes', 'diffuse_transfer', 'inout_prt', 'sh_table', 'prt_matrix'];

const json = (bytes) => JSON.parse(new TextDecoder().decode(bytes));

/** The representations of an object's lobes (a plan before planner v2 has none: its object is one SHRM). */
export function objectRepresentations(o) {
  const reps = o.representations || [];
  return reps.length ? reps.map((r) => r.representation) : ['shrm'];
}

async function shrmItem(pub, api, o, base) {
  if (!o.files.texture || !o.files.coefficients_bin) {
    throw new Error(`scene object ${o.name} has no viewer texture`);
  }
  const [manifestBytes, buffer] = await Promise.all([api.sceneFile(pub.id, o.files.texture),
    api.sceneFile(pub.id, o.files.coefficients_bin)]);
  return { ...base, kind: 'shrm', mode: o.viewer === 'near' ? 'near' : 'distant', manifest: json(manifestBytes),
    buffer };
}

/** A Lambertian lobe's albedo as one number (the PRT shader's u_albedo); a coloured albedo is not drawn. */
function greyAlbedo(name, lobe) {
  const a = lobe?.albedo ?? 1;
  const values = Array.isArray(a) ? a.map(Number) : [Number(a)];
  if (!values.every((x) => x === values[0] && Number.isFinite(x))) {
    throw new Error(`scene object ${name}: its diffuse transfer is drawn with one albedo, the lobe has ${a}`);
  }
  return values[0];
}

async function transferItem(pub, api, o, base) {
  const rep = (o.representations || []).find((r) => r.representation === 'diffuse_transfer');
  const albedo = greyAlbedo(o.name, rep?.lobe);
  if (!o.files.prt) {
    throw new Error(`scene object ${o.name} has no viewer form of its diffuse transfer (${o.name}.prt.json)`);
  }
  const prt = json(await api.sceneFile(pub.id, o.files.prt));
  const [geometryBuffer, transferBuffer] = await Promise.all([api.sceneFile(pub.id, prt.geometry.name),
    api.sceneFile(pub.id, prt.files['transfer.bin'].name)]);
  return { ...base, kind: 'diffuse_transfer', prt, geometryBuffer, transferBuffer, albedo };
}

async function gaussianItem(pub, api, rep, base, loaders) {
  const runs = (pub.result?.jobs || []).filter((j) => rep.jobs.includes(j.id));
  const run = (kind) => {
    const r = runs.find((j) => j.kind === kind);
    if (!r?.executed) {
      throw new Error(`scene object ${base.name}: its Gaussian lobes have no ${kind} job run`);
    }
    return r;
  };
  const [fit, chain] = [run('gaussian_fit'), run('gaussian_chain')];
  const file = (r, suffix) => r.files.find((f) => f.endsWith(`.${suffix}`));
  const [spec, lobes, levels] = await Promise.all([api.sceneFile(pub.id, file(fit, 'json')),
    api.sceneFile(pub.id, file(fit, 'lobes.bin')),
    Promise.all(chain.summary.levels.map((lv) => api.sceneFile(pub.id, file(chain, lv.file))))]);
  const material = loaders.material({ material: json(spec), lobes: fit.summary.lobes,
    elevations: fit.summary.elevations, errors: fit.summary.errors }, lobes);
  return { ...base, kind: 'gaussian_lobes', material, chain: loaders.chain(chain.summary, levels) };
}

async function inoutItem(pub, api, rep, base) {
  const inout = json(await api.sceneFile(pub.id, viewerRun(pub, rep, base.name, 'inout_transport', '.inout.json',
    'in-out PRT')));
  const [geometryBuffer, transportBuffer, factorsBuffer] = await Promise.all([inout.geometry.name,
    inout.transport_texture.name, inout.factors_texture.name].map((name) => api.sceneFile(pub.id, name)));
  return { ...base, kind: 'inout_prt', inout, geometryBuffer, transportBuffer, factorsBuffer };
}

/** A job run of a lobe's representation (its `kind`) that wrote a viewer form (a file ending in `suffix`). */
function viewerRun(pub, rep, name, kind, suffix, what) {
  const run = (pub.result?.jobs || []).find((j) => rep.jobs.includes(j.id) && j.kind === kind);
  const file = run?.executed && run.files.find((f) => f.endsWith(suffix));
  if (!file) {
    throw new Error(`scene object ${name}: its ${what} has no ${kind} job run with a viewer form`);
  }
  return file;
}

async function tableItem(pub, api, rep, base, tangent) {
  const table = json(await api.sceneFile(pub.id, viewerRun(pub, rep, base.name, 'sh_table', '.table.json',
    'SH table')));
  const tableBuffer = await api.sceneFile(pub.id, table.files['table.bin'].name);
  return { ...base, kind: 'sh_table', table, tableBuffer, tangent: tangent || null };
}

async function matrixItem(pub, api, rep, base, tangent) {
  const file = viewerRun(pub, rep, base.name, 'shadow_matrix', '.prt_matrix.json', 'PRT (transfer matrices)');
  const [table, matrices] = await Promise.all([tableItem(pub, api, rep, base, tangent),
    api.sceneFile(pub.id, file).then(json)]);
  const [geometryBuffer, matrixBuffer] = await Promise.all([matrices.geometry.name,
    matrices.files['shadow_matrix.bin'].name].map((name) => api.sceneFile(pub.id, name)));
  return { ...table, kind: 'prt_matrix', matrices, geometryBuffer, matrixBuffer };
}

/**
 * The 3-D view's items of a finished scene (ShrmViewer.setSceneObjects): per object, one item per way its lobes
 * are drawn, each with the object's centre, bounding radius and geometry (`loadShape(shape)`: 'sphere' or a
 * BufferGeometry in the unit ball): kind 'shrm' (the lobes of SHRM_REPRESENTATIONS: its SHRM texture and planned
 * viewer), 'gaussian_lobes' (each such lobe: its fit and the plan's chain, through `loaders.material` and
 * `loaders.chain`: gaussian_panel.js's materialFromLobes, gaussian.js's chainFromLevels), 'diffuse_transfer'
 * (the object's {name}.prt.json, geometry and transfer texture) and 'inout_prt' (each such lobe: its
 * inout_transport job's P.inout.json, geometry, transport and factors), 'sh_table' (each such lobe: its sh_table
 * job's P.table.json and float16 table, the object's tangent field) and 'prt_matrix' (each such lobe: that table
 * and its shadow_matrix job's P.prt_matrix.json, geometry and float16 world-frame transfer matrices). An object's
 * items after its first are `added`.
 * Returns {items, errors}: an object with a representation the viewer cannot draw, or whose files are missing or
 * refused by the API (the problem's title, status and detail), is left out with its error ({name, message}); the
 * others are drawn.
 */
export async function sceneItems(pub, api, loadShape, loaders) {
  if (pub?.state !== 'succeeded') {
    throw new Error(`the scene is ${pub?.state}; only a finished scene can be shown`);
  }
  const done = await Promise.all(sceneObjects(pub).map(async (o) => {
    try {
      const kinds = objectRepresentations(o);
      const unknown = kinds.filter((k) => !SHRM_REPRESENTATIONS.includes(k) && !PART_REPRESENTATIONS.includes(k));
      if (unknown.length) {
        throw new Error(`scene object ${o.name}: the viewer cannot draw representation ${unknown.join(', ')} `
          + `(it draws ${[...SHRM_REPRESENTATIONS, ...PART_REPRESENTATIONS].join(', ')})`);
      }
      if (kinds.includes('diffuse_transfer') && kinds.some((k) => SHRM_REPRESENTATIONS.includes(k))) {
        // the run's SHRM holds every computation of the object, the shadowed Lambertian lobe's irradiance too
        throw new Error(`scene object ${o.name}: its SHRM also holds the unshadowed form of its diffuse-transfer `
          + 'lobe; drawing both would count that lobe twice');
      }
      const shape = o.shape || 'sphere';
      const several = new Set(kinds.map((k) => (SHRM_REPRESENTATIONS.includes(k) ? 'shrm' : k))).size > 1
        || kinds.filter((k) => k === 'gaussian_lobes').length > 1;
      // several parts on the analytic sphere share one tessellated sphere, so that their depths agree
      const base = { name: o.name, shape, center: objectCenter(o), radius: Number(o.size),
        geometry: shape === 'sphere' && several ? 'sphere-mesh' : await loadShape(shape) };
      const parts = [];
      if (kinds.some((k) => SHRM_REPRESENTATIONS.includes(k))) {
        parts.push(shrmItem(pub, api, o, base));
      }
      if (kinds.includes('diffuse_transfer')) {
        parts.push(transferItem(pub, api, o, base));
      }
      for (const rep of o.representations || []) {
        if (rep.representation === 'gaussian_lobes') {
          parts.push(gaussianItem(pub, api, rep, base, loaders));
        } else if (rep.representation === 'inout_prt') {
          parts.push(inoutItem(pub, api, rep, base));
        } else if (rep.representation === 'sh_table') {
          parts.push(tableItem(pub, api, rep, base, o.tangent));
        } else if (rep.representation === 'prt_matrix') {
          parts.push(matrixItem(pub, api, rep, base, o.tangent));
        }
      }
      return { items: (await Promise.all(parts)).map((it, k) => ({ ...it, added: k > 0 })) };
    } catch (err) {
      // an API answer's problem (ApiError.display: title, status, the server's detail), else the error's text
      const message = typeof err?.display === 'function' ? err.display() : err?.message || String(err);
      return { error: { name: o.name, message } };
    }
  }));
  return { items: done.flatMap((d) => d.items || []), errors: done.filter((d) => d.error).map((d) => d.error) };
}

/** A top-view SVG of the objects (circles of their bounding radius; log-spaced distances keep far ones visible). */
export function layoutSvg(objects, { width = 260, height = 120 } = {}) {
  const pos = objects.map((o) => ({ o, ...objectPosition(o) }));
  const maxD = Math.max(1, ...pos.map((p) => Math.hypot(p.x, p.z) + p.o.size));
  const k = (height - 20) / Math.log1p(maxD);
  const out = [`<svg xmlns="http://www.w3.org/2000/svg" class="scene-layout" viewBox="0 0 ${width} ${height}" `
    + `width="${width}" height="${height}" role="img" aria-label="scene seen from above">`,
  `<rect width="${width}" height="${height}" fill="#1b1d21"/>`,
  `<path d="M${width / 2 - 5} ${height - 4}L${width / 2 + 5} ${height - 4}L${width / 2} ${height - 12}Z" fill="#999">`
    + '<title>viewer</title></path>'];
  for (const p of pos) {
    const d = Math.hypot(p.x, p.z);
    const s = d > 0 ? (k * Math.log1p(d)) / d : 0;
    const cx = width / 2 + p.x * s;
    const cy = height - 8 + p.z * s;
    const r = Math.max(3, Math.min(30, p.o.size * s));
    out.push(`<circle class="scene-object" data-name="${p.o.name}" cx="${cx.toFixed(1)}" cy="${cy.toFixed(1)}" `
      + `r="${r.toFixed(1)}" fill="none" stroke="#6cb4ff"><title>${p.o.name}: ${p.o.shape}, size ${p.o.size}, `
      + `distance ${p.o.distance}</title></circle><text x="${(cx + r + 2).toFixed(1)}" y="${cy.toFixed(1)}" `
      + `font-size="9" fill="#ddd">${p.o.name}</text>`);
  }
  out.push('</svg>');
  return out.join('');
}

function el(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  Object.assign(node, props);
  node.append(...children);
  return node;
}

/** Under each object of the panel (showScene) that the 3-D view leaves out, why (sceneItems' errors). */
export function showSceneErrors(box, errors) {
  box.querySelectorAll('.scene-object-plan .scene-draw-error').forEach((n) => n.remove());
  for (const e of errors) {
    const item = [...box.querySelectorAll('.scene-object-plan')].find((n) => n.dataset.name === e.name);
    const p = el('p', { className: 'error scene-draw-error', textContent: `not drawn in the 3-D view: ${e.message}` });
    (item || box).append(p);
  }
}

/** Fill `box` with the scene: state line, layout, and per object its summary, preview and effects. */
export async function showScene(box, pub, api) {
  box.textContent = '';
  const objects = sceneObjects(pub);
  box.append(el('p', { className: 'status', textContent: `scene ${pub.scene?.name || ''} (${pub.id.slice(0, 10)}): `
    + `${pub.state}${pub.failure_reason ? ` — ${pub.failure_reason}` : ''}` }));
  if (objects.length) {
    const layout = el('div', { className: 'scene-layout-box' });
    layout.innerHTML = layoutSvg(objects);
    box.append(layout);
  }
  for (const o of objects) {
    const item = el('div', { className: 'scene-object-plan' });
    item.dataset.name = o.name;
    const head = `${o.name}: ${o.shape}, size ${o.size} at distance ${o.distance}`
      + (o.viewer ? ` — ${o.viewer} viewer, SHRM ${o.shrm}` : '')
      + (o.predicted_error?.rms_min_of_errors !== undefined
        ? `, predicted RMS ${(100 * o.predicted_error.rms_min_of_errors).toPrecision(2)} %` : '');
    item.append(el('h3', { textContent: head }));
    if (o.representations?.length) {
      item.append(el('p', { className: 'scene-representations', textContent: 'lobes: ' + o.representations
        .map((r) => `${r.kind} → ${r.representation} (seed ${r.seed})`).join('; ') }));
    }
    if (o.files.sphere_png && pub.state === 'succeeded') {
      try {
        const data = await api.sceneFile(pub.id, o.files.sphere_png);
        const img = el('img', { className: 'scene-preview', alt: `${o.name}: its SHRM rendered by the server` });
        img.src = URL.createObjectURL(new Blob([data], { type: 'image/png' }));
        item.append(img);
      } catch (err) {
        item.append(el('p', { className: 'error', textContent: `preview: ${err.message || err}` }));
      }
    }
    const ul = el('ul', { className: 'effects' });
    for (const e of o.effects) {
      ul.append(el('li', { className: e.simulated ? 'simulated' : 'skipped',
        textContent: `${e.simulated ? 'simulated' : 'skipped'}: ${e.effect} — ${e.reason}` }));
    }
    item.append(ul);
    box.append(item);
  }
  if (pub.state === 'succeeded' && pub.result) {
    const r = pub.result;
    box.append(el('p', { className: 'status', textContent: `measured ${Number(r.measured_seconds).toPrecision(3)} s `
      + `(predicted ${Number(r.predicted_seconds).toPrecision(3)} s); per-object SHRMs: `
      + objects.map((o) => o.files.shrm).filter(Boolean).join(', ') }));
  }
}
