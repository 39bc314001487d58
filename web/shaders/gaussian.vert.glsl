// Vertices of the Gaussian-lobe shader (seed 002): world position and normal, and with GAUSSIAN_VISIBILITY the
// vertex's SH visibility (16 coefficients, relight.visibility's world-frame real basis) as four vec4 attributes,
// interpolated to the pixel like the normal (relight.mesh_render.interpolate on the CPU). GAUSSIAN_SPHERE: a
// full-screen triangle (the fragment shader finds the sphere's normal per pixel). GAUSSIAN_MODEL: the mesh is placed
// by u_model (a uniform scale, rotation and translation: a scene object in the viewer, web/src/scene_parts.js)
// and its normal turned into the environment's frame by u_normal_env (the environment's rotation).

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
#ifdef GAUSSIAN_MODEL
uniform mat4 u_model;
uniform mat3 u_normal_env;
#endif
out vec3 v_normal;
#endif

void main() {
#ifdef GAUSSIAN_SPHERE
    gl_Position = vec4(a_position.xy, 0.0, 1.0);
#else
#ifdef GAUSSIAN_MODEL
    v_normal = u_normal_env * (mat3(u_model) * a_normal);
#else
    v_normal = a_normal;
#endif
#ifdef GAUSSIAN_VISIBILITY
    v_visibility0 = a_visibility0;
    v_visibility1 = a_visibility1;
    v_visibility2 = a_visibility2;
    v_visibility3 = a_visibility3;
#endif
#ifdef GAUSSIAN_MODEL
    gl_Position = u_view_projection * (u_model * vec4(a_position, 1.0));
#else
    gl_Position = u_view_projection * vec4(a_position, 1.0);
#endif
#endif
}
