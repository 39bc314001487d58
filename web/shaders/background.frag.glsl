// The environment behind the object, sharp (the environment map itself, not the prefiltered one), through the
// same display transform as the object. v_ndc comes from fullscreen.vert.glsl.

#include "generated/constants.glsl"
#include "common.glsl"
#include "tonemap.glsl"

in vec2 v_ndc;

uniform mat4 u_inverse_view_projection;
uniform vec2 u_env_rotation;  // as in object.frag.glsl
uniform highp sampler2D u_environment;

layout(location = 0) out vec4 o_color;

void main() {
    vec4 near = u_inverse_view_projection * vec4(v_ndc, -1.0, 1.0);
    vec4 far = u_inverse_view_projection * vec4(v_ndc, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w - near.xyz / near.w);
    vec3 color = texture(u_environment, latlong_uv(rotate_y(dir, u_env_rotation))).rgb;
    o_color = vec4(tonemap_display(color), 1.0);
}
