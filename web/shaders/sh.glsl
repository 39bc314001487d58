// Real spherical harmonics Yr_pq up to order SH_ORDER (relight.shrm.real_harmonics, relight.sh.to_real):
//   Yr_p0 = Y_p0,  Yr_{p,q>0} = sqrt2 (-1)^q Re Y_pq,  Yr_{p,q<0} = sqrt2 (-1)^q Im Y_{p|q|},
// at index p^2 + p + q, orthonormal, Condon-Shortley phase (which cancels in the real form).
//
// Notes: with the argument d = (x', y', z') a unit vector in the SH frame (z' the pole),
//   c_q + i s_q = (x' + i y')^q = sin^q(theta) e^{i q phi},
//   Yr_{p,+-q} = sqrt2 Q_pq (c_q | s_q),  Yr_p0 = Q_p0,
// where Q_pq = Pbar_pq / sin^q(theta) without the CS sign follows relight.sh.legendre_rows' recursion:
//   Q_00 = Y_00,  Q_qq = Q_{q-1,q-1} sqrt((2q + 1) / (2q)),
//   Q_pq = a_pq (z' Q_{p-1,q} - b_pq Q_{p-2,q}),  a_pq = sqrt((4p^2 - 1) / (p^2 - q^2)),
//   b_pq = sqrt(((p - 1)^2 - q^2) / (4 (p - 1)^2 - 1))   (b_{q+1,q} = 0).
// Same algorithm in web/src/sh.js (the per-frame uniforms of the distant viewer).

#define SH_COUNT ((SH_ORDER + 1) * (SH_ORDER + 1))

void sh_real(vec3 d, out float y[SH_COUNT]) {
    float c = 1.0;
    float s = 0.0;
    float qmm = SH_Y00;
    for (int q = 0; q <= SH_ORDER; ++q) {
        if (q > 0) {
            float cn = c * d.x - s * d.y;
            s = c * d.y + s * d.x;
            c = cn;
            float fq = float(q);
            qmm *= sqrt((2.0 * fq + 1.0) / (2.0 * fq));
        }
        float q1 = qmm;
        float q2 = 0.0;
        for (int p = q; p <= SH_ORDER; ++p) {
            float qp = q1;
            if (p > q) {
                float fp = float(p);
                float fq = float(q);
                float a = sqrt((4.0 * fp * fp - 1.0) / (fp * fp - fq * fq));
                float b = sqrt(max(((fp - 1.0) * (fp - 1.0) - fq * fq) / (4.0 * (fp - 1.0) * (fp - 1.0) - 1.0), 0.0));
                qp = a * (d.z * q1 - b * q2);
                q2 = q1;
                q1 = qp;
            }
            int centre = p * p + p;
            if (q == 0) {
                y[centre] = qp;
            } else {
                y[centre + q] = SQRT2 * qp * c;
                y[centre - q] = SQRT2 * qp * s;
            }
        }
    }
}
