// One object of the viewer lit by its own SHRM: coefficient textures (local layers for eq. 6, their global form
// for eq. 12), its per-frame view map, its geometry, placement (centre and bounding radius) and materials. The
// viewer (viewer.js) owns what every object shares: renderer, camera, environment, display options, and the
// uniforms of the camera and display; each object's uniforms reference those shared entries and add its own
// (model matrix, sphere, view direction in the environment's frame, textures and layer weights).
//
// A scene (POST /scenes) is several of these, each with the viewer the planner chose for it: 'distant' (the view
// direction is the one from the object's centre to the camera, the same for all its pixels: eq. 12 once per
// frame into the object's own view map) or 'near' (every pixel's own direction: eq. 6 in the shader).
import * as THREE from 'three';

import { globalLayers } from './global.js';
import { defines as layoutDefines, fromManifest, halfArray, numLayers, rgbaLayers, uniformWeights } from './layout.js';
import { rotateY } from './sh.js';

/** A full-screen triangle in clip space (fullscreen.vert.glsl). */
export function fullscreenGeometry() {
  const g = new THREE.BufferGeometry();
  const pos = new THREE.BufferAttribute(new Float32Array([-1, -1, 3, -1, -1, 3]), 2);
  g.setAttribute('a_position', pos);
  g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(9), 3)); // three.js counts vertices here
  return g;
}

/** Give a geometry the shader's attribute names (a_position, a_normal) alongside three.js's own. */
export function withShaderAttributes(geometry) {
  geometry.setAttribute('a_position', geometry.getAttribute('position'));
  if (!geometry.getAttribute('normal')) {
    geometry.computeVertexNormals();
  }
  geometry.setAttribute('a_normal', geometry.getAttribute('normal'));
  return geometry;
}

/** The proxy of an exact sphere: a box around the unit ball (object.frag.glsl intersects the ray itself). */
export function sphereProxy() {
  return withShaderAttributes(new THREE.BoxGeometry(2, 2, 2));
}

/** A float16 RGBA lat-long texture as every one here is sampled: bilinear, columns wrap, rows clamp, no mipmaps. */
export function latlongHalfTexture(tex) {
  tex.type = THREE.HalfFloatType;
  tex.format = THREE.RGBAFormat;
  tex.internalFormat = 'RGBA16F';
  tex.minFilter = THREE.LinearFilter;
  tex.magFilter = THREE.LinearFilter;
  tex.wrapS = THREE.RepeatWrapping;
  tex.wrapT = THREE.ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.needsUpdate = true;
  return tex;
}

function arrayTexture(data, layout) {
  return latlongHalfTexture(new THREE.DataArrayTexture(data, layout.width, layout.height, numLayers(layout)));
}

/**
 * The unit vector from an object's centre toward a distant viewer: the viewer's fixed view, the orthographic
 * camera's direction, or the direction from the centre to the (perspective) camera.
 */
export function objectViewDirection(viewer, center, camera) {
  const fixed = viewer.fixedView;
  if (fixed) {
    return fixed.view.slice();
  }
  const d = camera.isOrthographicCamera
    ? new THREE.Vector3(0, 0, 1).transformDirection(camera.matrixWorld)
    : new THREE.Vector3().setFromMatrixPosition(camera.matrixWorld).sub(center);
  if (!(d.lengthSq() > 0)) {
    return [0, 0, 1];
  }
  d.normalize();
  return [d.x, d.y, d.z];
}

export class ShrmObject {
  /**
   * @param viewer the ShrmViewer (shared uniforms, shader sources, renderer, options)
   * @param name a label (scene object name)
   * @param center world position of the centre; radius the bounding radius (the unit-ball geometry is scaled)
   * @param mode 'distant' | 'near' to fix this object's viewer (a scene's plan), or null for the viewer's option
   */
  constructor(viewer, { name = 'object', center = [0, 0, 0], radius = 1, mode = null } = {}) {
    if (!(radius > 0) || !Number.isFinite(radius) || !center.every(Number.isFinite)) {
      throw new RangeError(`object ${name}: needs a finite centre and a positive radius`);
    }
    if (mode !== null && mode !== 'distant' && mode !== 'near') {
      throw new RangeError(`object ${name}: mode must be 'distant', 'near' or null, got ${mode}`);
    }
    this.viewer = viewer;
    this.name = name;
    this.center = new THREE.Vector3(...center);
    this.radius = radius;
    this.mode = mode;
    this.uniforms = {
      ...viewer.uniforms, // the same {value} entries: camera, display, environment
      u_model: { value: new THREE.Matrix4() },
      u_normal_matrix: { value: new THREE.Matrix3() },
      u_sphere: { value: new THREE.Vector4(center[0], center[1], center[2], radius) },
      u_view_env: { value: new THREE.Vector3(0, 0, 1) },
      u_coefficients: { value: null },
      u_layer_weight: { value: new Float32Array(1) },
      u_view_map: { value: null },
      u_view_map_rows: { value: 1 },
    };
    // the view-map pass reads the global layers with their own weights
    this.viewMapUniforms = {
      u_coefficients: { value: null },
      u_layer_weight: { value: new Float32Array(1) },
      u_view_env: this.uniforms.u_view_env,
      u_view_map_rows: this.uniforms.u_view_map_rows,
    };
    this.layout = null;
    this.globalLayout = null;
    this.manifest = null;
    this._viewMapKey = null;
    this.viewMapTarget = null;
    this.shape = 'sphere';
    this.geometry = null;
    this._materials = new Map();

    this.mesh = new THREE.Mesh(undefined, null);
    this.mesh.frustumCulled = false;
    this.mesh.name = name;
    this.mesh.visible = false;
    this.mesh.position.copy(this.center);
    this.mesh.scale.setScalar(radius);
    this.viewMapScene = new THREE.Scene();
    this.viewMapQuad = new THREE.Mesh(fullscreenGeometry(), null);
    this.viewMapQuad.frustumCulled = false;
    this.viewMapScene.add(this.viewMapQuad);
  }

  /**
   * Load an SHRM result: its manifest and the bytes of coefficients.bin (float16 RGB layers). The layers as
   * stored (local maps, eq. 6) serve the near viewer; their global form (eq. 8, computed here once) serves the
   * distant viewer's per-frame eq. 12.
   */
  setShrm(manifest, coefficientsBuffer) {
    const layout = fromManifest(manifest);
    const halves = halfArray(coefficientsBuffer);
    this.uniforms.u_coefficients.value?.dispose();
    this.uniforms.u_coefficients.value = arrayTexture(rgbaLayers(layout, halves), layout);
    const global = globalLayers(layout, halves);
    this.globalLayout = global.layout;
    this.viewMapUniforms.u_coefficients.value?.dispose();
    this.viewMapUniforms.u_coefficients.value = arrayTexture(global.rgba, global.layout);
    this.viewMapUniforms.u_layer_weight.value = new Float32Array(numLayers(global.layout));
    this._viewMapKey = null;

    this.viewMapTarget?.dispose();
    this.viewMapTarget = new THREE.WebGLRenderTarget(2 * layout.height, layout.height * layout.components.length, {
      type: this.viewer.floatLinear ? THREE.FloatType : THREE.HalfFloatType,
      format: THREE.RGBAFormat,
      minFilter: THREE.LinearFilter,
      magFilter: THREE.LinearFilter,
      wrapS: THREE.RepeatWrapping,
      wrapT: THREE.ClampToEdgeWrapping,
      depthBuffer: false,
      generateMipmaps: false,
    });
    this.uniforms.u_view_map.value = this.viewMapTarget.texture;
    this.uniforms.u_view_map_rows.value = layout.height;
    this.uniforms.u_layer_weight.value = new Float32Array(numLayers(layout));
    this.layout = layout;
    this.manifest = manifest;
    this._disposeMaterials();
    this.viewMapQuad.material = this._material('view_map', () => this.viewer.rawMaterial('fullscreen.vert.glsl',
      'view_map.frag.glsl', layoutDefines(global.layout), { uniforms: this.viewMapUniforms }));
    this.updateMaterial();
  }

  /** 'sphere' (exact: ray-sphere intersection inside a proxy box), or a BufferGeometry in the unit ball. */
  setGeometry(nameOrGeometry, label = 'mesh') {
    const geometry = nameOrGeometry === 'sphere' ? sphereProxy() : withShaderAttributes(nameOrGeometry);
    this.shape = nameOrGeometry === 'sphere' ? 'sphere' : label;
    this.geometry?.dispose();
    this.geometry = geometry;
    this.mesh.geometry = geometry;
    this.updateMaterial();
  }

  /** 'plain', or this object's viewer: its own mode if the scene fixed one, else the viewer's option. */
  shading() {
    const o = this.viewer.options;
    return o.shading === 'plain' ? 'plain' : (this.mode || o.mode);
  }

  defines(shading, output = 'display') {
    const defs = shading === 'plain' ? {} : { ...layoutDefines(this.layout) };
    defs[{ distant: 'SHADING_VIEW_MAP', near: 'SHADING_LOCAL', plain: 'SHADING_PLAIN_ENV' }[shading]] = null;
    if (this.shape === 'sphere') {
      defs.OBJECT_SPHERE = null;
    }
    if (output === 'linear') {
      defs.OUTPUT_LINEAR = null;
    }
    return defs;
  }

  material(shading, output = 'display') {
    const key = `object:${this.shape === 'sphere' ? 'sphere' : 'mesh'}:${shading}:${output}`;
    return this._material(key, () => this.viewer.rawMaterial('object.vert.glsl', 'object.frag.glsl',
      this.defines(shading, output), { uniforms: this.uniforms }));
  }

  updateMaterial() {
    if (!this.viewer.read || !this.geometry) {
      return;
    }
    const shading = this.shading();
    const ready = shading === 'plain' ? this.uniforms.u_environment.value : this.layout;
    this.mesh.visible = !!ready;
    if (ready) {
      this.mesh.material = this.material(shading);
    }
  }

  /**
   * The unit vector from this object toward the viewer for its distant-viewer map: the fixed view, the
   * orthographic camera's direction, or the direction from the centre to the (perspective) camera.
   */
  viewDirection(camera) {
    return objectViewDirection(this.viewer, this.center, camera);
  }

  /** Per-frame uniforms: placement and, with an SHRM, the layer weights of this object's view. */
  prepare(camera, rotation) {
    this.mesh.position.copy(this.center);
    this.mesh.scale.setScalar(this.radius);
    this.mesh.updateMatrixWorld();
    const u = this.uniforms;
    u.u_model.value.copy(this.mesh.matrixWorld);
    u.u_normal_matrix.value.getNormalMatrix(this.mesh.matrixWorld);
    u.u_sphere.value.set(this.center.x, this.center.y, this.center.z, this.radius);
    const vEnv = rotateY(this.viewDirection(camera), rotation);
    u.u_view_env.value.set(...vEnv);
    if (this.layout) {
      u.u_layer_weight.value.set(uniformWeights(this.layout, vEnv));
      this.viewMapUniforms.u_layer_weight.value.set(uniformWeights(this.globalLayout, vEnv));
    }
    return vEnv;
  }

  /** Eq. 12 into this object's view map when its view (in the environment's frame) or its SHRM changed. */
  renderViewMap(renderer, camera, force = false) {
    if (!this.layout || !this.mesh.visible || this.shading() !== 'distant') {
      return false;
    }
    const key = this.uniforms.u_view_env.value.toArray().join(',');
    if (!force && key === this._viewMapKey) {
      return false;
    }
    this._viewMapKey = key;
    renderer.setRenderTarget(this.viewMapTarget);
    renderer.render(this.viewMapScene, camera);
    renderer.setRenderTarget(null);
    return true;
  }

  _material(key, make) {
    if (!this._materials.has(key)) {
      this._materials.set(key, make());
    }
    return this._materials.get(key);
  }

  _disposeMaterials() {
    for (const m of this._materials.values()) {
      m.dispose();
    }
    this._materials.clear();
  }

  dispose() {
    this._disposeMaterials();
    this.uniforms.u_coefficients.value?.dispose();
    this.viewMapUniforms.u_coefficients.value?.dispose();
    this.viewMapTarget?.dispose();
    this.geometry?.dispose();
    this.viewMapQuad.geometry.dispose();
    this.mesh.removeFromParent();
  }
}
