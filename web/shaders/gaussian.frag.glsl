// Seed 002's per-pixel shading (§5): Gaussian lobes looked up in the Gaussian chain (gaussian.glsl), for a mesh or
// the unit sphere (GAUSSIAN_SPHERE: orthographic, the frame [-1, 1]^2 as relight.shrm.sphere_geometry), seen by a
// distant viewer along -u_view_direction. GAUSSIAN_PLAIN: the baseline, the chain's sharpest level looked up at R
// (one texture lookup: a plain environment reflection). OUTPUT_LINEAR: radiance out (float targets), else the
// display transform (tonemap.glsl).

#include "generated/constants.glsl"
#include "common.glsl"
#include "gaussian.glsl"
#ifndef OUTPUT_LINEAR
#include "tonemap.glsl"
#endif

uniform vec3 u_view_direction;  // from the object toward the (distant) viewer, unit
#ifdef GAUSSIAN_SPHERE
uniform vec2 u_viewport;  // render target size in pixels
uniform vec3 u_right;  // image right and up (relight.gl.render.camera_basis)
uniform vec3 u_up;
#else
in vec3 v_normal;
#ifdef GAUSSIAN_VISIBILITY
in vec4 v_visibility0;
in vec4 v_visibility1;
in vec4 v_visibility2;
in vec4 v_visibility3;
#endif
#endif

#ifdef GAUSSIAN_PLAIN
uniform highp sampler2D u_env;  // the chain's sharpest level as a 2-D texture
#endif

layout(location = 0) out vec4 o_color;

void main() {
    vec3 v = u_view_direction;
#ifdef GAUSSIAN_SPHERE
    vec2 p = gl_FragCoord.xy / u_viewport * 2.0 - 1.0;
    float rr = dot(p, p);
    if (rr >= 1.0) {
        discard;
    }
    vec3 n = normalize(p.x * u_right + p.y * u_up + sqrt(1.0 - rr) * v);
#else
    vec3 n = normalize(v_normal);
#endif
#if defined(GAUSSIAN_PLAIN)
    vec3 color = texture(u_env, latlong_uv(reflect_view(n, v))).rgb;
#elif defined(GAUSSIAN_VISIBILITY)
    vec3 color = gaussian_shade(n, v, mat4(v_visibility0, v_visibility1, v_visibility2, v_visibility3));
#else
    vec3 color = gaussian_shade(n, v);
#endif
#ifdef OUTPUT_LINEAR
    o_color = vec4(color, 1.0);
#else
    o_color = vec4(tonemap_display(color), 1.0);
#endif
}
