// Spherical Harmonic Reflection Map evaluation (seed 000 §4 eqs. 6-7, §7.5 eq. 12; relight/shrm.py).
//
// The coefficient texture u_coefficients is a 2-D array: layer k holds one RGB lat-long map (common.glsl) of
// the component whose layers are first..first+count-1. A component has a centre (CENTER_R: the reflection
// vector, CENTER_N: the normal, CENTER_T: the tangent field) and a frame saying what its layers are:
//   FRAME_MAP     a plain reflection map B(C) (P = 0, relight.prefilter): weight 1;
//   FRAME_GLOBAL  global SHRM maps B~r_pq(C) (eq. 8): weight Yr_pq(V) of the view's world angles (eq. 7/12);
//   FRAME_LOCAL   local SHRM maps Br_pq(C) (eq. 6): weight Yr_pq(theta_o, phi_o) of V in C's local frame.
// The tables below come from the result's manifest (relight/gl/layout.py, web/src/layout.js):
//   SHRM_NUM_LAYERS, SHRM_NUM_COMPONENTS, SHRM_MAX_LAYERS (most layers of one component), SH_ORDER (largest P),
//   SHRM_HAS_LOCAL (1 if a component has local layers), SHRM_LAYER_SH (p^2 + p + q of each layer),
//   SHRM_COMPONENT_{CENTER,FRAME,FIRST,COUNT} (per component).

const int shrm_layer_sh[SHRM_NUM_LAYERS] = int[SHRM_NUM_LAYERS](SHRM_LAYER_SH);
const int shrm_component_center[SHRM_NUM_COMPONENTS] = int[SHRM_NUM_COMPONENTS](SHRM_COMPONENT_CENTER);
const int shrm_component_frame[SHRM_NUM_COMPONENTS] = int[SHRM_NUM_COMPONENTS](SHRM_COMPONENT_FRAME);
const int shrm_component_first[SHRM_NUM_COMPONENTS] = int[SHRM_NUM_COMPONENTS](SHRM_COMPONENT_FIRST);
const int shrm_component_count[SHRM_NUM_COMPONENTS] = int[SHRM_NUM_COMPONENTS](SHRM_COMPONENT_COUNT);

uniform highp sampler2DArray u_coefficients;
// Per-frame weights of the layers that do not vary over the map: 1 (FRAME_MAP) or Yr_pq(V) (FRAME_GLOBAL).
uniform float u_layer_weight[SHRM_NUM_LAYERS];

// The centre direction C of a lobe for a surface point with normal n and reflection vector r (shrm.lobe_centres).
vec3 shrm_centre(int center, vec3 n, vec3 r) {
    if (center == CENTER_N) {
        return n;
    }
    if (center == CENTER_T) {
        return tangent_field(n);
    }
    return r;
}

// V in the local frame of C as an SH-frame vector (theta_hat . V, phi_hat . V, C . V) (shrm.local_view_angles):
// theta_hat = (cos a cos b, -sin a, cos a sin b), phi_hat = (-sin b, 0, cos b) for C at the SH angles (a, b).
vec3 shrm_local_view(vec3 c, vec3 v) {
    float rho = length(c.xz);
    vec2 cs = rho > 0.0 ? c.xz / rho : vec2(1.0, 0.0);
    vec3 theta_hat = vec3(c.y * cs.x, -rho, c.y * cs.y);
    vec3 phi_hat = vec3(-cs.y, 0.0, cs.x);
    return vec3(dot(theta_hat, v), dot(phi_hat, v), dot(c, v));
}

// Harmonic weights of component `comp` for centre c and view v (both in the environment's frame).
void shrm_weights(int comp, vec3 c, vec3 v, out float y[SH_COUNT]) {
    int frame = shrm_component_frame[comp];
    if (frame == FRAME_LOCAL) {
        sh_real(shrm_local_view(c, v), y);
    } else if (frame == FRAME_GLOBAL) {
        sh_real(sh_frame(v), y);
    }
}

// Eq. 12 (distant viewer) at texel (column, row) of component comp's maps with the per-frame weights only
// (plain maps and global layers): sum_k u_layer_weight[k] B_k(texel).
vec3 shrm_view_texel_uniform(int comp, ivec2 texel) {
    int first = shrm_component_first[comp];
    int count = shrm_component_count[comp];
    vec3 sum = vec3(0.0);
    for (int i = 0; i < SHRM_MAX_LAYERS; ++i) {
        if (i < count) {
            sum += u_layer_weight[first + i] * texelFetch(u_coefficients, ivec3(texel, first + i), 0).rgb;
        }
    }
    return sum;
}

// Eq. 12 (distant viewer) at texel (column, row) of component comp's maps; c is the texel's centre direction.
// Layers with per-frame weights use u_layer_weight; local layers are weighted at this texel (eq. 6 = eq. 12).
vec3 shrm_view_texel(int comp, ivec2 texel, vec3 c, vec3 v) {
    float y[SH_COUNT];
    bool local_frame = shrm_component_frame[comp] == FRAME_LOCAL;
    if (local_frame) {
        shrm_weights(comp, c, v, y);
    }
    int first = shrm_component_first[comp];
    int count = shrm_component_count[comp];
    vec3 sum = vec3(0.0);
    for (int i = 0; i < SHRM_MAX_LAYERS; ++i) {
        if (i >= count) {
            break;
        }
        int k = first + i;
        float w = local_frame ? y[shrm_layer_sh[k]] : u_layer_weight[k];
        sum += w * texelFetch(u_coefficients, ivec3(texel, k), 0).rgb;
    }
    return sum;
}

// Eq. 6 (or eq. 7 for global maps) per pixel, for a near viewer: every component's layers sampled bilinearly
// at its centre and weighted with the harmonics of this pixel's own view direction v (environment frame).
vec3 shrm_sum(vec3 n, vec3 r, vec3 v) {
    vec3 sum = vec3(0.0);
    for (int comp = 0; comp < SHRM_NUM_COMPONENTS; ++comp) {
        vec3 c = shrm_centre(shrm_component_center[comp], n, r);
        vec2 uv = latlong_uv(c);
        float y[SH_COUNT];
        bool uniform_weights = shrm_component_frame[comp] == FRAME_MAP;
        if (!uniform_weights) {
            shrm_weights(comp, c, v, y);
        }
        int first = shrm_component_first[comp];
        int count = shrm_component_count[comp];
        for (int i = 0; i < SHRM_MAX_LAYERS; ++i) {
            if (i >= count) {
                break;
            }
            int k = first + i;
            float w = uniform_weights ? u_layer_weight[k] : y[shrm_layer_sh[k]];
            sum += w * texture(u_coefficients, vec3(uv, float(k))).rgb;
        }
    }
    return sum;
}

// The per-frame view map (eq. 12 summed once per frame, §7.5) holds one S x 2S band per component, stacked
// along t: band comp covers texture rows comp S .. (comp + 1) S - 1, row 0 of a band being the +Y row.
// Lookup: bilinear, columns wrap, rows clamped to the band's first and last pixel centres (sample_latlong).
uniform highp sampler2D u_view_map;
uniform float u_view_map_rows;  // S

vec3 shrm_view_map_lookup(vec3 n, vec3 r) {
    vec3 sum = vec3(0.0);
    for (int comp = 0; comp < SHRM_NUM_COMPONENTS; ++comp) {
        vec3 c = shrm_centre(shrm_component_center[comp], n, r);
        vec2 uv = latlong_uv(c);
        float row = clamp(uv.y * u_view_map_rows, 0.5, u_view_map_rows - 0.5);
        float t = (float(comp) * u_view_map_rows + row) / (float(SHRM_NUM_COMPONENTS) * u_view_map_rows);
        sum += texture(u_view_map, vec2(uv.x, t)).rgb;
    }
    return sum;
}
