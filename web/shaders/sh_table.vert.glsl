// Per-vertex shading with a per-view SH table (seed 003, Kautz, Sloan & Snyder 2002, §4 "Rendering Algorithm",
// eq. 1): Q_p = sum_i L_{p,i} c_i(v_p), shared by relight/gl/sh_table.py (moderngl) and web/src/sh_table.js.
//
// Modes (one define):
//   MODE_GENERAL      view and lighting both change: per vertex the world lighting u_light is rotated into the
//                     local frame on the GPU (sh_rotation.glsl, steps 1-4 of §4);
//   MODE_FIXED_LIGHT  the local lighting L_p was stored per vertex (u_vertex_data, a PRECOMPUTE pass): steps 2-4;
//   MODE_FIXED_VIEW   the table coefficients at v_p, turned to the world frame, were stored per vertex: per frame
//                     one dot product with u_light.
//   MODE_TRANSFER     PRT (§5): per vertex the folded transfer matrix T'_p = S M(R_p) T_p (relight/sh_prt.py) in
//                     u_vertex_data, row i in SHR_ROW_TEXELS RGBA texels (row-major, rows padded with zeros),
//                     vertex p from texel p * SHR_COUNT * SHR_ROW_TEXELS: L_p = T'_p u_light, then steps 3-4.
//                     With TRANSFER_WORLD the matrices are the world-frame T_p (unfolded: relight.visibility's
//                     shadow_matrix) and L_p = S M(R_p) (T_p u_light) is rotated here, as MODE_GENERAL does.
// Targets (at most one define):
//   (none)            the mesh through u_view_projection, v_color = Q;
//   PROBE             one point per vertex at texel gl_VertexID (row-major) of a u_output_size float target (tests);
//   PRECOMPUTE        the per-vertex data of the fixed modes: instance i writes coefficient i of vertex
//                     gl_VertexID to texel gl_VertexID * SHR_COUNT + i (MODE_FIXED_LIGHT: L_p; MODE_FIXED_VIEW:
//                     (S M)^T c(v_p), zero where the vertex faces away).
// Table: a texture array of SHR_COUNT RGB layers, R x R texels over the view map (TABLE_PARABOLIC or
// TABLE_HEMI_OCTAHEDRAL; relight/view_maps.py), bilinear, clamped to the edge; views below z = VIEW_RIM_Z are moved to
// the rim direction of their azimuth first. Frames: t = a_tangent.xyz, b = a_tangent.w (n x t), n = a_normal.
// TABLE_VARYING (with TABLE_COUNT = Q >= 2): spatially varying tables (§3, Fig. 4; relight/sh_table_varying.py): Q
// tables stacked in the array (layer q * SHR_COUNT + i), a_table the vertex's fractional position among them
// (VaryingTable.positions: linear in q or log q), clamped to [0, Q - 1]; the lookup blends the two neighbours.

#include "generated/constants.glsl"
#include "sh_rotation.glsl"

in vec3 a_position;
in vec3 a_normal;
in vec4 a_tangent;
#ifdef TABLE_VARYING
in float a_table;
#endif

uniform mat4 u_view_projection;
uniform vec3 u_view;               // unit world direction toward the distant viewer
uniform vec3 u_light[SHR_COUNT];   // world real SH lighting coefficients (RGB)
uniform highp sampler2DArray u_table;
uniform highp sampler2D u_vertex_data;
uniform ivec2 u_output_size;  // PROBE / PRECOMPUTE target (texels)

out vec3 v_color;

vec3 tbl_c[SHR_COUNT];

#define SHR_ROW_TEXELS ((SHR_COUNT + 3) / 4)

vec3 table_clamp(vec3 v) {
    if (v.z >= VIEW_RIM_Z) {
        return v;
    }
    float r = length(v.xy);
    vec2 dir = r > 0.0 ? v.xy / r : vec2(1.0, 0.0);
    return vec3(dir * sqrt(1.0 - VIEW_RIM_Z * VIEW_RIM_Z), VIEW_RIM_Z);
}

vec2 table_uv(vec3 v) {
#ifdef TABLE_PARABOLIC
    vec2 p = v.xy / (1.0 + v.z);
#else
    float s = abs(v.x) + abs(v.y) + v.z;
    vec2 ab = v.xy / s;
    vec2 p = vec2(ab.x + ab.y, ab.x - ab.y);
#endif
    return 0.5 * (p + 1.0);
}

void table_lookup(vec3 v_local) {
    vec2 uv = table_uv(table_clamp(normalize(v_local)));
#ifdef TABLE_VARYING
    float pos = clamp(a_table, 0.0, float(TABLE_COUNT - 1));
    float k0 = min(floor(pos), float(TABLE_COUNT - 2));
    float w = pos - k0;
    int base = int(k0) * SHR_COUNT;
    for (int i = 0; i < SHR_COUNT; ++i) {
        tbl_c[i] = mix(textureLod(u_table, vec3(uv, float(base + i)), 0.0).rgb,
                       textureLod(u_table, vec3(uv, float(base + SHR_COUNT + i)), 0.0).rgb, w);
    }
#else
    for (int i = 0; i < SHR_COUNT; ++i) {
        tbl_c[i] = textureLod(u_table, vec3(uv, float(i)), 0.0).rgb;
    }
#endif
}

vec3 vertex_data(int vertex, int i) {
    int k = vertex * SHR_COUNT + i;
    int w = textureSize(u_vertex_data, 0).x;
    return texelFetch(u_vertex_data, ivec2(k % w, k / w), 0).rgb;
}

void main() {
    vec3 n = normalize(a_normal);
    vec3 t = normalize(a_tangent.xyz);
    vec3 b = a_tangent.w * cross(n, t);
    vec3 v_local = vec3(dot(t, u_view), dot(b, u_view), dot(n, u_view));
    vec3 q = vec3(0.0);
#if defined(MODE_FIXED_VIEW) && !defined(PRECOMPUTE)
    for (int i = 0; i < SHR_COUNT; ++i) {
        q += u_light[i] * vertex_data(gl_VertexID, i);
    }
#else
    // local lighting L_p
#  if defined(MODE_GENERAL) || (defined(MODE_FIXED_LIGHT) && defined(PRECOMPUTE))
    for (int i = 0; i < SHR_COUNT; ++i) {
        shr_c[i] = u_light[i];
    }
    sh_rotate_frame(t, b, n, false);
#  elif defined(MODE_FIXED_LIGHT)
    for (int i = 0; i < SHR_COUNT; ++i) {
        shr_c[i] = vertex_data(gl_VertexID, i);
    }
#  elif defined(MODE_TRANSFER)
    vec3 light[4 * SHR_ROW_TEXELS];
    for (int j = 0; j < 4 * SHR_ROW_TEXELS; ++j) {
        light[j] = j < SHR_COUNT ? u_light[j] : vec3(0.0);
    }
    int w = textureSize(u_vertex_data, 0).x;
    int base = gl_VertexID * SHR_COUNT * SHR_ROW_TEXELS;
    for (int i = 0; i < SHR_COUNT; ++i) {
        vec3 acc = vec3(0.0);
        for (int j4 = 0; j4 < SHR_ROW_TEXELS; ++j4) {
            int k = base + i * SHR_ROW_TEXELS + j4;
            vec4 row = texelFetch(u_vertex_data, ivec2(k % w, k / w), 0);
            acc += row.x * light[4 * j4] + row.y * light[4 * j4 + 1] + row.z * light[4 * j4 + 2]
                + row.w * light[4 * j4 + 3];
        }
        shr_c[i] = acc;
    }
#    ifdef TRANSFER_WORLD
    sh_rotate_frame(t, b, n, false);
#    endif
#  endif
#  ifdef PRECOMPUTE
#    ifdef MODE_FIXED_VIEW
    table_lookup(v_local);
    for (int i = 0; i < SHR_COUNT; ++i) {
        shr_c[i] = v_local.z > 0.0 ? tbl_c[i] : vec3(0.0);
    }
    sh_rotate_frame(t, b, n, true);
#    endif
    q = shr_c[gl_InstanceID];
#  else
    table_lookup(v_local);
    for (int i = 0; i < SHR_COUNT; ++i) {
        q += shr_c[i] * tbl_c[i];
    }
    q = v_local.z > 0.0 ? q : vec3(0.0);
#  endif
#endif
    v_color = q;
#if defined(PROBE) || defined(PRECOMPUTE)
#  ifdef PRECOMPUTE
    int k = gl_VertexID * SHR_COUNT + gl_InstanceID;
#  else
    int k = gl_VertexID;
#  endif
    vec2 texel = vec2(float(k % u_output_size.x) + 0.5, float(k / u_output_size.x) + 0.5);
    gl_Position = vec4(texel / vec2(u_output_size) * 2.0 - 1.0, 0.0, 1.0);
    gl_PointSize = 1.0;
#else
    gl_Position = u_view_projection * vec4(a_position, 1.0);
#endif
}
