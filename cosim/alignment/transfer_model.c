/* The transfer-alignment error model over one filter period (seed 001), compiled.
 *
 * transfer_propagate is the twin of cosim.alignment.transfer_model.propagate (the UKF's
 * fx, applied to every sigma point of a stack): the same formulas in the same order,
 * including those of the functions it calls (models.earth R_M and R_N,
 * models.conventions euler_to_dcm, rotvec_to_dcm with its series below 1e-4 rad, and
 * dcm_to_euler). The matrix products are summed in the order k = 0, 1, 2, ...; numpy's
 * may go through BLAS (another order, FMA), so the two paths agree to rounding
 * (tests/test_native_propagate.py). The Python side is cosim/alignment/transfer_native.py.
 * Built with the other kernels (models/native/__init__.py: gcc -O2, no -ffast-math, no
 * contraction into FMA).
 *
 * Parameter block p (float64, the layout of transfer_native.PARAM_*):
 *   p[0] T      period [s]            p[1] lat   mechanisation latitude L^ [rad]
 *   p[2] height [m]                   p[3] OMEGA_IE, p[4] A, p[5] E2 (models.constants)
 *   p[6..8]   dv_f = int C^ f~ dt     p[9..17]  c_int = int C^ dt (3x3, row-major)
 *   p[18..20] v_int = int v^ dt       p[21..23] w_in = int w^_in dt
 *   p[24..26] cor = int (2 w^_ie + w^_en) dt
 *   p[27..44] m0 (3x6)   p[45..62] m1 (3x6)   p[63..98] phi_flex (6x6)   (flexure only)
 */
#include <math.h>

#include "conventions.h"
#include "kernel.h"

/* models.earth.R_M and R_N at latitude lat (same expressions, same order) */
static double meridian_radius(double lat, double a, double e2)
{
    double s = sin(lat);
    return a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5);
}

static double transverse_radius(double lat, double a, double e2)
{
    double s = sin(lat);
    return a / sqrt(1.0 - e2 * s * s);
}

/* models.conventions.rotvec_to_dcm: I + s1 [v x] + s2 [v x]^2, series below |v| = 1e-4 */
static void rotvec_dcm(const double *v, double *c)
{
    double a = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    double a2 = a * a, s1, s2;
    if (a < 1e-4) {
        s1 = 1.0 - a2 / 6.0 + a2 * a2 / 120.0;
        s2 = 0.5 - a2 / 24.0 + a2 * a2 / 720.0;
    } else {
        s1 = sin(a) / a;
        s2 = (1.0 - cos(a)) / (a * a);
    }
    double k[9] = {0.0, -v[2], v[1], v[2], 0.0, -v[0], -v[1], v[0], 0.0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double kk = k[3 * i] * k[j] + k[3 * i + 1] * k[3 + j] + k[3 * i + 2] * k[6 + j];
            c[3 * i + j] = (i == j ? 1.0 : 0.0) + s1 * k[3 * i + j] + s2 * kk;
        }
}

/* o = M v, M of r rows and c columns (row-major): o_i = sum_k M_ik v_k, k ascending */
static void matvec(const double *m, const double *v, int r, int c, double *o)
{
    for (int i = 0; i < r; i++) {
        double s = m[c * i] * v[0];
        for (int k = 1; k < c; k++)
            s += m[c * i + k] * v[k];
        o[i] = s;
    }
}

/* The nonlinear error model over one period for m stacked states x (m, n) -> out (m, n).
 * n = 19 with the flexure states (flexure = 1), else 13. out must not overlap x. */
KERNEL void transfer_propagate(const double *x, double *out, const double *p, long m, int n,
                        int flexure)
{
    const double T = p[0], lat_h = p[1], height = p[2];
    const double omega_ie = p[3], a_earth = p[4], e2 = p[5];
    const double *dv_f = p + 6, *c_int = p + 9, *v_int = p + 18, *w_in = p + 21;
    const double *cor = p + 24, *m0 = p + 27, *m1 = p + 45, *phi_flex = p + 63;
    const int nabla = flexure ? 13 : 7, eps_ = flexure ? 16 : 10;
    const double rm = meridian_radius(lat_h, a_earth, e2) + height;
    const double rn = transverse_radius(lat_h, a_earth, e2) + height;
    const double cl = cos(lat_h), sl = sin(lat_h), tl = tan(lat_h);
    const double v_mean_e = T > 0 ? v_int[1] / T : 0.0;
    for (long q = 0; q < m; q++) {
        const double *xq = x + q * n;
        double *oq = out + q * n;
        const double dl = xq[0], *dV = xq + 1, *att = xq + 4;
        const double *nab = xq + nabla, *eps = xq + eps_, *xi = xq + 7;
        double dv0[3], xm[3];
        if (flexure) {
            matvec(m0, xi, 3, 6, xm); /* xi @ m0.T */
            for (int i = 0; i < 3; i++)
                dv0[i] = dV[i] - xm[i];
        } else {
            for (int i = 0; i < 3; i++)
                dv0[i] = dV[i];
        }
        const double lat_t = lat_h - dl;
        double d_wie[3], d_wen[3], d_win[3], dwt[3], w[3];
        d_wie[0] = omega_ie * (cl - cos(lat_t));
        d_wie[1] = 0.0;
        d_wie[2] = omega_ie * -(sl - sin(lat_t));
        const double dv0_n = dv0[0], dv0_e = dv0[1], dv0_d = dv0[2];
        d_wen[0] = dv0_e / rn;
        d_wen[1] = -dv0_n / rm;
        d_wen[2] = -dv0_e * tl / rn - v_mean_e * dl / (rn * cl * cl);
        for (int i = 0; i < 3; i++) {
            d_win[i] = d_wie[i] + d_wen[i];
            dwt[i] = d_win[i] * T;
        }
        double E0[9], R[9], E1[9], EbT[9];
        nc_euler_to_dcm(att, E0);
        /* rot = eps @ c_int.T + E0 @ w_in - w_in - E0 @ (d_win T) */
        double ec[3], ew[3], ed[3], rot[3];
        matvec(c_int, eps, 3, 3, ec);
        matvec(E0, w_in, 3, 3, ew);
        matvec(E0, dwt, 3, 3, ed);
        for (int i = 0; i < 3; i++)
            rot[i] = ec[i] + ew[i] - w_in[i] - ed[i];
        rotvec_dcm(rot, R);
        for (int i = 0; i < 3; i++) /* E1 = R @ E0 */
            for (int j = 0; j < 3; j++)
                E1[3 * i + j] =
                    R[3 * i] * E0[j] + R[3 * i + 1] * E0[3 + j] + R[3 * i + 2] * E0[6 + j];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                EbT[3 * i + j] = 0.5 * (E0[3 * j + i] + E1[3 * j + i]);
        /* cor x dv0 and (2 dw_ie + dw_en) x v_int */
        double cc[3], cv[3];
        for (int i = 0; i < 3; i++)
            w[i] = 2.0 * d_wie[i] + d_wen[i];
        cc[0] = cor[1] * dv0_d - cor[2] * dv0_e;
        cc[1] = cor[2] * dv0_n - cor[0] * dv0_d;
        cc[2] = cor[0] * dv0_e - cor[1] * dv0_n;
        cv[0] = w[1] * v_int[2] - w[2] * v_int[1];
        cv[1] = w[2] * v_int[0] - w[0] * v_int[2];
        cv[2] = w[0] * v_int[1] - w[1] * v_int[0];
        /* dv1 = dv0 + dv_f - EbT @ dv_f + EbT @ (nab @ c_int.T) - cc - cv */
        double ebf[3], nc[3], ebn[3], dv1[3];
        matvec(EbT, dv_f, 3, 3, ebf);
        matvec(c_int, nab, 3, 3, nc);
        matvec(EbT, nc, 3, 3, ebn);
        for (int i = 0; i < 3; i++)
            dv1[i] = dv0[i] + dv_f[i] - ebf[i] + ebn[i] - cc[i] - cv[i];
        double xi1[6], xm1[3];
        if (flexure)
            matvec(phi_flex, xi, 6, 6, xi1); /* xi @ phi_flex.T */
        oq[0] = dl + 0.5 * (dv0_n + dv1[0]) * T / rm;
        /* dcm_to_euler(E1) */
        oq[4] = atan2(E1[7], E1[8]);
        oq[5] = atan2(-E1[6], hypot(E1[7], E1[8]));
        oq[6] = atan2(E1[3], E1[0]);
        for (int i = 0; i < 3; i++) {
            oq[nabla + i] = nab[i];
            oq[eps_ + i] = eps[i];
        }
        if (flexure) {
            for (int i = 0; i < 6; i++)
                oq[7 + i] = xi1[i];
            matvec(m1, xi1, 3, 6, xm1); /* xi1 @ m1.T */
            for (int i = 0; i < 3; i++)
                oq[1 + i] = dv1[i] + xm1[i];
        } else {
            for (int i = 0; i < 3; i++)
                oq[1 + i] = dv1[i];
        }
    }
}
