/* The compiled step of DeckFlexure (deck_flexure.py, the arithmetic of its numpy code, one call per step).
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

/* ------------------------------------------------------------------ deck flexure
 * phi, root: (axis, 3, 3); noise: (axis, 3) standard normals of this step;
 * st: theta (0:3), theta_dot (3:6), updated; beta2 (3), two_beta (3);
 * out: theta 0, theta_dot 3, theta_ddot 6, eta 9, dtheta_flex 12, dtheta_dot_flex 15 (18)
 */
KERNEL void deck_flexure_step(const double *phi, const double *root, const double *noise,
                       const double *two_beta, const double *beta2, double *st, double *out,
                       double h)
{
    for (int a = 0; a < 3; a++) {
        const double *p = phi + 9 * a, *q = root + 9 * a, *z = noise + 3 * a;
        double x0[3] = {0.0, st[a], st[3 + a]}, x1[3];
        for (int i = 0; i < 3; i++)
            x1[i] = (p[3 * i] * x0[0] + p[3 * i + 1] * x0[1] + p[3 * i + 2] * x0[2]) +
                    (q[3 * i] * z[0] + q[3 * i + 1] * z[1] + q[3 * i + 2] * z[2]);
        double d_theta = x1[1] - st[a], d_theta_dot = x1[2] - st[3 + a];
        double eta = (d_theta_dot + two_beta[a] * d_theta + beta2[a] * x1[0]) / h;
        out[a] = x1[1];
        out[3 + a] = x1[2];
        out[6 + a] = -two_beta[a] * x1[2] - beta2[a] * x1[1] + eta;
        out[9 + a] = eta;
        out[12 + a] = d_theta;
        out[15 + a] = d_theta_dot;
        st[a] = x1[1];
        st[3 + a] = x1[2];
    }
}
