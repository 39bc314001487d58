// The Shadows panel's comparison: the service mesh drawn here with diffuse PRT (the current shading mode, a linear
// float read-back of relight.mesh_render's orthographic camera) beside Mitsuba 3's path-traced image of the same
// mesh, map, rotation and camera (GET /meshes/{id}/reference.exr: Lambertian, exact self-shadowing; issue 13 item 5),
// and a false-colour image of their difference. The numbers are the project's metric (relative RMS of Rec. 709
// luminance) over the pixels whose 3 x 3 neighbourhood the mesh covers (silhouettes excluded: Mitsuba's box filter
// averages them with the black background, the rasteriser samples the pixel centre), next to Mitsuba's own Monte
// Carlo noise, so a difference at the noise level reads as agreement.
import { decodeExr } from './compare.js';
import { falseColour, interior, relativeError } from './metrics.js';
import { tonemapImage } from './tonemap.js';

function paint(canvas, size, rgba) {
  canvas.width = size;
  canvas.height = size;
  canvas.getContext('2d').putImageData(new ImageData(rgba, size, size), 0, 0);
}

/**
 * Draw the PRT mesh and fetch Mitsuba's image for the same view; paint the three canvases and return
 * {view, size, spp, mode, rotation, rms, max, noise, pixels, ours, reference, mask}.
 */
export async function compareMesh({ viewer, api, envmapId, size, spp, canvases }) {
  const prt = viewer.prt;
  if (!prt?.meshInfo) {
    throw new Error('show a mesh first');
  }
  if (!envmapId) {
    throw new Error('load an environment map first');
  }
  const view = viewer.viewDirection();
  const rotation = viewer.options.rotation;
  const mode = prt.modes().includes(prt.mode) ? prt.mode : 'unshadowed';
  const { rgb: ours, coverage } = viewer.renderLinearPrt(view, size);
  const fetched = await api.meshReference(prt.meshInfo.id, {
    envmap: envmapId, view, size, spp, rotation: (rotation * 180) / Math.PI, albedo: prt.albedo,
  });
  const ref = decodeExr(fetched.data);
  if (ref.width !== size || ref.height !== size) {
    throw new Error(`the reference is ${ref.width} x ${ref.height}, expected ${size} x ${size}`);
  }
  const mask = interior(coverage, size);
  const { exposure, tonemap } = viewer.options;
  paint(canvases.ours, size, tonemapImage(ours, exposure, tonemap));
  paint(canvases.reference, size, tonemapImage(ref.data, exposure, tonemap));
  paint(canvases.error, size, falseColour(ours, ref.data, mask));
  const err = relativeError(ours, ref.data, mask);
  const pixels = mask.reduce((a, b) => a + b, 0);
  return { view, size, spp, mode, rotation, ...err, noise: fetched.noise, pixels, ours, reference: ref.data,
    mask };
}
