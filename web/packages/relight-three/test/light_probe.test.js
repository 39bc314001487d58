// SH9 documents -> three's LightProbe: every convention's numbers (written here from their definitions in
// docs/conventions.md, independently of src/light_probe.js's table) come back as three's radiance coefficients,
// and three's own getIrradianceAt of a clamped-cosine light equals the closed form of its order-2 irradiance.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { Vector3 } from 'three';

import { lightProbeFromSH, threeCoefficients } from '../src/index.js';

const PI = Math.PI;
const K = [0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274];
const A = [PI, (2 * PI) / 3, (2 * PI) / 3, (2 * PI) / 3, PI / 4, PI / 4, PI / 4, PI / 4, PI / 4];
const SIGN = [1, -1, 1, -1, 1, -1, 1, -1, 1];  // Condon-Shortley: odd m (l1-1, l11, l2-1, l21)
const C = Array.from({ length: 9 }, (_, k) => [0.5 + k, -0.25 * k, 2 - 0.1 * k]);

test('every convention converts back to three radiance coefficients', () => {
  const docs = {
    three: C,
    babylon: C.map((c, k) => c.map((v) => SIGN[k] * v)),
    gltf: C.map((c, k) => c.map((v) => A[k] * SIGN[k] * v)),
    filament: C.map((c, k) => c.map((v) => (A[k] / PI) * K[k] * v)),
  };
  for (const [convention, coefficients] of Object.entries(docs)) {
    const got = threeCoefficients({ convention, coefficients });
    got.flat().forEach((v, i) => assert.ok(Math.abs(v - C.flat()[i]) < 2e-6 * (1 + Math.abs(v)),
      `${convention} [${i}]: ${v} vs ${C.flat()[i]}`));
  }
  // the sh9 object of a manifest / the service's sh.json
  assert.deepEqual(threeCoefficients({ sh9: { gltf: { coefficients: docs.gltf }, three: { coefficients: C } } }), C);
  assert.throws(() => threeCoefficients({ convention: 'raw', coefficients: C }), /not one of/);
  assert.throws(() => threeCoefficients({ convention: 'three', coefficients: C.slice(1) }), /9 finite/);
});

test("three's LightProbe irradiance is the order-2 clamped-cosine closed form", () => {
  // L(d) = max(0, d . a): radiance coefficients c_k = 2 pi I_l K_k P_k(a), I = [1/4, 1/3, 1/8] (Ramamoorthi and
  // Hanrahan 2001, the clamped cosine's Legendre coefficients); irradiance E(n) = sum_l A_l I_l (4 pi / (2l+1))
  // ... written directly: E(n) = pi/4 + (pi/2) (n.a)/... with the three band sums A_l^2 / (2 pi) P_l(n.a) (2l+1)/(4 pi).
  const a = new Vector3(0.3, -0.5, 0.8).normalize();
  const I = [0.25, 1 / 3, 1 / 3, 1 / 3, 0.125, 0.125, 0.125, 0.125, 0.125];
  const [x, y, z] = [a.x, a.y, a.z];
  const P = [1, y, z, x, x * y, y * z, 3 * z * z - 1, x * z, x * x - y * y];
  const coefficients = P.map((p, k) => Array(3).fill(2 * PI * I[k] * K[k] * p));
  const probe = lightProbeFromSH({ convention: 'three', coefficients });
  for (const n of [new Vector3(0, 0, 1), new Vector3(-1, 0.2, 0.1).normalize(), a.clone()]) {
    const t = n.dot(a);
    // E(n) = sum_l A_l (2 pi I_l) (2l + 1) / (4 pi) P_l(t), Legendre P_0..P_2
    const legendre = [1, t, (3 * t * t - 1) / 2];
    const expected = [0, 1, 2].reduce((s, l) => s + [PI, (2 * PI) / 3, PI / 4][l] * 2 * PI * [0.25, 1 / 3, 0.125][l]
      * ((2 * l + 1) / (4 * PI)) * legendre[l], 0);
    const got = probe.sh.getIrradianceAt(n, new Vector3()).x;
    assert.ok(Math.abs(got - expected) < 1e-5, `n.a = ${t}: ${got} vs ${expected}`);
  }
});
