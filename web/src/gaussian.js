// Seed 002's Gaussian-lobe shading in WebGL2: the viewer's side of relight/gl/gaussian.py, with the same GLSL
// (web/shaders/gaussian.glsl through gaussian.vert.glsl / gaussian.frag.glsl, assembled by shaders.js).
//
// Data are float16 bit patterns (Uint16Array), as stored: the material's lobes (per elevation and lobe: mu, sigma,
// 0, 0 and w_r, w_g, w_b, 0), packed for the shader by packLobes into one RGBA16F texture (row = elevation:
// (mu_k, sigma_k, w_r, w_g) per lobe, then the blue weights four to a texel; relight.gl.gaussian.pack_lobes), and
// the chain's levels (one S x 2S RGBA lat-long map each, one size) as the slices of one RGBA16F 3-D texture
// (LINEAR, REPEAT in u, CLAMP_TO_EDGE in v and across the levels, as relight.conventions.sample_latlong).

import { build, loadSources } from './shaders.js';

/** The shader's defines (relight.gl.gaussian.GaussianRenderer.defines). */
export function gaussianDefines({ lobes, elevations, levels, sphere = false, linear = true }) {
  const d = { GAUSSIAN_K: lobes, GAUSSIAN_N: elevations, GAUSSIAN_LEVELS: levels };
  if (linear) {
    d.OUTPUT_LINEAR = null;
  }
  if (sphere) {
    d.GAUSSIAN_SPHERE = null;
  }
  return d;
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

/**
 * Sampling of the bound lobe texture: LINEAR, CLAMP_TO_EDGE (gaussian.glsl interpolates the elevations with one
 * filtered lookup per texel).
 */
export function lobeSampling(gl) {
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
}

/** Texels per elevation of the packed lobe texture: one per lobe, then the blue weights four to a texel. */
export function lobeTexels(lobes) {
  return lobes + Math.floor((lobes + 3) / 4);
}

/**
 * The shader's lobe texture (float16 bits, N rows of lobeTexels(K) RGBA texels) from the material's `shape` and
 * `weight` (N * K * 4 each): texel k = (mu_k, sigma_k, w_k.r, w_k.g), then w_0.b, ..., w_{K-1}.b, zero-padded.
 */
export function packLobes(material) {
  const k = material.lobes;
  const n = material.elevations.length;
  const texels = lobeTexels(k);
  const out = new Uint16Array(n * texels * 4);
  for (let i = 0; i < n; i += 1) {
    for (let l = 0; l < k; l += 1) {
      const src = 4 * (i * k + l);
      const dst = 4 * (i * texels + l);
      out[dst] = material.shape[src];
      out[dst + 1] = material.shape[src + 1];
      out[dst + 2] = material.weight[src];
      out[dst + 3] = material.weight[src + 1];
      out[4 * (i * texels + k) + l] = material.weight[src + 2];
    }
  }
  return out;
}

/** Upload the packed lobes of `material` into the bound 2-D texture. */
export function uploadLobes(gl, material) {
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA16F, lobeTexels(material.lobes), material.elevations.length, 0, gl.RGBA,
    gl.HALF_FLOAT, packLobes(material));
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
  uploadLobes(gl, material);
  return { lobes, chain: uploadChain(gl, chain), material, chainInfo: chain };
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
  gl.uniform1fv(gl.getUniformLocation(prog, 'u_elevations'), new Float32Array(data.material.elevations));
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
  const prog = await gaussianProgram(gl, gaussianDefines({
    lobes: material.lobes, elevations: material.elevations.length, levels: chain.levels.length, sphere: true,
  }), base);
  const data = uploadGaussian(gl, material, chain);
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
