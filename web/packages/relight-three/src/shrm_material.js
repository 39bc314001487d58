// An object lit by a relight SHRM (seed 000: the viewer's eq. 6 per pixel, or eq. 12 once per frame into a view
// map for a distant viewer) as a three.js material: the viewer's own GLSL (object.vert/frag.glsl, shrm.glsl,
// view_map.frag.glsl; copied into src/viewer/ by scripts/sync.mjs) and its own layout code, so a mesh drawn
// with this material in any three.js scene is the viewer's image of it.
//
// Input: an SHRM result's manifest (GET /shrms/{id}) and the bytes of its coefficients.bin (float16 RGB layers),
// i.e. any BRDF relight represents. Per draw (`onBeforeRender`) the material reads the mesh's world matrix and
// the camera; `mode: 'distant'` renders the per-frame view map (eq. 12) for the direction from the mesh's
// centre to the camera whenever it changes (a nested render, as three's Reflector does).
import { BufferAttribute, BufferGeometry, ClampToEdgeWrapping, DataArrayTexture, FloatType, GLSL3,
  HalfFloatType, LinearFilter, Matrix3, Matrix4, Mesh, OrthographicCamera, RawShaderMaterial, RGBAFormat,
  RepeatWrapping, Scene, Vector2, Vector3, WebGLRenderTarget } from 'three';

import { GLSL } from './viewer/glsl.js';
import { CONSTANTS } from './viewer/generated/constants.js';
import { globalLayers } from './viewer/global.js';
import { defines as layoutDefines, fromManifest, halfArray, numLayers, rgbaLayers, uniformWeights }
  from './viewer/layout.js';
import { build } from './viewer/shaders.js';

export const TONEMAPS = { aces: CONSTANTS.TONEMAP_ACES, reinhard: CONSTANTS.TONEMAP_REINHARD,
  none: CONSTANTS.TONEMAP_NONE };

/** The GLSL source of `name` with `defines`, as three's GLSL3 materials take it (no #version line). */
export function shaderSource(name, defines = {}) {
  return build(name, { defines, read: (n) => GLSL[n] }).replace(/^#version 300 es\n/, '');
}

function layerTexture(data, layout) {
  const tex = new DataArrayTexture(data, layout.width, layout.height, numLayers(layout));
  tex.type = HalfFloatType;
  tex.format = RGBAFormat;
  tex.internalFormat = 'RGBA16F';
  tex.minFilter = LinearFilter;
  tex.magFilter = LinearFilter;
  tex.wrapS = RepeatWrapping;
  tex.wrapT = ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.needsUpdate = true;
  return tex;
}

function fullscreenTriangle() {
  const g = new BufferGeometry();
  g.setAttribute('a_position', new BufferAttribute(new Float32Array([-1, -1, 3, -1, -1, 3]), 2));
  g.setAttribute('position', new BufferAttribute(new Float32Array(9), 3));
  return g;
}

/** Give a geometry the viewer's attribute names (a_position, a_normal); normals are computed if missing. */
export function withShaderAttributes(geometry) {
  if (!geometry.getAttribute('normal')) {
    geometry.computeVertexNormals();
  }
  geometry.setAttribute('a_position', geometry.getAttribute('position'));
  geometry.setAttribute('a_normal', geometry.getAttribute('normal'));
  return geometry;
}

const _centre = new Vector3();
const _camera = new Vector3();

export class ShrmMaterial extends RawShaderMaterial {
  /**
   * @param {object} options
   * @param {object} options.manifest the SHRM result's manifest
   * @param {ArrayBuffer} options.coefficients coefficients.bin (little-endian float16 RGB layers)
   * @param {'near'|'distant'} [options.mode] eq. 6 per pixel (default) or eq. 12 through a per-frame view map
   * @param {'display'|'linear'} [options.output] the viewer's display transform (exposure, tone map, sRGB) or
   *   linear radiance (for a float render target)
   * @param {number} [options.exposure] stops (display output)
   * @param {'aces'|'reinhard'|'none'} [options.tonemap] (display output)
   * @param {number} [options.rotation] the environment's rotation about +Y, radians (the viewer's)
   */
  constructor({ manifest, coefficients, mode = 'near', output = 'display', exposure = 0, tonemap = 'aces',
    rotation = 0 } = {}) {
    if (mode !== 'near' && mode !== 'distant') {
      throw new RangeError(`relight-three: mode must be 'near' or 'distant', got ${mode}`);
    }
    if (output !== 'display' && output !== 'linear') {
      throw new RangeError(`relight-three: output must be 'display' or 'linear', got ${output}`);
    }
    if (!(tonemap in TONEMAPS)) {
      throw new RangeError(`relight-three: tonemap must be one of ${Object.keys(TONEMAPS)}, got ${tonemap}`);
    }
    const layout = fromManifest(manifest);
    const halves = halfArray(coefficients instanceof ArrayBuffer ? coefficients
      : coefficients.buffer.slice(coefficients.byteOffset, coefficients.byteOffset + coefficients.byteLength));
    const defs = { ...layoutDefines(layout), [mode === 'near' ? 'SHADING_LOCAL' : 'SHADING_VIEW_MAP']: null };
    if (output === 'linear') {
      defs.OUTPUT_LINEAR = null;
    }
    const uniforms = {
      u_model: { value: new Matrix4() },
      u_normal_matrix: { value: new Matrix3() },
      u_view_projection: { value: new Matrix4() },
      u_camera_position: { value: new Vector3() },
      u_view_direction: { value: new Vector3(0, 0, 1) },
      u_orthographic: { value: false },
      u_env_rotation: { value: new Vector2(Math.cos(-rotation), Math.sin(-rotation)) },
      u_exposure: { value: exposure },
      u_tonemap: { value: TONEMAPS[tonemap] },
      u_coefficients: { value: layerTexture(rgbaLayers(layout, halves), layout) },
      u_layer_weight: { value: new Float32Array(numLayers(layout)) },
      u_view_map: { value: null },
      u_view_map_rows: { value: layout.height },
    };
    super({
      vertexShader: shaderSource('object.vert.glsl'),
      fragmentShader: shaderSource('object.frag.glsl', defs),
      uniforms,
      glslVersion: GLSL3,
    });
    this.type = 'ShrmMaterial';
    this.isShrmMaterial = true;
    this.layout = layout;
    this.mode = mode;
    this.rotation = rotation;
    this.viewEnv = new Vector3(0, 0, 1);
    this._viewMapKey = null;
    if (mode === 'distant') {
      const global = globalLayers(layout, halves);
      this.globalLayout = global.layout;
      this.viewMapUniforms = {
        u_coefficients: { value: layerTexture(global.rgba, global.layout) },
        u_layer_weight: { value: new Float32Array(numLayers(global.layout)) },
        u_view_env: { value: this.viewEnv },
        u_view_map_rows: uniforms.u_view_map_rows,
      };
      this.viewMapTarget = new WebGLRenderTarget(2 * layout.height, layout.height * layout.components.length, {
        type: FloatType, format: RGBAFormat, minFilter: LinearFilter, magFilter: LinearFilter,
        wrapS: RepeatWrapping, wrapT: ClampToEdgeWrapping, depthBuffer: false, generateMipmaps: false,
      });
      uniforms.u_view_map.value = this.viewMapTarget.texture;
      this.viewMapScene = new Scene();
      this._viewMapQuad = new Mesh(fullscreenTriangle(), new RawShaderMaterial({
        vertexShader: shaderSource('fullscreen.vert.glsl'),
        fragmentShader: shaderSource('view_map.frag.glsl', layoutDefines(global.layout)),
        uniforms: this.viewMapUniforms, glslVersion: GLSL3, depthTest: false, depthWrite: false,
      }));
      this._viewMapQuad.frustumCulled = false;
      this.viewMapScene.add(this._viewMapQuad);
      this._viewMapCamera = new OrthographicCamera();
    }
  }

  /** The environment's rotation about +Y (radians), as the viewer's rotation slider. */
  setRotation(angle) {
    this.rotation = angle;
    this.uniforms.u_env_rotation.value.set(Math.cos(-angle), Math.sin(-angle));
    this._viewMapKey = null;
  }

  /** Per-draw uniforms from the mesh and the camera (three calls this before drawing `object`). */
  onBeforeRender(renderer, scene, camera, geometry, object) {
    const u = this.uniforms;
    u.u_model.value.copy(object.matrixWorld);
    u.u_normal_matrix.value.getNormalMatrix(object.matrixWorld);
    u.u_view_projection.value.multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse);
    u.u_camera_position.value.setFromMatrixPosition(camera.matrixWorld);
    u.u_orthographic.value = !!camera.isOrthographicCamera;
    const dir = camera.isOrthographicCamera
      ? _camera.set(0, 0, 1).transformDirection(camera.matrixWorld)
      : _camera.setFromMatrixPosition(camera.matrixWorld).sub(_centre.setFromMatrixPosition(object.matrixWorld));
    if (!(dir.lengthSq() > 0)) {
      dir.set(0, 0, 1);
    }
    dir.normalize();
    u.u_view_direction.value.copy(dir);
    // the view in the environment's frame: rotate_y(d, -rotation) (common.glsl)
    const c = Math.cos(-this.rotation);
    const s = Math.sin(-this.rotation);
    this.viewEnv.set(c * dir.x + s * dir.z, dir.y, -s * dir.x + c * dir.z);
    const v = [this.viewEnv.x, this.viewEnv.y, this.viewEnv.z];
    u.u_layer_weight.value.set(uniformWeights(this.layout, v));
    if (this.mode === 'distant') {
      this.viewMapUniforms.u_layer_weight.value.set(uniformWeights(this.globalLayout, v));
      const key = v.join(',');
      if (key !== this._viewMapKey) {
        this._viewMapKey = key;
        const target = renderer.getRenderTarget();
        const autoClear = renderer.autoClear;
        renderer.autoClear = true;
        renderer.setRenderTarget(this.viewMapTarget);
        renderer.render(this.viewMapScene, this._viewMapCamera);
        renderer.setRenderTarget(target);
        renderer.autoClear = autoClear;
      }
    }
  }

  dispose() {
    this.uniforms.u_coefficients.value?.dispose();
    if (this.mode === 'distant') {
      this.viewMapUniforms.u_coefficients.value.dispose();
      this.viewMapTarget.dispose();
      this._viewMapQuad.geometry.dispose();
      this._viewMapQuad.material.dispose();
    }
    super.dispose();
  }
}
