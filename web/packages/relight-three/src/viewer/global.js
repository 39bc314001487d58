// Global SHRM layers from local ones (seed 000 eq. 8), computed once when a result is loaded, so that the distant
// viewer's per-frame work is eq. 12 alone: sum_pq B~r_pq(alpha, beta) Yr_pq(V) with per-frame constant weights.
// The port of relight.shrm.local_to_global (same conventions; web/test/global.test.js checks it against Python):
//   B~_pq(alpha, beta) = e^{-i q beta} sum_s d^p_qs(alpha) B_ps(alpha, beta)
// with the real <-> complex forms of relight.sh.to_real / from_real and the Wigner/Edmonds small d of
// relight.wigner (Condon-Shortley phase, d^1_10(b) = -sin(b)/sqrt2).
import { CONSTANTS } from './generated/constants.js';
import { halfToFloat, floatToHalf } from './half.js';
import { numLayers, textureOrder } from './layout.js';
import { shIndex } from './sh.js';

const { PI, SQRT2 } = CONSTANTS;

function factorials(n) {
  const f = [1];
  for (let k = 1; k <= n; k += 1) {
    f.push(f[k - 1] * k);
  }
  return f;
}

/**
 * d^p_{qs}(beta) for |q|, |s| <= p as a flat Float64Array, entry (q + p) (2p + 1) + (s + p) (Wigner's sum,
 * Edmonds eq. 4.1.23; exact enough for the small p of SHRMs).
 */
export function wignerSmallD(p, beta) {
  const n = 2 * p + 1;
  const f = factorials(2 * p + 1);
  const c = Math.cos(beta / 2);
  const s = Math.sin(beta / 2);
  const out = new Float64Array(n * n);
  for (let q = -p; q <= p; q += 1) {
    for (let m = -p; m <= p; m += 1) {
      const norm = Math.sqrt(f[p + q] * f[p - q] * f[p + m] * f[p - m]);
      let sum = 0;
      for (let k = Math.max(0, m - q); k <= Math.min(p + m, p - q); k += 1) {
        const sign = (k - m + q) % 2 === 0 ? 1 : -1;
        const den = f[p + m - k] * f[k] * f[p - k - q] * f[k - m + q];
        sum += (sign * c ** (2 * p - 2 * k + m - q) * s ** (2 * k - m + q)) / den;
      }
      out[(q + p) * n + (m + p)] = norm * sum;
    }
  }
  return out;
}

/**
 * Global maps of one local component: `maps` is a Float64Array (K, S, 2S, 3) for `terms` [[p, q]...];
 * returns a Float64Array ((P+1)^2, S, 2S, 3) in real index order p^2 + p + q.
 */
export function localToGlobal(maps, terms, rows) {
  const cols = 2 * rows;
  const P = Math.max(...terms.map(([p]) => p));
  const K = (P + 1) * (P + 1);
  const texels = rows * cols;
  const out = new Float64Array(K * texels * 3);
  const slot = new Map(terms.map(([p, q], k) => [shIndex(p, q), k]));
  const re = new Float64Array(2 * P + 1);
  const im = new Float64Array(2 * P + 1);
  const rotRe = new Float64Array(2 * P + 1);
  const rotIm = new Float64Array(2 * P + 1);
  for (let i = 0; i < rows; i += 1) {
    const alpha = ((i + 0.5) * PI) / rows;
    const dmats = [];
    for (let p = 0; p <= P; p += 1) {
      dmats.push(wignerSmallD(p, alpha));
    }
    for (let j = 0; j < cols; j += 1) {
      const beta = ((j + 0.5) / cols - 0.5) * 2 * PI;
      const t = i * cols + j;
      for (let ch = 0; ch < 3; ch += 1) {
        for (let p = 0; p <= P; p += 1) {
          const n = 2 * p + 1;
          const real = (q) => {
            const k = slot.get(shIndex(p, q));
            return k === undefined ? 0 : maps[(k * texels + t) * 3 + ch];
          };
          // local complex B_ps (relight.shrm._real_to_complex), index s + p
          re[p] = real(0);
          im[p] = 0;
          for (let s = 1; s <= p; s += 1) {
            const sign = s % 2 === 0 ? 1 : -1;
            const a = real(s);
            const b = real(-s);
            re[p + s] = (sign * a) / SQRT2;
            im[p + s] = (-sign * b) / SQRT2;
            re[p - s] = a / SQRT2;
            im[p - s] = b / SQRT2;
          }
          const d = dmats[p];
          for (let q = -p; q <= p; q += 1) {
            let sr = 0;
            let si = 0;
            for (let s = -p; s <= p; s += 1) {
              const w = d[(q + p) * n + (s + p)];
              sr += w * re[s + p];
              si += w * im[s + p];
            }
            const c = Math.cos(q * beta);
            const sn = -Math.sin(q * beta); // e^{-i q beta}
            rotRe[q + p] = sr * c - si * sn;
            rotIm[q + p] = sr * sn + si * c;
          }
          // relight.shrm._complex_to_real
          out[(shIndex(p, 0) * texels + t) * 3 + ch] = rotRe[p];
          for (let q = 1; q <= p; q += 1) {
            const sign = SQRT2 * (q % 2 === 0 ? 1 : -1);
            out[(shIndex(p, q) * texels + t) * 3 + ch] = sign * rotRe[p + q];
            out[(shIndex(p, -q) * texels + t) * 3 + ch] = -sign * rotIm[p + q];
          }
        }
      }
    }
  }
  return out;
}

/**
 * The layout and RGBA float16 data (Uint16Array, texture order, alpha 1) of the global form of a result: local
 * components become global ones with all (P+1)^2 terms (P = 0 ones keep their single layer: B~_00 = B_00);
 * plain maps and global components are copied. `halfRgb` is coefficients.bin as a Uint16Array.
 */
export function globalLayers(layout, halfRgb) {
  const rows = layout.height;
  const texels = rows * layout.width;
  const components = [];
  const blocks = [];
  for (const c of layout.components) {
    const P = c.P;
    if (c.frame !== 'local' || P === 0) {
      const data = new Float64Array(c.layers.length * texels * 3);
      c.layers.forEach((l, k) => {
        for (let x = 0; x < texels * 3; x += 1) {
          data[k * texels * 3 + x] = halfToFloat(halfRgb[l.index * texels * 3 + x]);
        }
      });
      const frame = c.frame === 'local' ? 'global' : c.frame;
      components.push({ center: c.center, frame, P, layers: c.layers.map((l) => ({ p: l.p, q: l.q })) });
      blocks.push(data);
      continue;
    }
    const maps = new Float64Array(c.layers.length * texels * 3);
    c.layers.forEach((l, k) => {
      for (let x = 0; x < texels * 3; x += 1) {
        maps[k * texels * 3 + x] = halfToFloat(halfRgb[l.index * texels * 3 + x]);
      }
    });
    const terms = c.layers.map((l) => [l.p, l.q]);
    const layers = [];
    for (let p = 0; p <= P; p += 1) {
      for (let q = -p; q <= p; q += 1) {
        layers.push({ p, q: q + 0 }); // + 0: no -0 for p = 0
      }
    }
    components.push({ center: c.center, frame: 'global', P, layers });
    blocks.push(localToGlobal(maps, terms, rows));
  }
  let index = 0;
  for (const c of components) {
    for (const l of c.layers) {
      l.index = index;
      index += 1;
    }
  }
  const out = { height: layout.height, width: layout.width, components };
  const rgba = new Uint16Array(index * texels * 4);
  let layer = 0;
  for (const block of blocks) {
    const count = block.length / (texels * 3);
    for (let k = 0; k < count; k += 1, layer += 1) {
      for (let x = 0; x < texels; x += 1) {
        const src = (k * texels + x) * 3;
        const dst = (layer * texels + x) * 4;
        rgba[dst] = floatToHalf(block[src]);
        rgba[dst + 1] = floatToHalf(block[src + 1]);
        rgba[dst + 2] = floatToHalf(block[src + 2]);
        rgba[dst + 3] = 0x3c00;
      }
    }
  }
  if (numLayers(out) !== index || textureOrder(out).length !== index) {
    throw new Error('internal: global layout and data disagree');
  }
  return { layout: out, rgba };
}
