// relight's exports against three.js' own image-based lighting on the same map (issue 17, items 4 and 9): rows
// of metal spheres (MeshStandardMaterial, metalness 1) lit once by relight's KTX2 cube chain through
// @relight/three and once by three's PMREMGenerator on the same lat-long map, and a white Lambert sphere lit by
// a LightProbe from relight's SH9. Drawn into linear float targets (no tone mapping): the numbers of
// tests/web/test_three_package_browser.py; drawSideBySide paints the viewer's panel (web/src/exports_panel.js).
import * as THREE from 'three';

import { cubeChainTexture, lightProbeFromSH } from '@relight/three';

export const ROUGHNESS = [0, 0.25, 0.5, 0.75, 1];

/**
 * three's equirectangular texture of a relight lat-long map (float16 RGB, row 0 at +Y): three's equirectUv puts
 * +Y at v = 1, so rows are reversed; columns agree (u = atan(z, x) / 2 pi + 1/2 in both).
 */
export function equirectTexture(halfRgb, height, width) {
  const rgba = new Uint16Array(height * width * 4);
  for (let row = 0; row < height; row += 1) {
    const dst = (height - 1 - row) * width;
    for (let col = 0; col < width; col += 1) {
      const s = 3 * (row * width + col);
      const d = 4 * (dst + col);
      rgba[d] = halfRgb[s];
      rgba[d + 1] = halfRgb[s + 1];
      rgba[d + 2] = halfRgb[s + 2];
      rgba[d + 3] = 0x3c00;
    }
  }
  const tex = new THREE.DataTexture(rgba, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
  tex.mapping = THREE.EquirectangularReflectionMapping;
  tex.colorSpace = THREE.LinearSRGBColorSpace;
  tex.minFilter = THREE.LinearFilter;
  tex.magFilter = THREE.LinearFilter;
  tex.wrapS = THREE.RepeatWrapping;
  tex.generateMipmaps = false;
  tex.needsUpdate = true;
  return tex;
}

/** three's own PMREM of a relight lat-long map. */
export function pmremTexture(renderer, halfRgb, height, width) {
  const src = equirectTexture(halfRgb, height, width);
  const gen = new THREE.PMREMGenerator(renderer);
  const target = gen.fromEquirectangular(src);
  gen.dispose();
  src.dispose();
  return target.texture;
}

/** relight's chain (KTX2 bytes) as three's prefiltered environment. */
export function chainTexture(bytes) {
  return cubeChainTexture(bytes);
}

const SEGMENTS = [256, 128];

/** An orthographic camera on +Z seeing [-1, 1]^2 around `x` (one sphere of radius 1 per cell). */
function cellCamera(x) {
  const cam = new THREE.OrthographicCamera(-1, 1, 1, -1, 0.1, 10);
  cam.position.set(x, 0, 5);
  cam.lookAt(x, 0, 0);
  cam.updateMatrixWorld();
  return cam;
}

function renderCells(renderer, scene, count, size) {
  const target = new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType, format: THREE.RGBAFormat,
    depthBuffer: true, minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter });
  const out = new Float32Array(count * size * size * 4);
  const cell = new Float32Array(size * size * 4);
  const toneMapping = renderer.toneMapping;
  renderer.toneMapping = THREE.NoToneMapping;
  for (let i = 0; i < count; i += 1) {
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, cellCamera(3 * i));
    renderer.readRenderTargetPixels(target, 0, 0, size, size, cell);
    out.set(cell, i * cell.length);
  }
  renderer.setRenderTarget(null);
  renderer.toneMapping = toneMapping;
  target.dispose();
  return out;
}

/**
 * Linear RGBA float pixels (cells of size x size, row 0 at the bottom, alpha 0 off the spheres) of metal spheres
 * at `roughness` lit by `envTexture` (a PMREM-like texture: relight's chain or three's PMREM).
 */
export function renderMetalSpheres(renderer, envTexture, { roughness = ROUGHNESS, size = 64 } = {}) {
  const scene = new THREE.Scene();
  const geometry = new THREE.SphereGeometry(1, ...SEGMENTS);
  const materials = roughness.map((r, i) => {
    const m = new THREE.MeshStandardMaterial({ color: 0xffffff, metalness: 1, roughness: r, envMap: envTexture });
    const mesh = new THREE.Mesh(geometry, m);
    mesh.position.set(3 * i, 0, 0);
    scene.add(mesh);
    return m;
  });
  const data = renderCells(renderer, scene, roughness.length, size);
  materials.forEach((m) => m.dispose());
  geometry.dispose();
  return data;
}

/** A white Lambert sphere lit only by a LightProbe from a relight SH9 document; linear pixels as above. */
export function renderProbeSphere(renderer, shDocument, { size = 64 } = {}) {
  const scene = new THREE.Scene();
  scene.add(lightProbeFromSH(shDocument));
  const geometry = new THREE.SphereGeometry(1, ...SEGMENTS);
  const material = new THREE.MeshLambertMaterial({ color: 0xffffff });
  scene.add(new THREE.Mesh(geometry, material));
  const data = renderCells(renderer, scene, 1, size);
  material.dispose();
  geometry.dispose();
  return data;
}

/** Relative RMS of a against b over the pixels both cover (alpha > 0), per cell. */
export function relativeRms(a, b, cells, size) {
  const per = size * size * 4;
  const out = [];
  for (let c = 0; c < cells; c += 1) {
    let num = 0;
    let den = 0;
    for (let i = c * per; i < (c + 1) * per; i += 4) {
      if (a[i + 3] > 0 && b[i + 3] > 0) {
        for (let k = 0; k < 3; k += 1) {
          num += (a[i + k] - b[i + k]) ** 2;
          den += b[i + k] ** 2;
        }
      }
    }
    out.push(Math.sqrt(num / den));
  }
  return out;
}

/**
 * The viewer's side-by-side (issue 17, item 9): on `renderer`'s canvas, the top row lit by relight's chain and the
 * bottom row by three's PMREM of the same map (MeshStandardMaterial, metalness 1, roughness 0 ... 1; ACES, sRGB);
 * returns the per-roughness relative RMS between the two (linear, sphere pixels).
 */
export function drawSideBySide(renderer, { chainBytes, halfRgb, height, width, size = 64 }) {
  const relight = chainTexture(chainBytes);
  const three = pmremTexture(renderer, halfRgb, height, width);
  const rms = relativeRms(renderMetalSpheres(renderer, relight, { size }),
    renderMetalSpheres(renderer, three, { size }), ROUGHNESS.length, size);
  renderer.setPixelRatio(1);
  renderer.setSize(ROUGHNESS.length * size, 2 * size, false);
  const toneMapping = renderer.toneMapping;
  renderer.toneMapping = THREE.ACESFilmicToneMapping;
  renderer.setClearColor(0x000000, 1);
  renderer.setScissorTest(true);
  const geometry = new THREE.SphereGeometry(1, 64, 32);
  ROUGHNESS.forEach((r, i) => {
    [relight, three].forEach((env, row) => {
      const scene = new THREE.Scene();
      const material = new THREE.MeshStandardMaterial({ color: 0xffffff, metalness: 1, roughness: r, envMap: env });
      scene.add(new THREE.Mesh(geometry, material));
      const y = row === 0 ? size : 0;
      renderer.setViewport(i * size, y, size, size);
      renderer.setScissor(i * size, y, size, size);
      renderer.clear();
      renderer.render(scene, cellCamera(0));
      material.dispose();
    });
  });
  geometry.dispose();
  renderer.setScissorTest(false);
  renderer.toneMapping = toneMapping;
  relight.dispose();
  three.dispose();
  return rms;
}
