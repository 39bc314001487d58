// A mesh of the service (GET /meshes/{id}: geometry.bin, canonical vertex order) shaded with diffuse PRT
// (web/shaders/prt.vert.glsl; relight/gl/prt.py is the same GLSL on moderngl): unshadowed irradiance, ambient
// occlusion x irradiance, or the shadowed SH transfer of a visibility job (float16 data textures indexed by
// gl_VertexID). Drawn indexed, so gl_VertexID is the canonical vertex id of the per-vertex data. The environment's
// rotation re-lights every frame by rotating the lighting coefficients (rotateLightingY), never the data.
import * as THREE from 'three';

import { cosineZonal, parseGeometry, projectLatlongHalf, rotateLightingY } from './prt.js';
import { build } from './shaders.js';
import { shCount } from './sh.js';

export const PRT_MODES = ['unshadowed', 'ao', 'transfer'];
const DEFINE = { unshadowed: 'MODE_UNSHADOWED', ao: 'MODE_AO', transfer: 'MODE_TRANSFER' };

function dataTexture(bits, texture) {
  const tex = new THREE.DataTexture(new Uint16Array(bits), texture.width, texture.height, THREE.RGBAFormat,
    THREE.HalfFloatType);
  tex.internalFormat = 'RGBA16F';
  tex.minFilter = THREE.NearestFilter;
  tex.magFilter = THREE.NearestFilter;
  tex.generateMipmaps = false;
  tex.flipY = false;
  tex.needsUpdate = true;
  return tex;
}

export class PrtObject {
  /** @param viewer the ShrmViewer (shared camera and display uniforms, shader sources) */
  constructor(viewer) {
    this.viewer = viewer;
    this.order = 3;
    this.mode = 'unshadowed';
    this.albedo = 0.8;
    this.lighting = null; // Float64Array n x 3, the unrotated environment
    this.manifest = null; // the visibility result's manifest
    this.meshInfo = null;
    this.textures = { transfer: null, ao: null };
    this.uniforms = {
      u_view_projection: viewer.uniforms.u_view_projection,
      u_exposure: viewer.uniforms.u_exposure,
      u_tonemap: viewer.uniforms.u_tonemap,
      u_model: { value: new THREE.Matrix4() },
      u_light: { value: [] },
      u_cosine: { value: [] },
      u_albedo: { value: this.albedo },
      u_transfer: { value: null },
      u_ao: { value: null },
      u_output_size: { value: new THREE.Vector2(1, 1) },
    };
    this.placement = new THREE.Matrix4(); // where the unit-ball mesh goes (a scene object: centre, radius)
    this.normalise = new THREE.Matrix4();
    this.mesh = new THREE.Mesh(new THREE.BufferGeometry(), null);
    this.mesh.frustumCulled = false; // the shader places it (u_model), not three.js's object matrix
    this.mesh.visible = false;
    this._materials = new Map();
  }

  /** The mesh's manifest (GET /meshes/{id}) and its geometry.bin bytes. */
  setMesh(info, buffer) {
    const g = parseGeometry(buffer, info.geometry);
    const geo = new THREE.BufferGeometry();
    const pos = new THREE.BufferAttribute(g.positions, 3);
    geo.setAttribute('position', pos);
    geo.setAttribute('a_position', pos);
    geo.setAttribute('a_normal', new THREE.BufferAttribute(g.normals, 3));
    geo.setIndex(new THREE.BufferAttribute(g.indices, 1));
    this.mesh.geometry.dispose();
    this.mesh.geometry = geo;
    // relight's TriangleMesh.normalised: the bounding-box centre to the origin, the bounding radius to 1
    const [lo, hi] = [info.bounds.min, info.bounds.max];
    const c = lo.map((v, k) => 0.5 * (v + hi[k]));
    const s = 1 / (info.bounding_radius > 0 ? info.bounding_radius : 1);
    this.normalise.set(s, 0, 0, -c[0] * s, 0, s, 0, -c[1] * s, 0, 0, s, -c[2] * s, 0, 0, 0, 1);
    this.uniforms.u_model.value.multiplyMatrices(this.placement, this.normalise);
    this.meshInfo = info;
    this.setVisibility(null, {});
  }

  /** Place the unit-ball mesh: centre [x, y, z] and bounding radius (a scene object); the origin and 1 by default. */
  setPlacement(center, radius) {
    this.placement.makeScale(radius, radius, radius).setPosition(...center);
    this.uniforms.u_model.value.multiplyMatrices(this.placement, this.normalise);
  }

  /**
   * A visibility result for this mesh: its manifest (GET /visibility/{id}) and the bytes of its textures
   * ({'transfer.bin': ArrayBuffer, 'ao.bin': ArrayBuffer}); null clears it (only the unshadowed mode remains).
   */
  setVisibility(manifest, buffers) {
    for (const k of Object.keys(this.textures)) {
      this.textures[k]?.dispose();
      this.textures[k] = null;
    }
    this.manifest = manifest;
    if (manifest) {
      if (this.meshInfo && manifest.geometry.sha256 !== this.meshInfo.geometry.sha256) {
        throw new Error('the visibility result belongs to another mesh');
      }
      for (const name of ['transfer', 'ao']) {
        const file = manifest.files[`${name}.bin`];
        if (file && buffers[`${name}.bin`]) {
          this.textures[name] = dataTexture(buffers[`${name}.bin`], file.texture);
        }
      }
      this.order = manifest.order;
    }
    this.uniforms.u_transfer.value = this.textures.transfer;
    this.uniforms.u_ao.value = this.textures.ao;
    this.updateLighting();
    this.updateMaterial();
  }

  /** The modes the loaded data supports. */
  modes() {
    return PRT_MODES.filter((m) => m === 'unshadowed' || this.textures[m]);
  }

  setMode(mode) {
    if (!PRT_MODES.includes(mode)) {
      throw new RangeError(`unknown PRT mode ${mode}; expected one of ${PRT_MODES.join(', ')}`);
    }
    this.mode = mode;
    this.updateMaterial();
  }

  /** Project the viewer's current environment (its float16 lat-long) to this object's order. */
  updateLighting() {
    const env = this.viewer.environment;
    this.lighting = env ? projectLatlongHalf(env.halfRgb, env.height, env.width, this.order) : null;
    this.uniforms.u_cosine.value = Array.from(cosineZonal(this.order));
  }

  /** Per frame: the lighting rotated with the environment (radians about +Y). */
  prepare(rotation) {
    if (!this.lighting) {
      return;
    }
    const rot = rotateLightingY(this.lighting, this.order, rotation);
    const n = shCount(this.order);
    const light = this.uniforms.u_light.value;
    light.length = n;
    for (let k = 0; k < n; k += 1) {
      light[k] = (light[k] || new THREE.Vector3()).set(rot[3 * k], rot[3 * k + 1], rot[3 * k + 2]);
    }
    this.uniforms.u_albedo.value = this.albedo;
  }

  /** The lighting of the last prepare() (n x 3 floats, for tests). */
  currentLighting() {
    return this.uniforms.u_light.value.map((v) => [v.x, v.y, v.z]);
  }

  material(mode, output = 'display') {
    const key = `${mode}:${this.order}:${output}`;
    if (!this._materials.has(key)) {
      const defines = { PRT_ORDER: this.order, [DEFINE[mode]]: null };
      const frag = output === 'linear' ? { OUTPUT_LINEAR: null } : {};
      if (output === 'linear') {
        defines.OUTPUT_LINEAR = null;
      }
      const body = (name, defs) => build(name, { defines: defs, read: this.viewer.read })
        .replace(/^#version 300 es\n/, '');
      this._materials.set(key, new THREE.RawShaderMaterial({
        vertexShader: body('prt.vert.glsl', defines),
        fragmentShader: body('sh_table.frag.glsl', frag),
        uniforms: this.uniforms,
        glslVersion: THREE.GLSL3,
      }));
    }
    return this._materials.get(key);
  }

  updateMaterial() {
    const mode = this.modes().includes(this.mode) ? this.mode : 'unshadowed';
    this.mesh.material = this.material(mode);
  }

  dispose() {
    this.mesh.geometry.dispose();
    Object.values(this.textures).forEach((t) => t?.dispose());
    this._materials.forEach((m) => m.dispose());
  }
}
