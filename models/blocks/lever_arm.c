/* The compiled step of LeverArm (lever_arm.py, the arithmetic of its numpy code, one call per step).
 *
 * The function mirrors the block's numpy step operation by operation (same formulas, same
 * order where it matters), so that the outputs equal the numpy path's to rounding (~1e-16
 * relative; tests/test_native.py). Arrays are float64, C order, in the layout of the
 * Python caller, which keeps the numpy code as the fallback. Declared in the kernel table
 * and built with every other kernel by models/native (IEEE arithmetic: no -ffast-math, no
 * contraction into FMA).
 */
#include <math.h>

#include "conventions.h"
#include "kernel.h"

/* ------------------------------------------------------------------ small helpers */
/* o = v @ M (row vector times a row-major 3x3 matrix) */
static void vecmat3(const double *v, const double *m, double *o)
{
    for (int j = 0; j < 3; j++)
        o[j] = v[0] * m[j] + v[1] * m[3 + j] + v[2] * m[6 + j];
}

/* o = M @ v */
static void matvec3(const double *m, const double *v, double *o)
{
    for (int i = 0; i < 3; i++)
        o[i] = m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2];
}

static double norm3(const double *v) { return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

/* models.conventions.rotvec_to_dcm_and_jacobian of one vector: C = exp([phi x]), J_r */
static void rotvec_dcm_jacobian(const double *phi, double *c, double *jr)
{
    double x = phi[0], y = phi[1], z = phi[2];
    double xx = x * x, yy = y * y, zz = z * z;
    double a = sqrt(xx + yy + zz);
    double a2 = a * a, a4 = a2 * a2, s1, s2, s3;
    if (a < 1e-3) {
        s1 = 1.0 - a2 / 6.0 + a4 / 120.0;
        s2 = 0.5 - a2 / 24.0 + a4 / 720.0;
        s3 = 1.0 / 6.0 - a2 / 120.0 + a4 / 5040.0;
    } else {
        s1 = sin(a) / a;
        s2 = (1.0 - cos(a)) / (a * a);
        s3 = (a - sin(a)) / (a * a * a);
    }
    double k[9] = {0.0, -z, y, z, 0.0, -x, -y, x, 0.0};
    double k2[9] = {-zz - yy, y * x, z * x, x * y, -zz - xx, z * y, x * z, y * z, -yy - xx};
    for (int i = 0; i < 9; i++) {
        double eye = (i % 4 == 0) ? 1.0 : 0.0;
        c[i] = eye + s1 * k[i] + s2 * k2[i];
        jr[i] = eye - s2 * k[i] + s3 * k2[i];
    }
}

/* ------------------------------------------------------------------ lever arm
 * par:  r0 (0:3), R0 row-major (3:12), C_s_d row-major (12:21), flexure (21),
 *       path rel_tol (22), omega_ie [rad/s] (23), dt_truth [s] (24)
 * in:   omega_ib_b 0, omega_dot_b 3, f_b 6, dtheta_b 9, dv_b 12, rpy 15, v_n 18,
 *       theta 21, theta_dot 24, theta_ddot 27, dtheta_flex 30, dtheta_dot_flex 33 (36);
 *       lat [rad] passed on its own
 * st:   rate path: has_t (0), t (1), x (2:5), has_xd (5), xd (6:9);
 *       force path: has_t (9), t (10), x (11:14)                                   (14)
 * out:  omega_is_s 0, f_s 3, dtheta_s 6, dv_s 9, rpy_s 12, v_n_s 15, r_p 18          (21)
 */
/* slave rate, specific force (slave axes) and C_d_b at one instant (slave_kinematics) */
static void lever_node(const double *par, const double *w, const double *wd, const double *f,
                       const double *th, const double *thd, const double *thdd, double *w_s,
                       double *f_s, double *c_d_b)
{
    const double *r0 = par, *R0 = par + 3, *csd = par + 12;
    int flexure = par[21] != 0.0;
    double rt[3], r[3], cwr[3], f_p[3];
    matvec3(R0, th, rt);
    for (int i = 0; i < 3; i++)
        r[i] = r0[i] + rt[i];
    double wr = w[0] * r[0] + w[1] * r[1] + w[2] * r[2];
    double ww = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    nc_cross3(wd, r, cwr);
    for (int i = 0; i < 3; i++)
        f_p[i] = f[i] + cwr[i] + w[i] * wr - r[i] * ww;
    if (!flexure) {
        vecmat3(w, csd, w_s);
        vecmat3(f_p, csd, f_s);
        return;
    }
    double rd[3], rdd[3], cr[3];
    matvec3(R0, thd, rd);
    matvec3(R0, thdd, rdd);
    nc_cross3(w, rd, cr);
    for (int i = 0; i < 3; i++)
        f_p[i] = f_p[i] + 2.0 * cr[i] + rdd[i];
    double jr[9], w_d[3], f_d[3], jt[3];
    rotvec_dcm_jacobian(th, c_d_b, jr);
    vecmat3(w, c_d_b, w_d);
    vecmat3(f_p, c_d_b, f_d);
    matvec3(jr, thd, jt);
    for (int i = 0; i < 3; i++)
        w_d[i] += jt[i];
    vecmat3(w_d, csd, w_s);
    vecmat3(f_d, csd, f_s);
}

/* the step-end outputs (LeverArm._finish) */
static void lever_finish(const double *par, const double *in, double lat, const double *w_s,
                         const double *f_s, const double *th, const double *thd,
                         const double *c_d_b, double *out)
{
    const double *r0 = par, *R0 = par + 3, *csd = par + 12;
    double omega_ie = par[23];
    for (int i = 0; i < 3; i++) {
        out[i] = w_s[i];
        out[3 + i] = f_s[i];
    }
    double cbn[9], csb[9], csn[9];
    nc_euler_to_dcm(in + 15, cbn);
    if (c_d_b != 0)
        nc_matmul3(c_d_b, csd, csb);
    else
        for (int i = 0; i < 9; i++)
            csb[i] = csd[i];
    nc_matmul3(cbn, csb, csn);
    out[12] = atan2(csn[7], csn[8]);
    out[13] = atan2(-csn[6], hypot(csn[7], csn[8]));
    out[14] = atan2(csn[3], csn[0]);
    double rt[3], r_p[3];
    matvec3(R0, th, rt);
    for (int i = 0; i < 3; i++)
        r_p[i] = r0[i] + rt[i];
    double w_ie[3] = {omega_ie * cos(lat), 0.0, -omega_ie * sin(lat)};
    double wn[3], w_eb[3], c[3], rd[3], s[3], vs[3];
    vecmat3(w_ie, cbn, wn);
    for (int i = 0; i < 3; i++)
        w_eb[i] = in[i] - wn[i];
    nc_cross3(w_eb, r_p, c);
    matvec3(R0, thd, rd);
    for (int i = 0; i < 3; i++)
        s[i] = c[i] + rd[i];
    matvec3(cbn, s, vs);
    for (int i = 0; i < 3; i++) {
        out[15 + i] = in[18 + i] + vs[i];
        out[18 + i] = r_p[i];
    }
}

/* outputs at the time of the current inputs (LeverArm._publish_end) */
KERNEL void lever_arm_publish(const double *par, const double *in, double lat, double *out)
{
    static const double zero[3] = {0.0, 0.0, 0.0};
    int flexure = par[21] != 0.0;
    const double *th = flexure ? in + 21 : zero, *thd = flexure ? in + 24 : zero;
    const double *thdd = flexure ? in + 27 : zero;
    double w_s[3], f_s[3], c_d_b[9];
    lever_node(par, in, in + 3, in + 6, th, thd, thdd, w_s, f_s, c_d_b);
    lever_finish(par, in, lat, w_s, f_s, th, thd, flexure ? c_d_b : 0, out);
    for (int i = 6; i < 12; i++)
        out[i] = 0.0;
}

/* StepPath.coefficients with a derivative: rows [x0, h x0', x1, h x1', c] (15), or 0 */
static int rate_path(double *st, double t, double h, const double *x1, const double *inc,
                     const double *xd1, double rel_tol, double *coef)
{
    int valid = st[0] != 0.0 && fabs(t - st[1]) <= 1e-6 * h;
    int ok = 0;
    if (valid && st[5] != 0.0) {
        double n[5] = {0.0, 0.0, 0.0, 0.0, 0.0};
        for (int i = 0; i < 3; i++) {
            double x0 = st[2 + i], m0 = st[6 + i] * h, m1 = xd1[i] * h, mean = inc[i] / h;
            double mismatch = mean - (0.5 * (x0 + x1[i]) + (m0 - m1) / 12.0);
            coef[i] = x0;
            coef[3 + i] = m0;
            coef[6 + i] = x1[i];
            coef[9 + i] = m1;
            coef[12 + i] = 30.0 * mismatch;
        }
        for (int r = 0; r < 5; r++)
            n[r] = norm3(coef + 3 * r);
        double scale = n[0] + n[2] + n[1] + n[3];
        ok = n[4] <= 30.0 * (rel_tol * scale + 1e-300);
    }
    st[0] = 1.0;
    st[1] = t + h;
    st[5] = 1.0;
    for (int i = 0; i < 3; i++) {
        st[2 + i] = x1[i];
        st[6 + i] = xd1[i];
    }
    return ok;
}

/* StepPath.coefficients without a derivative: rows [x0, x1, 6 c] (9), or 0 */
static int force_path(double *st, double t, double h, const double *x1, const double *inc,
                      double rel_tol, double *coef)
{
    int valid = st[0] != 0.0 && fabs(t - st[1]) <= 1e-6 * h;
    int ok = 0;
    if (valid) {
        for (int i = 0; i < 3; i++) {
            double x0 = st[2 + i], mean = inc[i] / h;
            double c = mean - 0.5 * (x0 + x1[i]);
            coef[i] = x0;
            coef[3 + i] = x1[i];
            coef[6 + i] = 6.0 * c;
        }
        double n0 = norm3(coef), n1 = norm3(coef + 3), n2 = norm3(coef + 6);
        ok = n2 <= 6.0 * (rel_tol * (n0 + n1) + 1e-300);
    }
    st[0] = 1.0;
    st[1] = t + h;
    for (int i = 0; i < 3; i++)
        st[2 + i] = x1[i];
    return ok;
}

/* One LeverArm.step from t to t + h (the nodes are evaluated one at a time); returns 0. */
KERNEL int lever_arm_step(const double *par, double *st, const double *in, double lat, double *out,
                   double t, double h)
{
    double dt = par[24];
    long n = 1;
    if (dt > 0.0) {
        double q = nearbyint(h / dt);
        n = q > 1.0 ? (long)q : 1;
    }
    long m = 2 * n;
    int flexure = par[21] != 0.0;
    double rel_tol = par[22];
    double cw[15], cf[9];
    int has_w = rate_path(st, t, h, in, in + 9, in + 3, rel_tol, cw);
    int has_f = force_path(st + 9, t, h, in + 6, in + 12, rel_tol, cf);
    const double *R0 = par + 3, *csd = par + 12;
    /* memoryless fallbacks: step_quadratic of the rate, step_linear of the force */
    double qd1[3], qc[3], lb[3];
    for (int i = 0; i < 3; i++) {
        qd1[i] = in[3 + i] * h;
        qc[i] = 3.0 * (in[9 + i] / h - in[i] + 0.5 * qd1[i]);
        lb[i] = 2.0 * (in[6 + i] - in[12 + i] / h);
    }
    double p[12] = {0.0};
    const double *th1 = in + 21, *thd1 = in + 24;
    if (flexure)
        for (int i = 0; i < 3; i++) {
            p[i] = th1[i] - in[30 + i];
            p[3 + i] = (thd1[i] - in[33 + i]) * h;
            p[6 + i] = th1[i];
            p[9 + i] = thd1[i] * h;
        }
    double sum_w[3] = {0.0, 0.0, 0.0}, sum_f[3] = {0.0, 0.0, 0.0};
    double w_s[3], f_s[3], c_d_b[9], th[3] = {0.0, 0.0, 0.0}, thd[3] = {0.0, 0.0, 0.0};
    double thdd[3] = {0.0, 0.0, 0.0};
    double den = 3.0 * (double)m;
    for (long k = 0; k <= m; k++) {
        double u = (double)k / (double)m;
        double wt = (k == 0 || k == m) ? 1.0 : ((k % 2) ? 4.0 : 2.0);
        wt = wt / den;
        double u2 = u * u, u3 = u * u * u;
        double b0[4] = {2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2};
        double b1[4] = {6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u};
        double bump = u * (1.0 - u);
        double w[3], wd[3], f[3];
        for (int i = 0; i < 3; i++) {
            if (has_w) {
                w[i] = b0[0] * cw[i] + b0[1] * cw[3 + i] + b0[2] * cw[6 + i] + b0[3] * cw[9 + i] +
                       bump * bump * cw[12 + i];
                wd[i] = (b1[0] * cw[i] + b1[1] * cw[3 + i] + b1[2] * cw[6 + i] +
                         b1[3] * cw[9 + i] + 2.0 * bump * (1.0 - 2.0 * u) * cw[12 + i]) /
                        h;
            } else {
                double v = u - 1.0;
                w[i] = in[i] + qd1[i] * v + qc[i] * v * v;
                wd[i] = (qd1[i] + 2.0 * qc[i] * v) / h;
            }
            if (has_f)
                f[i] = (1.0 - u) * cf[i] + u * cf[3 + i] + bump * cf[6 + i];
            else
                f[i] = in[6 + i] + lb[i] * (u - 1.0);
        }
        if (flexure) {
            double b2[4] = {12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2};
            for (int i = 0; i < 3; i++) {
                th[i] = b0[0] * p[i] + b0[1] * p[3 + i] + b0[2] * p[6 + i] + b0[3] * p[9 + i];
                thd[i] =
                    (b1[0] * p[i] + b1[1] * p[3 + i] + b1[2] * p[6 + i] + b1[3] * p[9 + i]) / h;
                thdd[i] = (b2[0] * p[i] + b2[1] * p[3 + i] + b2[2] * p[6 + i] +
                           b2[3] * p[9 + i]) /
                          (h * h);
            }
        }
        lever_node(par, w, wd, f, th, thd, thdd, w_s, f_s, c_d_b);
        for (int i = 0; i < 3; i++) {
            sum_w[i] += wt * w_s[i];
            sum_f[i] += wt * f_s[i];
        }
    }
    for (int i = 0; i < 3; i++) {
        out[6 + i] = h * sum_w[i];
        out[9 + i] = h * sum_f[i];
    }
    static const double zero[3] = {0.0, 0.0, 0.0};
    if (!flexure) {
        lever_finish(par, in, lat, w_s, f_s, zero, zero, 0, out);
        return 0;
    }
    /* step end: theta'' is the flexure's theta_ddot, not the Hermite end slope */
    double d_acc[3], ra[3], rc[3], rs[3], f_end[3];
    for (int i = 0; i < 3; i++)
        d_acc[i] = in[27 + i] - thdd[i];
    matvec3(R0, d_acc, ra);
    vecmat3(ra, c_d_b, rc);
    vecmat3(rc, csd, rs);
    for (int i = 0; i < 3; i++)
        f_end[i] = f_s[i] + rs[i];
    lever_finish(par, in, lat, w_s, f_end, th1, thd1, c_d_b, out);
    return 0;
}
