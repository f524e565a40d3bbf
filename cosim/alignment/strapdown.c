/* The alignment filters' strapdown step, two-sample increments (cosim.alignment.nav).
 *
 * strapdown_two_sample_step is the compiled twin of Strapdown._step_two_sample (and of the
 * re-orthonormalisation of Strapdown.step, and of PeriodSums.add when `sums` is given):
 * the same scalar operations in the same order. The three matrix products (C u, and
 * nav_rot C exp([phi x])) are summed k = 0, 1, 2 here; numpy may send them through BLAS,
 * so the two paths agree to rounding (cosim/alignment/nav_compiled.py gives the layout).
 *
 * nav (double[NAV_SIZE], read and written):
 *   0  C_s_n (3x3, row-major)      9  v_n        12 v_prev      15 lat      16 height
 *   17 gyro_bias                   20 accel_bias 23 C_prev (3x3)
 *   32 phi                         35 dv_n       38 w_in        41 cor
 *   44 previous increments (dtheta, dv, bias-corrected)         50 has previous (0/1)
 *   51 w_ie                        54 2 w_ie     57 R_M + h     58 R_N + h  59 tan(lat)
 *   60 g                           61 steps since the start     62 nav_rot (3x3, cached)
 *   71 step of the cached nav_rot (-1: none)
 * sums (double[22] or NULL): 0 T, 1 dv_f, 4 c_int (3x3), 13 v_int, 16 w_in T, 19 cor T.
 * flags: 1 transport rate, 2 vertical channel, 4 mid-point velocity; `every`: the
 * re-orthonormalisation period in steps (0: never).
 */
#include <math.h>
#include <stddef.h>

#include "conventions.h"
#include "kernel.h"

static void rotvec_dcm(double x, double y, double z, double *r)
{
    double a2 = x * x + y * y + z * z, s1, s2;
    if (a2 < 1e-6) {
        s1 = 1.0 - a2 / 6.0 + a2 * a2 / 120.0;
        s2 = 0.5 - a2 / 24.0 + a2 * a2 / 720.0;
    } else {
        double a = sqrt(a2);
        s1 = sin(a) / a;
        s2 = (1.0 - cos(a)) / a2;
    }
    r[0] = 1.0 - s2 * (y * y + z * z);
    r[1] = s2 * x * y - s1 * z;
    r[2] = s2 * x * z + s1 * y;
    r[3] = s2 * x * y + s1 * z;
    r[4] = 1.0 - s2 * (x * x + z * z);
    r[5] = s2 * y * z - s1 * x;
    r[6] = s2 * x * z - s1 * y;
    r[7] = s2 * y * z + s1 * x;
    r[8] = 1.0 - s2 * (x * x + y * y);
}

KERNEL void strapdown_two_sample_step(double *nav, double *sums, const double *dtheta,
                               const double *dv, double h, int flags, long every)
{
    const int transport = flags & 1, vertical = flags & 2, midpoint = flags & 4;
    double *C = nav, *v = nav + 9, *vp = nav + 12, *prev = nav + 44;
    const double *gb = nav + 17, *ab = nav + 20;
    double t0 = dtheta[0] - gb[0] * h, t1 = dtheta[1] - gb[1] * h, t2 = dtheta[2] - gb[2] * h;
    double d0 = dv[0] - ab[0] * h, d1 = dv[1] - ab[1] * h, d2 = dv[2] - ab[2] * h;
    if (nav[50] == 0.0) { /* no previous increment: no coning/sculling terms this step */
        prev[0] = t0, prev[1] = t1, prev[2] = t2, prev[3] = d0, prev[4] = d1, prev[5] = d2;
        nav[50] = 1.0;
    }
    double p0 = prev[0], p1 = prev[1], p2 = prev[2], q0 = prev[3], q1 = prev[4], q2 = prev[5];
    prev[0] = t0, prev[1] = t1, prev[2] = t2, prev[3] = d0, prev[4] = d1, prev[5] = d2;
    double phi0 = t0 + (p1 * t2 - p2 * t1) / 12.0;
    double phi1 = t1 + (p2 * t0 - p0 * t2) / 12.0;
    double phi2 = t2 + (p0 * t1 - p1 * t0) / 12.0;
    double c0_ = t1 * d2 - t2 * d1, c1_ = t2 * d0 - t0 * d2, c2_ = t0 * d1 - t1 * d0;
    double u[3];
    u[0] = d0 + 0.5 * c0_ + (t1 * c2_ - t2 * c1_) / 6.0
           + ((p1 * d2 - p2 * d1) + (q1 * t2 - q2 * t1)) / 12.0;
    u[1] = d1 + 0.5 * c1_ + (t2 * c0_ - t0 * c2_) / 6.0
           + ((p2 * d0 - p0 * d2) + (q2 * t0 - q0 * t2)) / 12.0;
    u[2] = d2 + 0.5 * c2_ + (t0 * c1_ - t1 * c0_) / 6.0
           + ((p0 * d1 - p1 * d0) + (q0 * t1 - q1 * t0)) / 12.0;
    double v0 = v[0], v1 = v[1], v2 = v[2], r0, r1, r2;
    if (midpoint) {
        r0 = 1.5 * v0 - 0.5 * vp[0], r1 = 1.5 * v1 - 0.5 * vp[1], r2 = 1.5 * v2 - 0.5 * vp[2];
    } else {
        r0 = v0, r1 = v1, r2 = v2;
    }
    double e0 = nav[51], e1 = nav[52], e2 = nav[53];
    double k0 = nav[54], k1 = nav[55], k2 = nav[56];
    const double rm = nav[57], rn = nav[58], tn = nav[59];
    double z0, z1, z2, rot_new[9];
    const double *nav_rot;
    if (transport) {
        double n0 = r1 / rn, n1 = -r0 / rm, n2 = -r1 * tn / rn;
        e0 = e0 + n0, e1 = e1 + n1, e2 = e2 + n2;
        k0 = k0 + n0, k1 = k1 + n1, k2 = k2 + n2;
        z0 = e0 * h, z1 = e1 * h, z2 = e2 * h;
        rotvec_dcm(-z0, -z1, -z2, rot_new);
        nav_rot = rot_new;
    } else {
        z0 = e0 * h, z1 = e1 * h, z2 = e2 * h;
        if (h != nav[71]) { /* exp(-[zeta x]) for a constant w_in, cached per step size */
            nav[71] = h;
            rotvec_dcm(-z0, -z1, -z2, nav + 62);
        }
        nav_rot = nav + 62;
    }
    double u0 = C[0] * u[0] + C[1] * u[1] + C[2] * u[2];
    double u1 = C[3] * u[0] + C[4] * u[1] + C[5] * u[2];
    double u2 = C[6] * u[0] + C[7] * u[1] + C[8] * u[2];
    double f0 = u0 - 0.5 * (z1 * u2 - z2 * u1);
    double f1 = u1 - 0.5 * (z2 * u0 - z0 * u2);
    double f2 = u2 - 0.5 * (z0 * u1 - z1 * u0);
    double w0, w1, w2;
    if (vertical) {
        w0 = v0 + f0 + (0.0 - (k1 * r2 - k2 * r1)) * h;
        w1 = v1 + f1 + (0.0 - (k2 * r0 - k0 * r2)) * h;
        w2 = v2 + f2 + (nav[60] - (k0 * r1 - k1 * r0)) * h;
    } else {
        double k = k2 * h;
        w0 = v0 + f0 + k * r1;
        w1 = v1 + f1 - k * r0;
        w2 = 0.0;
    }
    if (transport)
        nav[15] += r0 * h / rm;
    double *Cp = nav + 23;
    for (int i = 0; i < 9; i++)
        Cp[i] = C[i];
    nav[38] = e0, nav[39] = e1, nav[40] = e2;
    nav[41] = k0, nav[42] = k1, nav[43] = k2;
    nav[32] = phi0, nav[33] = phi1, nav[34] = phi2;
    nav[35] = f0, nav[36] = f1, nav[37] = f2;
    vp[0] = v0, vp[1] = v1, vp[2] = v2;
    v[0] = w0, v[1] = w1, v[2] = w2;
    double body[9], left[9];
    rotvec_dcm(phi0, phi1, phi2, body);
    nc_matmul3(nav_rot, Cp, left);
    nc_matmul3(left, body, C);
    nav[61] += 1.0;
    if (every > 0 && fmod(nav[61], (double)every) == 0.0) { /* 1.5 C - 0.5 C C^T C */
        double cct[9], ccc[9];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                cct[3 * i + j] = C[3 * i] * C[3 * j] + C[3 * i + 1] * C[3 * j + 1]
                                 + C[3 * i + 2] * C[3 * j + 2];
        nc_matmul3(cct, C, ccc);
        for (int i = 0; i < 9; i++)
            C[i] = 1.5 * C[i] - 0.5 * ccc[i];
    }
    if (sums != NULL) { /* PeriodSums.add: trapezoidal in attitude and velocity */
        double hh = 0.5 * h;
        sums[0] += h;
        sums[1] += f0, sums[2] += f1, sums[3] += f2;
        for (int i = 0; i < 9; i++)
            sums[4 + i] += hh * (Cp[i] + C[i]);
        for (int i = 0; i < 3; i++) {
            sums[13 + i] += hh * (vp[i] + v[i]);
            sums[16 + i] += nav[38 + i] * h;
            sums[19 + i] += nav[41 + i] * h;
        }
    }
}

/* Strapdown.refresh: the latitude-dependent constants at nav[15] (lat) and nav[16] (height),
 * with models.earth.R_M, R_N, gravity and cosim.alignment.nav.earth_rate (same expressions,
 * same order); c: A, E2, OMEGA_IE, GAMMA_E, K_SOMIGLIANA, F, M_RATIO (models.constants). */
KERNEL void strapdown_refresh(double *nav, const double *c)
{
    const double a = c[0], e2 = c[1], w = c[2], gamma_e = c[3], k = c[4], f = c[5], m = c[6];
    const double lat = nav[15], h = nav[16], s = sin(lat);
    nav[57] = a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5) + h;
    nav[58] = a / sqrt(1.0 - e2 * s * s) + h;
    nav[59] = tan(lat);
    nav[51] = w * cos(lat), nav[52] = 0.0, nav[53] = -w * sin(lat);
    nav[54] = 2.0 * nav[51], nav[55] = 2.0 * nav[52], nav[56] = 2.0 * nav[53];
    const double s2 = s * s;
    const double g0 = gamma_e * (1.0 + k * s2) / sqrt(1.0 - e2 * s2);
    nav[60] = g0 * (1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * h + 3.0 * h * h / (a * a));
    nav[71] = -1.0;
}
