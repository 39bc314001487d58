// Diffuse precomputed radiance transfer per vertex (Sloan, Kautz & Snyder 2002, §4 and §8: exit radiance
// = albedo T(x) . L), shared by relight/gl/prt.py (moderngl) and web/src/prt_object.js; the fragment stage is
// sh_table.frag.glsl (the interpolated v_color, linear or through the display transform).
//
// Per-vertex data comes from float16 RGBA data textures indexed by gl_VertexID, the canonical vertex id of an
// indexed draw of geometry.bin (relight/vertex_texture.py): value k of vertex v in texel v * ceil(n / 4) + k / 4,
// channel k % 4, row-major in a texture textureSize().x texels wide. u_light holds the world lighting's real SH
// coefficients (RGB, order PRT_ORDER, index l^2 + l + m) already rotated with the environment, so rotating the
// map re-lights every frame without new per-vertex data.
//
// Modes (one define):
//   MODE_UNSHADOWED  irradiance of an unoccluded point: sum_k L_k c_k(n), c_lm(n) = 2 I_l Yr_lm(n) with
//                    I_l = int_0^1 mu P_l(mu) dmu (u_cosine[l]; relight.mesh_render.unshadowed_transfer);
//   MODE_AO          the same times the vertex's ambient occlusion (u_ao, 1 value per vertex);
//   MODE_TRANSFER    the shadowed transfer vector T (u_transfer, (PRT_ORDER + 1)^2 values per vertex): T . L.
// Target: PROBE writes vertex gl_VertexID's radiance to texel gl_VertexID of a u_output_size float target (tests).

#include "generated/constants.glsl"
#include "common.glsl"
#define SH_ORDER PRT_ORDER
#include "sh.glsl"

in vec3 a_position;
in vec3 a_normal;

uniform mat4 u_model;              // the mesh into the unit ball (translation and uniform scale)
uniform mat4 u_view_projection;
uniform vec3 u_light[SH_COUNT];
uniform float u_cosine[PRT_ORDER + 1];
uniform float u_albedo;
uniform highp sampler2D u_transfer;
uniform highp sampler2D u_ao;
uniform ivec2 u_output_size;

out vec3 v_color;

float vertex_value(highp sampler2D tex, int vertex, int k, int texels) {
    int t = vertex * texels + k / 4;
    int w = textureSize(tex, 0).x;
    vec4 texel = texelFetch(tex, ivec2(t % w, t / w), 0);
    int c = k - 4 * (k / 4);
    return c == 0 ? texel.x : (c == 1 ? texel.y : (c == 2 ? texel.z : texel.w));
}

void main() {
    vec3 q = vec3(0.0);
#ifdef MODE_TRANSFER
    const int texels = (SH_COUNT + 3) / 4;
    for (int k = 0; k < SH_COUNT; ++k) {
        q += u_light[k] * vertex_value(u_transfer, gl_VertexID, k, texels);
    }
#else
    float y[SH_COUNT];
    sh_real(sh_frame(normalize(a_normal)), y);
    for (int l = 0; l <= PRT_ORDER; ++l) {
        for (int k = l * l; k <= l * l + 2 * l; ++k) {
            q += u_light[k] * (u_cosine[l] * y[k]);
        }
    }
#  ifdef MODE_AO
    q *= vertex_value(u_ao, gl_VertexID, 0, 1);
#  endif
#endif
    v_color = u_albedo * q;
#ifdef PROBE
    vec2 texel = vec2(float(gl_VertexID % u_output_size.x) + 0.5, float(gl_VertexID / u_output_size.x) + 0.5);
    gl_Position = vec4(texel / vec2(u_output_size) * 2.0 - 1.0, 0.0, 1.0);
    gl_PointSize = 1.0;
#else
    gl_Position = u_view_projection * (u_model * vec4(a_position, 1.0));
#endif
}
