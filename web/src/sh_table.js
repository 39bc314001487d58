// SH-table shading in WebGL2 (seed 003, Kautz, Sloan & Snyder 2002, §4): the browser twin of
// relight/gl/sh_table.py, with the same GLSL (web/shaders/sh_table.vert.glsl, sh_rotation.glsl; the rotation of the
// lighting into each vertex's frame runs on the GPU). Modes: 'general' (view and lighting both change),
// 'fixed-light' (per-vertex local lighting prepared once per lighting), 'fixed-view' (per-vertex world-frame table
// coefficients prepared once per view), and 'transfer' (PRT, §5: per-vertex folded transfer matrices T'_p, shadows
// or interreflections, uploaded by setTransfer). The fixed modes' per-vertex data is a float32 RGBA texture
// DATA_WIDTH texels wide, texel p * n + i = coefficient i of vertex p; the transfer's is float16 RGBA, each matrix
// row padded to a multiple of 4 values, vertex p from texel p * n * ceil(n / 4) (docs/conventions.md, "SH tables").
//
// Raw WebGL2 (no three.js) so that tests/web/test_sh_table_browser.py can probe the shader at given frames and
// compare with the CPU evaluation (relight.sh_render.shade) on the same float16 table.

import { build } from './shaders.js';

export const MODES = ['general', 'fixed-light', 'fixed-view'];
const MODE_DEFINE = {
  general: 'MODE_GENERAL', 'fixed-light': 'MODE_FIXED_LIGHT', 'fixed-view': 'MODE_FIXED_VIEW',
  transfer: 'MODE_TRANSFER',
};
/** Width of the probe / per-vertex data targets (relight.gl.sh_table.DATA_WIDTH). */
export const DATA_WIDTH = 2048;
export const SHADER_FILES = ['sh_table.vert.glsl', 'sh_table.frag.glsl'];

/**
 * The defines of sh_table.vert.glsl, as relight.gl.sh_table.shader_defines; `transferWorld`: the 'transfer' mode's
 * matrices are world-frame T_p (relight.visibility's shadow_matrix), rotated into the local frame on the GPU.
 */
export function shaderDefines(order, layout, mode, target = null, tables = 1, transferWorld = false) {
  if (!(mode in MODE_DEFINE)) {
    throw new Error(`unknown SH-table mode ${mode}`);
  }
  if (layout !== 'parabolic' && layout !== 'hemi-octahedral') {
    throw new Error(`unknown view-map layout ${layout}`);
  }
  const defines = { SH_ORDER: order };
  defines[layout === 'parabolic' ? 'TABLE_PARABOLIC' : 'TABLE_HEMI_OCTAHEDRAL'] = null;
  defines[MODE_DEFINE[mode]] = null;
  defines.OUTPUT_LINEAR = null;
  if (transferWorld && mode === 'transfer') {
    defines.TRANSFER_WORLD = null;
  }
  if (target) {
    defines[target] = null;
  }
  if (tables > 1) {  // spatially varying tables (sh_table.vert.glsl, TABLE_VARYING)
    defines.TABLE_VARYING = null;
    defines.TABLE_COUNT = tables;
  }
  return defines;
}

function compile(gl, type, source) {
  const sh = gl.createShader(type);
  gl.shaderSource(sh, source);
  gl.compileShader(sh);
  if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
    throw new Error(`shader compile: ${gl.getShaderInfoLog(sh)}`);
  }
  return sh;
}

export class SHTableGL {
  /**
   * @param {WebGL2RenderingContext} gl
   * @param {function(string): string} read shader source reader (shaders.loadSources)
   * @param {{order: number, layout: string, resolution: number, half: Uint16Array, tables?: number}} table
   *   float16 bits in (coefficient, row, column, RGB) order; with `tables` = Q > 1, Q such tables one after the
   *   other (spatially varying: each vertex's position among them comes from setTablePositions)
   */
  constructor(gl, read, { order, layout, resolution, half, tables = 1 }) {
    if (!gl.getExtension('EXT_color_buffer_float')) {
      throw new Error('EXT_color_buffer_float is required for float targets');
    }
    this.gl = gl;
    this.read = read;
    this.order = order;
    this.layout = layout;
    this.n = (order + 1) * (order + 1);
    this.tables = tables;
    this.positions = null;
    if (half.length !== tables * this.n * resolution * resolution * 3) {
      throw new Error(`table data holds ${half.length} values, expected `
        + `${tables * this.n * resolution * resolution * 3}`);
    }
    this.table = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.table);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage3D(gl.TEXTURE_2D_ARRAY, 0, gl.RGB16F, resolution, resolution, this.n * tables, 0, gl.RGB,
      gl.HALF_FLOAT, half);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D_ARRAY, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    this.programs = new Map();
    this.data = null;  // the fixed modes' per-vertex data (prepare)
    this.transfer = null;  // the transfer mode's matrices (setTransfer): kept apart, so that neither evicts the other
    this.transferWorld = false;
  }

  /** `target`: null (the mesh, linear radiance), 'PROBE', 'PRECOMPUTE' or 'DISPLAY' (the mesh, tone-mapped). */
  program(mode, target = null) {
    const key = `${mode}/${target}/${mode === 'transfer' && this.transferWorld}`;
    if (!this.programs.has(key)) {
      const gl = this.gl;
      const display = target === 'DISPLAY';
      const defines = shaderDefines(this.order, this.layout, mode, display ? null : target, this.tables,
        this.transferWorld);
      const prog = gl.createProgram();
      gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, build('sh_table.vert.glsl', { defines, read: this.read })));
      gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER,
        build('sh_table.frag.glsl', { defines: display ? {} : { OUTPUT_LINEAR: null }, read: this.read })));
      gl.linkProgram(prog);
      if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
        throw new Error(`shader link: ${gl.getProgramInfoLog(prog)}`);
      }
      this.programs.set(key, prog);
    }
    return this.programs.get(key);
  }

  /** Interleaved (position, normal, tangent) float32 vertices -> a vertex array bound to `prog`'s attributes. */
  vertexArray(prog, vertices) {
    const gl = this.gl;
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, vertices, gl.STATIC_DRAW);
    let offset = 0;
    for (const [name, size] of [['a_position', 3], ['a_normal', 3], ['a_tangent', 4]]) {
      const loc = gl.getAttribLocation(prog, name);
      if (loc >= 0) {
        gl.enableVertexAttribArray(loc);
        gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 40, offset);
      }
      offset += 4 * size;
    }
    let posBuf = null;
    const tableLoc = gl.getAttribLocation(prog, 'a_table');
    if (tableLoc >= 0) {
      if (!this.positions) {
        throw new Error('spatially varying tables need setTablePositions first');
      }
      posBuf = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, posBuf);
      gl.bufferData(gl.ARRAY_BUFFER, this.positions, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(tableLoc);
      gl.vertexAttribPointer(tableLoc, 1, gl.FLOAT, false, 4, 0);
    }
    return { vao, buf, posBuf };
  }

  /**
   * Per-vertex fractional positions among the tables (relight.sh_table_varying.VaryingTable.positions).
   * @param {Float32Array} positions
   */
  setTablePositions(positions) {
    this.positions = positions;
  }

  setUniforms(prog, view, light, mode = null) {
    const gl = this.gl;
    gl.useProgram(prog);
    const norm = Math.hypot(...view);
    gl.uniform3f(gl.getUniformLocation(prog, 'u_view'), view[0] / norm, view[1] / norm, view[2] / norm);
    const lightLoc = gl.getUniformLocation(prog, 'u_light');
    if (lightLoc) {
      gl.uniform3fv(lightLoc, light.subarray(0, this.n * 3));
    }
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, this.table);
    gl.uniform1i(gl.getUniformLocation(prog, 'u_table'), 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, mode === 'transfer' ? this.transfer : this.data);
    gl.uniform1i(gl.getUniformLocation(prog, 'u_vertex_data'), 1);
  }

  /** Draw `count` points x `instances` into a fresh float target; returns [texture, Float32Array RGBA]. */
  points(prog, vertices, count, instances, keep = false) {
    const gl = this.gl;
    const rows = Math.max(1, Math.ceil((count * instances) / DATA_WIDTH));
    gl.uniform2i(gl.getUniformLocation(prog, 'u_output_size'), DATA_WIDTH, rows);
    const tex = gl.createTexture();
    gl.activeTexture(gl.TEXTURE2);  // units 0 and 1 hold the table and the per-vertex data being read
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, DATA_WIDTH, rows, 0, gl.RGBA, gl.FLOAT, null);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    const fbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    gl.viewport(0, 0, DATA_WIDTH, rows);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.BLEND);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    const { vao, buf, posBuf } = this.vertexArray(prog, vertices);
    gl.drawArraysInstanced(gl.POINTS, 0, count, instances);
    const out = new Float32Array(DATA_WIDTH * rows * 4);
    gl.readPixels(0, 0, DATA_WIDTH, rows, gl.RGBA, gl.FLOAT, out);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fbo);
    gl.deleteVertexArray(vao);
    gl.deleteBuffer(buf);
    if (posBuf) {
      gl.deleteBuffer(posBuf);
    }
    if (!keep) {
      gl.deleteTexture(tex);
      return [null, out];
    }
    return [tex, out];
  }

  /**
   * Folded transfer matrices for 'transfer' (relight.gl.sh_table.TableRenderer.set_transfer): float16 bits of
   * (count, n, 4 ceil(n / 4)), each row zero-padded, vertex-major. With `world`, the matrices are world-frame
   * T_p (unfolded) and the shader rotates T_p L' into each vertex's frame (TRANSFER_WORLD).
   * @param {Uint16Array} half
   * @param {number} count vertices
   * @param {{world?: boolean}} options
   */
  setTransfer(half, count, { world = false } = {}) {
    const gl = this.gl;
    this.transferWorld = world;
    const row = 4 * Math.ceil(this.n / 4);
    if (half.length !== count * this.n * row) {
      throw new Error(`transfer data holds ${half.length} values, expected ${count * this.n * row}`);
    }
    const texels = half.length / 4;
    const rows = Math.max(1, Math.ceil(texels / DATA_WIDTH));
    const data = new Uint16Array(rows * DATA_WIDTH * 4);
    data.set(half);
    if (this.transfer) {
      gl.deleteTexture(this.transfer);
    }
    this.transfer = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.transfer);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA16F, DATA_WIDTH, rows, 0, gl.RGBA, gl.HALF_FLOAT, data);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  }

  /**
   * Draw an indexed mesh into the bound framebuffer with the display transform (target DISPLAY): `mesh` holds
   * `vertices` (interleaved float32 position, normal, tangent as vertexArray) and `indices` (Uint32Array); its
   * vertex arrays are kept on it per program (releaseMesh frees them).
   * @param {Float32Array} viewProjection column-major 4 x 4
   */
  draw(mode, mesh, viewProjection, view, light, { exposure = 0, tonemap = 0 } = {}) {
    const gl = this.gl;
    const prog = this.program(mode, 'DISPLAY');
    this.setUniforms(prog, view, light, mode);
    gl.uniformMatrix4fv(gl.getUniformLocation(prog, 'u_view_projection'), false, viewProjection);
    gl.uniform1f(gl.getUniformLocation(prog, 'u_exposure'), exposure);
    gl.uniform1i(gl.getUniformLocation(prog, 'u_tonemap'), tonemap);
    mesh.vaos = mesh.vaos || new Map();
    if (!mesh.vaos.has(prog)) {
      const arrays = this.vertexArray(prog, mesh.vertices);  // leaves its vertex array bound
      const ibuf = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibuf);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.indices, gl.STATIC_DRAW);
      mesh.vaos.set(prog, { ...arrays, ibuf });
    }
    gl.bindVertexArray(mesh.vaos.get(prog).vao);
    gl.drawElements(gl.TRIANGLES, mesh.indices.length, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }

  /** Free the vertex arrays draw() kept on `mesh`. */
  releaseMesh(mesh) {
    const gl = this.gl;
    for (const { vao, buf, posBuf, ibuf } of (mesh.vaos || new Map()).values()) {
      gl.deleteVertexArray(vao);
      [buf, posBuf, ibuf].forEach((b) => b && gl.deleteBuffer(b));
    }
    mesh.vaos = new Map();
  }

  /** The fixed modes' per-vertex data (nothing for 'general'; 'transfer' reads what setTransfer uploaded). */
  prepare(mode, vertices, count, view, light) {
    if (mode === 'general' || mode === 'transfer') {
      return;
    }
    const prog = this.program(mode, 'PRECOMPUTE');
    this.setUniforms(prog, view, light);
    const [tex] = this.points(prog, vertices, count, this.n, true);
    if (this.data) {
      this.gl.deleteTexture(this.data);
    }
    this.data = tex;
  }

  /**
   * Q (count x 3) at points with normals and glTF tangents (xyz, w), through `mode`'s vertex shader.
   * @returns {Float32Array}
   */
  probe(mode, normals, tangents, view, light) {
    const count = normals.length / 3;
    const vertices = new Float32Array(count * 10);
    for (let k = 0; k < count; k += 1) {
      vertices.set(normals.subarray(3 * k, 3 * k + 3), 10 * k + 3);
      vertices.set(tangents.subarray(4 * k, 4 * k + 4), 10 * k + 6);
    }
    this.prepare(mode, vertices, count, view, light);
    const prog = this.program(mode, 'PROBE');
    this.setUniforms(prog, view, light, mode);
    const [, raw] = this.points(prog, vertices, count, 1);
    const out = new Float32Array(count * 3);
    for (let k = 0; k < count; k += 1) {
      out.set(raw.subarray(4 * k, 4 * k + 3), 3 * k);
    }
    return out;
  }
}
