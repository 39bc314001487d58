// Real spherical harmonics Yr_pq (relight.shrm.real_harmonics, relight.sh.to_real's basis), in double precision,
// for the per-frame weights of the distant viewer (seed 000 §7.5: Y_pq(V) "evaluated once per frame").
// Same recursion as web/shaders/sh.glsl (see its Notes); index p^2 + p + q.
import { CONSTANTS } from './generated/constants.js';

const { SQRT2, SH_Y00 } = CONSTANTS;

/** Number of terms of an order-P expansion. */
export function shCount(order) {
  return (order + 1) * (order + 1);
}

/** Index of term (p, q). */
export function shIndex(p, q) {
  return p * p + p + q;
}

/**
 * Yr_pq for p <= order at the unit vector d = [x', y', z'] of the SH frame (z' the pole).
 * @returns {Float64Array} (order + 1)^2 values
 */
export function realHarmonicsCartesian(order, d) {
  if (!Number.isInteger(order) || order < 0) {
    throw new RangeError(`order must be a non-negative integer, got ${order}`);
  }
  const [x, y, z] = d;
  const out = new Float64Array(shCount(order));
  let c = 1.0;
  let s = 0.0;
  let qmm = SH_Y00;
  for (let q = 0; q <= order; q += 1) {
    if (q > 0) {
      const cn = c * x - s * y;
      s = c * y + s * x;
      c = cn;
      qmm *= Math.sqrt((2 * q + 1) / (2 * q));
    }
    let q1 = qmm;
    let q2 = 0.0;
    for (let p = q; p <= order; p += 1) {
      let qp = q1;
      if (p > q) {
        const a = Math.sqrt((4 * p * p - 1) / (p * p - q * q));
        const b = Math.sqrt(Math.max(((p - 1) * (p - 1) - q * q) / (4 * (p - 1) * (p - 1) - 1), 0));
        qp = a * (z * q1 - b * q2);
        q2 = q1;
        q1 = qp;
      }
      const centre = p * p + p;
      if (q === 0) {
        out[centre] = qp;
      } else {
        out[centre + q] = SQRT2 * qp * c;
        out[centre - q] = SQRT2 * qp * s;
      }
    }
  }
  return out;
}

/** The SH frame's coordinates of a world direction: (x', y', z') = (X, Z, Y) (docs/conventions.md). */
export function shFrame(dir) {
  return [dir[0], dir[2], dir[1]];
}

/** Yr_pq of a world direction (normalised here). */
export function realHarmonics(order, dir) {
  const n = Math.hypot(dir[0], dir[1], dir[2]);
  if (!(n > 0) || !Number.isFinite(n)) {
    throw new RangeError(`direction must be a finite non-zero vector, got ${dir}`);
  }
  return realHarmonicsCartesian(order, shFrame([dir[0] / n, dir[1] / n, dir[2] / n]));
}

/** The environment rotated by angle a about +Y is looked up at rotateY(d, -a) (web/shaders/common.glsl). */
export function rotateY(d, angle) {
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  return [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]];
}
