// The SHRM viewer: three.js scene, camera, controls and textures; the shading itself is web/shaders (shared with
// the server's moderngl renderer, relight/gl). Seed 000 §7.5:
//  - distant viewer (eq. 12): the layers are summed once per frame into one small S x 2S map per component for
//    the camera's view direction V (view_map.frag.glsl; Yr_pq(V) computed here on the CPU for global maps), then
//    the object looks that map up once per component at its lobe centre (R, N or T) — as cheap as plain
//    environment mapping;
//  - near viewer (eq. 6): every layer is sampled at the centre and weighted with the harmonics of the pixel's
//    own view direction, evaluated in the shader.
// P = 0 takes the same path with one layer. The environment rotates about +Y by rotating the lookups instead of
// the data (a shift of beta: nothing is recomputed). Per-object state (textures, view map, placement) lives in
// shrm_object.js: one object at the origin for the current material, or a scene's objects (setSceneObjects), each
// with its own SHRM and the viewer its plan chose.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

import { makePart, partGeometry } from './scene_parts.js';
import { build, loadSources } from './shaders.js';
import {
  fullscreenGeometry, latlongHalfTexture, ShrmObject, sphereProxy, withShaderAttributes,
} from './shrm_object.js';
import { TONEMAPS } from './tonemap.js';

export { withShaderAttributes };

const SHADER_FILES = ['fullscreen.vert.glsl', 'object.vert.glsl', 'object.frag.glsl', 'view_map.frag.glsl',
  'background.frag.glsl', 'prt.vert.glsl', 'sh_table.frag.glsl', 'gaussian.vert.glsl', 'gaussian.frag.glsl',
  'inout.vert.glsl', 'sh_table.vert.glsl'];
const HALF_ONE = 0x3c00;
const ORBIT_MIN_DISTANCE = 2.0; // the unit sphere's proxy box reaches sqrt(3)

/** A size x size float RGBA render target for linear read-backs. */
function linearTarget(size) {
  return new THREE.WebGLRenderTarget(size, size, { type: THREE.FloatType, format: THREE.RGBAFormat,
    minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter, depthBuffer: true, generateMipmaps: false });
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
    this.controls.minDistance = ORBIT_MIN_DISTANCE;
    this.controls.maxDistance = 20;
    this.fixedView = null; // {view, orthographic, distance} for tests and the comparison
    this.fixedSize = null; // [width, height] for tests and the benchmark

    this.options = { mode: 'distant', exposure: 0, tonemap: 'aces', rotation: 0, background: true, shading: 'shrm' };
    // uniforms every object shares (camera, display, environment); each ShrmObject adds its own
    this.uniforms = {
      u_view_projection: { value: new THREE.Matrix4() },
      u_inverse_view_projection: { value: new THREE.Matrix4() },
      u_camera_position: { value: new THREE.Vector3() },
      u_view_direction: { value: new THREE.Vector3(0, 0, 1) },
      u_orthographic: { value: false },
      u_env_rotation: { value: new THREE.Vector2(1, 0) },
      u_viewport: { value: new THREE.Vector2(1, 1) },
      u_exposure: { value: 0 },
      u_tonemap: { value: TONEMAPS.aces },
      u_environment: { value: null },
    };
    this.read = null;
    this.frameTimes = [];
    this._materials = new Map();

    this.background = new THREE.Mesh(fullscreenGeometry(), null);
    this.background.frustumCulled = false;
    this.background.renderOrder = -1;
    this.scene.add(this.background);
    // the single-object view (the current material's SHRM on the sphere or a mesh at the origin) ...
    this.primary = new ShrmObject(this, { name: 'object' });
    this.scene.add(this.primary.mesh);
    // ... or a scene's objects, each with its own SHRM (setSceneObjects)
    this.sceneObjects = [];
    this.sceneTarget = new THREE.Vector3();
    this.sceneHalfAngles = [0, 0]; // largest angles of the scene's objects off the view axis, horizontal, vertical
    this.environment = null; // {halfRgb, height, width}: the map shown, also projected for PRT lighting
    this.prt = null; // a PrtObject (prt_object.js) shown instead of the single object, or null
  }

  async init() {
    this.read = await loadSources(SHADER_FILES, this.shaderBase);
    this.setObject('sphere');
    return this;
  }

  /** The objects drawn now: a scene's, or the single object. */
  get objects() {
    return this.sceneObjects.length ? this.sceneObjects : [this.primary];
  }

  get layout() {
    return this.primary.layout;
  }

  get manifest() {
    return this.primary.manifest;
  }

  get objectName() {
    return this.primary.shape;
  }

  // ------------------------------------------------------------------------------------------------ data
  /** Load the single object's SHRM: its result manifest and the bytes of coefficients.bin (ShrmObject.setShrm). */
  setShrm(manifest, coefficientsBuffer) {
    this.primary.setShrm(manifest, coefficientsBuffer);
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
    const tex = latlongHalfTexture(new THREE.DataTexture(rgba, width, height));
    this.environment = { halfRgb, height, width };
    this.prt?.updateLighting();
    this.uniforms.u_environment.value?.dispose();
    this.uniforms.u_environment.value = tex;
    this.background.material = this._material('background', () => this.rawMaterial('fullscreen.vert.glsl',
      'background.frag.glsl', {}, { depthTest: false, depthWrite: false }));
    this._updateMaterials();
  }

  /** The single object: 'sphere' (exact: ray-sphere intersection inside a proxy box), or a BufferGeometry. */
  setObject(nameOrGeometry, label = 'mesh') {
    this.setPrt(null);
    this.primary.setGeometry(nameOrGeometry, label);
  }

  /** Show a PrtObject (a service mesh with diffuse PRT) instead of the single object; null returns to it. */
  setPrt(prt) {
    if (this.prt && this.prt !== prt) {
      this.scene.remove(this.prt.mesh);
    }
    this.prt = prt;
    if (prt) {
      this.scene.add(prt.mesh);
      prt.mesh.visible = true;
    }
    this.primary.mesh.visible = !prt && !this.sceneObjects.length;
  }

  /**
   * Show a scene: several objects, each `{name, shape, center: [x, y, z], radius, mode: 'distant' | 'near',
   * geometry: 'sphere' | BufferGeometry (in the unit ball), manifest, buffer}` (its SHRM as ShrmObject.setShrm
   * takes it), or an item of another representation (`kind`: scene_parts.js's makePart).
   * The viewer stands at `eye` (the scene's viewer, the origin) and looks at the nearest object, with a field of
   * view wide enough for all of them. An empty list returns to the single object.
   */
  setSceneObjects(items, { eye = [0, 0, 0] } = {}) {
    if (items.length) {
      this.setPrt(null);
    }
    const made = [];
    try {
      for (const it of items) {
        if (it.kind && it.kind !== 'shrm') {
          made.push(makePart(this, it));
          continue;
        }
        const obj = new ShrmObject(this, { name: it.name, center: it.center, radius: it.radius,
          mode: it.mode ?? null });
        made.push(obj);
        const geometry = it.geometry === 'sphere-mesh' ? partGeometry('sphere') : it.geometry;
        obj.setGeometry(geometry ?? 'sphere', it.shape ?? it.name);
        obj.setShrm(it.manifest, it.buffer);
      }
    } catch (err) {
      made.forEach((o) => o.dispose());
      throw err;
    }
    this.sceneObjects.forEach((o) => o.dispose());
    this.sceneObjects = made;
    made.forEach((o) => this.scene.add(o.mesh));
    this.primary.mesh.visible = !made.length && !this.prt;
    if (!made.length) {
      this.primary.updateMaterial();
      this._frameSingle();
      return;
    }
    this._frameScene(new THREE.Vector3(...eye));
  }

  clearScene() {
    this.setSceneObjects([]);
  }

  _frameSingle() {
    this.camera.fov = 35;
    this.camera.near = 0.05;
    this.camera.far = 100;
    this.camera.position.set(0, 0.6, 3.6);
    this.sceneTarget.set(0, 0, 0);
    this.controls.target.set(0, 0, 0);
    this.controls.minDistance = ORBIT_MIN_DISTANCE;
    this.controls.maxDistance = 20;
    this.camera.lookAt(0, 0, 0);
    this.controls.update();
  }

  /**
   * Camera at `eye` looking at the nearest object, with a field of view that holds every object (see _fitFov;
   * at most 100 degrees vertically).
   */
  _frameScene(eye) {
    const objs = this.sceneObjects;
    const dist = (o) => o.center.distanceTo(eye);
    const nearest = objs.reduce((a, b) => (dist(b) < dist(a) ? b : a));
    this.camera.position.copy(eye);
    this.camera.up.set(0, 1, 0);
    this.camera.lookAt(nearest.center);
    this.camera.updateMatrixWorld();
    const toCamera = this.camera.matrixWorldInverse;
    let x = 0;
    let y = 0;
    let far = 0;
    for (const o of objs) {
      const d = dist(o);
      const c = o.center.clone().applyMatrix4(toCamera); // camera looks down -Z
      const a = Math.asin(Math.min(1, o.radius / d));
      x = Math.max(x, Math.atan2(Math.abs(c.x), -c.z) + a);
      y = Math.max(y, Math.atan2(Math.abs(c.y), -c.z) + a);
      far = Math.max(far, d + o.radius);
    }
    this.sceneHalfAngles = [Math.min(x, 1.45), Math.min(y, 1.45)];
    const closest = Math.min(...objs.map((o) => dist(o) - o.radius));
    this.camera.near = Math.max(1e-3, 0.5 * closest);
    this.camera.far = 2 * far;
    this.sceneTarget.copy(nearest.center);
    this.controls.target.copy(nearest.center);
    this.controls.minDistance = 1.1 * nearest.radius;
    this.controls.maxDistance = 2 * far;
    this.controls.update();
  }

  /** A scene's vertical field of view for this aspect: its objects' half-angles (x, y) with a 15 % margin. */
  _fitFov(aspect) {
    const [hx, hy] = this.sceneHalfAngles;
    const t = 1.15 * Math.max(Math.tan(hy), Math.tan(hx) / aspect);
    this.camera.fov = Math.min(100, Math.max(20, (2 * Math.atan(t) * 180) / Math.PI));
  }

  setOptions(options) {
    const before = this.options.mode + this.options.shading;
    Object.assign(this.options, options);
    if (before !== this.options.mode + this.options.shading) {
      this._updateMaterials();
    }
  }

  // ------------------------------------------------------------------------------------------------ materials
  /** A RawShaderMaterial of the loader's shaders (web/shaders) with `defines`; uniforms default to the shared ones. */
  rawMaterial(vertexName, fragmentName, defines, extra = {}) {
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

  _updateMaterials() {
    this.primary.updateMaterial();
    this.sceneObjects.forEach((o) => o.updateMaterial());
    if (this.sceneObjects.length || this.prt) {
      this.primary.mesh.visible = false;
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
    cam.position.copy(v).multiplyScalar(distance).add(this.sceneTarget);
    cam.lookAt(this.sceneTarget);
    cam.updateMatrixWorld();
    return cam;
  }

  _prepare(camera, width, height) {
    if (camera.isPerspectiveCamera) {
      camera.aspect = width / height;
      if (this.sceneObjects.length && camera === this.camera) {
        this._fitFov(camera.aspect);
      }
    }
    camera.updateProjectionMatrix();
    camera.updateMatrixWorld();
    const u = this.uniforms;
    const rot = -this.options.rotation;
    u.u_env_rotation.value.set(Math.cos(rot), Math.sin(rot));
    u.u_view_direction.value.set(...this.viewDirection());
    u.u_camera_position.value.setFromMatrixPosition(camera.matrixWorld);
    u.u_orthographic.value = !!camera.isOrthographicCamera;
    u.u_viewport.value.set(width, height);
    u.u_view_projection.value.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    u.u_inverse_view_projection.value.copy(u.u_view_projection.value).invert();
    u.u_exposure.value = this.options.exposure;
    u.u_tonemap.value = TONEMAPS[this.options.tonemap];
    for (const o of this.objects) {
      o.prepare(camera, rot);
    }
    this.prt?.prepare(this.options.rotation);
  }

  /** Eq. 12 into each distant-viewer object's map, when its view (in the environment's frame) or SHRM changed. */
  _renderViewMaps(force = false) {
    let n = 0;
    for (const o of this.objects) {
      n += o.renderViewMap(this.renderer, this.orthoCamera, force) ? 1 : 0;
    }
    return n;
  }

  /** One frame to the canvas; returns the CPU time spent issuing it (ms). */
  render() {
    const t0 = performance.now();
    const { width, height } = this.canvas;
    const camera = this._activeCamera();
    this._prepare(camera, width, height);
    this._renderViewMaps();
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
   * Linear radiance of a unit sphere seen orthographically from `view` (relight.shrm.render_sphere's camera),
   * lit by the SHRM of `object` (default: the single object; or a scene object's name), by that object's viewer
   * (distant: eq. 12, near: eq. 6): Float32Array RGB, size x size, row 0 at the top; off-sphere pixels are 0.
   */
  renderLinearSphere(view, size, object = null) {
    const obj = object === null ? this.primary : this.sceneObjects.find((o) => o.name === object);
    if (!obj?.layout) {
      throw new Error(object === null ? 'no SHRM loaded' : `no scene object ${object} with an SHRM`);
    }
    const saved = { fixed: this.fixedView, shape: obj.shape, geometry: obj.mesh.geometry,
      center: obj.center.clone(), radius: obj.radius, target: this.sceneTarget.clone(),
      visible: this.objects.map((o) => o.mesh.visible), material: obj.mesh.material };
    const target = linearTarget(size);
    const sphere = sphereProxy();
    try {
      this.objects.forEach((o) => { o.mesh.visible = o === obj; });
      obj.center.set(0, 0, 0);
      obj.radius = 1;
      this.sceneTarget.set(0, 0, 0);
      this.setFixedView({ view, orthographic: true });
      obj.shape = 'sphere';
      obj.mesh.geometry = sphere;
      const cam = this._activeCamera();
      this._prepare(cam, size, size);
      const shading = obj.mode || this.options.mode;
      if (shading === 'distant') {
        const keep = this.options.shading;
        this.options.shading = 'shrm';
        obj.renderViewMap(this.renderer, this.orthoCamera);
        this.options.shading = keep;
      }
      obj.mesh.material = obj.material(shading, 'linear');
      const bg = this.background.visible;
      this.background.visible = false;
      const { rgb } = this._drawLinear(target, cam, size);
      this.background.visible = bg;
      return rgb;
    } finally {
      this.renderer.setRenderTarget(null);
      target.dispose();
      sphere.dispose();
      this.setFixedView(saved.fixed);
      obj.shape = saved.shape;
      obj.mesh.geometry = saved.geometry;
      obj.mesh.material = saved.material;
      obj.center.copy(saved.center);
      obj.radius = saved.radius;
      obj._viewMapKey = null;
      this.sceneTarget.copy(saved.target);
      this.objects.forEach((o, k) => { o.mesh.visible = saved.visible[k]; });
      obj.updateMaterial();
    }
  }

  /**
   * Linear radiance of the PrtObject (the service mesh with diffuse PRT) in its current mode, seen
   * orthographically from `view` (relight.mesh_render's camera: the mesh normalised into the unit ball, looked at
   * from 3 V) with the environment turned by the current rotation: {rgb: Float32Array RGB, coverage: Uint8Array
   * (1 where the mesh covers the pixel centre)}, size x size, row 0 at the top.
   */
  renderLinearPrt(view, size) {
    const prt = this.prt;
    if (!prt) {
      throw new Error('no mesh with PRT shown');
    }
    const saved = { fixed: this.fixedView, target: this.sceneTarget.clone(), material: prt.mesh.material,
      bg: this.background.visible };
    const target = linearTarget(size);
    try {
      this.sceneTarget.set(0, 0, 0);
      this.setFixedView({ view, orthographic: true });
      const cam = this._activeCamera();
      this._prepare(cam, size, size);
      prt.mesh.material = prt.material(prt.modes().includes(prt.mode) ? prt.mode : 'unshadowed', 'linear');
      this.background.visible = false;
      return this._drawLinear(target, cam, size);
    } finally {
      this.renderer.setRenderTarget(null);
      target.dispose();
      this.background.visible = saved.bg;
      prt.mesh.material = saved.material;
      this.setFixedView(saved.fixed);
      this.sceneTarget.copy(saved.target);
    }
  }

  /** Draw the scene into the float target; RGB and coverage (alpha > 0) with row 0 at the top. */
  _drawLinear(target, cam, size) {
    this.renderer.setRenderTarget(target);
    this.renderer.setClearColor(0x000000, 0);
    this.renderer.clear();
    this.renderer.render(this.scene, cam);
    this.renderer.setClearColor(0x000000, 1);
    const raw = new Float32Array(size * size * 4);
    this.renderer.readRenderTargetPixels(target, 0, 0, size, size, raw);
    const rgb = new Float32Array(size * size * 3);
    const coverage = new Uint8Array(size * size);
    for (let y = 0; y < size; y += 1) {
      for (let x = 0; x < size; x += 1) {
        const s = ((size - 1 - y) * size + x) * 4;
        const d = y * size + x;
        rgb[3 * d] = raw[s];
        rgb[3 * d + 1] = raw[s + 1];
        rgb[3 * d + 2] = raw[s + 2];
        coverage[d] = raw[s + 3] > 0 ? 1 : 0;
      }
    }
    return { rgb, coverage };
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
