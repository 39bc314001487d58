// Scene parts drawn with seed 003's per-view SH tables (Kautz, Sloan & Snyder 2002; issue 16 item 4: "the viewer
// draws the whole scene, each object with its chosen representation"), both through web/shaders/sh_table.vert.glsl,
// the GLSL of sh_table.js's SHTableGL and relight.gl.sh_table:
//  - ShTablePart (`sh_table`): an anisotropic (or band-limited) lobe without shadows, the 'general' mode: per vertex
//    the lighting rotated into the vertex's tangent frame, dotted with the table's coefficients at the local view,
//    on the plan's shared sh_table job; the object's geometry (the unit sphere or its mesh).
//  - PrtMatrixPart (`prt_matrix`, §5): the same table on shadow-transferred lighting, the 'transfer' mode with
//    TRANSFER_WORLD: per vertex L_p = T_p L' with the plan's shared shadow_matrix job's world-frame matrices T_p
//    (the job's P.shadow_matrix.bin, the layout of the visibility kind's shadow_matrix.bin, re-packed by
//    sh_table_data.js transferLayout), rotated into the vertex's frame on the GPU, then the table lookup; drawn on
//    the job's own geometry (P.geometry.bin: canonical vertex order, gl_VertexID indexes the matrices), normalised
//    to the unit ball (relight's TriangleMesh.normalised) and placed at the object's centre and radius. The CPU
//    twin is relight.sh_prt.shade_prt (with folded_transfer: the rotation folded into T_p, the same product).
// The tangent field is the object's (sh_lights.js tangentField; default azimuthal about +Y); the environment's
// rotation turns the lighting (as PrtPart); the view is the direction from the object's centre to the camera.
import * as THREE from 'three';

import { parseGeometry, projectLatlongHalf, rotateLightingY } from './prt.js';
import { build } from './shaders.js';
import { shCount } from './sh.js';
import { tangentField } from './sh_lights.js';
import { DATA_WIDTH, shaderDefines } from './sh_table.js';
import { transferLayout } from './sh_table_data.js';
import { additive, Part, partGeometry } from './scene_part_base.js';
import { objectViewDirection, withShaderAttributes } from './shrm_object.js';

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

/**
 * A shadow_matrix job's P.shadow_matrix.bin (float16 bits, the manifest's `texture` layout: ceil(n^2 / 4) texels per
 * vertex) as the RGBA float16 texels sh_table.vert.glsl's MODE_TRANSFER reads (SHTableGL.setTransfer's layout:
 * vertex p, row i from texel (p n + i) ceil(n / 4)), DATA_WIDTH texels wide: {data, width, height}.
 */
export function matrixTexels(half, texture, order) {
  const n = shCount(order);
  const shape = texture.value_shape || [];
  if (shape.length !== 2 || shape[0] < n || shape[1] !== shape[0]
    || half.length < 4 * texture.vertices * texture.texels_per_vertex) {
    throw new Error(`transfer matrices of shape [${shape}] for ${texture.vertices} vertices do not fit order `
      + `${order} (${n} x ${n}) or ${half.length} values`);
  }
  const m = shape[0];
  let square = half;
  if (m > n) { // the leading n x n block (relight.sh_prt.folded_transfer): the lighting is order F
    square = new Uint16Array(4 * texture.vertices * Math.ceil((n * n) / 4));
    const t = Math.ceil((n * n) / 4);
    for (let v = 0; v < texture.vertices; v += 1) {
      for (let i = 0; i < n; i += 1) {
        const from = 4 * v * texture.texels_per_vertex + i * m;
        square.set(half.subarray(from, from + n), 4 * v * t + i * n);
      }
    }
  }
  const rows = transferLayout(square, { vertices: texture.vertices, texels_per_vertex: Math.ceil((n * n) / 4) }, n);
  const height = Math.max(1, Math.ceil(rows.length / 4 / DATA_WIDTH));
  const data = new Uint16Array(4 * DATA_WIDTH * height);
  data.set(rows);
  return { data, width: DATA_WIDTH, height };
}

function halfTexture(tex, linear) {
  tex.type = THREE.HalfFloatType;
  tex.format = THREE.RGBAFormat;
  tex.internalFormat = 'RGBA16F';
  tex.minFilter = linear ? THREE.LinearFilter : THREE.NearestFilter;
  tex.magFilter = linear ? THREE.LinearFilter : THREE.NearestFilter;
  tex.wrapS = THREE.ClampToEdgeWrapping;
  tex.wrapT = THREE.ClampToEdgeWrapping;
  tex.generateMipmaps = false;
  tex.flipY = false;
  tex.needsUpdate = true;
  return tex;
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
    // bilinear over the view map, clamped (sh_table.js SHTableGL)
    this.texture = halfTexture(new THREE.DataArrayTexture(tableRgba(new Uint16Array(item.tableBuffer), table), cols,
      rows, n), true);
    const shared = viewer.uniforms;
    this.uniforms = {
      u_view_projection: { value: new THREE.Matrix4() }, // the viewer's times this part's placement (prepare)
      u_exposure: shared.u_exposure,
      u_tonemap: shared.u_tonemap,
      u_view: { value: new THREE.Vector3(0, 0, 1) },
      u_light: { value: [] },
      u_table: { value: this.texture },
      u_vertex_data: { value: null },
    };
    this.lighting = null;
    this.layout = table.layout;
    this.added = !!item.added;
    this._materials = new Map();
    this.normalise = new THREE.Matrix4(); // the geometry into the unit ball (identity: already there)
    this.mesh = new THREE.Mesh(this.geometry(item), this.material('display'));
    this.mesh.name = item.name;
    this.mesh.frustumCulled = false; // placed by u_view_projection, not three.js's object matrix
    this.mesh.renderOrder = this.added ? 1 : 0;
  }

  /** The object's geometry (the unit sphere or its mesh) with its tangent field (a_tangent). */
  geometry(item) {
    const geometry = partGeometry(item.geometry);
    const normals = geometry.getAttribute('normal').array;
    geometry.setAttribute('a_tangent', new THREE.BufferAttribute(tangentField(normals, item.tangent
      || { kind: 'azimuthal' }), 4));
    return geometry;
  }

  /** sh_table.vert.glsl's defines: the 'general' mode. */
  defines() {
    return shaderDefines(this.order, this.layout, 'general');
  }

  /** 'display' (tonemapped, the canvas) or 'linear' (radiance, float targets). */
  material(output) {
    if (!this._materials.has(output)) {
      const body = (name, defs) => build(name, { defines: defs, read: this.viewer.read })
        .replace(/^#version 300 es\n/, '');
      const m = new THREE.RawShaderMaterial({ vertexShader: body('sh_table.vert.glsl', this.defines()),
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
    const model = new THREE.Matrix4().makeScale(this.radius, this.radius, this.radius).setPosition(this.center)
      .multiply(this.normalise);
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
    this.uniforms.u_vertex_data.value?.dispose();
    this.mesh.geometry.dispose();
    this.mesh.removeFromParent();
  }
}

export class PrtMatrixPart extends ShTablePart {
  /**
   * @param item {name, center, radius, shape, table, tableBuffer, tangent (as ShTablePart), matrices (the
   *   shadow_matrix job's P.prt_matrix.json), geometryBuffer (its P.geometry.bin), matrixBuffer (its
   *   P.shadow_matrix.bin), added}
   */
  constructor(viewer, item) {
    super(viewer, item);
    this.representation = 'prt_matrix';
  }

  /** The job's mesh (canonical vertex order), normalised to the unit ball, with the object's tangent field. */
  geometry(item) {
    const { matrices } = item;
    const g = parseGeometry(item.geometryBuffer, matrices.geometry);
    const texture = matrices.files['shadow_matrix.bin'].texture;
    const count = g.positions.length / 3;
    if (texture.vertices !== count || matrices.order < this.order) {
      throw new Error(`object ${item.name}: its transfer matrices (order ${matrices.order}, ${texture.vertices} `
        + `vertices) do not fit its SH table (order ${this.order}) or its mesh (${count} vertices)`);
    }
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(g.positions, 3));
    geo.setAttribute('normal', new THREE.BufferAttribute(g.normals, 3));
    geo.setIndex(new THREE.BufferAttribute(g.indices, 1));
    withShaderAttributes(geo);
    const spec = item.tangent || { kind: 'azimuthal' };
    if (spec.kind === 'mesh' && !g.tangents) {
      throw new Error(`object ${item.name}: its tangent field is the mesh's, and its geometry has no tangents`);
    }
    geo.setAttribute('a_tangent', new THREE.BufferAttribute(tangentField(g.normals, spec.kind === 'mesh'
      ? { kind: 'mesh', tangents: g.tangents } : spec), 4));
    // relight's TriangleMesh.normalised: the bounding-box centre to the origin, the bounding radius to 1
    const [lo, hi] = [matrices.bounds.min, matrices.bounds.max];
    const c = lo.map((v, k) => 0.5 * (v + hi[k]));
    const s = 1 / (matrices.bounding_radius > 0 ? matrices.bounding_radius : 1);
    this.normalise.set(s, 0, 0, -c[0] * s, 0, s, 0, -c[1] * s, 0, 0, s, -c[2] * s, 0, 0, 0, 1);
    const packed = matrixTexels(new Uint16Array(item.matrixBuffer), texture, this.order);
    this.uniforms.u_vertex_data.value = halfTexture(new THREE.DataTexture(packed.data, packed.width, packed.height),
      false);
    return geo;
  }

  /** The 'transfer' mode on world-frame matrices (TRANSFER_WORLD: the shader rotates T_p L' per vertex). */
  defines() {
    return shaderDefines(this.order, this.layout, 'transfer', null, 1, true);
  }
}
