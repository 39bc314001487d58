// relight's SH9 (`relight sh --convention NAME`, the `sh9` object of the manifest of every export and of the
// service's sh.json) as a three.js LightProbe.
//
// three's LightProbe holds SphericalHarmonics3 radiance coefficients c_k = int L K_k P_k dOmega (K positive, the
// order l00, l1-1, l10, l11, l2-2, l2-1, l20, l21, l22) and applies the clamped-cosine factors A_l itself: that
// is relight's `three` convention. The other conventions are the same numbers rescaled (relight/sh9.py,
// docs/conventions.md "SH9"), so they are converted back here: babylon = s_k c_k, gltf = A_l s_k c_k,
// filament = (A_l / pi) K_k c_k, with s the Condon-Shortley signs of odd m. `raw` (relight's own SH frame and
// normalisation) is not an engine convention and is refused.
import { LightProbe, SphericalHarmonics3, Vector3 } from 'three';

export const CONVENTIONS = ['three', 'babylon', 'gltf', 'filament'];
const DEGREE = [0, 1, 1, 1, 2, 2, 2, 2, 2];
const A_L = [Math.PI, (2 * Math.PI) / 3, Math.PI / 4];
const CS_SIGN = [1, -1, 1, -1, 1, -1, 1, -1, 1];
const K = [Math.sqrt(1 / (4 * Math.PI)), ...Array(3).fill(Math.sqrt(3 / (4 * Math.PI))),
  ...Array(2).fill(Math.sqrt(15 / (4 * Math.PI))), Math.sqrt(5 / (16 * Math.PI)), Math.sqrt(15 / (4 * Math.PI)),
  Math.sqrt(15 / (16 * Math.PI))];

/** Per-coefficient factor f_k with (convention's number) = f_k c_k. */
export function conventionScale(convention) {
  switch (convention) {
    case 'three':
      return Array(9).fill(1);
    case 'babylon':
      return CS_SIGN.slice();
    case 'gltf':
      return DEGREE.map((l, k) => A_L[l] * CS_SIGN[k]);
    case 'filament':
      return DEGREE.map((l, k) => (A_L[l] / Math.PI) * K[k]);
    default:
      throw new Error(`relight-three: SH convention ${JSON.stringify(convention)} is not one of ${CONVENTIONS}`);
  }
}

/**
 * three's radiance coefficients (9 [r, g, b]) from any relight SH document: `{convention, coefficients}`
 * (`relight sh`), an object with `sh9` (the manifest of an export, the sh.json of the service; its `three` entry is used),
 * or `{three: {coefficients}}` (the `sh9` object itself).
 */
export function threeCoefficients(doc) {
  if (!doc || typeof doc !== 'object') {
    throw new TypeError('relight-three: an SH document (object) is needed');
  }
  if (doc.sh9) {
    return threeCoefficients(doc.sh9);
  }
  let convention = doc.convention;
  let coefficients = doc.coefficients;
  if (coefficients === undefined) {
    convention = CONVENTIONS.find((c) => doc[c] && doc[c].coefficients);
    if (!convention) {
      throw new Error('relight-three: no SH coefficients in the document');
    }
    coefficients = doc[convention].coefficients;
  }
  if (!Array.isArray(coefficients) || coefficients.length !== 9
    || !coefficients.every((c) => Array.isArray(c) && c.length === 3 && c.every(Number.isFinite))) {
    throw new Error('relight-three: coefficients must be 9 finite [r, g, b] triples');
  }
  const scale = conventionScale(convention ?? 'three');
  return coefficients.map((c, k) => c.map((v) => v / scale[k]));
}

/** A SphericalHarmonics3 with the document's radiance coefficients. */
export function sphericalHarmonics(doc) {
  const sh = new SphericalHarmonics3();
  sh.set(threeCoefficients(doc).map((c) => new Vector3(c[0], c[1], c[2])));
  return sh;
}

/** A LightProbe lit by the document's SH9 (`intensity` as LightProbe's). */
export function lightProbeFromSH(doc, intensity = 1) {
  return new LightProbe(sphericalHarmonics(doc), intensity);
}
