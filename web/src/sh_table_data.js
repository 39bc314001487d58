// Data layouts and the camera shared by the SH-table panels (web/src/brushed_panel.js, sh_order_grid.js): the
// service's table.bin and transfer textures re-packed for SHTableGL, and an orthographic view-projection.

/** Column-major orthographic view-projection looking from `dir` (toward the viewer) at the unit ball. */
export function viewProjection(dir, half = 1.15) {
  const v = dir.map((x) => x / Math.hypot(...dir));
  const up = Math.abs(v[1]) > 0.99 ? [0, 0, 1] : [0, 1, 0];
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const norm = (a) => a.map((x) => x / Math.hypot(...a));
  const r = norm(cross(up, v));
  const u = cross(v, r);
  const [near, far] = [0.5, 5.5];
  const eye = v.map((x) => 3 * x);
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const zs = -2 / (far - near);
  const rows = [[...r.map((x) => x / half), -dot(r, eye) / half], [...u.map((x) => x / half), -dot(u, eye) / half],
    [...v.map((x) => x * zs), -dot(v, eye) * zs - (far + near) / (far - near)], [0, 0, 0, 1]];
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c += 1) {
    for (let k = 0; k < 4; k += 1) {
      out[4 * c + k] = rows[k][c];
    }
  }
  return out;
}

/** table.bin (float16 [(F+1)^2, R, R, C]) as RGB float16 bits (C = 1 repeated). */
export function tableRgb(half, channels) {
  if (channels === 3) {
    return half;
  }
  const out = new Uint16Array(3 * half.length);
  for (let k = 0; k < half.length; k += 1) {
    out.fill(half[k], 3 * k, 3 * k + 3);
  }
  return out;
}

/**
 * A visibility job's shadow_matrix.bin (relight.vertex_texture: ceil(n^2 / 4) RGBA texels per vertex, the n x n
 * matrix row-major) as setTransfer's layout (count, n, 4 ceil(n / 4)), rows zero-padded.
 */
export function transferLayout(half, texture, n) {
  const row = 4 * Math.ceil(n / 4);
  const out = new Uint16Array(texture.vertices * n * row);
  for (let v = 0; v < texture.vertices; v += 1) {
    const base = 4 * v * texture.texels_per_vertex;
    for (let i = 0; i < n; i += 1) {
      out.set(half.subarray(base + i * n, base + (i + 1) * n), (v * n + i) * row);
    }
  }
  return out;
}
