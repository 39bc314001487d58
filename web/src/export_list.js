// The engine-export panel's list (issue 17, item 9): one entry per export of the current map and material that
// the API serves, each with its API path (GET /envmaps/{id}/ibl, GET /dfg); no three.js here, so node --test
// runs it (web/test/exports_panel.test.js).

export const TARGETS = ['three', 'filament', 'gltf', 'babylon'];
export const CONVENTIONS = ['three', 'gltf', 'filament', 'babylon', 'raw'];
/** The DFG tables offered: [label, query, file name] (size 128, relight dfg's default). */
export const DFG_TABLES = [['DFG (EXR)', 'size=128&format=exr', 'dfg-128.exr'],
  ['DFG (16-bit PNG)', 'size=128&format=png', 'dfg-128.png'],
  ['DFG (KTX2)', 'size=128&format=ktx2', 'dfg-128.ktx2'],
  ['DFG multiscatter (KTX2)', 'size=128&multiscatter=true&format=ktx2', 'dfg-128-multiscatter.ktx2']];

function specValue(v) {
  return Array.isArray(v) ? v.join('/') : String(v);
}

/**
 * A BRDF spec object of the viewer (`{kind, ...params}` or `{kind: 'sum', lobes}`) as relight's spec string
 * (`phong:s=32`, `lambert:albedo=0.2+phong:s=32`, colours as r/g/b); null for anything else (a measured BRDF's id).
 */
export function specString(spec) {
  if (!spec || typeof spec !== 'object') {
    return null;
  }
  if (spec.kind === 'sum') {
    const parts = (spec.lobes || []).map(specString);
    return parts.length && parts.every(Boolean) ? parts.join('+') : null;
  }
  const args = Object.keys(spec).filter((k) => k !== 'kind').sort()
    .map((k) => `${k}=${specValue(spec[k])}`);
  return args.length ? `${spec.kind}:${args.join(',')}` : spec.kind;
}

/**
 * Every export of map `id` (and material `brdf`, a spec string or null): [label, file name, API path, SH
 * convention or null, query]. A convention's file is its entry of the API's sh.json (`relight sh --convention C`'s
 * fields: convention, quantity, coefficients). `query` is the map resource's query (null for the DFG tables).
 */
export function exportList(id, brdf = null) {
  const short = id.slice(0, 12);
  const ibl = (query) => `/envmaps/${id}/ibl?${query}`;
  const out = [
    ...TARGETS.map((t) => [`KTX2 ${t}`, `${short}-${t}.ktx2`, `target=${t}&format=ktx2`, null]),
    ['glTF (EXT_lights_image_based)', `${short}-lighting.glb`, 'target=gltf&format=gltf', null],
  ];
  if (brdf) {
    const b = `&brdf=${encodeURIComponent(brdf)}`;
    const tag = brdf.replace(/[^A-Za-z0-9.=-]+/g, '_').slice(0, 40);
    out.push(...TARGETS.map((t) => [`KTX2 ${t} + material`, `${short}-${tag}-${t}.ktx2`,
      `target=${t}&format=ktx2${b}`, null]));
    out.push(['glTF + material', `${short}-${tag}-lighting.glb`, `target=gltf&format=gltf${b}`, null]);
  }
  out.push(['SH9 (all conventions)', `${short}-sh9.json`, 'format=sh', null],
    ...CONVENTIONS.map((c) => [`SH9 ${c}`, `${short}-sh9-${c}.json`, 'format=sh', c]));
  return [...out.map(([label, name, query, conv]) => [label, name, ibl(query), conv, query]),
    ...DFG_TABLES.map(([label, query, name]) => [label, name, `/dfg?${query}`, null, null])];
}

export const MEDIA = { json: 'application/json', ktx2: 'image/ktx2', glb: 'model/gltf-binary', exr: 'image/x-exr',
  png: 'image/png' };
