// In-out factorized PRT per vertex (Mahajan, Tseng & Ramamoorthi 2008, eq. 4; relight/inout_prt.py is the CPU
// reference): B = sum_k sigma_k h_k(F w_o) (T_k . L), shared by relight/gl/inout.py (moderngl) and
// web/src/inout_object.js; the fragment stage is sh_table.frag.glsl (the interpolated v_color).
//
// u_transport: float16 RGBA data texture indexed by gl_VertexID (relight/vertex_texture.py), the vertex's K x n
//   transport values T_kj (world-frame real SH, n = (INOUT_ORDER + 1)^2, index k n + j) in ceil(K n / 4) texels.
// u_factors: R32F, one row per term k: texel 0 = m, texel 1 = parity (0 cos, 1 sin), texels 2 .. N + 1 = sigma_k
//   times the radial profile of h_k at theta = i (pi / 2) / (N - 1) (relight/inout_factors.py), interpolated
//   linearly in theta here as on the CPU.
// u_light: the world lighting's real SH coefficients (RGB), already rotated with the environment.
// Local frame: n and tangent_field(n); with whole (cos, sin) pairs the sum depends on the normal only, so any
// tangent matches the one the transport was computed with.
// View: u_eye.w = 0: the distant direction u_view (toward the viewer); u_eye.w = 1: toward the eye point u_eye.xyz.
// Target: PROBE writes vertex gl_VertexID's radiance to texel gl_VertexID of a u_output_size float target (tests).

#include "generated/constants.glsl"
#include "common.glsl"

#define INOUT_COUNT ((INOUT_ORDER + 1) * (INOUT_ORDER + 1))
// INOUT_STORED: the terms each vertex stores (the texel stride); INOUT_TERMS <= INOUT_STORED are summed, so the
// viewer's K slider truncates without new data (whole pairs: relight/inout_factors.py).
#ifndef INOUT_STORED
#define INOUT_STORED INOUT_TERMS
#endif

in vec3 a_position;
in vec3 a_normal;

uniform mat4 u_model;
uniform mat4 u_view_projection;
uniform vec3 u_light[INOUT_COUNT];
uniform vec3 u_view;
uniform vec4 u_eye;
uniform highp sampler2D u_transport;
uniform highp sampler2D u_factors;
uniform ivec2 u_output_size;

out vec3 v_color;

void main() {
    vec3 n = normalize(a_normal);
    vec4 world = u_model * vec4(a_position, 1.0);
    vec3 v = u_eye.w > 0.5 ? normalize(u_eye.xyz - world.xyz) : normalize(u_view);
    vec3 t = tangent_field(n);
    vec3 b = cross(n, t);
    vec3 vl = vec3(dot(t, v), dot(b, v), dot(n, v));
    vec3 color = vec3(0.0);
    if (vl.z > 0.0) {
        vec3 q[INOUT_TERMS];
        for (int k = 0; k < INOUT_TERMS; ++k) {
            q[k] = vec3(0.0);
        }
        const int total = INOUT_TERMS * INOUT_COUNT;
        const int stride = (INOUT_STORED * INOUT_COUNT + 3) / 4;
        int w = textureSize(u_transport, 0).x;
        for (int i = 0; i < (total + 3) / 4; ++i) {
            int tx = gl_VertexID * stride + i;
            vec4 texel = texelFetch(u_transport, ivec2(tx % w, tx / w), 0);
            for (int c = 0; c < 4; ++c) {
                int idx = 4 * i + c;
                if (idx < total) {
                    int k = idx / INOUT_COUNT;
                    q[k] += u_light[idx - k * INOUT_COUNT] * texel[c];
                }
            }
        }
        int size = textureSize(u_factors, 0).x - 2;
        float x = acos(clamp(vl.z, 0.0, 1.0)) / (0.5 * PI) * float(size - 1);
        int i0 = clamp(int(floor(x)), 0, size - 2);
        float f = x - float(i0);
        float phi = atan(vl.y, vl.x);
        for (int k = 0; k < INOUT_TERMS; ++k) {
            float m = texelFetch(u_factors, ivec2(0, k), 0).r;
            float parity = texelFetch(u_factors, ivec2(1, k), 0).r;
            float h0 = texelFetch(u_factors, ivec2(2 + i0, k), 0).r;
            float h1 = texelFetch(u_factors, ivec2(3 + i0, k), 0).r;
            float a = parity > 0.5 ? sin(m * phi) : cos(m * phi);
            color += (h0 + (h1 - h0) * f) * a * q[k];
        }
    }
    v_color = color;
#ifdef PROBE
    vec2 texel = vec2(float(gl_VertexID % u_output_size.x) + 0.5, float(gl_VertexID / u_output_size.x) + 0.5);
    gl_Position = vec4(texel / vec2(u_output_size) * 2.0 - 1.0, 0.0, 1.0);
    gl_PointSize = 1.0;
#else
    gl_Position = u_view_projection * world;
#endif
}
