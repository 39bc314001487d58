// Scenes (POST /scenes, relight/planning/): the plan per object (what is simulated, what is skipped and why), a
// top view of where the objects are (from each object's distance and view direction; the viewer at the origin),
// per object the server's render of that object's own SHRM (`{name}.sphere.png`, asked for with preview_size),
// and the scene itself in the 3-D view: every object at its place, lit by its own SHRM (the float16 texture
// `{name}.coefficients.bin` with its manifest `{name}.texture.json`), with the viewer (distant: eq. 12, near:
// eq. 6) its plan chose.

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

/**
 * The 3-D view's items of a finished scene (ShrmViewer.setSceneObjects): per object its centre, bounding radius,
 * planned viewer, geometry (`loadShape(shape)`: 'sphere' or a BufferGeometry in the unit ball) and SHRM texture.
 * Throws when an object has no texture (a scene stored before textures were part of the result).
 */
export async function sceneItems(pub, api, loadShape) {
  if (pub?.state !== 'succeeded') {
    throw new Error(`the scene is ${pub?.state}; only a finished scene can be shown`);
  }
  const objects = sceneObjects(pub);
  return Promise.all(objects.map(async (o) => {
    if (!o.files.texture || !o.files.coefficients_bin) {
      throw new Error(`scene object ${o.name} has no viewer texture`);
    }
    const [manifestBytes, buffer, geometry] = await Promise.all([api.sceneFile(pub.id, o.files.texture),
      api.sceneFile(pub.id, o.files.coefficients_bin), loadShape(o.shape || 'sphere')]);
    const manifest = JSON.parse(new TextDecoder().decode(manifestBytes));
    return { name: o.name, shape: o.shape || 'sphere', center: objectCenter(o), radius: Number(o.size),
      mode: o.viewer === 'near' ? 'near' : 'distant', geometry, manifest, buffer };
  }));
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
