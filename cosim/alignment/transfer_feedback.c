/* The fine UKF's closed-loop feedback (transfer alignment, seed 001, stage 2), compiled.
 *
 * transfer_feedback is the twin of TransferFilter._feedback followed by the reset state of
 * TransferFilter.update (cosim/alignment/transfer_filter.py): wrap the heading estimate
 * (models.conventions.wrap_angle), correct the mechanisation in its compiled state buffer
 * (Strapdown.correct with rotation = euler_to_dcm(phi)^T, d_v = dV - M1 xi and d_lat =
 * dL; then accel_bias += nabla, gyro_bias += eps), return the reset covariance
 * sym(J P J^T), J = reset_jacobian (the identity but for the attitude block, the Euler-rate
 * matrix of cosim.alignment.nav.euler_rate_matrix), and the state after the reset (zero but
 * for the flexure states xi, kept, and dV = M1 xi). The same formulas in the same order;
 * the products run over k = 0, 1, ... (J's zeros and ones, which add exact zeros and copy,
 * are left out), where numpy's go through BLAS: the two agree to rounding
 * (tests/test_native_feedback.py).
 *
 * transfer_ukf_fed_period runs transfer_ukf_period (transfer_ukf.c) and, when it succeeds,
 * transfer_feedback on its posterior: the whole stage-2 period in one call.
 *
 * Arguments (float64, row-major): nav, the state buffer of strapdown.c (C_s_n at 0, v_n at 9,
 * v_prev at 12, lat at 15, gyro_bias at 17, accel_bias at 20; corrected in place); x (n) and
 * P (n x n), the posterior (read only); m1 (3 x 6), the flexure matrix at the period's end
 * (read only with flexure); heading, the index of the heading error; fed: the state after
 * the reset (n) and the reset covariance (n x n).
 */
#include <math.h>

#include "conventions.h"
#include "kernel.h"

KERNEL int transfer_ukf_period(double *x, double *P, const double *Q, const double *R, const double *z,
                        const double *par, const double *Wm, const double *Wc, double spread,
                        int n, int flexure, int heading, double *out);

/* state layout (cosim.alignment.transfer_model.StateLayout) */
#define DL 0
#define DV 1
#define ATT 4
#define XI 7

KERNEL void transfer_feedback(double *nav, const double *x, const double *P, const double *m1, int n,
                       int flexure, int heading, double *fed)
{
    double xw[n], mxi[3] = {0.0, 0.0, 0.0}, d_v[3], c[9], rot[9], cn[9], a[9];
    const int nabla = flexure ? 13 : 7, eps = flexure ? 16 : 10;
    double *x_new = fed, *Pn = fed + n;
    for (int i = 0; i < n; i++)
        xw[i] = x[i];
    xw[heading] = nc_wrap_angle(x[heading]);
    /* d_v = x[dv] - m1 @ x[xi] (or - 0.0) */
    if (flexure)
        for (int i = 0; i < 3; i++) {
            double acc = 0.0;
            for (int k = 0; k < 6; k++)
                acc += m1[6 * i + k] * xw[XI + k];
            mxi[i] = acc;
        }
    for (int i = 0; i < 3; i++)
        d_v[i] = xw[DV + i] - mxi[i];
    /* euler_to_dcm(x[att]) (models.conventions.euler_to_dcm_3), transposed */
    const double cr = cos(xw[ATT]), sr = sin(xw[ATT]);
    const double cp = cos(xw[ATT + 1]), sp = sin(xw[ATT + 1]);
    const double cy = cos(xw[ATT + 2]), sy = sin(xw[ATT + 2]);
    c[0] = cp * cy, c[1] = sr * sp * cy - cr * sy, c[2] = cr * sp * cy + sr * sy;
    c[3] = cp * sy, c[4] = sr * sp * sy + cr * cy, c[5] = cr * sp * sy - sr * cy;
    c[6] = -sp, c[7] = sr * cp, c[8] = cr * cp;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            rot[3 * i + j] = c[3 * j + i];
    /* Strapdown.correct: v_n, v_prev -= d_v; C_s_n <- rot C_s_n; lat -= d_lat */
    for (int i = 0; i < 3; i++) {
        nav[9 + i] = nav[9 + i] - d_v[i];
        nav[12 + i] = nav[12 + i] - d_v[i];
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cn[3 * i + j] = rot[3 * i] * nav[j] + rot[3 * i + 1] * nav[3 + j]
                            + rot[3 * i + 2] * nav[6 + j];
    for (int i = 0; i < 9; i++)
        nav[i] = cn[i];
    nav[15] -= xw[DL];
    for (int i = 0; i < 3; i++)
        nav[20 + i] = nav[20 + i] + xw[nabla + i];
    for (int i = 0; i < 3; i++)
        nav[17 + i] = nav[17 + i] + xw[eps + i];
    /* J = reset_jacobian(x): its attitude block, euler_rate_matrix(x[att]) */
    a[0] = cy * cp, a[1] = -sy, a[2] = 0.0;
    a[3] = sy * cp, a[4] = cy, a[5] = 0.0;
    a[6] = -sp, a[7] = 0.0, a[8] = 1.0;
    /* JP = J @ P into Pn; then M = JP @ J^T (column by column: only the attitude columns
     * change), in place; then sym(M) */
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            Pn[i * n + j] = P[i * n + j];
    for (int j = 0; j < n; j++) {
        double col[3];
        for (int r = 0; r < 3; r++)
            col[r] = a[3 * r] * P[ATT * n + j] + a[3 * r + 1] * P[(ATT + 1) * n + j]
                     + a[3 * r + 2] * P[(ATT + 2) * n + j];
        for (int r = 0; r < 3; r++)
            Pn[(ATT + r) * n + j] = col[r];
    }
    for (int i = 0; i < n; i++) {
        double *row = Pn + i * n + ATT, res[3];
        for (int r = 0; r < 3; r++)
            res[r] = row[0] * a[3 * r] + row[1] * a[3 * r + 1] + row[2] * a[3 * r + 2];
        for (int r = 0; r < 3; r++)
            row[r] = res[r];
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++) {
            double s = 0.5 * (Pn[i * n + j] + Pn[j * n + i]);
            Pn[i * n + j] = s;
            Pn[j * n + i] = s;
        }
    /* the state after the reset */
    for (int i = 0; i < n; i++)
        x_new[i] = 0.0;
    if (flexure) {
        for (int k = 0; k < 6; k++)
            x_new[XI + k] = xw[XI + k];
        for (int i = 0; i < 3; i++)
            x_new[DV + i] = mxi[i];
    }
}

KERNEL int transfer_ukf_fed_period(double *x, double *P, const double *Q, const double *R,
                            const double *z, const double *par, const double *Wm,
                            const double *Wc, double spread, int n, int flexure, int heading,
                            double *out, double *nav, const double *m1, double *fed)
{
    int code = transfer_ukf_period(x, P, Q, R, z, par, Wm, Wc, spread, n, flexure, heading, out);
    if (code != 0)
        return code;
    transfer_feedback(nav, x, P, m1, n, flexure, heading, fed);
    return 0;
}
