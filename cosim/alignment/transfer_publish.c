/* The transfer-alignment block's per-step outputs (cosim.alignment.transfer).
 *
 * transfer_publish is the compiled twin of TransferAlignment._attitude_numpy plus the
 * master's attitude of the step (euler_to_dcm_3(rpy_master), TransferAlignment.step): the
 * same scalar operations in the same order. The 3x3 products are summed k = 0, 1, 2 here;
 * numpy may send them through BLAS (other order, FMA), so the two paths agree to rounding
 * (tests/test_native_publish.py).
 *
 * in (9): rpy_master, rpy_s_true, rpy_m_true [rad] (the block's input span, or a copy).
 * c_nav (9): the slave mechanisation's C_s_n (row-major); not read when mode = 0.
 * mode: 0 before the filter starts (estimate = the master's attitude), 1 stage 1 (estimate
 *   = att_T C_s_n, the best hypothesis' attitude error applied), 2 stage 2 (C_s_n).
 * per (28), set when P changes: 0 att_T = E(phi^)^T (stage 1), 9 P_att, 18 P_att^-1
 *   (3x3 each, rad^2, rad^-2), 27 ARCMIN [rad].
 * c_m (9, written): C_b_n of rpy_master, the newest entry of the block's attitude history.
 * out (9, written): rpy_err [arcmin], rpy_sigma [arcmin], rel_rpy [rad].
 * Returns the NEES of the attitude error (3 degrees of freedom).
 */
#include <math.h>

#include "conventions.h"
#include "kernel.h"


/* o = A^T B (row-major 3x3) */
static void tp_tmul(const double *a, const double *b, double *o)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            o[3 * i + j] = a[i] * b[j] + a[3 + i] * b[3 + j] + a[6 + i] * b[6 + j];
}

/* models.conventions.dcm_to_euler_3 */
static void tp_dcm_to_euler(const double *c, double *rpy)
{
    rpy[0] = atan2(c[7], c[8]);
    rpy[1] = atan2(-c[6], hypot(c[7], c[8]));
    rpy[2] = atan2(c[3], c[0]);
}

KERNEL double transfer_publish(const double *in, const double *c_nav, int mode, const double *per,
                        double *c_m, double *out)
{
    const double *att_t = per, *p_att = per + 9, *p_inv = per + 18;
    double arcmin = per[27];
    double c_mt[9], c_s[9], c_est[9], m[9], rel_est[3], r[3], rel[3];
    nc_euler_to_dcm(in, c_m);
    if (mode == 0) {
        for (int i = 0; i < 9; i++)
            c_est[i] = c_m[i];
    } else if (mode == 1) {
        nc_matmul3(att_t, c_nav, c_est);
    } else {
        for (int i = 0; i < 9; i++)
            c_est[i] = c_nav[i];
    }
    nc_euler_to_dcm(in + 6, c_mt); /* C_m, used transposed */
    nc_euler_to_dcm(in + 3, c_s);
    tp_tmul(c_mt, c_est, m);
    tp_dcm_to_euler(m, rel_est);
    tp_tmul(c_mt, c_s, m);
    tp_dcm_to_euler(m, r);
    for (int i = 0; i < 3; i++)
        out[i] = nc_wrap_angle(rel_est[i] - r[i]) / arcmin;
    /* B = euler_rate_matrix_inv(rel_est) C_m^T; diag(B P_att B^T) */
    double cp = cos(rel_est[1]), tp = tan(rel_est[1]);
    double cy = cos(rel_est[2]), sy = sin(rel_est[2]);
    double minv[9] = {cy / cp, sy / cp, 0.0, -sy, cy, 0.0, tp * cy, tp * sy, 1.0};
    double b[9], bp[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            b[3 * i + j] = minv[3 * i] * c_mt[3 * j] + minv[3 * i + 1] * c_mt[3 * j + 1] +
                           minv[3 * i + 2] * c_mt[3 * j + 2];
    nc_matmul3(b, p_att, bp);
    for (int i = 0; i < 3; i++) {
        double s = bp[3 * i] * b[3 * i] + bp[3 * i + 1] * b[3 * i + 1] +
                   bp[3 * i + 2] * b[3 * i + 2];
        out[3 + i] = sqrt(0.0 > s ? 0.0 : s) / arcmin;
    }
    tp_tmul(c_m, c_est, m);
    tp_dcm_to_euler(m, rel);
    for (int i = 0; i < 3; i++)
        out[6 + i] = rel[i];
    /* d = c_est c_s^T: the small-angle rotation vector of the error, then e P^-1 e */
    double d[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            d[3 * i + j] = c_est[3 * i] * c_s[3 * j] + c_est[3 * i + 1] * c_s[3 * j + 1] +
                           c_est[3 * i + 2] * c_s[3 * j + 2];
    double e[3] = {0.5 * (d[7] - d[5]), 0.5 * (d[2] - d[6]), 0.5 * (d[3] - d[1])};
    double nees = 0.0;
    for (int j = 0; j < 3; j++) {
        double w = e[0] * p_inv[j] + e[1] * p_inv[3 + j] + e[2] * p_inv[6 + j];
        nees = j == 0 ? w * e[0] : nees + w * e[j];
    }
    return nees;
}
