// The per-frame reflection map of a distant viewer (seed 000 §7.5, eq. 12): for every texel (alpha, beta) of
// every component's S x 2S band, B~(alpha, beta) = sum_pq B~r_pq(alpha, beta) Yr_pq(V)
// (relight.shrm.SHRMComponent.view_map). The viewport is 2S x (S x components); fragment row y of the target
// is band floor(y / S), lat-long row y - band S (row 0 = +Y, common.glsl). The viewers pass global layers
// (eq. 8 done once at load), so only the per-frame weights are needed; local layers also work (weighted per
// texel, SHRM_HAS_LOCAL).

#include "generated/constants.glsl"
#include "common.glsl"
#include "sh.glsl"
#include "shrm.glsl"

uniform vec3 u_view_env;  // the view direction V in the environment's frame (unit, toward the viewer)

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 frag = ivec2(gl_FragCoord.xy);
    int rows = int(u_view_map_rows);
    int comp = frag.y / rows;
    ivec2 texel = ivec2(frag.x, frag.y - comp * rows);
#if SHRM_HAS_LOCAL
    float theta = (float(texel.y) + 0.5) * PI / u_view_map_rows;
    float phi = ((float(texel.x) + 0.5) / (2.0 * u_view_map_rows) - 0.5) * 2.0 * PI;
    vec3 c = vec3(sin(theta) * cos(phi), cos(theta), sin(theta) * sin(phi));
    o_color = vec4(shrm_view_texel(comp, texel, c, u_view_env), 1.0);
#else
    o_color = vec4(shrm_view_texel_uniform(comp, texel), 1.0);
#endif
}
