// Objects for the viewer: the sample meshes (served at /samples/meshes/) and user files (OBJ, glTF/GLB), loaded in the
// browser, merged into one geometry with smooth normals and scaled into the unit ball (like relight/gl/mesh.py).
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OBJLoader } from 'three/addons/loaders/OBJLoader.js';
import { mergeGeometries, mergeVertices } from 'three/addons/utils/BufferGeometryUtils.js';

export const SAMPLE_MESHES = ['bunny', 'teapot'];

/**
 * One BufferGeometry (positions + normals, world transforms applied) from every mesh under `root`. Normals are
 * kept when every mesh has them (and `keepNormals`), else recomputed smooth (area-weighted, shared vertices).
 */
export function mergedGeometry(root, keepNormals = true) {
  const parts = [];
  root.updateMatrixWorld(true);
  root.traverse((node) => {
    if (node.isMesh && node.geometry?.getAttribute('position')) {
      const g = node.geometry.clone();
      g.applyMatrix4(node.matrixWorld);
      for (const name of Object.keys(g.attributes)) {
        if (name !== 'position' && name !== 'normal') {
          g.deleteAttribute(name);
        }
      }
      parts.push(g.index ? g.toNonIndexed() : g);
    }
  });
  if (!parts.length) {
    throw new Error('the file has no triangle meshes');
  }
  const hasNormals = keepNormals && parts.every((g) => g.getAttribute('normal'));
  if (!hasNormals) {
    parts.forEach((g) => g.deleteAttribute('normal'));
  }
  let merged = mergeGeometries(parts, false);
  if (!hasNormals) {
    merged = mergeVertices(merged, 1e-6); // share vertices so the computed normals are smooth
    merged.computeVertexNormals();
  }
  return normaliseToUnitBall(merged);
}

/** Centre on the bounding box and scale so the farthest vertex is at distance 1. */
export function normaliseToUnitBall(geometry) {
  geometry.computeBoundingBox();
  const centre = new THREE.Vector3();
  geometry.boundingBox.getCenter(centre);
  geometry.translate(-centre.x, -centre.y, -centre.z);
  const pos = geometry.getAttribute('position');
  let r = 0;
  for (let i = 0; i < pos.count; i += 1) {
    r = Math.max(r, Math.hypot(pos.getX(i), pos.getY(i), pos.getZ(i)));
  }
  if (!(r > 0)) {
    throw new Error('the mesh is empty or degenerate');
  }
  geometry.scale(1 / r, 1 / r, 1 / r);
  geometry.computeBoundingSphere();
  return geometry;
}

/** OBJ text; without `vn` lines OBJLoader makes flat face normals, so smooth ones are computed instead. */
export function parseObj(text) {
  return mergedGeometry(new OBJLoader().parse(text), /^vn\s/m.test(text));
}

export async function parseGltf(arrayBuffer) {
  const gltf = await new GLTFLoader().parseAsync(arrayBuffer, '');
  return mergedGeometry(gltf.scene);
}

/** A sample mesh by name (bunny, teapot). */
export async function loadSample(name, base = 'samples/meshes/') {
  const resp = await fetch(`${base}${name}.obj`);
  if (!resp.ok) {
    throw new Error(`mesh ${name}: HTTP ${resp.status}`);
  }
  return parseObj(await resp.text());
}

/** A user's File: .obj, .gltf or .glb. */
export async function loadFile(file) {
  const lower = file.name.toLowerCase();
  if (lower.endsWith('.obj')) {
    return parseObj(await file.text());
  }
  if (lower.endsWith('.glb') || lower.endsWith('.gltf')) {
    return parseGltf(await file.arrayBuffer());
  }
  throw new Error(`${file.name}: expected an .obj, .gltf or .glb file`);
}
