// IEEE 754 binary16 <-> number, for float16 texture data on the CPU (no three.js: unit-tested with node).

const F32 = new Float32Array(1);
const U32 = new Uint32Array(F32.buffer);

/** binary16 bits -> number (exact). */
export function halfToFloat(h) {
  const s = h & 0x8000 ? -1 : 1;
  const e = (h >> 10) & 0x1f;
  const m = h & 0x3ff;
  if (e === 0) {
    return s * m * 2 ** -24;
  }
  if (e === 31) {
    return m ? Number.NaN : s * Infinity;
  }
  return s * (1 + m / 1024) * 2 ** (e - 15);
}

/** number -> binary16 bits, rounding to nearest even; beyond +-65504 clamps to +-65504 (as the server does). */
export function floatToHalf(x) {
  if (Number.isNaN(x)) {
    return 0x7e00;
  }
  const clamped = Math.max(-65504, Math.min(65504, x));
  F32[0] = clamped;
  const f = U32[0];
  const sign = (f >>> 16) & 0x8000;
  const exp = (f >>> 23) & 0xff;
  let mant = f & 0x7fffff;
  if (exp < 103) {
    return sign; // below half the smallest subnormal: +-0
  }
  if (exp < 113) {
    // subnormal half: shift the implicit bit in, round to nearest even
    mant |= 0x800000;
    const shift = 126 - exp;
    const half = mant >>> shift;
    const rest = mant & ((1 << shift) - 1);
    const mid = 1 << (shift - 1);
    return sign | (half + (rest > mid || (rest === mid && half & 1) ? 1 : 0));
  }
  const e = exp - 112;
  let h = (e << 10) | (mant >>> 13);
  const rest = mant & 0x1fff;
  if (rest > 0x1000 || (rest === 0x1000 && h & 1)) {
    h += 1; // may carry into the exponent: still correct
  }
  return sign | h;
}
