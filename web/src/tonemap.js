// The display transform of web/shaders/tonemap.glsl and relight.envmap.tonemap, for images drawn on the CPU
// (the comparison panel): max(x, 0) 2^exposure, ACES (Narkowicz 2016) / Reinhard / none, clamp, sRGB OETF.
import { CONSTANTS } from './generated/constants.js';

const { ACES_A, ACES_B, ACES_C, ACES_D, ACES_E } = CONSTANTS;

export const TONEMAPS = { aces: CONSTANTS.TONEMAP_ACES, reinhard: CONSTANTS.TONEMAP_REINHARD, none: CONSTANTS.TONEMAP_NONE };

/** sRGB OETF (IEC 61966-2-1). */
export function srgbOetf(c) {
  return c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055;
}

export function tonemapValue(v, exposure, operator) {
  const x = Math.max(Number.isNaN(v) ? 0 : v, 0) * 2 ** exposure;
  let y;
  if (operator === 'aces') {
    y = (x * (ACES_A * x + ACES_B)) / (x * (ACES_C * x + ACES_D) + ACES_E);
  } else if (operator === 'reinhard') {
    y = x / (1 + x);
  } else if (operator === 'none') {
    y = x;
  } else {
    throw new Error(`unknown tone-mapping operator ${operator}`);
  }
  return srgbOetf(Math.min(Math.max(y, 0), 1));
}

/** Linear RGB (Float32Array, 3 per pixel, row 0 at the top) to RGBA8 (Uint8ClampedArray) for ImageData. */
export function tonemapImage(rgb, exposure = 0, operator = 'aces') {
  const n = rgb.length / 3;
  const out = new Uint8ClampedArray(n * 4);
  for (let i = 0; i < n; i += 1) {
    for (let c = 0; c < 3; c += 1) {
      out[4 * i + c] = Math.round(tonemapValue(rgb[3 * i + c], exposure, operator) * 255);
    }
    out[4 * i + 3] = 255;
  }
  return out;
}
