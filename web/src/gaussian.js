// Seed 002's Gaussian-lobe shading in WebGL2: the viewer's side of relight/gl/gaussian.py, with the same GLSL
// (web/shaders/gaussian.glsl through gaussian.vert.glsl / gaussian.frag.glsl, assembled by shaders.js).
//
// Data are float16 bit patterns (Uint16Array), as stored: the material's lobes (per elevation and lobe: mu, sigma,
// 0, 0 and w_r, w_g, w_b, 0), turned by lobeTable into the shader's lobe table (relight.gl.gaussian.LobeTable: a
// row per elevation, or per row of an even grid through them, the float16 values two to a 32-bit word in one
// RGBA32UI texture read with texelFetch), and the chain's levels (one S x 2S RGBA lat-long map each, one size) as
// the slices of one RGBA16F 3-D texture (LINEAR, REPEAT in u, CLAMP_TO_EDGE in v and across the levels, as
// relight.conventions.sample_latlong).

import { halfToFloat, floatToHalf } from './half.js';
import { build, loadSources } from './shaders.js';

/** relight.gl.gaussian.MAX_GRID_ROWS, GRID_SUBDIVISIONS, GRID_TOLERANCE. */
export const MAX_GRID_ROWS = 1024;
const GRID_SUBDIVISIONS = 16;
const GRID_TOLERANCE = 1e-3;

/**
 * relight.gl.gaussian.lobe_grid: [theta0, step, rows] of the coarsest even grid with a row at every elevation
 * (within GRID_TOLERANCE rows; step = the smallest gap / q, q = 1 ... GRID_SUBDIVISIONS), or null.
 */
export function lobeGrid(elevations) {
  const e = elevations;
  if (e.length < 2) {
    return null;
  }
  let gap = Infinity;
  for (let i = 1; i < e.length; i += 1) {
    gap = Math.min(gap, e[i] - e[i - 1]);
  }
  const span = e[e.length - 1] - e[0];
  for (let q = 1; q <= GRID_SUBDIVISIONS; q += 1) {
    const rows = Math.round(span / (gap / q)) + 1;
    if (rows > MAX_GRID_ROWS) {
      return null;
    }
    const step = span / (rows - 1);
    const onGrid = e.every((x) => {
      const m = (x - e[0]) / step;
      return Math.abs(m - Math.round(m)) <= GRID_TOLERANCE;
    });
    if (onGrid) {
      return [e[0], step, rows];
    }
  }
  return null;
}

/** RGBA32UI texels per row of the lobe table: 2 words per lobe and the blue weights two to a word. */
export function lobeTexels(lobes) {
  return Math.floor((2 * lobes + Math.floor((lobes + 1) / 2) + 3) / 4);
}

/**
 * relight.gl.gaussian.LobeTable of `material` ({lobes K, elevations, shape, weight}): {lobes, rows, grid
 * ([theta0, rows per radian] or null), elevations (the rows' theta_o), words (Uint32Array, rows x lobeTexels(K)
 * RGBA texels: per row the halves mu_0, sigma_0, w_0.r, w_0.g, mu_1, ..., then w_0.b, ..., w_{K-1}.b, two to a
 * word, low half first)}. The elevations are rounded to float32 and the values interpolated at the grid's rows
 * exactly as GaussianLobes.params_at does, then rounded to float16.
 */
export function lobeTable(material) {
  const k = material.lobes;
  const e = Array.from(material.elevations, Math.fround);
  const n = e.length;
  const grid = lobeGrid(e);
  const rows = grid ? grid[2] : n;
  const at = grid ? Array.from({ length: rows }, (_, i) => grid[0] + grid[1] * i) : e;
  const texels = lobeTexels(k);
  const halves = new Uint16Array(rows * texels * 8);
  for (let i = 0; i < rows; i += 1) {
    const t = Math.min(Math.max(at[i], e[0]), e[n - 1]);
    let j = 0;
    while (j < n - 2 && e[j + 1] <= t) {
      j += 1;
    }
    const f = n > 1 ? (t - e[j]) / (e[j + 1] - e[j]) : 0;
    const nxt = n > 1 ? j + 1 : j;
    // the value of one channel at row i: exact where f = 0 (the material's own row)
    const lerp = (arr, l, c) => {
      const a = arr[4 * (j * k + l) + c];
      return f === 0 ? a : floatToHalf(halfToFloat(a) * (1 - f) + halfToFloat(arr[4 * (nxt * k + l) + c]) * f);
    };
    const row = i * texels * 8;
    for (let l = 0; l < k; l += 1) {
      halves[row + 4 * l] = lerp(material.shape, l, 0);
      halves[row + 4 * l + 1] = lerp(material.shape, l, 1);
      halves[row + 4 * l + 2] = lerp(material.weight, l, 0);
      halves[row + 4 * l + 3] = lerp(material.weight, l, 1);
      halves[row + 4 * k + l] = lerp(material.weight, l, 2);
    }
  }
  return { lobes: k, rows, grid: grid ? [grid[0], 1 / grid[1]] : null, elevations: at,
    words: new Uint32Array(halves.buffer) };
}

/** The shader's defines (relight.gl.gaussian.GaussianRenderer.defines) for a lobeTable and a chain of `levels`. */
export function gaussianDefines({ table, levels, sphere = false, linear = true }) {
  const d = { GAUSSIAN_K: table.lobes, GAUSSIAN_ROWS: table.rows };
  if (table.grid) {
    d.GAUSSIAN_GRID = null;
  } else {
    let step = table.rows > 2 ? 1 : 0; // the largest power of two <= rows - 2
    while (step && 2 * step <= table.rows - 2) {
      step *= 2;
    }
    d.GAUSSIAN_SEARCH_STEP = step;
  }
  d.GAUSSIAN_LEVELS = levels;
  if (linear) {
    d.OUTPUT_LINEAR = null;
  }
  if (sphere) {
    d.GAUSSIAN_SPHERE = null;
  }
  return d;
}

/** A key of the program a lobeTable needs (tables with one key share a program). */
export function tableKey(table) {
  return `${table.lobes}/${table.rows}/${table.grid ? 'grid' : 'search'}`;
}

function compile(gl, type, text) {
  const sh = gl.createShader(type);
  gl.shaderSource(sh, text);
  gl.compileShader(sh);
  if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
    throw new Error(`shader compile: ${gl.getShaderInfoLog(sh)}`);
  }
  return sh;
}

/** A linked program for the defines (sources fetched from `base`). */
export async function gaussianProgram(gl, defines, base = 'shaders/') {
  const read = await loadSources(['gaussian.vert.glsl', 'gaussian.frag.glsl'], base);
  const prog = gl.createProgram();
  gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, build('gaussian.vert.glsl', { defines, read })));
  gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, build('gaussian.frag.glsl', { defines, read })));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
    throw new Error(`shader link: ${gl.getProgramInfoLog(prog)}`);
  }
  return prog;
}

/** Sampling of the bound lobe texture: NEAREST (an integer texture; gaussian.glsl reads it with texelFetch). */
export function lobeSampling(gl) {
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
}

/** Upload a lobeTable into the bound 2-D texture. */
export function uploadLobes(gl, table) {
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32UI, lobeTexels(table.lobes), table.rows, 0, gl.RGBA_INTEGER,
    gl.UNSIGNED_INT, table.words);
}

/**
 * The chain's levels (`chain` = {height, width, levels: [Uint16Array of H * W * 4]}) as the slices of one RGBA16F
 * 3-D texture: one trilinear lookup blends two levels (gaussian.glsl).
 */
export function uploadChain(gl, chain) {
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_3D, tex);
  gl.texStorage3D(gl.TEXTURE_3D, 1, gl.RGBA16F, chain.width, chain.height, chain.levels.length);
  chain.levels.forEach((bits, j) => {
    gl.texSubImage3D(gl.TEXTURE_3D, 0, 0, 0, j, chain.width, chain.height, 1, gl.RGBA, gl.HALF_FLOAT, bits);
  });
  gl.texParameteri(gl.TEXTURE_3D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_3D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_3D, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_3D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_3D, gl.TEXTURE_WRAP_R, gl.CLAMP_TO_EDGE);
  return tex;
}

/**
 * Upload a material and a chain: `material` = {lobes K, elevations (N numbers, radians), shape, weight}
 * (Uint16Array of N * K * 4 each); `chain` = {sigma0, ratio, height, width, levels: [Uint16Array of H * W * 4]}.
 */
export function uploadGaussian(gl, material, chain) {
  const lobes = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, lobes);
  lobeSampling(gl);
  const table = lobeTable(material);
  uploadLobes(gl, table);
  return { lobes, chain: uploadChain(gl, chain), table, chainInfo: chain };
}

/**
 * A chain as uploadGaussian and the viewer take it, from a gaussian_chain result (`{sigma0, ratio, levels: [{height,
 * width}]}`, every level one size) and its levels' bytes (float16 RGB lat-long, row 0 = +Y): each level padded to
 * RGBA (alpha 0, unused).
 */
export function chainFromLevels(result, rgbBuffers) {
  const { height, width } = result.levels[0];
  if (result.levels.some((lv) => lv.height !== height || lv.width !== width)) {
    throw new Error('the chain\'s levels must share one size (one 3-D texture)');
  }
  const levels = rgbBuffers.map((buffer, j) => {
    const rgb = new Uint16Array(buffer);
    if (rgb.length !== height * width * 3) {
      throw new Error(`chain level ${j}: ${rgb.length} values; ${height} x ${width} RGB need ${height * width * 3}`);
    }
    const rgba = new Uint16Array(height * width * 4);
    for (let p = 0; p < height * width; p += 1) {
      rgba.set(rgb.subarray(3 * p, 3 * p + 3), 4 * p);
    }
    return rgba;
  });
  return { sigma0: result.sigma0, ratio: result.ratio, height, width, levels };
}

/** Bind the textures and the material's uniforms (the camera's are set by the caller). */
export function bindGaussian(gl, prog, data) {
  gl.useProgram(prog);
  const units = [[data.lobes, gl.TEXTURE_2D, 'u_lobes'], [data.chain, gl.TEXTURE_3D, 'u_chain']];
  units.forEach(([tex, target, name], unit) => {
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(target, tex);
    gl.uniform1i(gl.getUniformLocation(prog, name), unit);
  });
  if (data.table.grid) {
    gl.uniform2f(gl.getUniformLocation(prog, 'u_lobe_grid'), data.table.grid[0], data.table.grid[1]);
  } else {
    gl.uniform1fv(gl.getUniformLocation(prog, 'u_elevations'), new Float32Array(data.table.elevations));
  }
  const c = data.chainInfo;
  gl.uniform1f(gl.getUniformLocation(prog, 'u_chain_sigma0'), c.sigma0);
  gl.uniform1f(gl.getUniformLocation(prog, 'u_chain_log_ratio'), c.levels.length > 1 ? Math.log(c.ratio) : 1.0);
}

/** Image right and up of a camera looking along -V, +Y up (+Z when V = +-Y): relight.gl.render.camera_basis. */
export function cameraBasis(v) {
  const up = Math.abs(v[1]) < 1 - 1e-9 ? [0, 1, 0] : [0, 0, 1];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  let right = cross(up, v);
  const len = Math.hypot(...right);
  right = right.map((x) => x / len);
  return [right, cross(v, right)];
}

/**
 * The unit sphere (orthographic along -view, the frame [-1, 1]^2) as linear radiance: Float32Array of
 * size * size * 4, row 0 at the bottom (GL order). Needs EXT_color_buffer_float.
 */
export async function renderSphere(gl, material, chain, view, size, base = 'shaders/') {
  if (!gl.getExtension('EXT_color_buffer_float')) {
    throw new Error('EXT_color_buffer_float is not available');
  }
  const data = uploadGaussian(gl, material, chain);
  const prog = await gaussianProgram(gl, gaussianDefines({ table: data.table, levels: chain.levels.length,
    sphere: true }), base);
  bindGaussian(gl, prog, data);
  const len = Math.hypot(...view);
  const v = view.map((x) => x / len);
  const [right, up] = cameraBasis(v);
  gl.uniform3fv(gl.getUniformLocation(prog, 'u_view_direction'), v);
  gl.uniform3fv(gl.getUniformLocation(prog, 'u_right'), right);
  gl.uniform3fv(gl.getUniformLocation(prog, 'u_up'), up);
  gl.uniform2f(gl.getUniformLocation(prog, 'u_viewport'), size, size);
  const target = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, target);
  gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, size, size);
  const fbo = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fbo);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, target, 0);
  gl.viewport(0, 0, size, size);
  gl.clearColor(0, 0, 0, 1);
  gl.clear(gl.COLOR_BUFFER_BIT);
  const quad = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, quad);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 0, 3, -1, 0, -1, 3, 0]), gl.STATIC_DRAW);
  const loc = gl.getAttribLocation(prog, 'a_position');
  gl.enableVertexAttribArray(loc);
  gl.vertexAttribPointer(loc, 3, gl.FLOAT, false, 0, 0);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  const out = new Float32Array(size * size * 4);
  gl.readPixels(0, 0, size, size, gl.RGBA, gl.FLOAT, out);
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  return out;
}
