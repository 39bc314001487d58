// The material panel's models, read from the server's OpenAPI schema (the BrdfSpec union of contract/brdfs.py), so
// new BRDF models appear without changing the viewer. Shown: every model whose required parameters are numbers
// (or number-or-list, shown as one number) or enumerations; optional parameters without a default are left out
// (the server's default applies). Sums of lobes are offered as "+ Lambert diffuse" on any R-centred model.

/** UI starting values for parameters that have no default in the schema (by name). */
export const UI_PRESETS = { s: 32, alpha: 0.3, sigma: 0.3, rho_d: 0.5, rho_s: 0.5, albedo: 1 };
const SKIP = new Set(['sum', 'lobe1d', 'lafortune']); // need arrays or nested lobes: not slider material

function numberSchema(p) {
  if (p.type === 'number' || p.type === 'integer') {
    return p;
  }
  return (p.anyOf || []).find((x) => x.type === 'number' || x.type === 'integer') || null;
}

function enumSchema(p) {
  if (p.type === 'string' && Array.isArray(p.enum)) {
    return p;
  }
  return null;
}

/** One parameter's control description, or null if it cannot be a slider/select (or is optional without default). */
export function parameter(name, p, required) {
  const num = numberSchema(p);
  const en = enumSchema(p);
  if (!required && (p.default === undefined || p.default === null)) {
    return null;
  }
  if (en) {
    return { name, type: 'enum', options: en.enum, value: p.default ?? en.enum[0] };
  }
  if (!num) {
    return null;
  }
  let min = num.minimum ?? num.exclusiveMinimum ?? 0;
  const max = num.maximum ?? num.exclusiveMaximum ?? Math.max(1, 100 * (p.default ?? UI_PRESETS[name] ?? 1));
  // log scale for wide positive ranges: exponents (0 .. 1e5) and strictly positive roughnesses (0 < a <= 10)
  const strictlyPositive = num.exclusiveMinimum === 0 || min > 0;
  const log = min >= 0 && (max >= 1000 * Math.max(min, 1) || (strictlyPositive && max / Math.max(min, max * 1e-3) >= 100));
  if (log) {
    min = Math.max(min, max * (max >= 1000 ? 1e-4 : 1e-3));
  }
  let value = typeof p.default === 'number' ? p.default : UI_PRESETS[name];
  if (value === undefined) {
    value = log ? Math.sqrt(min * max) : (min + max) / 2;
  }
  value = Math.min(Math.max(value, min), max);
  return { name, type: 'number', min, max, value, log, integer: num.type === 'integer', description: p.description };
}

/** [{kind, params: [...]}] sorted by kind, from an OpenAPI document. */
export function modelsFromOpenapi(openapi) {
  const schemas = openapi?.components?.schemas || {};
  const models = [];
  for (const schema of Object.values(schemas)) {
    const kind = schema.properties?.kind;
    const name = kind?.const ?? (Array.isArray(kind?.enum) && kind.enum.length === 1 ? kind.enum[0] : null);
    if (!name || SKIP.has(name)) {
      continue;
    }
    const required = new Set(schema.required || []);
    const params = [];
    let usable = true;
    for (const [pname, p] of Object.entries(schema.properties)) {
      if (pname === 'kind') {
        continue;
      }
      const param = parameter(pname, p, required.has(pname));
      if (param) {
        params.push(param);
      } else if (required.has(pname)) {
        usable = false;
      }
    }
    if (usable) {
      models.push({ kind: name, params, description: schema.description || '' });
    }
  }
  models.sort((a, b) => a.kind.localeCompare(b.kind));
  return models;
}

/** The spec object for a model and its current values ({name: value}); `diffuse` > 0 adds a Lambert lobe. */
export function specFor(model, values, diffuse = 0) {
  const spec = { kind: model.kind };
  for (const p of model.params) {
    spec[p.name] = values[p.name] ?? p.value;
  }
  if (diffuse > 0 && model.kind !== 'lambert') {
    return { kind: 'sum', lobes: [{ kind: 'lambert', albedo: diffuse }, spec] };
  }
  return spec;
}
