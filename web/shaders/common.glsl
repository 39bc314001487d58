// Direction conventions shared by every relight shader (docs/conventions.md, relight/conventions.py).
//
// World frame: +Y up. A lat-long map of H rows has row i at the polar angle theta = (i + 1/2) pi / H from +Y
// and column j of W at phi = ((j + 1/2) / W - 1/2) 2 pi, direction d = (sin t cos p, cos t, sin t sin p).
// Texture coordinates put the pixel centres at (j + 1/2) / W and (i + 1/2) / H, with row 0 (+Y) at t = 0, so
//   u = atan(z, x) / (2 pi) + 1/2,   v = theta / pi.
// Columns wrap (REPEAT), rows clamp at the poles (CLAMP_TO_EDGE): relight.shrm.sample_latlong.
// The SH Cartesian frame is (x', y', z') = (X, Z, Y) (z' = +Y is the pole).

vec2 latlong_uv(vec3 d) {
    d = normalize(d);
    return vec2(atan(d.z, d.x) / (2.0 * PI) + 0.5, acos(clamp(d.y, -1.0, 1.0)) / PI);
}

// The SH frame's Cartesian coordinates of a world direction.
vec3 sh_frame(vec3 d) {
    return vec3(d.x, d.z, d.y);
}

// Rotate a world direction about +Y by the angle whose cosine and sine are cs = (cos a, sin a), right-handed:
// +Z goes to +X for a = pi / 2. The environment rotated by a is looked up at rotate_y(d, -a).
vec3 rotate_y(vec3 d, vec2 cs) {
    return vec3(cs.x * d.x + cs.y * d.z, d.y, -cs.y * d.x + cs.x * d.z);
}

// R = 2 (N.V) N - V (relight.shrm.reflect_dirs).
vec3 reflect_view(vec3 n, vec3 v) {
    return 2.0 * dot(n, v) * n - v;
}

// The tangent of T-centred (Kajiya-Kay) lobes: normalize(+Y x N), +X at the poles (relight.shrm.tangent_field).
vec3 tangent_field(vec3 n) {
    vec3 t = vec3(n.z, 0.0, -n.x);
    float len = length(t);
    return len > 1e-12 ? t / len : vec3(1.0, 0.0, 0.0);
}
