// What every part of a scene object shares (scene_parts.js, scene_table_parts.js: issue 16 item 4): its geometry on
// the unit sphere or a mesh, the additive blending of an object's parts after its first, and the Part base class
// (what the viewer asks of a scene object: name, center, radius, mode, shape; see scene_parts.js).
import * as THREE from 'three';

import { withShaderAttributes } from './shrm_object.js';

/** The viewer's geometry for a part: a tessellated unit sphere (normals exact at the vertices) or the mesh. */
export function partGeometry(geometry) {
  return withShaderAttributes(geometry === 'sphere' || geometry === 'sphere-mesh' || !geometry ? new THREE.SphereGeometry(1, 128, 64)
    : geometry.clone());
}

/** Make a part's material the added one of a several-part object (see the module comment). */
export function additive(material) {
  material.blending = THREE.AdditiveBlending;
  material.depthFunc = THREE.LessEqualDepth;
  material.depthWrite = false;
  return material;
}

export class Part {
  constructor(viewer, { name, center, radius, shape }) {
    if (!(radius > 0) || !Number.isFinite(radius) || !center.every(Number.isFinite)) {
      throw new RangeError(`object ${name}: needs a finite centre and a positive radius`);
    }
    this.viewer = viewer;
    this.name = name;
    this.center = new THREE.Vector3(...center);
    this.radius = radius;
    this.mode = 'distant';
    this.shape = shape;
  }

  renderViewMap() {
    return false;
  }

  updateMaterial() {}
}

