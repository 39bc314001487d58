// A scene object drawn with a representation other than seed 000's SHRM (issue 16 item 4: "the viewer draws the
// whole scene, each object with its chosen representation"). Each part has what the viewer asks of a scene object
// (shrm_object.js's ShrmObject): name, center, radius, mode, shape, mesh, prepare(camera, rotation),
// renderViewMap(), updateMaterial(), dispose().
//  - GaussianPart: seed 002's Gaussian lobes (web/shaders/gaussian.vert.glsl / gaussian.frag.glsl, the shaders of
//    the Gaussian panel and of relight.gl.gaussian) with the plan's shared chain; a distant viewer (the direction
//    from the object's centre to the camera), the environment's rotation turning the normals.
//  - PrtPart: the diffuse transfer of a Lambertian mesh with shadows (prt_object.js's PrtObject in its transfer
//    mode: albedo T . L per vertex), placed at the object's centre and radius.
//  - InOutPart: seed 004's in-out PRT of a glossy mesh with shadows (inout_object.js's InOutObject on the plan's
//    shared inout_transport job: K terms, view and lighting dynamic), placed likewise.
//  - ShTablePart, PrtMatrixPart: seed 003's SH tables without and with shadows (scene_table_parts.js).
// An object whose lobes have several representations is several parts: the first opaque, the others added
// (additive blending on the same geometry, drawn where the first part's depth is).
import * as THREE from 'three';

import { gaussianDefines, lobeTable, lobeTexels } from './gaussian.js';
import { InOutObject } from './inout_object.js';
import { PrtObject } from './prt_object.js';
import { build } from './shaders.js';
import { additive, Part, partGeometry } from './scene_part_base.js';
import { PrtMatrixPart, ShTablePart } from './scene_table_parts.js';
import { latlongHalfTexture, objectViewDirection } from './shrm_object.js';

export { partGeometry } from './scene_part_base.js';
export { PrtMatrixPart, ShTablePart, tableRgba } from './scene_table_parts.js';

/** gaussian.glsl's u_lobes: the material's lobe table (gaussian.js lobeTable), RGBA32UI read with texelFetch. */
function lobeTexture(table) {
  const tex = new THREE.DataTexture(table.words, lobeTexels(table.lobes), table.rows, THREE.RGBAIntegerFormat,
    THREE.UnsignedIntType);
  tex.internalFormat = 'RGBA32UI';
  tex.minFilter = THREE.NearestFilter;
  tex.magFilter = THREE.NearestFilter;
  tex.wrapS = THREE.ClampToEdgeWrapping;
  tex.wrapT = THREE.ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.flipY = false;
  tex.needsUpdate = true;
  return tex;
}

export class GaussianPart extends Part {
  /**
   * @param item {name, center, radius, shape, geometry ('sphere' or a BufferGeometry in the unit ball), material
   *   (gaussian_panel.js's materialFromLobes), chain (gaussian.js's chainFromLevels), added (bool)}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'gaussian_lobes';
    const { material, chain } = item;
    const table = lobeTable(material);
    const rgba = new Uint16Array(chain.levels.length * chain.height * chain.width * 4);
    chain.levels.forEach((lv, j) => rgba.set(lv, j * chain.height * chain.width * 4));
    // the levels as the slices of a 3-D texture, filtered across them too (gaussian.glsl, gaussian.js uploadChain)
    const chainTex = latlongHalfTexture(new THREE.Data3DTexture(rgba, chain.width, chain.height, chain.levels.length));
    chainTex.wrapR = THREE.ClampToEdgeWrapping;
    this.textures = [lobeTexture(table), chainTex];
    const shared = viewer.uniforms;
    this.uniforms = {
      u_view_projection: shared.u_view_projection,
      u_exposure: shared.u_exposure,
      u_tonemap: shared.u_tonemap,
      u_model: { value: new THREE.Matrix4() },
      u_normal_env: { value: new THREE.Matrix3() },
      u_view_direction: { value: new THREE.Vector3(0, 0, 1) },
      u_lobes: { value: this.textures[0] },
      u_chain: { value: this.textures[1] },
      ...(table.grid ? { u_lobe_grid: { value: new THREE.Vector2(...table.grid) } }
        : { u_elevations: { value: Array.from(table.elevations) } }),
      u_chain_sigma0: { value: chain.sigma0 },
      u_chain_log_ratio: { value: chain.levels.length > 1 ? Math.log(chain.ratio) : 1.0 },
    };
    this.defines = { ...gaussianDefines({ table, levels: chain.levels.length, linear: false }), GAUSSIAN_MODEL: null };
    this.added = !!item.added;
    this._materials = new Map();
    this.mesh = new THREE.Mesh(partGeometry(item.geometry), this.material('display'));
    this.mesh.name = item.name;
    this.mesh.frustumCulled = false;
    this.mesh.renderOrder = this.added ? 1 : 0;
  }

  /** 'display' (tonemapped, the canvas) or 'linear' (radiance, float targets). */
  material(output) {
    if (!this._materials.has(output)) {
      const defs = output === 'linear' ? { ...this.defines, OUTPUT_LINEAR: null } : this.defines;
      const body = (name) => build(name, { defines: defs, read: this.viewer.read }).replace(/^#version 300 es\n/, '');
      const m = new THREE.RawShaderMaterial({ vertexShader: body('gaussian.vert.glsl'),
        fragmentShader: body('gaussian.frag.glsl'), uniforms: this.uniforms, glslVersion: THREE.GLSL3 });
      this._materials.set(output, this.added ? additive(m) : m);
    }
    return this._materials.get(output);
  }

  /** Per frame: placement, the normals' turn into the environment's frame, the view from the centre. */
  prepare(camera, rotation) {
    this.uniforms.u_model.value.makeScale(this.radius, this.radius, this.radius).setPosition(this.center);
    const c = Math.cos(rotation);
    const s = Math.sin(rotation);
    this.uniforms.u_normal_env.value.set(c, 0, s, 0, 1, 0, -s, 0, c); // sh.js rotateY(d, rotation)
    const v = objectViewDirection(this.viewer, this.center, camera);
    this.uniforms.u_view_direction.value.set(c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]);
  }

  dispose() {
    this._materials.forEach((m) => m.dispose());
    this.textures.forEach((t) => t.dispose());
    this.mesh.geometry.dispose();
    this.mesh.removeFromParent();
  }
}

export class PrtPart extends Part {
  /**
   * @param item {name, center, radius, shape, prt (the object's {name}.prt.json), geometryBuffer, transferBuffer,
   *   albedo, added}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'diffuse_transfer';
    this.prt = new PrtObject(viewer);
    this.prt.albedo = item.albedo ?? this.prt.albedo;
    this.prt.setPlacement(item.center, item.radius);
    this.prt.setMesh({ geometry: item.prt.geometry, bounds: item.prt.bounds,
      bounding_radius: item.prt.bounding_radius }, item.geometryBuffer);
    this.prt.setVisibility(item.prt, { 'transfer.bin': item.transferBuffer });
    this.prt.setMode('transfer');
    this.added = !!item.added;
    this.mesh = this.prt.mesh;
    this.mesh.name = item.name;
    this.mesh.visible = true;
    this.mesh.renderOrder = this.added ? 1 : 0;
    this.updateMaterial();
  }

  /** 'transfer' (shadowed, as planned) or 'unshadowed' (the same lighting without visibility: for comparisons). */
  setMode(mode) {
    this.prt.setMode(mode);
    this.updateMaterial();
  }

  material(output) {
    const m = this.prt.material(this.prt.mode, output);
    return this.added ? additive(m) : m;
  }

  updateMaterial() {
    if (!this.prt.lighting) {
      this.prt.updateLighting();
    }
    this.mesh.material = this.material('display');
  }

  prepare(camera, rotation) {
    this.prt.setPlacement(this.center.toArray(), this.radius);
    this.prt.prepare(-rotation); // the viewer passes -options.rotation; PrtObject takes the environment's turn
  }

  dispose() {
    this.prt.dispose();
    this.mesh.removeFromParent();
  }
}

export class InOutPart extends Part {
  /**
   * @param item {name, center, radius, shape, inout (the job's P.inout.json), geometryBuffer, transportBuffer,
   *   factorsBuffer, added}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'inout_prt';
    this.inout = new InOutObject(viewer);
    this.inout.read = viewer.read;
    this.inout.setPlacement(item.center, item.radius);
    this.inout.setMesh({ geometry: item.inout.geometry, bounds: item.inout.bounds,
      bounding_radius: item.inout.bounding_radius }, item.geometryBuffer);
    this.inout.setData(item.inout, { 'transport.bin': item.transportBuffer, 'factors.bin': item.factorsBuffer });
    this.added = !!item.added;
    this.mesh = this.inout.mesh;
    this.mesh.name = item.name;
    this.mesh.visible = true;
    this.mesh.renderOrder = this.added ? 1 : 0;
    this.updateMaterial();
  }

  material(output) {
    const m = this.inout.material('inout', output);
    return this.added ? additive(m) : m;
  }

  updateMaterial() {
    this.mesh.material = this.material('display');
  }

  prepare(camera, rotation) {
    this.inout.setPlacement(this.center.toArray(), this.radius);
    this.inout.prepare(-rotation); // as PrtPart
  }

  dispose() {
    this.inout.dispose();
    this.mesh.removeFromParent();
  }
}

/** The part of one scene item (sceneItems in scene.js): by its representation. */
export function makePart(viewer, item) {
  if (item.kind === 'gaussian_lobes') {
    return new GaussianPart(viewer, item);
  }
  if (item.kind === 'diffuse_transfer') {
    return new PrtPart(viewer, item);
  }
  if (item.kind === 'inout_prt') {
    return new InOutPart(viewer, item);
  }
  if (item.kind === 'sh_table') {
    return new ShTablePart(viewer, item);
  }
  if (item.kind === 'prt_matrix') {
    return new PrtMatrixPart(viewer, item);
  }
  throw new Error(`scene object ${item.name}: no part for representation ${item.kind}`);
}

/**
 * Linear radiance of one scene part alone, moved to the origin with radius 1 and seen orthographically from
 * `view` (relight.mesh_render's and relight.sg_render's camera: the unit ball looked at from 3 V), the environment
 * turned by the viewer's rotation: {rgb: Float32Array RGB, coverage: Uint8Array}, size x size, row 0 at the top.
 * For tests (the CPU twins render the same part).
 */
export function renderPartLinear(viewer, part, view, size) {
  const saved = { center: part.center.clone(), radius: part.radius, material: part.mesh.material,
    visible: viewer.sceneObjects.map((o) => o.mesh.visible), fixed: viewer.fixedView,
    target: viewer.sceneTarget.clone(), bg: viewer.background.visible };
  const target = new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType, format: THREE.RGBAFormat,
    minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true, generateMipmaps: false });
  try {
    viewer.sceneObjects.forEach((o) => { o.mesh.visible = o === part; });
    part.center.set(0, 0, 0);
    part.radius = 1;
    viewer.sceneTarget.set(0, 0, 0);
    viewer.setFixedView({ view, orthographic: true });
    const cam = viewer._activeCamera();
    viewer._prepare(cam, size, size);
    part.mesh.material = part.material('linear');
    viewer.background.visible = false;
    return viewer._drawLinear(target, cam, size);
  } finally {
    viewer.renderer.setRenderTarget(null);
    target.dispose();
    part.center.copy(saved.center);
    part.radius = saved.radius;
    part.mesh.material = saved.material;
    viewer.sceneObjects.forEach((o, k) => { o.mesh.visible = saved.visible[k]; });
    viewer.setFixedView(saved.fixed);
    viewer.sceneTarget.copy(saved.target);
    viewer.background.visible = saved.bg;
  }
}
