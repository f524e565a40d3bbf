/* The compiled step of ShipMotion's look-ahead (ship_motion.py, the arithmetic of its numpy code, one call per step).
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

static const double TWO_PI = 6.283185307179586476925286766559; /* 2 * math.pi */

/* ------------------------------------------------------------------ ship motion
 * The moored ship (no linear motion) at the instants tt, and the rows of ShipMotion's
 * look-ahead (models/blocks/ship_motion.py, models/earth.py euler_motion_truth, fixed position).
 * par: w (0:3), amp (3:6), phase (6:9), rpy_mean (9:12), OMEGA_IE cos lat0 (12),
 *      OMEGA_IE sin lat0 (13), gravity (14)
 * tt: (size m) instants, step k's nodes at k m .. k m + m - 1; wts: (m) Simpson weights;
 * steps: (size) step lengths; rows: (size, 21) rpy (yaw wrapped), v_n (0), omega_ib_b,
 * omega_dot_b, f_b at each step end, then dtheta_b, dv_b (plain integrals)
 */
KERNEL void ship_truth_steps(const double *par, const double *tt, const double *wts,
                      const double *steps, long size, long m, double *rows)
{
    const double *w = par, *amp = par + 3, *phase = par + 6, *mean = par + 9;
    double wc = par[12], ws = par[13], g = par[14];
    for (long k = 0; k < size; k++) {
        double sum_w[3] = {0.0, 0.0, 0.0}, sum_f[3] = {0.0, 0.0, 0.0};
        double *row = rows + 21 * k;
        for (long j = 0; j < m; j++) {
            double t = tt[k * m + j], rpy[3], d[3], dd[3];
            for (int i = 0; i < 3; i++) {
                double arg = t * w[i] + phase[i];
                double sa = sin(arg), ca = cos(arg);
                rpy[i] = mean[i] + amp[i] * sa;
                d[i] = amp[i] * w[i] * ca;
                dd[i] = -amp[i] * (w[i] * w[i]) * sa;
            }
            double c[9];
            nc_euler_to_dcm(rpy, c);
            double cr = cos(rpy[0]), sr = sin(rpy[0]), cp = cos(rpy[1]), sp = sin(rpy[1]);
            double rd = d[0], pd = d[1], yd = d[2];
            double w_nb[3] = {d[0] - d[2] * sp, d[1] * cr + d[2] * sr * cp,
                              -d[1] * sr + d[2] * cr * cp};
            double w_nb_dot[3] = {
                dd[0] - dd[2] * sp - yd * pd * cp,
                dd[1] * cr - pd * rd * sr + dd[2] * sr * cp + yd * rd * cr * cp -
                    yd * pd * sr * sp,
                -dd[1] * sr - pd * rd * cr + dd[2] * cr * cp - yd * rd * sr * cp -
                    yd * pd * cr * sp};
            double w_in[3], om[3], omd[3], f[3], cx[3];
            for (int i = 0; i < 3; i++)
                w_in[i] = c[i] * wc - c[6 + i] * ws;
            for (int i = 0; i < 3; i++)
                om[i] = w_nb[i] + w_in[i];
            nc_cross3(w_nb, w_in, cx);
            for (int i = 0; i < 3; i++) {
                omd[i] = w_nb_dot[i] - cx[i];
                f[i] = c[6 + i] * (-g);
                sum_w[i] += wts[j] * om[i];
                sum_f[i] += wts[j] * f[i];
            }
            if (j == m - 1)
                for (int i = 0; i < 3; i++) {
                    row[i] = rpy[i];
                    row[3 + i] = 0.0;
                    row[6 + i] = om[i];
                    row[9 + i] = omd[i];
                    row[12 + i] = f[i];
                }
        }
        row[2] = remainder(row[2], TWO_PI);
        for (int i = 0; i < 3; i++) {
            row[15 + i] = steps[k] * sum_w[i];
            row[18 + i] = steps[k] * sum_f[i];
        }
    }
}
