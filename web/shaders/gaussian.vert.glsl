// Vertices of the Gaussian-lobe shader (seed 002): world position and normal, and with GAUSSIAN_VISIBILITY the
// vertex's SH visibility (16 coefficients, relight.visibility's world-frame real basis) as four vec4 attributes,
// interpolated to the pixel like the normal (relight.mesh_render.interpolate on the CPU). GAUSSIAN_SPHERE: a
// full-screen triangle (the fragment shader finds the sphere's normal per pixel).

in vec3 a_position;
#ifndef GAUSSIAN_SPHERE
in vec3 a_normal;
#ifdef GAUSSIAN_VISIBILITY
in vec4 a_visibility0;
in vec4 a_visibility1;
in vec4 a_visibility2;
in vec4 a_visibility3;
out vec4 v_visibility0;
out vec4 v_visibility1;
out vec4 v_visibility2;
out vec4 v_visibility3;
#endif
uniform mat4 u_view_projection;
out vec3 v_normal;
#endif

void main() {
#ifdef GAUSSIAN_SPHERE
    gl_Position = vec4(a_position.xy, 0.0, 1.0);
#else
    v_normal = a_normal;
#ifdef GAUSSIAN_VISIBILITY
    v_visibility0 = a_visibility0;
    v_visibility1 = a_visibility1;
    v_visibility2 = a_visibility2;
    v_visibility3 = a_visibility3;
#endif
    gl_Position = u_view_projection * vec4(a_position, 1.0);
#endif
}
