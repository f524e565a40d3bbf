/* One filter period of the transfer alignment's fine UKF (seed 001, stage 2), compiled.
 *
 * transfer_ukf_period is the twin of what cosim.alignment.transfer_filter.TransferFilter
 * does with its stage-2 UnscentedKalmanFilter in a period: predict (Merwe scaled sigma
 * points of N(x, P), each through transfer_propagate, the heading-aware mean and residual
 * of cosim.estimation.angles, plus Q) and update with the velocity match z = dV + noise
 * (points redrawn from the prior, h(x) = x[1:4], plus R; gain from S K^T = Pxz^T), then the
 * normalised innovation squared. The same formulas in the same order; sums of products
 * run over k = 0, 1, ... here, where numpy goes through BLAS and LAPACK (another order,
 * Cholesky and LU solves): the two paths agree to rounding (tests/test_native_ukf.py).
 *
 * Arguments (float64, row-major): x (n) and P (n x n), overwritten with the posterior on
 * success; Q (n x n), R (3 x 3), z (3); par: transfer_propagate's parameter block; Wm, Wc
 * (2n + 1); spread: n + lambda; heading: the index of the angle state; out: x_prior (n),
 * P_prior (n x n), z_pred (3), S (9), K (n x 3), y (3), nis (1).
 * Returns 0, or 1 / 2 / 3 when the Cholesky factorisation of P, of the prior covariance
 * or of S fails (then nothing is written: the caller reruns numpy for its error).
 * transfer_feedback.c runs this period and the feedback in one call.
 */
#include <math.h>
#include <string.h>

#include "conventions.h"
#include "kernel.h"

KERNEL void transfer_propagate(const double *x, double *out, const double *p, long m, int n,
                        int flexure);


/* lower Cholesky factor of the n x n matrix a into l; 0, or 1 when not positive definite */
static int cholesky(const double *a, double *l, int n)
{
    memset(l, 0, sizeof(double) * (size_t)n * (size_t)n);
    for (int j = 0; j < n; j++) {
        double d = a[j * n + j];
        for (int k = 0; k < j; k++)
            d -= l[j * n + k] * l[j * n + k];
        if (!(d > 0.0))
            return 1;
        d = sqrt(d);
        l[j * n + j] = d;
        for (int i = j + 1; i < n; i++) {
            double s = a[i * n + j];
            for (int k = 0; k < j; k++)
                s -= l[i * n + k] * l[j * n + k];
            l[i * n + j] = s / d;
        }
    }
    return 0;
}

/* solve (l l^T) x = b in place, l lower d x d */
static void chol_solve(const double *l, double *b, int d)
{
    for (int i = 0; i < d; i++) {
        double s = b[i];
        for (int k = 0; k < i; k++)
            s -= l[i * d + k] * b[k];
        b[i] = s / l[i * d + i];
    }
    for (int i = d - 1; i >= 0; i--) {
        double s = b[i];
        for (int k = i + 1; k < d; k++)
            s -= l[k * d + i] * b[k];
        b[i] = s / l[i * d + i];
    }
}

/* the 2n + 1 sigma points of N(x, spread P) into sig (m x n); 0 or 1 (Cholesky failed) */
static int sigma_points(const double *x, const double *P, double spread, int n, double *l,
                        double *scaled, double *sig)
{
    for (int i = 0; i < n * n; i++)
        scaled[i] = spread * P[i];
    if (cholesky(scaled, l, n))
        return 1;
    for (int i = 0; i < n; i++)
        sig[i] = x[i];
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            sig[(1 + j) * n + i] = x[i] + l[i * n + j];
            sig[(1 + n + j) * n + i] = x[i] - l[i * n + j];
        }
    return 0;
}

/* cosim.estimation.angles.angle_mean with one angle column h, m points of size n */
static void angle_mean(const double *s, const double *w, int m, int n, int h, double *mean)
{
    for (int k = 0; k < n; k++) {
        double acc = 0.0;
        for (int i = 0; i < m; i++)
            acc += w[i] * s[i * n + k];
        mean[k] = acc;
    }
    double ss = 0.0, cc = 0.0;
    for (int i = 0; i < m; i++) {
        ss += fabs(w[i]) * sin(s[i * n + h]);
        cc += fabs(w[i]) * cos(s[i * n + h]);
    }
    double ref = atan2(ss, cc), dev = 0.0;
    for (int i = 0; i < m; i++)
        dev += w[i] * nc_wrap_angle(s[i * n + h] - ref);
    mean[h] = nc_wrap_angle(ref + dev);
}

KERNEL int transfer_ukf_period(double *x, double *P, const double *Q, const double *R, const double *z,
                        const double *par, const double *Wm, const double *Wc, double spread,
                        int n, int flexure, int heading, double *out)
{
    const int m = 2 * n + 1;
    double sig[m * n], sig_f[m * n], l[n * n], scaled[n * n], r[m * n];
    double xp[n], Pp[n * n], cov[n * n];
    /* -- predict ------------------------------------------------------------------ */
    if (sigma_points(x, P, spread, n, l, scaled, sig))
        return 1;
    transfer_propagate(sig, sig_f, par, m, n, flexure);
    angle_mean(sig_f, Wm, m, n, heading, xp);
    for (int i = 0; i < m; i++) {
        for (int k = 0; k < n; k++)
            r[i * n + k] = sig_f[i * n + k] - xp[k];
        r[i * n + heading] = nc_wrap_angle(r[i * n + heading]);
    }
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++) {
            double acc = 0.0;
            for (int i = 0; i < m; i++)
                acc += r[i * n + a] * Wc[i] * r[i * n + b];
            cov[a * n + b] = acc + Q[a * n + b];
        }
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++)
            Pp[a * n + b] = 0.5 * (cov[a * n + b] + cov[b * n + a]);
    /* -- update: points of the prior, h(x) = dV = x[1:4] --------------------------- */
    if (sigma_points(xp, Pp, spread, n, l, scaled, sig))
        return 2;
    double zp[3], rz[m * 3], S3[9], S[9], Pxz[n * 3], ls[9];
    for (int k = 0; k < 3; k++) {
        double acc = 0.0;
        for (int i = 0; i < m; i++)
            acc += Wm[i] * sig[i * n + 1 + k];
        zp[k] = acc;
    }
    for (int i = 0; i < m; i++)
        for (int k = 0; k < 3; k++)
            rz[i * 3 + k] = sig[i * n + 1 + k] - zp[k];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double acc = 0.0;
            for (int i = 0; i < m; i++)
                acc += rz[i * 3 + a] * Wc[i] * rz[i * 3 + b];
            S3[a * 3 + b] = acc + R[a * 3 + b];
        }
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            S[a * 3 + b] = 0.5 * (S3[a * 3 + b] + S3[b * 3 + a]);
    for (int i = 0; i < m; i++) {
        for (int k = 0; k < n; k++)
            r[i * n + k] = sig[i * n + k] - xp[k];
        r[i * n + heading] = nc_wrap_angle(r[i * n + heading]);
    }
    for (int a = 0; a < n; a++)
        for (int b = 0; b < 3; b++) {
            double acc = 0.0;
            for (int i = 0; i < m; i++)
                acc += r[i * n + a] * Wc[i] * rz[i * 3 + b];
            Pxz[a * 3 + b] = acc;
        }
    if (cholesky(S, ls, 3))
        return 3;
    double K[n * 3], y[3], sy[3], KS[n * 3];
    for (int a = 0; a < n; a++) { /* row a of K: S k = Pxz[a] (S symmetric) */
        double col[3] = {Pxz[a * 3], Pxz[a * 3 + 1], Pxz[a * 3 + 2]};
        chol_solve(ls, col, 3);
        K[a * 3] = col[0], K[a * 3 + 1] = col[1], K[a * 3 + 2] = col[2];
    }
    for (int k = 0; k < 3; k++)
        y[k] = z[k] - zp[k];
    for (int a = 0; a < n; a++)
        for (int b = 0; b < 3; b++)
            KS[a * 3 + b] = K[a * 3] * S[b] + K[a * 3 + 1] * S[3 + b] + K[a * 3 + 2] * S[6 + b];
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++)
            cov[a * n + b] = Pp[a * n + b] - (KS[a * 3] * K[b * 3] + KS[a * 3 + 1] * K[b * 3 + 1]
                                              + KS[a * 3 + 2] * K[b * 3 + 2]);
    sy[0] = y[0], sy[1] = y[1], sy[2] = y[2];
    chol_solve(ls, sy, 3);
    /* -- write ---------------------------------------------------------------------- */
    double *o = out;
    memcpy(o, xp, sizeof(double) * (size_t)n);
    o += n;
    memcpy(o, Pp, sizeof(double) * (size_t)n * (size_t)n);
    o += n * n;
    memcpy(o, zp, sizeof zp);
    o += 3;
    memcpy(o, S, sizeof S);
    o += 9;
    memcpy(o, K, sizeof(double) * (size_t)n * 3);
    o += n * 3;
    memcpy(o, y, sizeof y);
    o += 3;
    o[0] = y[0] * sy[0] + y[1] * sy[1] + y[2] * sy[2];
    for (int a = 0; a < n; a++)
        x[a] = xp[a] + (K[a * 3] * y[0] + K[a * 3 + 1] * y[1] + K[a * 3 + 2] * y[2]);
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++)
            P[a * n + b] = 0.5 * (cov[a * n + b] + cov[b * n + a]);
    return 0;
}
