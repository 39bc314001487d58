// A full-screen triangle: a_position holds clip-space (x, y) of (-1, -1), (3, -1), (-1, 3).

in vec2 a_position;
out vec2 v_ndc;

void main() {
    v_ndc = a_position;
    gl_Position = vec4(a_position, 0.0, 1.0);
}
