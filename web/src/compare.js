// Side-by-side comparison: the SHRM rendered here (linear float readback of the orthographic sphere, the
// distant-viewer path) against the server's angular-domain brute force for the same view and camera
// (GET /shrms/{id}/reference.exr, relight.reference_view.reference_sphere), with a false-colour error image.
import * as THREE from 'three';
import { EXRLoader } from 'three/addons/loaders/EXRLoader.js';

import { falseColour, relativeError, sphereMask } from './metrics.js';
import { tonemapImage } from './tonemap.js';

/** An EXR (RGB or RGBA float) as Float32Array RGB with row 0 at the top. */
export function decodeExr(buffer) {
  const loader = new EXRLoader();
  loader.setDataType(THREE.FloatType);
  const tex = loader.parse(buffer);
  const { width, height, data } = tex;
  const channels = data.length / (width * height);
  const out = new Float32Array(width * height * 3);
  for (let y = 0; y < height; y += 1) {
    const src = height - 1 - y; // EXRLoader stores the bottom row first (GL order)
    for (let x = 0; x < width; x += 1) {
      for (let c = 0; c < 3; c += 1) {
        out[(y * width + x) * 3 + c] = data[(src * width + x) * channels + c];
      }
    }
  }
  return { width, height, data: out };
}

function paint(canvas, size, rgba) {
  canvas.width = size;
  canvas.height = size;
  canvas.getContext('2d').putImageData(new ImageData(rgba, size, size), 0, 0);
}

/**
 * Run one comparison; draws into the three canvases and returns
 * {view, size, rms, max, envRows, shrm: Float32Array, reference: Float32Array}.
 */
export async function compare({ viewer, api, shrmId, size, canvases, envRows }) {
  const view = viewer.viewDirection();
  const ours = viewer.renderLinearSphere(view, size);
  const fetched = await api.reference(shrmId, view, size, envRows);
  const ref = decodeExr(fetched.data);
  if (ref.width !== size || ref.height !== size) {
    throw new Error(`the reference is ${ref.width} x ${ref.height}, expected ${size} x ${size}`);
  }
  const mask = sphereMask(size);
  const { exposure, tonemap } = viewer.options;
  paint(canvases.shrm, size, tonemapImage(ours, exposure, tonemap));
  paint(canvases.reference, size, tonemapImage(ref.data, exposure, tonemap));
  paint(canvases.error, size, falseColour(ours, ref.data, mask));
  const err = relativeError(ours, ref.data, mask);
  return { view, size, ...err, envRows: fetched.envRows, shrm: ours, reference: ref.data };
}
