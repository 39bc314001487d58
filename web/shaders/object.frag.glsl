// Shading of an object lit by an SHRM (seed 000 §7.5) or, for comparison, by a plain environment reflection.
//
// Defines: one of SHADING_VIEW_MAP (distant viewer: one lookup per component in the per-frame eq. 12 map),
// SHADING_LOCAL (near viewer: eq. 6 per pixel, shrm.glsl) or SHADING_PLAIN_ENV (the environment map looked up
// at R: the single-texture baseline); OBJECT_SPHERE (exact normals: the ray through the pixel centre, from
// gl_FragCoord and the inverse view-projection, meets the sphere; the rasterised proxy only has to cover it, and
// the depth written is the hit point's, so spheres and meshes of a scene occlude each other exactly);
// OUTPUT_LINEAR (write radiance, e.g. to a float target) instead of the display transform (tonemap.glsl).
//
// Radiance is clamped at 0 per colour, as relight.shrm.shade does (a truncated SHRM rings below 0 near grazing
// views and point-like lamps; against a non-negative truth the clamp never increases the error; issue 18).
//
// V is the unit vector from the surface toward the viewer: the pixel's own (perspective) or the camera's
// direction (orthographic). R = 2 (N.V) N - V is computed per pixel. The environment rotated by an angle a
// about +Y is looked up at rotate_y(d, -a): u_env_rotation holds (cos(-a), sin(-a)).

#include "generated/constants.glsl"
#include "common.glsl"
#if defined(SHADING_VIEW_MAP) || defined(SHADING_LOCAL)
#include "sh.glsl"
#include "shrm.glsl"
#endif
#ifndef OUTPUT_LINEAR
#include "tonemap.glsl"
#endif

in vec3 v_world;
in vec3 v_normal;

uniform vec3 u_camera_position;
uniform vec3 u_view_direction;  // from the target toward the camera (unit)
uniform bool u_orthographic;
uniform vec2 u_env_rotation;
#ifdef OBJECT_SPHERE
uniform vec4 u_sphere;  // centre, radius
uniform mat4 u_inverse_view_projection;
uniform mat4 u_view_projection;
uniform vec2 u_viewport;  // render target size in pixels
#endif
#ifdef SHADING_PLAIN_ENV
uniform highp sampler2D u_environment;
#endif

layout(location = 0) out vec4 o_color;

void main() {
#ifdef OBJECT_SPHERE
    // The ray through this pixel's centre (exact, unlike interpolated positions), then q = the centre's offset
    // from the ray's closest point, h = half the chord: p = centre + q - h ray (no b^2 - c cancellation).
    vec2 ndc = gl_FragCoord.xy / u_viewport * 2.0 - 1.0;
    vec4 near = u_inverse_view_projection * vec4(ndc, -1.0, 1.0);
    vec4 far = u_inverse_view_projection * vec4(ndc, 1.0, 1.0);
    vec3 origin = near.xyz / near.w;
    vec3 ray = normalize(far.xyz / far.w - origin);
    vec3 oc = origin - u_sphere.xyz;
    vec3 q = oc - dot(oc, ray) * ray;
    float h2 = u_sphere.w * u_sphere.w - dot(q, q);
    if (h2 < 0.0) {
        discard;
    }
    vec3 n = (q - sqrt(h2) * ray) / u_sphere.w;
    vec4 hit = u_view_projection * vec4(u_sphere.xyz + u_sphere.w * n, 1.0);
    gl_FragDepth = 0.5 * hit.z / hit.w + 0.5;  // the default depth range [0, 1]
#else
    vec3 ray = u_orthographic ? -u_view_direction : normalize(v_world - u_camera_position);
    vec3 n = normalize(v_normal);
#endif
    vec3 v = -ray;
    vec3 n_env = rotate_y(n, u_env_rotation);
    vec3 v_env = rotate_y(v, u_env_rotation);
    vec3 r_env = reflect_view(n_env, v_env);
#if defined(SHADING_VIEW_MAP)
    vec3 color = shrm_view_map_lookup(n_env, r_env);
#elif defined(SHADING_LOCAL)
    vec3 color = shrm_sum(n_env, r_env, v_env);
#else
    vec3 color = texture(u_environment, latlong_uv(r_env)).rgb;
#endif
    color = max(color, vec3(0.0));
#ifdef OUTPUT_LINEAR
    o_color = vec4(color, 1.0);
#else
    o_color = vec4(tonemap_display(color), 1.0);
#endif
}
