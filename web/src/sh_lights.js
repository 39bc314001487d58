// Lighting and tangent frames for SH-table shading in the viewer (seed 003, Kautz, Sloan & Snyder 2002): circular
// area lights in closed form (§3 "Calculating Lighting Coefficients": "circular light sources of parameterized
// solid angle and direction converted to SH coefficients via a simple formula"), windowing against ringing with its
// stated cost (Fig. 6, last column), the brushing directions of §6 and a UV sphere. No WebGL here: node unit tests
// and the browser test compare these with relight.sh_render (cap_light, window_lighting), relight.brdf.coefficients
// (window_factors) and relight.tangent_frames (projected_frames, azimuthal_frames) on the same inputs.
//
// Coefficient arrays are Float64Array (order + 1)^2 x 3, RGB interleaved (as web/src/prt.js), in relight's real
// basis of the world directions (the SH frame (X, Z, Y), web/src/sh.js).
import { realHarmonics, shCount } from './sh.js';

/** P_0..P_lmax at x (Bonnet's recursion). */
export function legendre(x, lmax) {
  const p = new Float64Array(lmax + 1);
  p[0] = 1;
  if (lmax >= 1) {
    p[1] = x;
  }
  for (let l = 1; l < lmax; l += 1) {
    p[l + 1] = ((2 * l + 1) * x * p[l] - l * p[l - 1]) / (l + 1);
  }
  return p;
}

function unit(v, what) {
  const n = Math.hypot(v[0], v[1], v[2]);
  if (!(n > 0) || !Number.isFinite(n)) {
    throw new RangeError(`${what} must be a finite non-zero 3-vector, got ${v}`);
  }
  return [v[0] / n, v[1] / n, v[2] / n];
}

/**
 * A circular light of constant radiance `color` (RGB) over the cap of `solidAngle` steradians (0, 4 pi] about the
 * world `direction` (relight.sh_render.cap_light): zonal z_0 = 2 pi (1 - t) Y_00, z_l = 2 pi sqrt((2l+1)/4pi)
 * (P_{l-1}(t) - P_{l+1}(t)) / (2l+1) with t = 1 - Omega / 2 pi, turned to the direction by the addition theorem,
 * L_lm = sqrt(4 pi / (2l+1)) z_l Yr_lm(d).
 */
export function capLight(direction, solidAngle, color, order) {
  if (!(solidAngle > 0 && solidAngle <= 4 * Math.PI)) {
    throw new RangeError(`a cap light's solid angle must lie in (0, 4 pi], got ${solidAngle}`);
  }
  const d = unit(direction, 'a cap light\'s direction');
  const t = 1 - solidAngle / (2 * Math.PI);
  const p = legendre(t, order + 1);
  const y = realHarmonics(order, d);
  const out = new Float64Array(3 * shCount(order));
  for (let l = 0; l <= order; l += 1) {
    const z = l === 0 ? 2 * Math.PI * (1 - t) * Math.sqrt(1 / (4 * Math.PI))
      : (2 * Math.PI * Math.sqrt((2 * l + 1) / (4 * Math.PI)) * (p[l - 1] - p[l + 1])) / (2 * l + 1);
    const scale = Math.sqrt((4 * Math.PI) / (2 * l + 1)) * z;
    for (let m = -l; m <= l; m += 1) {
      const i = l * l + l + m;
      for (let c = 0; c < 3; c += 1) {
        out[3 * i + c] = scale * y[i] * color[c];
      }
    }
  }
  return out;
}

/** The window sigma_l, l = 0..order (relight.brdf.coefficients.window_factors): none, hann or lanczos. */
export function windowFactors(order, kind) {
  const w = new Float64Array(order + 1);
  for (let l = 0; l <= order; l += 1) {
    const x = l / (order + 1);
    if (kind === 'none') {
      w[l] = 1;
    } else if (kind === 'hann') {
      w[l] = 0.5 * (1 + Math.cos(Math.PI * x));
    } else if (kind === 'lanczos') {
      w[l] = x === 0 ? 1 : Math.sin(Math.PI * x) / (Math.PI * x);
    } else {
      throw new RangeError(`unknown window ${kind}; use none, hann or lanczos`);
    }
  }
  return w;
}

/**
 * Windowed coefficients and the window's stated cost, the relative L2 change of the lighting
 * sqrt(sum (1 - sigma_l)^2 |L_lm|^2 / sum |L_lm|^2) (relight.sh_render.window_lighting).
 */
export function windowLighting(coeffs, order, kind) {
  const w = windowFactors(order, kind);
  const out = new Float64Array(coeffs.length);
  let total = 0;
  let change = 0;
  for (let i = 0; i < shCount(order); i += 1) {
    const l = Math.floor(Math.sqrt(i));
    for (let c = 0; c < 3; c += 1) {
      const v = coeffs[3 * i + c];
      out[3 * i + c] = v * w[l];
      total += v * v;
      change += (v - out[3 * i + c]) ** 2;
    }
  }
  return { coeffs: out, cost: total > 0 ? Math.sqrt(change / total) : 0 };
}

/** Sum of coefficient arrays of one length. */
export function addLighting(...parts) {
  const out = new Float64Array(parts[0].length);
  for (const p of parts) {
    for (let k = 0; k < out.length; k += 1) {
      out[k] += p[k];
    }
  }
  return out;
}

const SINGULAR_EPS = 1e-12;

function project(v, n) {
  const d = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
  return [v[0] - d * n[0], v[1] - d * n[1], v[2] - d * n[2]];
}

/** relight.tangent_frames.fallback_tangent: the world axis least aligned with `avoid`, projected on the plane. */
function fallbackTangent(n, avoid) {
  const axes = [0, 1, 2].sort((a, b) => Math.abs(avoid[a]) - Math.abs(avoid[b]) || a - b);
  for (const k of axes) {
    const axis = [0, 0, 0];
    axis[k] = 1;
    const p = project(axis, n);
    const ln = Math.hypot(...p);
    if (ln > 0.5) {
      return p.map((x) => x / ln);
    }
  }
  throw new Error('no fallback tangent');
}

function tangentWithFallback(raw, n, avoid) {
  if (Math.hypot(...raw) <= SINGULAR_EPS) {
    return fallbackTangent(n, avoid);
  }
  let t = raw;
  for (let k = 0; k < 3; k += 1) {  // normalise, then Gram–Schmidt twice (relight.tangent_frames)
    if (k > 0) {
      t = project(t, n);
    }
    const ln = Math.max(Math.hypot(...t), 1e-300);
    t = t.map((x) => x / ln);
  }
  return t;
}

/**
 * glTF-style tangents (count x 4: t, w = +1) of a tangent field at unit normals (count x 3):
 * `{kind: 'project', direction}` (Kautz §6, relight.tangent_frames.projected_frames), `{kind: 'azimuthal', axis}`
 * (t = normalize(axis x n), azimuthal_frames; axis +Y by default), or `{kind: 'mesh', tangents}` (count x 4 glTF
 * TANGENT as given; mesh_frames' fallback where the tangent is parallel to n).
 */
export function tangentField(normals, spec) {
  const count = normals.length / 3;
  const out = new Float32Array(4 * count);
  const avoid = spec.kind === 'project' ? unit(spec.direction, 'the brushing direction')
    : spec.kind === 'azimuthal' ? unit(spec.axis || [0, 1, 0], 'the azimuthal axis') : [0, 1, 0];
  for (let k = 0; k < count; k += 1) {
    const n = unit([normals[3 * k], normals[3 * k + 1], normals[3 * k + 2]], 'a normal');
    let raw;
    let w = 1;
    if (spec.kind === 'project') {
      raw = project(avoid, n);
    } else if (spec.kind === 'azimuthal') {
      raw = [avoid[1] * n[2] - avoid[2] * n[1], avoid[2] * n[0] - avoid[0] * n[2], avoid[0] * n[1] - avoid[1] * n[0]];
    } else if (spec.kind === 'mesh') {
      raw = project([spec.tangents[4 * k], spec.tangents[4 * k + 1], spec.tangents[4 * k + 2]], n);
      w = spec.tangents[4 * k + 3] < 0 ? -1 : 1;
    } else {
      throw new RangeError(`unknown tangent field ${spec.kind}`);
    }
    out.set([...tangentWithFallback(raw, n, avoid), w], 4 * k);
  }
  return out;
}

/** A UV sphere of unit radius: rows x cols quads, poles included (positions = normals, uint32 indices). */
export function sphereGeometry(rows = 48, cols = 96) {
  const positions = [];
  for (let i = 0; i <= rows; i += 1) {
    const th = (Math.PI * i) / rows;
    for (let j = 0; j <= cols; j += 1) {
      const ph = (2 * Math.PI * j) / cols;
      positions.push(Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph));
    }
  }
  const indices = [];
  for (let i = 0; i < rows; i += 1) {
    for (let j = 0; j < cols; j += 1) {
      const a = i * (cols + 1) + j;
      const b = a + cols + 1;
      indices.push(a, b, a + 1, a + 1, b, b + 1);
    }
  }
  const pos = new Float32Array(positions);
  return { positions: pos, normals: Float32Array.from(pos), indices: new Uint32Array(indices) };
}

/**
 * Line segments (float32 xyz pairs) along the tangent at every `stride`-th vertex, `length` long, lifted off the
 * surface by `lift` along the normal: the tangent-field overlay.
 */
export function tangentLines(positions, normals, tangents, { stride = 1, length = 0.05, lift = 0.005 } = {}) {
  const count = positions.length / 3;
  const out = [];
  for (let k = 0; k < count; k += stride) {
    const p = [0, 1, 2].map((c) => positions[3 * k + c] + lift * normals[3 * k + c]);
    const t = [0, 1, 2].map((c) => tangents[4 * k + c]);
    out.push(...p.map((x, c) => x - 0.5 * length * t[c]), ...p.map((x, c) => x + 0.5 * length * t[c]));
  }
  return new Float32Array(out);
}
