// The SHRM viewer: three.js scene, camera, controls and textures; the shading itself is web/shaders (shared with
// the server's moderngl renderer, relight/gl). Seed 000 §7.5:
//  - distant viewer (eq. 12): the layers are summed once per frame into one small S x 2S map per component for
//    the camera's view direction V (view_map.frag.glsl; Yr_pq(V) computed here on the CPU for global maps), then
//    the object looks that map up once per component at its lobe centre (R, N or T) — as cheap as plain
//    environment mapping;
//  - near viewer (eq. 6): every layer is sampled at the centre and weighted with the harmonics of the pixel's
//    own view direction, evaluated in the shader.
// P = 0 takes the same path with one layer. The environment rotates about +Y by rotating the lookups instead of
// the data (a shift of beta: nothing is recomputed).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

import { globalLayers } from './global.js';
import { defines as layoutDefines, fromManifest, halfArray, numLayers, rgbaLayers, uniformWeights } from './layout.js';
import { build, loadSources } from './shaders.js';
import { rotateY } from './sh.js';
import { TONEMAPS } from './tonemap.js';

const SHADER_FILES = ['fullscreen.vert.glsl', 'object.vert.glsl', 'object.frag.glsl', 'view_map.frag.glsl',
  'background.frag.glsl'];
const HALF_ONE = 0x3c00;

/** A full-screen triangle in clip space (fullscreen.vert.glsl). */
function fullscreenGeometry() {
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

export class ShrmViewer {
  constructor(canvas, { shaderBase = 'shaders/' } = {}) {
    this.canvas = canvas;
    this.shaderBase = shaderBase;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true, alpha: false });
    this.renderer.setPixelRatio(1);
    this.renderer.autoClear = true;
    this.renderer.setClearColor(0x000000, 1);
    const gl = this.renderer.getContext();
    this.floatLinear = !!gl.getExtension('OES_texture_float_linear') && !!gl.getExtension('EXT_color_buffer_float');

    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(35, 1, 0.05, 100);
    this.camera.position.set(0, 0.6, 3.6);
    this.orthoCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0.5, 6);
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = false;
    this.controls.minDistance = 2.0; // the sphere proxy box reaches sqrt(3)
    this.controls.maxDistance = 20;
    this.fixedView = null; // {view, orthographic} for tests and the comparison
    this.fixedSize = null; // [width, height] for tests and the benchmark

    this.options = { mode: 'distant', exposure: 0, tonemap: 'aces', rotation: 0, background: true, shading: 'shrm' };
    this.uniforms = {
      u_model: { value: new THREE.Matrix4() },
      u_view_projection: { value: new THREE.Matrix4() },
      u_normal_matrix: { value: new THREE.Matrix3() },
      u_inverse_view_projection: { value: new THREE.Matrix4() },
      u_camera_position: { value: new THREE.Vector3() },
      u_view_direction: { value: new THREE.Vector3(0, 0, 1) },
      u_view_env: { value: new THREE.Vector3(0, 0, 1) },
      u_orthographic: { value: false },
      u_env_rotation: { value: new THREE.Vector2(1, 0) },
      u_sphere: { value: new THREE.Vector4(0, 0, 0, 1) },
      u_viewport: { value: new THREE.Vector2(1, 1) },
      u_exposure: { value: 0 },
      u_tonemap: { value: TONEMAPS.aces },
      u_coefficients: { value: null },
      u_layer_weight: { value: new Float32Array(1) },
      u_view_map: { value: null },
      u_view_map_rows: { value: 1 },
      u_environment: { value: null },
    };
    // the view-map pass reads the global layers with their own weights; the other uniforms are shared
    this.viewMapUniforms = {
      u_coefficients: { value: null },
      u_layer_weight: { value: new Float32Array(1) },
      u_view_env: this.uniforms.u_view_env,
      u_view_map_rows: this.uniforms.u_view_map_rows,
    };
    this.layout = null;
    this.globalLayout = null;
    this._viewMapKey = null;
    this.read = null;
    this.objectName = 'sphere';
    this.objectGeometry = null;
    this.frameTimes = [];
    this._materials = new Map();

    this.background = new THREE.Mesh(fullscreenGeometry(), null);
    this.background.frustumCulled = false;
    this.background.renderOrder = -1;
    this.object = new THREE.Mesh(undefined, null);
    this.object.frustumCulled = false;
    this.scene.add(this.background, this.object);

    this.viewMapScene = new THREE.Scene();
    this.viewMapQuad = new THREE.Mesh(fullscreenGeometry(), null);
    this.viewMapQuad.frustumCulled = false;
    this.viewMapScene.add(this.viewMapQuad);
    this.viewMapTarget = null;
    this.environment = null;
  }

  async init() {
    this.read = await loadSources(SHADER_FILES, this.shaderBase);
    this.setObject('sphere');
    return this;
  }

  // ------------------------------------------------------------------------------------------------ data
  /**
   * Load an SHRM result: its manifest and the bytes of coefficients.bin (float16 RGB layers). The layers as
   * stored (local maps, eq. 6) serve the near viewer; their global form (eq. 8, computed here once) serves the
   * distant viewer's per-frame eq. 12.
   */
  setShrm(manifest, coefficientsBuffer) {
    const layout = fromManifest(manifest);
    const halves = halfArray(coefficientsBuffer);
    const arrayTexture = (data, lay) => {
      const tex = new THREE.DataArrayTexture(data, lay.width, lay.height, numLayers(lay));
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
    };
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
      type: this.floatLinear ? THREE.FloatType : THREE.HalfFloatType,
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
    this._disposeMaterials(false);
    this.viewMapQuad.material = this._material('view_map', () => this._raw('fullscreen.vert.glsl', 'view_map.frag.glsl',
      layoutDefines(global.layout), { uniforms: this.viewMapUniforms }));
    this._updateObjectMaterial();
  }

  /** The sharp background / baseline environment: float16 RGB lat-long texels (Uint16Array), row 0 = +Y. */
  setEnvironment(halfRgb, height, width) {
    const rgba = new Uint16Array(height * width * 4);
    for (let i = 0; i < height * width; i += 1) {
      rgba[4 * i] = halfRgb[3 * i];
      rgba[4 * i + 1] = halfRgb[3 * i + 1];
      rgba[4 * i + 2] = halfRgb[3 * i + 2];
      rgba[4 * i + 3] = HALF_ONE;
    }
    const tex = new THREE.DataTexture(rgba, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
    tex.internalFormat = 'RGBA16F';
    tex.minFilter = THREE.LinearFilter;
    tex.magFilter = THREE.LinearFilter;
    tex.wrapS = THREE.RepeatWrapping;
    tex.wrapT = THREE.ClampToEdgeWrapping;
    tex.generateMipmaps = false;
    tex.needsUpdate = true;
    this.uniforms.u_environment.value?.dispose();
    this.uniforms.u_environment.value = tex;
    this.background.material = this._material('background', () => this._raw('fullscreen.vert.glsl',
      'background.frag.glsl', {}, { depthTest: false, depthWrite: false }));
    this._updateObjectMaterial();
  }

  /** 'sphere' (exact: ray-sphere intersection inside a proxy box), or a BufferGeometry (normalised here). */
  setObject(nameOrGeometry, label = 'mesh') {
    let geometry;
    if (nameOrGeometry === 'sphere') {
      geometry = withShaderAttributes(new THREE.BoxGeometry(2, 2, 2));
      this.objectName = 'sphere';
    } else {
      geometry = withShaderAttributes(nameOrGeometry);
      this.objectName = label;
    }
    this.objectGeometry?.dispose();
    this.objectGeometry = geometry;
    this.object.geometry = geometry;
    this._updateObjectMaterial();
  }

  setOptions(options) {
    const before = this.options.mode + this.options.shading;
    Object.assign(this.options, options);
    if (before !== this.options.mode + this.options.shading) {
      this._updateObjectMaterial();
    }
  }

  // ------------------------------------------------------------------------------------------------ materials
  _raw(vertexName, fragmentName, defines, extra = {}) {
    // three.js writes "#version 300 es" itself (glslVersion GLSL3) followed by its SHADER_NAME defines, so the
    // loader's version line is dropped here; everything after it is the loader's output unchanged.
    const body = (name, defs) => build(name, { defines: defs, read: this.read }).replace(/^#version 300 es\n/, '');
    return new THREE.RawShaderMaterial({
      vertexShader: body(vertexName, {}),
      fragmentShader: body(fragmentName, defines),
      uniforms: this.uniforms,
      glslVersion: THREE.GLSL3,
      ...extra,
    });
  }

  _material(key, make) {
    if (!this._materials.has(key)) {
      this._materials.set(key, make());
    }
    return this._materials.get(key);
  }

  _disposeMaterials(all) {
    for (const [key, m] of this._materials) {
      if (all || key !== 'background') {
        m.dispose();
        this._materials.delete(key);
      }
    }
  }

  _objectDefines(shading, output = 'display') {
    const defs = shading === 'plain' ? {} : { ...layoutDefines(this.layout) };
    defs[{ distant: 'SHADING_VIEW_MAP', near: 'SHADING_LOCAL', plain: 'SHADING_PLAIN_ENV' }[shading]] = null;
    if (this.objectName === 'sphere') {
      defs.OBJECT_SPHERE = null;
    }
    if (output === 'linear') {
      defs.OUTPUT_LINEAR = null;
    }
    return defs;
  }

  _objectMaterial(shading, output = 'display') {
    const key = `object:${this.objectName === 'sphere' ? 'sphere' : 'mesh'}:${shading}:${output}`;
    return this._material(key, () => this._raw('object.vert.glsl', 'object.frag.glsl',
      this._objectDefines(shading, output)));
  }

  _shading() {
    return this.options.shading === 'plain' ? 'plain' : this.options.mode;
  }

  _updateObjectMaterial() {
    if (!this.read) {
      return;
    }
    const shading = this._shading();
    const ready = shading === 'plain' ? this.uniforms.u_environment.value : this.layout;
    this.object.visible = !!ready;
    if (ready) {
      this.object.material = this._objectMaterial(shading);
    }
  }

  // ------------------------------------------------------------------------------------------------ frames
  /** The unit vector from the target toward the camera. */
  viewDirection() {
    if (this.fixedView) {
      return this.fixedView.view.slice();
    }
    const d = this.camera.position.clone().sub(this.controls.target).normalize();
    return [d.x, d.y, d.z];
  }

  /** Fix the camera (orthographic: exactly relight.shrm.sphere_geometry's), or release it (null). */
  setFixedView(fixed) {
    if (fixed) {
      const n = Math.hypot(...fixed.view);
      if (!(n > 0) || !Number.isFinite(n)) {
        throw new RangeError(`view must be a finite non-zero vector, got ${fixed.view}`);
      }
      fixed = { ...fixed, view: fixed.view.map((x) => x / n) };
    }
    this.fixedView = fixed;
    this.controls.enabled = !fixed;
  }

  _activeCamera() {
    if (!this.fixedView) {
      return this.camera;
    }
    const v = new THREE.Vector3(...this.fixedView.view).normalize();
    const cam = this.fixedView.orthographic ? this.orthoCamera : this.camera;
    const distance = this.fixedView.orthographic ? 3 : (this.fixedView.distance ?? 3.6);
    cam.up.set(0, 1, 0);
    if (Math.abs(v.y) > 1 - 1e-9) {
      cam.up.set(0, 0, 1);
    }
    cam.position.copy(v).multiplyScalar(distance);
    cam.lookAt(0, 0, 0);
    cam.updateMatrixWorld();
    return cam;
  }

  _prepare(camera, width, height) {
    if (camera.isPerspectiveCamera) {
      camera.aspect = width / height;
    }
    camera.updateProjectionMatrix();
    camera.updateMatrixWorld();
    const u = this.uniforms;
    const v = this.viewDirection();
    const rot = -this.options.rotation;
    u.u_env_rotation.value.set(Math.cos(rot), Math.sin(rot));
    const vEnv = rotateY(v, rot);
    u.u_view_direction.value.set(...v);
    u.u_view_env.value.set(...vEnv);
    u.u_camera_position.value.setFromMatrixPosition(camera.matrixWorld);
    u.u_orthographic.value = !!camera.isOrthographicCamera;
    u.u_viewport.value.set(width, height);
    u.u_view_projection.value.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    u.u_inverse_view_projection.value.copy(u.u_view_projection.value).invert();
    this.object.updateMatrixWorld();
    u.u_model.value.copy(this.object.matrixWorld);
    u.u_normal_matrix.value.getNormalMatrix(this.object.matrixWorld);
    u.u_exposure.value = this.options.exposure;
    u.u_tonemap.value = TONEMAPS[this.options.tonemap];
    if (this.layout) {
      u.u_layer_weight.value.set(uniformWeights(this.layout, vEnv));
      this.viewMapUniforms.u_layer_weight.value.set(uniformWeights(this.globalLayout, vEnv));
    }
    return vEnv;
  }

  /** Eq. 12 into the per-frame map, when the view (in the environment's frame) or the SHRM changed. */
  _renderViewMap(force = false) {
    if (!this.layout || this._shading() !== 'distant') {
      return;
    }
    const key = this.uniforms.u_view_env.value.toArray().join(',');
    if (!force && key === this._viewMapKey) {
      return;
    }
    this._viewMapKey = key;
    const r = this.renderer;
    r.setRenderTarget(this.viewMapTarget);
    r.render(this.viewMapScene, this.orthoCamera);
    r.setRenderTarget(null);
  }

  /** One frame to the canvas; returns the CPU time spent issuing it (ms). */
  render() {
    const t0 = performance.now();
    const { width, height } = this.canvas;
    const camera = this._activeCamera();
    this._prepare(camera, width, height);
    this._renderViewMap();
    this.background.visible = this.options.background && !!this.uniforms.u_environment.value;
    this.renderer.setRenderTarget(null);
    this.renderer.render(this.scene, camera);
    return performance.now() - t0;
  }

  resize(width, height) {
    if (!this.fixedSize) {
      this.renderer.setSize(width, height, false);
    }
  }

  /** Render at exactly width x height pixels, shown 1:1 (tests, benchmark); null returns to the page's layout. */
  setFixedSize(size) {
    this.fixedSize = size;
    if (size) {
      this.renderer.setSize(size[0], size[1], false);
      this.canvas.style.width = `${size[0]}px`;
      this.canvas.style.height = `${size[1]}px`;
    } else {
      this.canvas.style.width = '';
      this.canvas.style.height = '';
      this.renderer.setSize(this.canvas.clientWidth, this.canvas.clientHeight, false);
    }
  }

  start() {
    const loop = () => {
      this.render();
      this._raf = requestAnimationFrame(loop);
    };
    loop();
  }

  stop() {
    cancelAnimationFrame(this._raf);
  }

  /** The canvas pixels, RGBA8, row 0 at the top (drawing buffer is preserved). */
  readPixels() {
    const gl = this.renderer.getContext();
    const { drawingBufferWidth: w, drawingBufferHeight: h } = gl;
    const buf = new Uint8Array(w * h * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, buf);
    const out = new Uint8Array(w * h * 4);
    for (let y = 0; y < h; y += 1) {
      out.set(buf.subarray((h - 1 - y) * w * 4, (h - y) * w * 4), y * w * 4);
    }
    return { width: w, height: h, data: out };
  }

  /**
   * Linear radiance of the unit sphere seen orthographically from `view` (relight.shrm.render_sphere's camera),
   * by the current viewer mode (distant: eq. 12, near: eq. 6): Float32Array RGB, size x size, row 0 at the top;
   * off-sphere pixels are 0.
   */
  renderLinearSphere(view, size) {
    if (!this.layout) {
      throw new Error('no SHRM loaded');
    }
    const saved = { fixed: this.fixedView, name: this.objectName, geometry: this.objectGeometry };
    const target = new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType, format: THREE.RGBAFormat,
      minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true, generateMipmaps: false });
    const sphere = withShaderAttributes(new THREE.BoxGeometry(2, 2, 2));
    try {
      this.setFixedView({ view, orthographic: true });
      this.objectName = 'sphere';
      this.object.geometry = sphere;
      const cam = this._activeCamera();
      this._prepare(cam, size, size);
      const shading = this.options.mode;
      if (shading === 'distant') {
        const keep = this.options.shading;
        this.options.shading = 'shrm';
        this._renderViewMap();
        this.options.shading = keep;
      }
      const material = this.object.material;
      this.object.material = this._objectMaterial(shading, 'linear');
      const bg = this.background.visible;
      this.background.visible = false;
      this.renderer.setRenderTarget(target);
      this.renderer.setClearColor(0x000000, 0);
      this.renderer.clear();
      this.renderer.render(this.scene, cam);
      this.renderer.setClearColor(0x000000, 1);
      const raw = new Float32Array(size * size * 4);
      this.renderer.readRenderTargetPixels(target, 0, 0, size, size, raw);
      this.background.visible = bg;
      this.object.material = material;
      const out = new Float32Array(size * size * 3);
      for (let y = 0; y < size; y += 1) {
        for (let x = 0; x < size; x += 1) {
          const s = ((size - 1 - y) * size + x) * 4;
          const d = (y * size + x) * 3;
          out[d] = raw[s];
          out[d + 1] = raw[s + 1];
          out[d + 2] = raw[s + 2];
        }
      }
      return out;
    } finally {
      this.renderer.setRenderTarget(null);
      target.dispose();
      sphere.dispose();
      this.setFixedView(saved.fixed);
      this.objectName = saved.name;
      this.object.geometry = saved.geometry;
      this._updateObjectMaterial();
    }
  }

  /**
   * Frame times (ms) over `frames` frames, each waited for with a 1-pixel read. `orbit` turns the camera by
   * `step` radians about +Y before every frame, so the distant viewer's per-frame map is recomputed every time.
   */
  benchmark(frames = 30, { orbit = true, step = 0.01 } = {}) {
    const gl = this.renderer.getContext();
    const px = new Uint8Array(4);
    const turn = () => {
      if (orbit) {
        this.camera.position.sub(this.controls.target).applyAxisAngle(new THREE.Vector3(0, 1, 0), step)
          .add(this.controls.target);
        this.camera.lookAt(this.controls.target);
      }
    };
    this.render();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const times = [];
    for (let i = 0; i < frames; i += 1) {
      turn();
      const t0 = performance.now();
      this.render();
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
      times.push(performance.now() - t0);
    }
    times.sort((a, b) => a - b);
    return { median: times[Math.floor(times.length / 2)], mean: times.reduce((a, b) => a + b, 0) / times.length,
      frames };
  }
}
