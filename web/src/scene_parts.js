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
//  - ShTablePart: seed 003's per-view SH table of an anisotropic lobe (sh_table.vert.glsl in its 'general' mode,
//    the GLSL of sh_table.js's SHTableGL and relight.gl.sh_table: per vertex the lighting rotated into the vertex's
//    tangent frame, dotted with the table's coefficients at the local view), on the plan's shared sh_table job;
//    the tangent field is the object's (sh_lights.js tangentField), the environment's rotation turns the lighting.
// An object whose lobes have several representations is several parts: the first opaque, the others added
// (additive blending on the same geometry, drawn where the first part's depth is).
import * as THREE from 'three';

import { gaussianDefines, lobeTexels, packLobes } from './gaussian.js';
import { InOutObject } from './inout_object.js';
import { projectLatlongHalf, rotateLightingY } from './prt.js';
import { PrtObject } from './prt_object.js';
import { build } from './shaders.js';
import { shCount } from './sh.js';
import { tangentField } from './sh_lights.js';
import { shaderDefines } from './sh_table.js';
import { latlongHalfTexture, objectViewDirection, withShaderAttributes } from './shrm_object.js';

/** The viewer's geometry for a part: a tessellated unit sphere (normals exact at the vertices) or the mesh. */
export function partGeometry(geometry) {
  return withShaderAttributes(geometry === 'sphere' || geometry === 'sphere-mesh' || !geometry ? new THREE.SphereGeometry(1, 128, 64)
    : geometry.clone());
}

/** gaussian.glsl's u_lobes: the material's lobes packed (gaussian.js packLobes), one row per elevation. */
function lobeTexture(material) {
  const tex = new THREE.DataTexture(packLobes(material), lobeTexels(material.lobes), material.elevations.length,
    THREE.RGBAFormat, THREE.HalfFloatType);
  tex.internalFormat = 'RGBA16F';
  tex.minFilter = THREE.LinearFilter; // gaussian.glsl: one filtered lookup interpolates the elevations
  tex.magFilter = THREE.LinearFilter;
  tex.wrapS = THREE.ClampToEdgeWrapping;
  tex.wrapT = THREE.ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.flipY = false;
  tex.needsUpdate = true;
  return tex;
}

/** Make a part's material the added one of a several-part object (see the module comment). */
function additive(material) {
  material.blending = THREE.AdditiveBlending;
  material.depthFunc = THREE.LessEqualDepth;
  material.depthWrite = false;
  return material;
}

class Part {
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

export class GaussianPart extends Part {
  /**
   * @param item {name, center, radius, shape, geometry ('sphere' or a BufferGeometry in the unit ball), material
   *   (gaussian_panel.js's materialFromLobes), chain (gaussian.js's chainFromLevels), added (bool)}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'gaussian_lobes';
    const { material, chain } = item;
    const n = material.elevations.length;
    const rgba = new Uint16Array(chain.levels.length * chain.height * chain.width * 4);
    chain.levels.forEach((lv, j) => rgba.set(lv, j * chain.height * chain.width * 4));
    // the levels as the slices of a 3-D texture, filtered across them too (gaussian.glsl, gaussian.js uploadChain)
    const chainTex = latlongHalfTexture(new THREE.Data3DTexture(rgba, chain.width, chain.height, chain.levels.length));
    chainTex.wrapR = THREE.ClampToEdgeWrapping;
    this.textures = [lobeTexture(material), chainTex];
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
      u_elevations: { value: Array.from(material.elevations) },
      u_chain_sigma0: { value: chain.sigma0 },
      u_chain_log_ratio: { value: chain.levels.length > 1 ? Math.log(chain.ratio) : 1.0 },
    };
    this.defines = { ...gaussianDefines({ lobes: material.lobes, elevations: n, levels: chain.levels.length,
      linear: false }), GAUSSIAN_MODEL: null };
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

/**
 * A scene sh_table job's table.bin (float16 [(F+1)^2, R, R, C], C = 1 or 3) as RGBA float16 texels, layer-major:
 * the layers of sh_table.vert.glsl's u_table (alpha unused).
 */
export function tableRgba(half, manifest) {
  const [n, rows, cols, channels] = manifest.files['table.bin'].shape;
  if (half.length !== n * rows * cols * channels || (channels !== 1 && channels !== 3)) {
    throw new Error(`SH table data holds ${half.length} values, expected ${n} x ${rows} x ${cols} x (1 or 3)`);
  }
  const texels = n * rows * cols;
  const out = new Uint16Array(4 * texels);
  for (let k = 0; k < texels; k += 1) {
    for (let c = 0; c < 3; c += 1) {
      out[4 * k + c] = half[channels * k + (channels === 3 ? c : 0)];
    }
  }
  return out;
}

export class ShTablePart extends Part {
  /**
   * @param item {name, center, radius, shape, geometry, table (the job's P.table.json), tableBuffer, tangent (the
   *   object's tangent spec, sh_lights.js tangentField's; default azimuthal about +Y), added}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'sh_table';
    const { table } = item;
    this.order = table.order;
    const [n, rows, cols] = table.files['table.bin'].shape;
    if (n !== shCount(this.order) || rows !== table.resolution || cols !== table.resolution) {
      throw new Error(`object ${item.name}: its SH table's shape does not match order ${this.order}`);
    }
    const tex = new THREE.DataArrayTexture(tableRgba(new Uint16Array(item.tableBuffer), table), cols, rows, n);
    tex.type = THREE.HalfFloatType;
    tex.format = THREE.RGBAFormat;
    tex.internalFormat = 'RGBA16F';
    tex.minFilter = THREE.LinearFilter; // bilinear over the view map, clamped (sh_table.js SHTableGL)
    tex.magFilter = THREE.LinearFilter;
    tex.wrapS = THREE.ClampToEdgeWrapping;
    tex.wrapT = THREE.ClampToEdgeWrapping;
    tex.generateMipmaps = false;
    tex.flipY = false;
    tex.needsUpdate = true;
    this.texture = tex;
    const shared = viewer.uniforms;
    this.uniforms = {
      u_view_projection: { value: new THREE.Matrix4() }, // the viewer's times this part's placement (prepare)
      u_exposure: shared.u_exposure,
      u_tonemap: shared.u_tonemap,
      u_view: { value: new THREE.Vector3(0, 0, 1) },
      u_light: { value: [] },
      u_table: { value: tex },
    };
    this.lighting = null;
    this.layout = table.layout;
    this.added = !!item.added;
    this._materials = new Map();
    const geometry = partGeometry(item.geometry);
    const normals = geometry.getAttribute('normal').array;
    geometry.setAttribute('a_tangent', new THREE.BufferAttribute(tangentField(normals, item.tangent
      || { kind: 'azimuthal' }), 4));
    this.mesh = new THREE.Mesh(geometry, this.material('display'));
    this.mesh.name = item.name;
    this.mesh.frustumCulled = false; // placed by u_view_projection, not three.js's object matrix
    this.mesh.renderOrder = this.added ? 1 : 0;
  }

  /** 'display' (tonemapped, the canvas) or 'linear' (radiance, float targets). */
  material(output) {
    if (!this._materials.has(output)) {
      const defines = shaderDefines(this.order, this.layout, 'general');
      const body = (name, defs) => build(name, { defines: defs, read: this.viewer.read })
        .replace(/^#version 300 es\n/, '');
      const m = new THREE.RawShaderMaterial({ vertexShader: body('sh_table.vert.glsl', defines),
        fragmentShader: body('sh_table.frag.glsl', output === 'linear' ? { OUTPUT_LINEAR: null } : {}),
        uniforms: this.uniforms, glslVersion: THREE.GLSL3 });
      this._materials.set(output, this.added ? additive(m) : m);
    }
    return this._materials.get(output);
  }

  /** Project the viewer's current environment (its float16 lat-long) to the table's order. */
  updateMaterial() {
    const env = this.viewer.environment;
    this.lighting = env ? projectLatlongHalf(env.halfRgb, env.height, env.width, this.order) : null;
  }

  /** Per frame: placement, the lighting turned with the environment (as PrtPart), the view from the centre. */
  prepare(camera, rotation) {
    if (!this.lighting) {
      this.updateMaterial();
    }
    const model = new THREE.Matrix4().makeScale(this.radius, this.radius, this.radius).setPosition(this.center);
    this.uniforms.u_view_projection.value.multiplyMatrices(this.viewer.uniforms.u_view_projection.value, model);
    this.uniforms.u_view.value.set(...objectViewDirection(this.viewer, this.center, camera)).normalize();
    const light = this.uniforms.u_light.value;
    const n = shCount(this.order);
    const rot = this.lighting ? rotateLightingY(this.lighting, this.order, -rotation) : new Float64Array(3 * n);
    light.length = n;
    for (let k = 0; k < n; k += 1) {
      light[k] = (light[k] || new THREE.Vector3()).set(rot[3 * k], rot[3 * k + 1], rot[3 * k + 2]);
    }
  }

  /** The lighting of the last prepare() (n x 3 floats, for tests). */
  currentLighting() {
    return this.uniforms.u_light.value.map((v) => [v.x, v.y, v.z]);
  }

  dispose() {
    this._materials.forEach((m) => m.dispose());
    this.texture.dispose();
    this.mesh.geometry.dispose();
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
