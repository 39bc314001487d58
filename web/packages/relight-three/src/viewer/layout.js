// Texture layout of an SHRM result for the shaders: the twin of relight/gl/layout.py (same rules, same fixtures;
// web/test/layout.test.js). Reads only these manifest fields: height, width, representation, center, layout,
// layers[*].{index, name, component, p, q}, components[*] or orders.components[*] .{index, center, layers,
// frame | layout}, and files["coefficients.bin"].shape (checked).
import { CONSTANTS } from './generated/constants.js';
import { realHarmonics, shIndex } from './sh.js';

const LAYER_NAME = /^c(\d+)\.p(\d+)\.q(-?\d+)$/;
export const CENTERS = { R: CONSTANTS.CENTER_R, N: CONSTANTS.CENTER_N, T: CONSTANTS.CENTER_T };
export const FRAMES = { map: CONSTANTS.FRAME_MAP, global: CONSTANTS.FRAME_GLOBAL, local: CONSTANTS.FRAME_LOCAL };
export const DEFAULT_SHRM_FRAME = 'local';

export class LayoutError extends Error {}

function componentOf(name) {
  const m = LAYER_NAME.exec(name || '');
  return m ? Number(m[1]) : null;
}

function checkFrame(value, where) {
  if (!(value in FRAMES)) {
    throw new LayoutError(`${where}: unknown layer frame ${JSON.stringify(value)}`);
  }
  return value;
}

function checkCenter(value, where) {
  if (!(value in CENTERS)) {
    throw new LayoutError(`${where}: unknown lobe centre ${JSON.stringify(value)}`);
  }
  return value;
}

function component(center, frame, layers) {
  return { center, frame, layers, P: Math.max(...layers.map((l) => l.p)) };
}

/** The layout of a result manifest: {height, width, components: [{center, frame, P, layers: [{index,p,q}]}]}. */
export function fromManifest(manifest) {
  const height = Number(manifest.height);
  const width = Number(manifest.width);
  if (!Number.isInteger(height) || !Number.isInteger(width) || !Array.isArray(manifest.layers)) {
    throw new LayoutError('manifest lacks height, width or layers');
  }
  const layers = manifest.layers.map((layer, i) => {
    const ref = { index: Number(layer.index ?? i), p: Number(layer.p), q: Number(layer.q) };
    if (!Number.isInteger(ref.p) || !Number.isInteger(ref.q)) {
      throw new LayoutError(`manifest layer ${i} lacks p or q`);
    }
    if (Math.abs(ref.q) > ref.p || ref.index < 0 || ref.index >= manifest.layers.length) {
      throw new LayoutError(`manifest layer ${i} is out of range`);
    }
    const name = String(layer.name ?? '');
    const owner = layer.component !== undefined && layer.component !== null ? Number(layer.component) : componentOf(name);
    return { ref, name, owner };
  });
  if (!layers.length) {
    throw new LayoutError('manifest has no layers');
  }
  const shape = manifest.files?.['coefficients.bin']?.shape;
  if (shape && JSON.stringify(shape) !== JSON.stringify([layers.length, height, width, 3])) {
    throw new LayoutError(`coefficients.bin has shape ${JSON.stringify(shape)}`);
  }
  const topCenter = manifest.center || 'R';
  if (manifest.representation === 'reflection_map') {
    return { height, width, components: [component(checkCenter(topCenter, 'manifest'), 'map', layers.map((l) => l.ref))] };
  }
  const defaultFrame = checkFrame(manifest.layout || DEFAULT_SHRM_FRAME, 'manifest layout');
  const byName = new Map(layers.filter((l) => l.name).map((l) => [l.name, l.ref]));
  const byIndex = new Map(layers.map((l) => [l.ref.index, l.ref]));
  const comps = [];
  const described = (Array.isArray(manifest.components) && manifest.components.length)
    ? manifest.components : manifest.orders?.components;
  if (Array.isArray(described) && described.length) {
    described.forEach((comp, k) => {
      const where = `manifest component ${k}`;
      let refs;
      if (Array.isArray(comp.layers) && comp.layers.length) {
        refs = comp.layers.map((item) => {
          const ref = typeof item === 'string' ? byName.get(item) : byIndex.get(Number(item));
          if (!ref) {
            throw new LayoutError(`${where}: layer ${JSON.stringify(item)} is not in the manifest's layers`);
          }
          return ref;
        });
      } else {
        refs = layers.filter((l) => l.owner === (comp.index ?? k)).map((l) => l.ref);
      }
      if (!refs.length) {
        throw new LayoutError(`${where} has no layers`);
      }
      const frame = checkFrame(comp.frame || comp.layout || defaultFrame, where);
      comps.push(component(checkCenter(comp.center ?? topCenter, where), frame, refs));
    });
  } else {
    const groups = new Map();
    for (const l of layers) {
      const k = l.owner || 0;
      if (!groups.has(k)) {
        groups.set(k, []);
      }
      groups.get(k).push(l.ref);
    }
    if (groups.size > 1) {
      throw new LayoutError("manifest has layers of several components but no 'components' giving their centres");
    }
    comps.push(component(checkCenter(topCenter, 'manifest'), defaultFrame, [...groups.values()][0]));
  }
  const used = comps.flatMap((c) => c.layers.map((l) => l.index));
  if (new Set(used).size !== used.length) {
    throw new LayoutError('manifest components share layers');
  }
  return { height, width, components: comps };
}

/** Manifest layer index of each texture layer (components contiguous, in order). */
export function textureOrder(layout) {
  return layout.components.flatMap((c) => c.layers.map((l) => l.index));
}

export function numLayers(layout) {
  return layout.components.reduce((n, c) => n + c.layers.length, 0);
}

/** Largest P of the components whose weights the shader evaluates (0 if none). */
export function shOrder(layout) {
  return Math.max(0, ...layout.components.filter((c) => c.frame !== 'map').map((c) => c.P));
}

/** The #define tables of web/shaders/shrm.glsl (relight.gl.layout.defines), in the same order. */
export function defines(layout) {
  const first = [];
  const counts = [];
  let k = 0;
  for (const c of layout.components) {
    first.push(k);
    counts.push(c.layers.length);
    k += c.layers.length;
  }
  return {
    SH_ORDER: shOrder(layout),
    SHRM_NUM_LAYERS: numLayers(layout),
    SHRM_NUM_COMPONENTS: layout.components.length,
    SHRM_MAX_LAYERS: Math.max(...counts),
    SHRM_HAS_LOCAL: layout.components.some((c) => c.frame === 'local') ? 1 : 0,
    SHRM_LAYER_SH: layout.components.flatMap((c) => c.layers.map((l) => shIndex(l.p, l.q))),
    SHRM_COMPONENT_CENTER: layout.components.map((c) => CENTERS[c.center]),
    SHRM_COMPONENT_FRAME: layout.components.map((c) => FRAMES[c.frame]),
    SHRM_COMPONENT_FIRST: first,
    SHRM_COMPONENT_COUNT: counts,
  };
}

/**
 * u_layer_weight for a distant view (environment frame): 1 for plain maps, Yr_pq(V) for global maps (eq. 12,
 * once per frame), 0 for local maps (the shader weights those per texel).
 */
export function uniformWeights(layout, viewEnv) {
  const y = realHarmonics(shOrder(layout), viewEnv);
  const out = new Float32Array(numLayers(layout));
  let k = 0;
  for (const c of layout.components) {
    for (const l of c.layers) {
      out[k] = c.frame === 'map' ? 1 : c.frame === 'global' ? y[shIndex(l.p, l.q)] : 0;
      k += 1;
    }
  }
  return out;
}

const HALF_ONE = 0x3c00; // 1.0 in IEEE binary16

/**
 * RGBA half-float texture data (Uint16Array, layers in texture order) from coefficients.bin's RGB halves
 * (little-endian (layers, height, width, 3)); alpha = 1.
 */
export function rgbaLayers(layout, halfRgb) {
  const texels = layout.height * layout.width;
  const order = textureOrder(layout);
  if (halfRgb.length !== order.length * texels * 3) {
    throw new LayoutError(`coefficients.bin holds ${halfRgb.length} values, expected ${order.length * texels * 3}`);
  }
  const out = new Uint16Array(order.length * texels * 4);
  order.forEach((src, dst) => {
    const s0 = src * texels * 3;
    const d0 = dst * texels * 4;
    for (let i = 0; i < texels; i += 1) {
      out[d0 + 4 * i] = halfRgb[s0 + 3 * i];
      out[d0 + 4 * i + 1] = halfRgb[s0 + 3 * i + 1];
      out[d0 + 4 * i + 2] = halfRgb[s0 + 3 * i + 2];
      out[d0 + 4 * i + 3] = HALF_ONE;
    }
  });
  return out;
}

/** Little-endian float16 bytes as a Uint16Array (copies only on a big-endian host). */
export function halfArray(buffer) {
  const little = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;
  if (little) {
    return new Uint16Array(buffer);
  }
  const view = new DataView(buffer);
  const out = new Uint16Array(buffer.byteLength / 2);
  for (let i = 0; i < out.length; i += 1) {
    out[i] = view.getUint16(2 * i, true);
  }
  return out;
}
