// Diffuse precomputed radiance transfer on the CPU side of the viewer (no three.js: unit-tested with node):
// the lighting's real SH coefficients from the float16 lat-long map the viewer shows, their rotation with the
// environment, the clamped cosine's zonal factors of the unshadowed modes, and the mesh geometry.bin / float16
// vertex-texture layouts of the service (relight/mesh/geometry.py, relight/vertex_texture.py). The shading itself
// is web/shaders/prt.vert.glsl, shared with relight/gl/prt.py.
import { halfToFloat } from './half.js';
import { realHarmonicsCartesian, shCount } from './sh.js';

/**
 * Real SH coefficients (order + 1)^2 x 3 (RGB interleaved, Float64Array) of a lat-long map given as float16
 * RGB bits (row 0 = +Y, docs/conventions.md): sum over pixels of L(d) Yr(d) dOmega with each pixel's exact solid
 * angle (2 pi / W)(cos theta_top - cos theta_bottom) — relight.sh.project(..., weights="area").
 */
export function projectLatlongHalf(halfRgb, height, width, order) {
  const n = shCount(order);
  const out = new Float64Array(3 * n);
  const lut = new Float64Array(65536);
  for (let h = 0; h < 65536; h += 1) {
    lut[h] = halfToFloat(h);
  }
  for (let i = 0; i < height; i += 1) {
    const t0 = (i * Math.PI) / height;
    const t1 = ((i + 1) * Math.PI) / height;
    const omega = ((2 * Math.PI) / width) * (Math.cos(t0) - Math.cos(t1));
    const theta = ((i + 0.5) * Math.PI) / height;
    const st = Math.sin(theta);
    const ct = Math.cos(theta);
    for (let j = 0; j < width; j += 1) {
      const phi = ((j + 0.5) / width - 0.5) * 2 * Math.PI;
      // world d = (sin t cos p, cos t, sin t sin p); SH frame (x', y', z') = (X, Z, Y)
      const y = realHarmonicsCartesian(order, [st * Math.cos(phi), st * Math.sin(phi), ct]);
      const p = 3 * (i * width + j);
      const r = lut[halfRgb[p]] * omega;
      const g = lut[halfRgb[p + 1]] * omega;
      const b = lut[halfRgb[p + 2]] * omega;
      for (let k = 0; k < n; k += 1) {
        out[3 * k] += r * y[k];
        out[3 * k + 1] += g * y[k];
        out[3 * k + 2] += b * y[k];
      }
    }
  }
  return out;
}

/**
 * The coefficients of the environment rotated by `angle` about +Y (the viewer's rotation: the map is looked up at
 * rotate_y(d, -angle)): the SH azimuth atan2(Z, X) shifts by +angle, so per band
 * (c_m, c_-m) -> (c_m cos(m a) + c_-m sin(m a), c_-m cos(m a) - c_m sin(m a)) — relight.gl.prt.rotate_lighting_y.
 */
export function rotateLightingY(coeffs, order, angle) {
  const out = Float64Array.from(coeffs);
  for (let l = 1; l <= order; l += 1) {
    for (let m = 1; m <= l; m += 1) {
      const c = Math.cos(m * angle);
      const s = Math.sin(m * angle);
      const pos = l * l + l + m;
      const neg = l * l + l - m;
      for (let ch = 0; ch < 3; ch += 1) {
        const cp = coeffs[3 * pos + ch];
        const cn = coeffs[3 * neg + ch];
        out[3 * pos + ch] = cp * c + cn * s;
        out[3 * neg + ch] = cn * c - cp * s;
      }
    }
  }
  return out;
}

function factorial(n) {
  let f = 1;
  for (let k = 2; k <= n; k += 1) {
    f *= k;
  }
  return f;
}

/** 2 I_l, I_l = int_0^1 mu P_l(mu) dmu, for l <= order (relight.gl.prt.cosine_zonal). */
export function cosineZonal(order) {
  const out = new Float64Array(order + 1);
  for (let l = 0; l <= order; l += 1) {
    let i;
    if (l === 0) {
      i = 0.5;
    } else if (l === 1) {
      i = 1 / 3;
    } else if (l % 2) {
      i = 0;
    } else {
      const h = l / 2;
      i = ((-1) ** (h - 1) * factorial(l)) / (2 ** l * factorial(h) ** 2 * (l + 2) * (l - 1));
    }
    out[l] = 2 * i;
  }
  return out;
}

/**
 * The sections of a mesh's geometry.bin (GET /meshes/{id}/geometry.bin) as typed arrays, from the layout in the
 * mesh's manifest (`geometry.sections`: offset and shape of positions, normals, tangents float32, indices uint32).
 */
export function parseGeometry(buffer, geometry) {
  if (buffer.byteLength !== geometry.bytes) {
    throw new RangeError(`geometry.bin has ${buffer.byteLength} bytes, the manifest says ${geometry.bytes}`);
  }
  const out = {};
  for (const [name, sec] of Object.entries(geometry.sections)) {
    const count = sec.shape[0] * sec.shape[1];
    out[name] = sec.dtype === 'uint32' ? new Uint32Array(buffer, sec.offset, count)
      : new Float32Array(buffer, sec.offset, count);
  }
  return out;
}

/**
 * Value k of vertex v of a float16 vertex texture (relight/vertex_texture.py's layout: ceil(n / 4) RGBA texels per
 * vertex, row-major, `width` texels wide), as the shader's texelFetch reads it.
 */
export function vertexValue(halfBits, texture, v, k) {
  const t = v * texture.texels_per_vertex + Math.floor(k / 4);
  return halfToFloat(halfBits[4 * t + (k % 4)]);
}
