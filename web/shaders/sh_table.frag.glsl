// Output of sh_table.vert.glsl: the interpolated radiance (OUTPUT_LINEAR, float targets: the moderngl renderer,
// probes, the per-vertex data passes) or its display transform (tonemap.glsl, the viewer).

#ifndef OUTPUT_LINEAR
#include "generated/constants.glsl"
#include "tonemap.glsl"
#endif

in vec3 v_color;

layout(location = 0) out vec4 o_color;

void main() {
#ifdef OUTPUT_LINEAR
    o_color = vec4(v_color, 1.0);
#else
    o_color = vec4(tonemap_display(v_color), 1.0);
#endif
}
