// The comparison panel's numbers (no three.js here: unit-tested with node). The error is the project's metric
// (docs/conventions.md: relative RMS on Rec. 709 luminance) taken over the pixels of the sphere image, i.e.
// weighted by projected area rather than solid angle.
import { CONSTANTS } from './generated/constants.js';

const { LUMA_R, LUMA_G, LUMA_B } = CONSTANTS;

/** Pixels of an orthographic size x size image of the unit sphere (relight.shrm.sphere_geometry's mask). */
export function sphereMask(size) {
  const mask = new Uint8Array(size * size);
  for (let i = 0; i < size; i += 1) {
    const y = 1 - (2 * (i + 0.5)) / size;
    for (let j = 0; j < size; j += 1) {
      const x = (2 * (j + 0.5)) / size - 1;
      mask[i * size + j] = x * x + y * y < 1 ? 1 : 0;
    }
  }
  return mask;
}

/** Pixels whose 3 x 3 neighbourhood is covered (row-major size x size masks of 0/1). */
export function interior(coverage, size) {
  const out = new Uint8Array(size * size);
  for (let y = 1; y < size - 1; y += 1) {
    for (let x = 1; x < size - 1; x += 1) {
      let all = 1;
      for (let dy = -1; dy <= 1 && all; dy += 1) {
        for (let dx = -1; dx <= 1; dx += 1) {
          if (!coverage[(y + dy) * size + x + dx]) {
            all = 0;
            break;
          }
        }
      }
      out[y * size + x] = all;
    }
  }
  return out;
}

export function luminance(rgb, i) {
  return LUMA_R * rgb[3 * i] + LUMA_G * rgb[3 * i + 1] + LUMA_B * rgb[3 * i + 2];
}

/** sqrt(sum (Y_test - Y_ref)^2 / sum Y_ref^2) over the masked pixels, and the largest |Y_test - Y_ref| / max Y_ref. */
export function relativeError(test, ref, mask) {
  let num = 0;
  let den = 0;
  let peak = 0;
  let worst = 0;
  for (let i = 0; i < mask.length; i += 1) {
    if (mask[i]) {
      const r = luminance(ref, i);
      const d = luminance(test, i) - r;
      num += d * d;
      den += r * r;
      peak = Math.max(peak, Math.abs(r));
      worst = Math.max(worst, Math.abs(d));
    }
  }
  return { rms: den > 0 ? Math.sqrt(num / den) : Number.NaN, max: peak > 0 ? worst / peak : Number.NaN };
}

// A perceptually ordered ramp (dark blue - teal - yellow - red) for log10 of the error.
const RAMP = [[13, 8, 135], [31, 120, 180], [60, 180, 120], [250, 220, 40], [220, 40, 30]];

function ramp(t) {
  const x = Math.min(Math.max(t, 0), 1) * (RAMP.length - 1);
  const k = Math.min(Math.floor(x), RAMP.length - 2);
  const f = x - k;
  return RAMP[k].map((c, i) => Math.round(c + f * (RAMP[k + 1][i] - c)));
}

/**
 * False-colour RGBA8 image of |Y_test - Y_ref| / max Y_ref on a log scale from 10^lo to 10^hi; black off the mask.
 */
export function falseColour(test, ref, mask, lo = -4, hi = -1) {
  let peak = 0;
  for (let i = 0; i < mask.length; i += 1) {
    if (mask[i]) {
      peak = Math.max(peak, Math.abs(luminance(ref, i)));
    }
  }
  const out = new Uint8ClampedArray(mask.length * 4);
  for (let i = 0; i < mask.length; i += 1) {
    out[4 * i + 3] = 255;
    if (!mask[i] || !(peak > 0)) {
      continue;
    }
    const e = Math.abs(luminance(test, i) - luminance(ref, i)) / peak;
    const t = (Math.log10(Math.max(e, 1e-12)) - lo) / (hi - lo);
    const [r, g, b] = ramp(t);
    out[4 * i] = r;
    out[4 * i + 1] = g;
    out[4 * i + 2] = b;
  }
  return out;
}
