// Gaussian lobes with a Gaussian-prefiltered chain (Green, Kautz & Durand 2007, §5, eqs. 5 and 7): the GPU twin
// of relight.sg_render.lobe_terms and relight.sg_shadow.lobe_visibility (docs/conventions.md, "Gaussian lobes").
//
// Defines: GAUSSIAN_K (lobes), GAUSSIAN_ROWS (rows of the lobe table), GAUSSIAN_LEVELS (chain levels), and either
// GAUSSIAN_GRID (the rows are evenly spaced in theta_o) or GAUSSIAN_SEARCH_STEP (the largest power of two
// <= GAUSSIAN_ROWS - 2, or 0: the rows are the material's own, unevenly spaced elevations); with
// GAUSSIAN_VISIBILITY also VIS_MODE (VIS_AO, VIS_SH or VIS_SH_LOBE below) and SH_ORDER <= 3 (the visibility's order).
// Data, all float16 as stored (the paper's Fig. 3 layout; relight.gl.gaussian.LobeTable, web/src/gaussian.js
// lobeTable):
//   u_lobes        RGBA32UI, GAUSSIAN_LOBE_TEXELS x ROWS texels, NEAREST (read with texelFetch): row i holds the
//                  lobes at elevation theta_i as float16 pairs (low half first; gaussian_halves), word 2k =
//                  (mu_k, sigma_k), word 2k + 1 = (w_k.r, w_k.g), then word 2K + k / 2 holds w_k.b (low half for
//                  even k); radians, w the lobe's integral. The rows are the material's elevations, or -- when
//                  those lie on an even grid of at most relight.gl.gaussian.MAX_GRID_ROWS rows -- every row of that
//                  grid, the inserted rows interpolated (the same piecewise-linear function of theta_o);
//   u_lobe_grid    with GAUSSIAN_GRID: (theta_0, rows per radian);
//   u_elevations   without it: the ROWS elevations theta_i (radians, increasing);
//   u_chain        the levels G_{sigma_j} * L as the slices of one 3-D texture (every level the same S x 2S
//                  lat-long size), LINEAR in all three axes, REPEAT in u, CLAMP_TO_EDGE in v and across the
//                  levels: relight.conventions.sample_latlong within a level.
// The parameters are interpolated linearly in theta_o between rows j and j + 1 (GaussianLobes.params_at), clamped
// at the end rows.
// A lobe's level is x = log(sigma / sigma_0) / log(ratio), clamped to the chain, blended linearly between floor(x)
// and floor(x) + 1 (relight.gaussian_chain.sample_chain) by the 3-D texture's filter.
// Written for SIMD rasterisers as much as for GPUs (bench/gaussian_frame.py, llvmpipe): no loop over lobes and no
// array indexed per pixel (llvmpipe keeps such arrays in memory; the row arrays below are indexed by constants
// only), one filtered lookup per lobe in the chain. The lobe table costs GAUSSIAN_LOBE_TEXELS unfiltered fetches
// per row (2 for K = 3; a filtered RGBA16F table cost one filtered fetch per lobe), and on a grid the interval is
// one multiply (a bisection over uniforms cost as much as a chain lookup on llvmpipe).

#define VIS_AO 1
#define VIS_SH 2
#define VIS_SH_LOBE 3

// 32-bit words and RGBA32UI texels per row of u_lobes.
#define GAUSSIAN_WORDS (2 * GAUSSIAN_K + (GAUSSIAN_K + 1) / 2)
#define GAUSSIAN_LOBE_TEXELS ((GAUSSIAN_WORDS + 3) / 4)

uniform highp usampler2D u_lobes;
#ifdef GAUSSIAN_GRID
uniform vec2 u_lobe_grid;
#else
uniform float u_elevations[GAUSSIAN_ROWS];
#endif
uniform highp sampler3D u_chain;
uniform float u_chain_sigma0;
uniform float u_chain_log_ratio;

// The rows j (<= ROWS - 2) and j + 1 around theta and the fraction f between them: on a grid one multiply; else a
// branchless bisection over the elevations with a fixed step count (ceil(log2(ROWS - 1)) steps: each keeps
// u_elevations[j] <= t and halves what is left above j).
void gaussian_interval(float theta, out int j, out float f) {
    j = 0;
    f = 0.0;
#if GAUSSIAN_ROWS > 1
#ifdef GAUSSIAN_GRID
    float x = clamp((theta - u_lobe_grid.x) * u_lobe_grid.y, 0.0, float(GAUSSIAN_ROWS - 1));
    j = min(int(x), GAUSSIAN_ROWS - 2);
    f = x - float(j);
#else
    float t = clamp(theta, u_elevations[0], u_elevations[GAUSSIAN_ROWS - 1]);
    for (int s = GAUSSIAN_SEARCH_STEP; s > 0; s /= 2) {
        int m = min(j + s, GAUSSIAN_ROWS - 2);
        j = t >= u_elevations[m] ? m : j;
    }
    f = (t - u_elevations[j]) / (u_elevations[j + 1] - u_elevations[j]);
#endif
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

// (cos(mu), sin(mu)) for |mu| <= pi/2 (GaussianLobes validates that range; float16 rounding adds < 1e-3): the
// Taylor polynomials of degree 12 and 11, whose truncation error there is below 6e-8 (the next terms,
// (pi/2)^14 / 14! and (pi/2)^13 / 13!; 3e-7 measured in float32), without the built-ins' range reduction (about 2 %
// of the sphere's frame on llvmpipe).
vec2 gaussian_cos_sin(float mu) {
    float x2 = mu * mu;
    float c = 1.0 + x2 * (-1.0 / 2.0 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0
              + x2 * (-1.0 / 3628800.0 + x2 * (1.0 / 479001600.0))))));
    float s = mu * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 * (1.0 / 362880.0
                + x2 * (-1.0 / 39916800.0))))));
    return vec2(c, s);
}

// One lobe's term from a = (mu, sigma, w_r, w_g) and its w_b.
#ifdef GAUSSIAN_VISIBILITY
vec3 gaussian_lobe(vec4 a, float wb, vec3 r, vec3 e, mat4 vis) {
#else
vec3 gaussian_lobe(vec4 a, float wb, vec3 r, vec3 e) {
#endif
    vec2 cs = gaussian_cos_sin(a.x);
    vec3 c = cs.x * r + cs.y * e;
    vec3 term = vec3(a.z, a.w, wb) * gaussian_chain_lookup(c, a.y);
#ifdef GAUSSIAN_VISIBILITY
    term *= gaussian_visibility(c, a.y, vis);
#endif
    return term;
}

// The float16 values in the low 16 bits of h's components, exactly for every finite value (the table holds no
// infinity or NaN: GaussianLobes validates them): normal halves by re-biasing the exponent, subnormal ones as
// m 2^-24. The built-in unpack of half pairs (GLSL ES 3.00, desktop 4.20) cost twice as much on llvmpipe.
vec4 gaussian_halves(uvec4 h) {
    uvec4 m = h & 0x7fffu;
    vec4 v = uintBitsToFloat(m * 8192u + 0x38000000u);
    v = mix(v, vec4(m) * 5.960464477539063e-08, lessThan(m, uvec4(0x400u)));
    return mix(v, -v, notEqual(h & 0x8000u, uvec4(0u)));
}

// A row as the float values of its words' low halves (L[t]) and high halves (H[t]) per texel t. Lobe k's (mu, sigma, w.r, w.g) are the halves of words 2k and 2k + 1
// (texel k / 2, components x, y for even k and z, w for odd k); its w.b is the low (even k) or high (odd k) half
// of word 2K + k / 2. (No ## pasting: GLSL ES has none.)
#define GAUSSIAN_PAIR(L, H, t, c1, c2) vec4(L[t].c1, H[t].c1, L[t].c2, H[t].c2)
#define GAUSSIAN_EVEN(L, H, k) GAUSSIAN_PAIR(L, H, (k) / 2, x, y)
#define GAUSSIAN_ODD(L, H, k) GAUSSIAN_PAIR(L, H, (k) / 2, z, w)
#define GAUSSIAN_PARAMS(L, H, k) ((k) % 2 == 0 ? GAUSSIAN_EVEN(L, H, k) : GAUSSIAN_ODD(L, H, k))
#define GAUSSIAN_BLUE_WORD(k) (2 * GAUSSIAN_K + (k) / 2)
#define GAUSSIAN_BLUE_OF(B, k) B[GAUSSIAN_BLUE_WORD(k) / 4][GAUSSIAN_BLUE_WORD(k) % 4]
#define GAUSSIAN_BLUE(L, H, k) ((k) % 2 == 0 ? GAUSSIAN_BLUE_OF(L, k) : GAUSSIAN_BLUE_OF(H, k))
// Lobe k (a literal): its row values interpolated between rows j (lo) and j + 1 (hi).
#define GAUSSIAN_LOBE_PARAMS(k) mix(GAUSSIAN_PARAMS(loL, loH, k), GAUSSIAN_PARAMS(hiL, hiH, k), f)
#define GAUSSIAN_LOBE_BLUE(k) mix(GAUSSIAN_BLUE(loL, loH, k), GAUSSIAN_BLUE(hiL, hiH, k), f)
#ifdef GAUSSIAN_VISIBILITY
#define GAUSSIAN_LOBE(k) gaussian_lobe(GAUSSIAN_LOBE_PARAMS(k), GAUSSIAN_LOBE_BLUE(k), r, e, vis)
#else
#define GAUSSIAN_LOBE(k) gaussian_lobe(GAUSSIAN_LOBE_PARAMS(k), GAUSSIAN_LOBE_BLUE(k), r, e)
#endif
// Texel i (a literal) of rows j (lo) and j + 1 (hi), fetched and unpacked (written out: a function with out
// parameters into the arrays cost 4 % of the frame on llvmpipe).
#define GAUSSIAN_FETCH_LO(i) lo = texelFetch(u_lobes, ivec2(i, j), 0); hi = texelFetch(u_lobes, ivec2(i, j1), 0)
#define GAUSSIAN_UNPACK_LO(i) loL[i] = gaussian_halves(lo & 0xffffu); loH[i] = gaussian_halves(lo >> 16)
#define GAUSSIAN_UNPACK_HI(i) hiL[i] = gaussian_halves(hi & 0xffffu); hiH[i] = gaussian_halves(hi >> 16)
#define GAUSSIAN_FETCH(i) GAUSSIAN_FETCH_LO(i); GAUSSIAN_UNPACK_LO(i); GAUSSIAN_UNPACK_HI(i)

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
    int j1 = min(j + 1, GAUSSIAN_ROWS - 1);
    uvec4 lo;
    uvec4 hi;
    vec4 loL[GAUSSIAN_LOBE_TEXELS];
    vec4 loH[GAUSSIAN_LOBE_TEXELS];
    vec4 hiL[GAUSSIAN_LOBE_TEXELS];
    vec4 hiH[GAUSSIAN_LOBE_TEXELS];
    GAUSSIAN_FETCH(0);
#if GAUSSIAN_LOBE_TEXELS > 1
    GAUSSIAN_FETCH(1);
#endif
#if GAUSSIAN_LOBE_TEXELS > 2
    GAUSSIAN_FETCH(2);
#endif
#if GAUSSIAN_LOBE_TEXELS > 3
    GAUSSIAN_FETCH(3);
#endif
#if GAUSSIAN_LOBE_TEXELS > 4
    GAUSSIAN_FETCH(4);
#endif
    vec3 e = gaussian_axis(n, r);
    vec3 sum = GAUSSIAN_LOBE(0);
#if GAUSSIAN_K > 1
    sum += GAUSSIAN_LOBE(1);
#endif
#if GAUSSIAN_K > 2
    sum += GAUSSIAN_LOBE(2);
#endif
#if GAUSSIAN_K > 3
    sum += GAUSSIAN_LOBE(3);
#endif
#if GAUSSIAN_K > 4
    sum += GAUSSIAN_LOBE(4);
#endif
#if GAUSSIAN_K > 5
    sum += GAUSSIAN_LOBE(5);
#endif
#if GAUSSIAN_K > 6
    sum += GAUSSIAN_LOBE(6);
#endif
#if GAUSSIAN_K > 7
    sum += GAUSSIAN_LOBE(7);
#endif
    return sum;
}
