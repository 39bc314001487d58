// Gaussian lobes with a Gaussian-prefiltered chain (Green, Kautz & Durand 2007, §5, eqs. 5 and 7): the GPU twin
// of relight.sg_render.lobe_terms and relight.sg_shadow.lobe_visibility (docs/conventions.md, "Gaussian lobes").
//
// Defines: GAUSSIAN_K (lobes), GAUSSIAN_N (elevations), GAUSSIAN_LEVELS (chain levels); with GAUSSIAN_VISIBILITY
// also VIS_MODE (VIS_AO, VIS_SH or VIS_SH_LOBE below) and SH_ORDER <= 3 (the visibility's order).
// Data, all float16 as stored (the paper's Fig. 3 layout):
//   u_lobes        GAUSSIAN_LOBE_TEXELS x N texels (y = elevation): texel k < K = (mu_k, sigma_k, w_k.r, w_k.g)
//                  (radians; w the lobe's integral), then w_0.b, ..., w_{K-1}.b four to a texel
//                  (relight.gl.gaussian.pack_lobes, web/src/gaussian.js packLobes);
//   u_elevations   the N elevations theta_o (radians, increasing);
//   u_chain        the levels G_{sigma_j} * L as the slices of one 3-D texture (every level the same S x 2S
//                  lat-long size), LINEAR in all three axes, REPEAT in u, CLAMP_TO_EDGE in v and across the
//                  levels: relight.conventions.sample_latlong within a level.
// u_lobes is LINEAR and CLAMP_TO_EDGE: one lookup per texel at its centre across and at texel coordinate j + f
// along the elevations interpolates linearly in theta_o (the sampler's weights), clamped at the end elevations
// (GaussianLobes.params_at), with no weight on the neighbouring texels.
// A lobe's level is x = log(sigma / sigma_0) / log(ratio), clamped to the chain, blended linearly between floor(x)
// and floor(x) + 1 (relight.gaussian_chain.sample_chain) by the 3-D texture's filter.
// Written for SIMD rasterisers as much as for GPUs (bench/gaussian_frame.py, llvmpipe): no loop over lobes and no
// array indexed per pixel (llvmpipe keeps such arrays in memory), one filtered lookup per lobe in the chain.

#define VIS_AO 1
#define VIS_SH 2
#define VIS_SH_LOBE 3

// Texels per elevation of u_lobes: (mu_k, sigma_k, w_k.r, w_k.g) for each lobe k, then the blue weights four to
// a texel.
#define GAUSSIAN_LOBE_TEXELS (GAUSSIAN_K + (GAUSSIAN_K + 3) / 4)

uniform highp sampler2D u_lobes;
uniform float u_elevations[GAUSSIAN_N];
uniform highp sampler3D u_chain;
uniform float u_chain_sigma0;
uniform float u_chain_log_ratio;

// The interval j (u_elevations[j] <= theta < u_elevations[j + 1], j <= N - 2) and the fraction f within it, by
// bisection: ceil(log2(N - 1)) steps (the fit's elevations are not evenly spaced: relight.sgfit_refine inserts
// some where interpolation fails, up to N = 39; a linear scan cost N - 2 compares per pixel).
void gaussian_interval(float theta, out int j, out float f) {
    j = 0;
    f = 0.0;
#if GAUSSIAN_N > 1
    float t = clamp(theta, u_elevations[0], u_elevations[GAUSSIAN_N - 1]);
    int hi = GAUSSIAN_N - 1;
    while (hi - j > 1) {
        int mid = (j + hi) / 2;
        if (t >= u_elevations[mid]) {
            j = mid;
        } else {
            hi = mid;
        }
    }
    f = (t - u_elevations[j]) / (u_elevations[j + 1] - u_elevations[j]);
#endif
}

// e = normalize(n - (n.r) r): the unit vector along n's component perpendicular to r, toward n in the plane of
// incidence; any perpendicular where r = n (mu = 0 there). It is the same for every lobe, so it is computed once
// per pixel; lobe k's centre is then c_k = cos(mu_k) r + sin(mu_k) e, r rotated by mu_k toward n
// (relight.brdf.gaussian_lobes.lobe_centres).
vec3 gaussian_axis(vec3 n, vec3 r) {
    vec3 e = n - dot(n, r) * r;
    float len = length(e);
    return len > 1e-6 ? e / len : normalize(cross(r, abs(r.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
}

vec3 gaussian_centre(vec3 n, vec3 r, float mu) {
    return cos(mu) * r + sin(mu) * gaussian_axis(n, r);
}

// (G_sigma * L)(d) from the chain: one trilinear lookup. The levels are the slices of a 3-D texture (LINEAR in all
// three axes, CLAMP_TO_EDGE in z), so at z = (x + 1/2) / LEVELS the sampler blends the bilinear lookups of levels
// floor(x) and floor(x) + 1 with weights 1 - fract(x) and fract(x), which is sample_chain's blend.
vec3 gaussian_chain_lookup(vec3 d, float sigma) {
    float x = 0.0;
#if GAUSSIAN_LEVELS > 1
    x = clamp(log(max(sigma, 1e-30) / u_chain_sigma0) / u_chain_log_ratio, 0.0, float(GAUSSIAN_LEVELS - 1));
#endif
    // d is a unit lobe centre (cos(mu) r + sin(mu) e, r and e orthonormal): latlong_uv without its normalize
    vec2 uv = vec2(atan(d.z, d.x) / (2.0 * PI) + 0.5, acos(clamp(d.y, -1.0, 1.0)) / PI);
    return texture(u_chain, vec3(uv, (x + 0.5) / float(GAUSSIAN_LEVELS))).rgb;
}

#ifdef GAUSSIAN_VISIBILITY
// The visibility weight of a lobe at centre c and width sigma from the point's SH visibility (16 coefficients as
// the columns of vis: vis[0] = (v_0, v_1, v_2, v_3), ..., vis[3] = (v_12, ..., v_15); the first (SH_ORDER + 1)^2
// used), clamped to [0, 1] (relight.sg_shadow.lobe_visibility). The 16 real harmonics of order <= 3 (sh.glsl's
// basis: relight.shrm.real_harmonics, index l^2 + l + m) of c in the SH frame are written as polynomials, four to
// a vec4 (the paper's per-lobe "directly evaluating the 4-th order SH", with no array and no loop: on SIMD
// rasterisers an array indexed in a loop lives in memory). Factors: sqrt(1/4pi), sqrt(3/4pi), sqrt(15/4pi),
// sqrt(5/16pi), sqrt(15/16pi), sqrt(35/32pi), sqrt(105/4pi), sqrt(21/32pi), sqrt(7/16pi), sqrt(105/16pi); checked
// against the CPU basis by tests/relight/test_gl_gaussian.py.
float gaussian_visibility(vec3 c, float sigma, mat4 vis) {
#if VIS_MODE == VIS_AO
    return clamp(2.0 * SH_Y00 * vis[0].x, 0.0, 1.0);
#else
    vec3 d = sh_frame(c);
    float x = d.x;
    float y = d.y;
    float z = d.z;
    vec4 y0 = vec4(0.28209479177387814, 0.4886025119029199 * y, 0.4886025119029199 * z, 0.4886025119029199 * x);
#if SH_ORDER == 0
    y0.yzw = vec3(0.0);
#endif
#if VIS_MODE == VIS_SH_LOBE
    // a_l = I_{l+1/2}(kappa) / I_{1/2}(kappa): a_0 = 1, a_1 = coth(kappa) - 1 / kappa, a_{l+1} = a_{l-1} - (2l + 1)
    // / kappa a_l (stable for l <= 3 in float32 over the fit's sigma range); exp(-l (l + 1) / (2 kappa)) for
    // sharp lobes (within 1e-6 there)
    float kappa = 1.0 / (sigma * sigma);
    vec3 band;  // a_1, a_2, a_3
    if (kappa > 1e4) {
        band = exp(-vec3(2.0, 6.0, 12.0) / (2.0 * kappa));
    } else {
        band.x = 1.0 / tanh(kappa) - 1.0 / kappa;
        band.y = 1.0 - 3.0 / kappa * band.x;
        band.z = band.x - 5.0 / kappa * band.y;
    }
    y0.yzw *= band.x;
#endif
    float acc = dot(y0, vis[0]);
#if SH_ORDER >= 2
    vec4 y1 = vec4(1.0925484305920792 * x * y, 1.0925484305920792 * y * z, 0.31539156525252005 * (3.0 * z * z - 1.0),
                   1.0925484305920792 * x * z);
    float y8 = 0.5462742152960396 * (x * x - y * y);
#if VIS_MODE == VIS_SH_LOBE
    y1 *= band.y;
    y8 *= band.y;
#endif
    acc += dot(y1, vis[1]);
#if SH_ORDER == 2
    acc += y8 * vis[2].x;
#else
    vec4 y2 = vec4(y8, 0.5900435899266435 * y * (3.0 * x * x - y * y), 2.890611442640554 * x * y * z,
                   0.4570457994644658 * y * (5.0 * z * z - 1.0));
    vec4 y3 = vec4(0.3731763325901154 * z * (5.0 * z * z - 3.0), 0.4570457994644658 * x * (5.0 * z * z - 1.0),
                   1.445305721320277 * z * (x * x - y * y), 0.5900435899266435 * x * (x * x - 3.0 * y * y));
#if VIS_MODE == VIS_SH_LOBE
    y2.yzw *= band.z;
    y3 *= band.z;
#endif
    acc += dot(y2, vis[2]) + dot(y3, vis[3]);
#endif
#endif
    return clamp(acc, 0.0, 1.0);
#endif
}
#endif

// One lobe's term from its texel a = (mu, sigma, w_r, w_g) and its w_b.
#ifdef GAUSSIAN_VISIBILITY
vec3 gaussian_lobe(vec4 a, float wb, vec3 r, vec3 e, mat4 vis) {
#else
vec3 gaussian_lobe(vec4 a, float wb, vec3 r, vec3 e) {
#endif
    vec3 c = cos(a.x) * r + sin(a.x) * e;
    vec3 term = vec3(a.z, a.w, wb) * gaussian_chain_lookup(c, a.y);
#ifdef GAUSSIAN_VISIBILITY
    term *= gaussian_visibility(c, a.y, vis);
#endif
    return term;
}

// Lobe k (a literal) with the blue weight b (a component of b0 or b1), its texel at column k of the pixel's row.
#ifdef GAUSSIAN_VISIBILITY
#define GAUSSIAN_LOBE(k, b) gaussian_lobe(texture(u_lobes, vec2((float(k) + 0.5) * dx, row)), b, r, e, vis)
#else
#define GAUSSIAN_LOBE(k, b) gaussian_lobe(texture(u_lobes, vec2((float(k) + 0.5) * dx, row)), b, r, e)
#endif

// Outgoing radiance toward the unit view v at the unit normal n: eq. 5, or eq. 7 with the point's visibility.
// The lobes are written out one by one (K <= 8, relight.sgfit's max_lobes) with no branch on a dead lobe (its
// weight 0 times a finite chain value adds 0, as the CPU's skip does): a loop over k, or per-lobe values kept in
// an array, is not unrolled into registers by every compiler (on llvmpipe such an array went to memory and cost
// more than the lookups).
#ifdef GAUSSIAN_VISIBILITY
vec3 gaussian_shade(vec3 n, vec3 v, mat4 vis) {
#else
vec3 gaussian_shade(vec3 n, vec3 v) {
#endif
    float ndv = clamp(dot(n, v), 0.0, 1.0);
    vec3 r = 2.0 * ndv * n - v;
    r /= max(length(r), 1e-30);
    int j;
    float f;
    gaussian_interval(acos(ndv), j, f);
    float row = (float(j) + f + 0.5) / float(GAUSSIAN_N);
    float dx = 1.0 / float(GAUSSIAN_LOBE_TEXELS);
    vec4 b0 = texture(u_lobes, vec2((float(GAUSSIAN_K) + 0.5) * dx, row));
    vec3 e = gaussian_axis(n, r);
    vec3 sum = GAUSSIAN_LOBE(0, b0.x);
#if GAUSSIAN_K > 1
    sum += GAUSSIAN_LOBE(1, b0.y);
#endif
#if GAUSSIAN_K > 2
    sum += GAUSSIAN_LOBE(2, b0.z);
#endif
#if GAUSSIAN_K > 3
    sum += GAUSSIAN_LOBE(3, b0.w);
#endif
#if GAUSSIAN_K > 4
    vec4 b1 = texture(u_lobes, vec2((float(GAUSSIAN_K) + 1.5) * dx, row));
    sum += GAUSSIAN_LOBE(4, b1.x);
#endif
#if GAUSSIAN_K > 5
    sum += GAUSSIAN_LOBE(5, b1.y);
#endif
#if GAUSSIAN_K > 6
    sum += GAUSSIAN_LOBE(6, b1.z);
#endif
#if GAUSSIAN_K > 7
    sum += GAUSSIAN_LOBE(7, b1.w);
#endif
    return sum;
}
