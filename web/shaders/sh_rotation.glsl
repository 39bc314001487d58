// Real SH rotation from a 3 x 3 matrix on the GPU (seed 003, Kautz, Sloan & Snyder 2002, §4 step 1 and Appendix;
// the GLSL twin of relight/sh_rotation.py, tested against it in tests/relight/test_gl_sh_table.py).
//
// Band matrices by the Ivanic–Ruedenberg recursion (J. Phys. Chem. 100 (1996) 6342, erratum 102 (1998) 9099):
// band l from band l - 1 and band 1, straight from the matrix, so there is no Euler-angle singularity. Only two
// band matrices live at a time (shr_prev, shr_cur); each band is applied to the RGB coefficients in shr_c as soon
// as it is built. Needs SH_ORDER (bands l <= SH_ORDER, (SH_ORDER + 1)^2 coefficients at l^2 + l + m).
//
// sh_rotate_frame(t, b, n, transpose) with the world frame rows (t, b, n) of a point (docs/conventions.md,
// "Parity"): transpose = false takes world lighting coefficients to the point's local coefficients,
// L_local = S M(R) L_world with R = -F P, S = (-1)^l for a right-handed frame and R = F P, S = 1 for a mirrored one
// (P the world -> SH-frame mirror (X, Z, Y)); transpose = true applies (S M)^T, taking local BRDF coefficients to
// world ones (the fixed-view mode: L_local . c = L_world . (S M)^T c).

#define SHR_COUNT ((SH_ORDER + 1) * (SH_ORDER + 1))
#define SHR_BAND ((2 * SH_ORDER + 1))

vec3 shr_c[SHR_COUNT];            // the coefficients being rotated (RGB)
float shr_r1[9];                   // band-1 real matrix, [m' + 1][m + 1]
float shr_prev[SHR_BAND * SHR_BAND];  // band l - 1, row-major (2l - 1) x (2l - 1)
float shr_cur[SHR_BAND * SHR_BAND];   // band l, row-major (2l + 1) x (2l + 1)
vec3 shr_tmp[SHR_BAND];

// Ivanic–Ruedenberg's P_i(l, a, b) from band l - 1 (shr_prev) and band 1.
float shr_p(int i, int a, int b, int l) {
    int w = 2 * l - 1;
    int row = (a + l - 1) * w;
    int ri = (i + 1) * 3;
    if (b == l) {
        return shr_r1[ri + 2] * shr_prev[row + w - 1] - shr_r1[ri] * shr_prev[row];
    }
    if (b == -l) {
        return shr_r1[ri + 2] * shr_prev[row] + shr_r1[ri] * shr_prev[row + w - 1];
    }
    return shr_r1[ri + 1] * shr_prev[row + b + l - 1];
}

// Band l >= 2 into shr_cur (Ivanic–Ruedenberg eqs. 8.1–8.5 with Table 2's u, v, w).
void shr_band(int l) {
    float fl = float(l);
    int size = 2 * l + 1;
    for (int m = -l; m <= l; ++m) {
        float fm = float(m);
        float am = abs(fm);
        float d0 = m == 0 ? 1.0 : 0.0;
        float d1 = (m == 1 || m == -1) ? 1.0 : 0.0;
        for (int n = -l; n <= l; ++n) {
            float fn = float(n);
            float denom = (n == l || n == -l) ? 2.0 * fl * (2.0 * fl - 1.0) : (fl + fn) * (fl - fn);
            float u = sqrt((fl + fm) * (fl - fm) / denom);
            float v = 0.5 * sqrt((1.0 + d0) * (fl + am - 1.0) * (fl + am) / denom) * (1.0 - 2.0 * d0);
            float w = -0.5 * sqrt(max((fl - am - 1.0) * (fl - am), 0.0) / denom) * (1.0 - d0);
            float val = 0.0;
            if (m > -l && m < l) {
                val += u * shr_p(0, m, n, l);
            }
            if (m == 0) {
                val += v * (shr_p(1, 1, n, l) + shr_p(-1, -1, n, l));
            } else if (m > 0) {
                val += v * (shr_p(1, m - 1, n, l) * sqrt(1.0 + d1) - shr_p(-1, -m + 1, n, l) * (1.0 - d1));
            } else {
                val += v * (shr_p(1, m + 1, n, l) * (1.0 - d1) + shr_p(-1, -m - 1, n, l) * sqrt(1.0 + d1));
            }
            if (m > 0 && m < l - 1) {
                val += w * (shr_p(1, m + 1, n, l) + shr_p(-1, -m - 1, n, l));
            } else if (m < 0 && m > -l + 1) {
                val += w * (shr_p(1, m - 1, n, l) - shr_p(-1, -m + 1, n, l));
            }
            shr_cur[(m + l) * size + n + l] = val;
        }
    }
}

// shr_c's band l <- sign * B shr_c (or sign * B^T shr_c), B the band matrix in shr_cur.
void shr_apply(int l, float sign, bool transpose) {
    int size = 2 * l + 1;
    int base = l * l;
    for (int k = 0; k < size; ++k) {
        shr_tmp[k] = shr_c[base + k];
    }
    for (int a = 0; a < size; ++a) {
        vec3 acc = vec3(0.0);
        for (int k = 0; k < size; ++k) {
            acc += (transpose ? shr_cur[k * size + a] : shr_cur[a * size + k]) * shr_tmp[k];
        }
        shr_c[base + a] = sign * acc;
    }
}

// Rotate shr_c by the real rotation of the proper 3 x 3 matrix r (r[i][j] = row i, column j, acting on SH-frame
// coordinates), band l multiplied by parity^l (parity = -1.0 or 1.0); transpose applies the transposed matrices.
void sh_rotate_matrix(float r[9], float parity, bool transpose) {
    // band 1: M^1[m'][m] = R[axis(m')][axis(m)], axes (y, z, x) for m = -1, 0, 1
    int ax[3] = int[3](1, 2, 0);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            shr_r1[i * 3 + j] = r[ax[i] * 3 + ax[j]];
            shr_cur[i * 3 + j] = shr_r1[i * 3 + j];
        }
    }
    float sign = 1.0;
    for (int l = 1; l <= SH_ORDER; ++l) {
        sign *= parity;
        if (l >= 2) {
            int prev = (2 * l - 1) * (2 * l - 1);
            for (int k = 0; k < prev; ++k) {
                shr_prev[k] = shr_cur[k];
            }
            shr_band(l);
        }
        shr_apply(l, sign, transpose);
    }
}

// World <-> local coefficients at a point with world frame rows (t, b, n) (header comment).
void sh_rotate_frame(vec3 t, vec3 b, vec3 n, bool transpose) {
    bool mirrored = dot(cross(t, b), n) < 0.0;
    float s = mirrored ? 1.0 : -1.0;  // R = s F P; F P has rows (t.x, t.z, t.y), ...
    float r[9] = float[9](s * t.x, s * t.z, s * t.y, s * b.x, s * b.z, s * b.y, s * n.x, s * n.z, s * n.y);
    sh_rotate_matrix(r, mirrored ? 1.0 : -1.0, transpose);
}
