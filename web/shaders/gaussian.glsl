// Gaussian lobes with a Gaussian-prefiltered chain (Green, Kautz & Durand 2007, §5, eqs. 5 and 7): the GPU twin
// of relight.sg_render.lobe_terms and relight.sg_shadow.lobe_visibility (docs/conventions.md, "Gaussian lobes").
//
// Defines: GAUSSIAN_K (lobes), GAUSSIAN_N (elevations), GAUSSIAN_LEVELS (chain levels); with GAUSSIAN_VISIBILITY
// also VIS_MODE (VIS_AO, VIS_SH or VIS_SH_LOBE below) and SH_ORDER <= 3 (the visibility's order).
// Data, all float16 as stored (the paper's Fig. 3 layout):
//   u_lobe_shape   K x N texels (x = lobe, y = elevation), R = mu, G = sigma (radians);
//   u_lobe_weight  K x N texels, RGB = w (the lobe's integral);
//   u_elevations   the N elevations theta_o (radians, increasing);
//   u_chain        the levels G_{sigma_j} * L as one 2-D array (every level the same S x 2S lat-long size),
//                  LINEAR, REPEAT in u, CLAMP_TO_EDGE in v: relight.conventions.sample_latlong.
// The lobe textures are LINEAR and CLAMP_TO_EDGE: one lookup per lobe and texture at the texel centre of lobe k
// across and at texel coordinate j + f along the elevations interpolates linearly in theta_o (the sampler's
// weights), clamped at the end elevations (GaussianLobes.params_at), with no weight on the neighbouring lobes.
// A lobe's level is x = log(sigma / sigma_0) / log(ratio), clamped to the chain, blended linearly between floor(x)
// and floor(x) + 1 (relight.gaussian_chain.sample_chain).

#define VIS_AO 1
#define VIS_SH 2
#define VIS_SH_LOBE 3

uniform highp sampler2D u_lobe_shape;
uniform highp sampler2D u_lobe_weight;
uniform float u_elevations[GAUSSIAN_N];
uniform highp sampler2DArray u_chain;
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

// (G_sigma * L)(d) from the chain.
vec3 gaussian_chain_lookup(vec3 d, float sigma) {
    float x = 0.0;
#if GAUSSIAN_LEVELS > 1
    x = clamp(log(max(sigma, 1e-30) / u_chain_sigma0) / u_chain_log_ratio, 0.0, float(GAUSSIAN_LEVELS - 1));
#endif
    float j0 = floor(x);
    float f = x - j0;
    // d is a unit lobe centre (cos(mu) r + sin(mu) e, r and e orthonormal): latlong_uv without its normalize
    vec2 uv = vec2(atan(d.z, d.x) / (2.0 * PI) + 0.5, acos(clamp(d.y, -1.0, 1.0)) / PI);
    vec3 a = texture(u_chain, vec3(uv, j0)).rgb;
    if (f > 0.0) {
        a = mix(a, texture(u_chain, vec3(uv, min(j0 + 1.0, float(GAUSSIAN_LEVELS - 1)))).rgb, f);
    }
    return a;
}

#ifdef GAUSSIAN_VISIBILITY
// The 16 real harmonics of order <= 3 (sh.glsl's basis: relight.shrm.real_harmonics, index l^2 + l + m) of a unit
// vector d = (x, y, z) in the SH frame, as polynomials: the paper's per-lobe "directly evaluating the 4-th order
// SH" without sh.glsl's general recursion (its square roots per step cost more than the whole lookup). Factors:
// sqrt(1/4pi), sqrt(3/4pi), sqrt(15/4pi), sqrt(5/16pi), sqrt(15/16pi), sqrt(35/32pi), sqrt(105/4pi),
// sqrt(21/32pi), sqrt(7/16pi), sqrt(105/16pi); checked against the CPU basis by tests/relight/test_gl_gaussian.py.
void gaussian_sh16(vec3 d, out float y[16]) {
    float x = d.x;
    float yy = d.y;
    float z = d.z;
    y[0] = 0.28209479177387814;
    y[1] = 0.4886025119029199 * yy;
    y[2] = 0.4886025119029199 * z;
    y[3] = 0.4886025119029199 * x;
    y[4] = 1.0925484305920792 * x * yy;
    y[5] = 1.0925484305920792 * yy * z;
    y[6] = 0.31539156525252005 * (3.0 * z * z - 1.0);
    y[7] = 1.0925484305920792 * x * z;
    y[8] = 0.5462742152960396 * (x * x - yy * yy);
    y[9] = 0.5900435899266435 * yy * (3.0 * x * x - yy * yy);
    y[10] = 2.890611442640554 * x * yy * z;
    y[11] = 0.4570457994644658 * yy * (5.0 * z * z - 1.0);
    y[12] = 0.3731763325901154 * z * (5.0 * z * z - 3.0);
    y[13] = 0.4570457994644658 * x * (5.0 * z * z - 1.0);
    y[14] = 1.445305721320277 * z * (x * x - yy * yy);
    y[15] = 0.5900435899266435 * x * (x * x - 3.0 * yy * yy);
}

// The visibility weight of a lobe at centre c and width sigma from the point's SH visibility (16 coefficients,
// the first (SH_ORDER + 1)^2 used), clamped to [0, 1] (relight.sg_shadow.lobe_visibility).
float gaussian_visibility(vec3 c, float sigma, float vis[16]) {
#if VIS_MODE == VIS_AO
    return clamp(2.0 * SH_Y00 * vis[0], 0.0, 1.0);
#else
    float y[16];
    gaussian_sh16(sh_frame(c), y);
    float band[4] = float[4](1.0, 1.0, 1.0, 1.0);
#if VIS_MODE == VIS_SH_LOBE
    // a_l = I_{l+1/2}(kappa) / I_{1/2}(kappa): a_0 = 1, a_1 = coth(kappa) - 1 / kappa, a_{l+1} = a_{l-1} - (2l + 1)
    // / kappa a_l (stable for l <= 3 in float32 over the fit's sigma range); exp(-l (l + 1) / (2 kappa)) for
    // sharp lobes (within 1e-6 there)
    float kappa = 1.0 / (sigma * sigma);
    if (kappa > 1e4) {
        for (int l = 1; l < 4; ++l) {
            band[l] = exp(-float(l * (l + 1)) / (2.0 * kappa));
        }
    } else {
        band[1] = 1.0 / tanh(kappa) - 1.0 / kappa;
        band[2] = band[0] - 3.0 / kappa * band[1];
        band[3] = band[1] - 5.0 / kappa * band[2];
    }
#endif
    float acc = 0.0;
    for (int l = 0; l <= SH_ORDER; ++l) {
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) {
            acc += band[l] * y[i] * vis[i];
        }
    }
    return clamp(acc, 0.0, 1.0);
#endif
}
#endif

// Outgoing radiance toward the unit view v at the unit normal n: eq. 5, or eq. 7 with the point's visibility.
#ifdef GAUSSIAN_VISIBILITY
vec3 gaussian_shade(vec3 n, vec3 v, float vis[16]) {
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
    vec3 e = gaussian_axis(n, r);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < GAUSSIAN_K; ++k) {
        vec2 tc = vec2((float(k) + 0.5) / float(GAUSSIAN_K), row);
        vec3 w = texture(u_lobe_weight, tc).rgb;
        if (max(w.r, max(w.g, w.b)) <= 0.0) {
            continue;
        }
        vec2 shape = texture(u_lobe_shape, tc).rg;
        vec3 c = cos(shape.x) * r + sin(shape.x) * e;
        vec3 term = w * gaussian_chain_lookup(c, shape.y);
#ifdef GAUSSIAN_VISIBILITY
        term *= gaussian_visibility(c, shape.y, vis);
#endif
        sum += term;
    }
    return sum;
}
