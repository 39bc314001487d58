// A mesh of the service drawn with in-out factorized PRT (Mahajan, Tseng & Ramamoorthi 2008, eq. 4; the GLSL is
// web/shaders/inout.vert.glsl, shared with relight/gl/inout.py): the data of an inout_prt job (transport.bin: the
// per-vertex K x (F+1)^2 transport as float16 RGBA texels indexed by gl_VertexID; factors.bin: R32F rows m, parity,
// sigma_k h_k(theta)). Per frame the environment's real SH (projected from the viewer's float16 map, rotated with the
// environment) and the camera are uniforms, so lighting, view and the number of summed terms (setTerms: whole
// pairs, no new data) all change freely. Duck-types PrtObject for ShrmViewer.setPrt (mesh, prepare, updateLighting).
import * as THREE from 'three';

import { parseGeometry, projectLatlongHalf, rotateLightingY } from './prt.js';
import { build, loadSources } from './shaders.js';
import { shCount } from './sh.js';

/** Terms rounded up to whole (cos, sin) pairs (relight/inout_factors.py whole_pairs). */
export function wholePairs(m, parity, terms) {
  let k = Math.max(1, Math.min(terms, m.length));
  if (k < m.length && m[k - 1] > 0 && parity[k - 1] === 0) {
    k += 1;
  }
  return k;
}

export class InOutObject {
  /** @param viewer the ShrmViewer (shared camera and display uniforms) */
  constructor(viewer) {
    this.viewer = viewer;
    this.mode = 'inout';
    this.manifest = null;
    this.meshInfo = null;
    this.terms = 1;
    this.lighting = null;
    this.read = null;
    this.textures = { transport: null, factors: null };
    this.uniforms = {
      u_view_projection: viewer.uniforms.u_view_projection,
      u_exposure: viewer.uniforms.u_exposure,
      u_tonemap: viewer.uniforms.u_tonemap,
      u_model: { value: new THREE.Matrix4() },
      u_light: { value: [] },
      u_view: { value: new THREE.Vector3(0, 0, 1) },
      u_eye: { value: new THREE.Vector4(0, 0, 0, 0) },
      u_transport: { value: null },
      u_factors: { value: null },
      u_output_size: { value: new THREE.Vector2(1, 1) },
    };
    this.placement = new THREE.Matrix4(); // where the unit-ball mesh goes (a scene object: centre, radius)
    this.normalise = new THREE.Matrix4();
    this.mesh = new THREE.Mesh(new THREE.BufferGeometry(), null);
    this.mesh.frustumCulled = false;
    this.mesh.visible = false;
    this._materials = new Map();
  }

  /** Fetch inout.vert.glsl and sh_table.frag.glsl with their includes (once). */
  async loadShaders(base = this.viewer.shaderBase) {
    this.read = await loadSources(['inout.vert.glsl', 'sh_table.frag.glsl'], base);
  }

  /** The mesh's manifest (GET /meshes/{id}) and its geometry.bin bytes (as PrtObject.setMesh). */
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
    const [lo, hi] = [info.bounds.min, info.bounds.max];
    const c = lo.map((v, k) => 0.5 * (v + hi[k]));
    const s = 1 / (info.bounding_radius > 0 ? info.bounding_radius : 1);
    this.normalise.set(s, 0, 0, -c[0] * s, 0, s, 0, -c[1] * s, 0, 0, s, -c[2] * s, 0, 0, 0, 1);
    this.uniforms.u_model.value.multiplyMatrices(this.placement, this.normalise);
    this.meshInfo = info;
  }

  /** Place the unit-ball mesh: centre [x, y, z] and bounding radius (a scene object); the origin and 1 by default. */
  setPlacement(center, radius) {
    this.placement.makeScale(radius, radius, radius).setPosition(...center);
    this.uniforms.u_model.value.multiplyMatrices(this.placement, this.normalise);
  }

  /** An inout_prt job's result (GET /jobs/{id}/result) and its files {'transport.bin', 'factors.bin'}. */
  setData(result, buffers) {
    Object.values(this.textures).forEach((t) => t?.dispose());
    const tex = result.transport_texture;
    const tr = new THREE.DataTexture(new Uint16Array(buffers['transport.bin']), tex.width, tex.height,
      THREE.RGBAFormat, THREE.HalfFloatType);
    tr.internalFormat = 'RGBA16F';
    const fac = result.factors_texture;
    const ft = new THREE.DataTexture(new Float32Array(buffers['factors.bin']), fac.width, fac.height,
      THREE.RedFormat, THREE.FloatType);
    ft.internalFormat = 'R32F';
    for (const t of [tr, ft]) {
      t.minFilter = THREE.NearestFilter;
      t.magFilter = THREE.NearestFilter;
      t.generateMipmaps = false;
      t.flipY = false;
      t.needsUpdate = true;
    }
    this.textures = { transport: tr, factors: ft };
    this.uniforms.u_transport.value = tr;
    this.uniforms.u_factors.value = ft;
    this.manifest = result;
    this.terms = result.terms;
    this.updateLighting();
    this.updateMaterial();
  }

  /** Sum the first `k` terms (rounded up to whole pairs); returns the count used. */
  setTerms(k) {
    const m = this.manifest;
    this.terms = wholePairs(m.m, m.parity, Math.round(k));
    this.updateMaterial();
    return this.terms;
  }

  /** The energy fraction of the kernel the summed terms capture (from the result's singular values). */
  captured() {
    const m = this.manifest;
    const all = m.sigma.reduce((a, s) => a + s * s, 0);
    const part = m.sigma.slice(0, this.terms).reduce((a, s) => a + s * s, 0);
    return m.captured * (all > 0 ? part / all : 1);
  }

  modes() {
    return ['inout'];
  }

  setMode() {}

  updateLighting() {
    const env = this.viewer.environment;
    const order = this.manifest?.order ?? 0;
    this.lighting = env ? projectLatlongHalf(env.halfRgb, env.height, env.width, order) : null;
  }

  /** Per frame: the lighting rotated with the environment, and the camera (perspective: the eye point). */
  prepare(rotation) {
    if (!this.lighting || !this.manifest) {
      return;
    }
    const order = this.manifest.order;
    const rot = rotateLightingY(this.lighting, order, rotation);
    const n = shCount(order);
    const light = this.uniforms.u_light.value;
    light.length = n;
    for (let k = 0; k < n; k += 1) {
      light[k] = (light[k] || new THREE.Vector3()).set(rot[3 * k], rot[3 * k + 1], rot[3 * k + 2]);
    }
    const vu = this.viewer.uniforms;
    this.uniforms.u_view.value.copy(vu.u_view_direction.value);
    const eye = vu.u_camera_position.value;
    this.uniforms.u_eye.value.set(eye.x, eye.y, eye.z, vu.u_orthographic.value ? 0 : 1);
  }

  currentLighting() {
    return this.uniforms.u_light.value.map((v) => [v.x, v.y, v.z]);
  }

  material(mode = 'inout', output = 'display') {
    if (!this.read) {
      throw new Error('InOutObject: loadShaders() first');
    }
    const key = `${mode}:${this.terms}:${this.manifest.terms}:${this.manifest.order}:${output}`;
    if (!this._materials.has(key)) {
      const defines = { INOUT_ORDER: this.manifest.order, INOUT_TERMS: this.terms, INOUT_STORED: this.manifest.terms };
      const frag = {};
      if (output === 'linear') {
        defines.OUTPUT_LINEAR = null;
        frag.OUTPUT_LINEAR = null;
      }
      const body = (name, defs) => build(name, { defines: defs, read: this.read }).replace(/^#version 300 es\n/, '');
      this._materials.set(key, new THREE.RawShaderMaterial({
        vertexShader: body('inout.vert.glsl', defines),
        fragmentShader: body('sh_table.frag.glsl', frag),
        uniforms: this.uniforms,
        glslVersion: THREE.GLSL3,
      }));
    }
    return this._materials.get(key);
  }

  updateMaterial() {
    if (this.manifest) {
      this.mesh.material = this.material();
    }
  }

  dispose() {
    this.mesh.geometry.dispose();
    Object.values(this.textures).forEach((t) => t?.dispose());
    this._materials.forEach((m) => m.dispose());
  }
}
