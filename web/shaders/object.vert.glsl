// Object vertices in world space for the SHRM and environment-reflection shaders.

in vec3 a_position;
in vec3 a_normal;

uniform mat4 u_model;
uniform mat4 u_view_projection;
uniform mat3 u_normal_matrix;  // inverse transpose of u_model's upper 3 x 3

out vec3 v_world;
out vec3 v_normal;

void main() {
    vec4 world = u_model * vec4(a_position, 1.0);
    v_world = world.xyz;
    v_normal = u_normal_matrix * a_normal;
    gl_Position = u_view_projection * world;
}
