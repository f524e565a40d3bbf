/* The transfer-alignment block's master state at a filter period (cosim.alignment.transfer).
 *
 * transfer_master_state is the compiled twin of TransferAlignment.master_state_numpy:
 * cosim.alignment.transfer_model.master_rate (five-point backward difference, the 3- and
 * 2-point formulas with fewer attitudes) of relative_rotvecs (Shepperd's quaternion,
 * normalised, 2 atan2(|q_v|, q_0) q_v / |q_v|; models.conventions.dcm_to_rotvec), plus
 * C^T omega_en_n from cosim.alignment.nav.nav_rates (models.earth.R_M, R_N): the same
 * scalar operations in the same order, the same branches. The 3x3 products are summed
 * k = 0, 1, 2 here; numpy may send them through BLAS (other order, FMA), so the two paths
 * agree to rounding (tests/test_native_master.py).
 *
 * ring (5 x 9): the block's ring of master attitudes C_b_n (row-major); the newest is
 *   ring[newest], the one j steps before it ring[(newest - j) mod 5].
 * k: how many attitudes the history holds (1..5; the rate is zero below 2).
 * h: their spacing [s].
 * v (3): master velocity, NED [m/s].
 * lat, height: master latitude [rad] and height [m].
 * consts (2): A [m], E2 (models.constants).
 * out (12, written): C_b_n of the newest attitude (9, a copy), omega_eb_b (3) [rad/s]
 *   = master_rate + C^T omega_en_n.
 */
#include <math.h>

#include "kernel.h"

#define TM_HISTORY 5

/* transfer_model.relative_rotvecs for one DCM c (row-major); rho (3, written) */
static void tm_rotvec(const double *c, double *rho)
{
    double c00 = c[0], c01 = c[1], c02 = c[2];
    double c10 = c[3], c11 = c[4], c12 = c[5];
    double c20 = c[6], c21 = c[7], c22 = c[8];
    double tr = c00 + c11 + c22;
    double cand[4] = {1.0 + tr, 1.0 + 2.0 * c00 - tr, 1.0 + 2.0 * c11 - tr,
                      1.0 + 2.0 * c22 - tr};
    int j = 0; /* the first largest, as tuple.index(max(...)) */
    for (int i = 1; i < 4; i++)
        if (cand[i] > cand[j])
            j = i;
    double big = sqrt(cand[j] > 0.0 ? cand[j] : 0.0);
    double d32 = c21 - c12, d13 = c02 - c20, d21 = c10 - c01;
    double s10 = c10 + c01, s20 = c20 + c02, s21 = c21 + c12;
    double q[4];
    if (j == 0) {
        q[0] = big, q[1] = d32 / big, q[2] = d13 / big, q[3] = d21 / big;
    } else if (j == 1) {
        q[0] = d32 / big, q[1] = big, q[2] = s10 / big, q[3] = s20 / big;
    } else if (j == 2) {
        q[0] = d13 / big, q[1] = s10 / big, q[2] = big, q[3] = s21 / big;
    } else {
        q[0] = d21 / big, q[1] = s20 / big, q[2] = s21 / big, q[3] = big;
    }
    double q0 = 0.5 * q[0], q1 = 0.5 * q[1], q2 = 0.5 * q[2], q3 = 0.5 * q[3];
    if (q0 < 0.0)
        q0 = -q0, q1 = -q1, q2 = -q2, q3 = -q3;
    double n = sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3);
    q0 = q0 / n, q1 = q1 / n, q2 = q2 / n, q3 = q3 / n;
    if (q0 < 0.0)
        q0 = -q0, q1 = -q1, q2 = -q2, q3 = -q3;
    double sv = sqrt(q1 * q1 + q2 * q2 + q3 * q3);
    double angle = 2.0 * atan2(sv, q0);
    double f = sv < 1e-12 ? 2.0 / q0 : angle / sv;
    rho[0] = f * q1, rho[1] = f * q2, rho[2] = f * q3;
}

KERNEL void transfer_master_state(const double *ring, int newest, int k, double h, const double *v,
                           double lat, double height, const double *consts, double *out)
{
    const double *c0 = ring + 9 * newest;
    double rho[TM_HISTORY - 1][3], rate[3] = {0.0, 0.0, 0.0};
    int m = k < TM_HISTORY ? k : TM_HISTORY;
    for (int j = 1; j < m; j++) { /* rho_j = rotvec(C_0^T C_j) */
        const double *cj = ring + 9 * (((newest - j) % TM_HISTORY + TM_HISTORY) % TM_HISTORY);
        double r[9];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                r[3 * a + b] = c0[a] * cj[b] + c0[3 + a] * cj[3 + b] + c0[6 + a] * cj[6 + b];
        tm_rotvec(r, rho[j - 1]);
    }
    if (k >= 5) {
        double s = 12.0 * h;
        for (int i = 0; i < 3; i++)
            rate[i] = (-48.0 * rho[0][i] + 36.0 * rho[1][i] - 16.0 * rho[2][i] +
                       3.0 * rho[3][i]) / s;
    } else if (k >= 3) {
        for (int i = 0; i < 3; i++)
            rate[i] = (-4.0 * rho[0][i] + rho[1][i]) / (2.0 * h);
    } else if (k == 2) {
        for (int i = 0; i < 3; i++)
            rate[i] = -rho[0][i] / h;
    }
    /* nav_rates: omega_en_n with R_N, R_M of models.earth */
    double a = consts[0], e2 = consts[1];
    double s = sin(lat);
    double rn = a / sqrt(1.0 - e2 * s * s) + height;
    double rm = a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5) + height;
    double w_en[3] = {v[1] / rn, -v[0] / rm, -v[1] * tan(lat) / rn};
    for (int i = 0; i < 9; i++)
        out[i] = c0[i];
    for (int i = 0; i < 3; i++)
        out[9 + i] = rate[i] + (c0[i] * w_en[0] + c0[3 + i] * w_en[1] + c0[6 + i] * w_en[2]);
}

/* transfer_period: the compiled twin of TransferAlignment.period_numpy, the outputs and
 * constants that change with the shown covariance P (once per filter period).
 *
 * P (n x n, row-major), x (n): the filter's shown covariance and estimate.
 * idx (4): first index of phi (att), nabla, eps, and of theta (flexure), or -1 for none.
 * bias (6): the mechanisation's accel_bias [m/s2], gyro_bias [rad/s] (zeros before it starts).
 * arcmin: ARCMIN [rad].
 * per (28, written 9..26): P_att (rad^2), P_att^-1 (rad^-2), each 3x3 row-major; the
 *   inverse by Gaussian elimination with partial pivoting (as LAPACK's getrf + getrs that
 *   numpy.linalg.inv calls, equal to rounding: cond(P_att) eps relative).
 * out (18, written): flex, flex_sigma [arcmin], accel_bias, accel_bias_sigma [m/s2],
 *   gyro_drift, gyro_drift_sigma [rad/s].
 * Returns 0, or 1 when P_att is singular (per untouched from 18 on; numpy raises).
 */
KERNEL int transfer_period(const double *P, int n, const double *x, const int *idx, const double *bias,
                    double arcmin, double *per, double *out)
{
    int att = idx[0], nabla = idx[1], eps = idx[2], flex = idx[3];
    double *p_att = per + 9, *p_inv = per + 18;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            p_att[3 * i + j] = P[n * (att + i) + att + j];
    /* LU with partial pivoting of P_att (first largest |pivot|), then A^-1 = U^-1 L^-1 Pr */
    double lu[9], inv[9];
    int perm[3] = {0, 1, 2};
    for (int i = 0; i < 9; i++)
        lu[i] = p_att[i];
    for (int c = 0; c < 3; c++) {
        int p = c;
        for (int r = c + 1; r < 3; r++)
            if (fabs(lu[3 * r + c]) > fabs(lu[3 * p + c]))
                p = r;
        if (lu[3 * p + c] == 0.0)
            return 1;
        if (p != c) {
            for (int j = 0; j < 3; j++) {
                double t = lu[3 * c + j];
                lu[3 * c + j] = lu[3 * p + j];
                lu[3 * p + j] = t;
            }
            int t = perm[c];
            perm[c] = perm[p];
            perm[p] = t;
        }
        double r_piv = 1.0 / lu[3 * c + c];
        for (int r = c + 1; r < 3; r++) {
            double l = lu[3 * r + c] * r_piv;
            lu[3 * r + c] = l;
            for (int j = c + 1; j < 3; j++)
                lu[3 * r + j] -= l * lu[3 * c + j];
        }
    }
    for (int col = 0; col < 3; col++) { /* solve A y = e_col */
        double y[3];
        for (int r = 0; r < 3; r++) { /* L y = Pr e_col (unit lower) */
            double s = perm[r] == col ? 1.0 : 0.0;
            for (int j = 0; j < r; j++)
                s -= lu[3 * r + j] * y[j];
            y[r] = s;
        }
        for (int r = 2; r >= 0; r--) { /* U y = y */
            double s = y[r];
            for (int j = r + 1; j < 3; j++)
                s -= lu[3 * r + j] * y[j];
            y[r] = s / lu[3 * r + r];
        }
        for (int r = 0; r < 3; r++)
            inv[3 * r + col] = y[r];
    }
    for (int i = 0; i < 9; i++)
        p_inv[i] = inv[i];
    for (int i = 0; i < 3; i++) {
        if (flex >= 0) {
            out[i] = x[flex + i] / arcmin;
            out[3 + i] = sqrt(P[(n + 1) * (flex + i)]) / arcmin;
        } else {
            out[i] = 0.0;
            out[3 + i] = 0.0;
        }
        out[6 + i] = bias[i] + x[nabla + i];
        out[9 + i] = sqrt(P[(n + 1) * (nabla + i)]);
        out[12 + i] = bias[3 + i] + x[eps + i];
        out[15 + i] = sqrt(P[(n + 1) * (eps + i)]);
    }
    return 0;
}
