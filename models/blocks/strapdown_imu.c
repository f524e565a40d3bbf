/* The compiled step of StrapdownImu (strapdown_imu.py, the arithmetic of its numpy code, one call per step).
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

/* ------------------------------------------------------------------ strapdown IMU
 * d_true: (2, 3) [dtheta_b; dv_b]; err: (2, 3, 3); bias_int, white: (2, 3) of this step;
 * lsb: (2); resid: (2, 3), updated;
 * out: dtheta_meas_b 0, dv_meas_b 3, omega_meas_b 6, f_meas_b 9, gyro_bias_b 12,
 *      accel_bias_b 15 (18)
 */
KERNEL void strapdown_imu_step(const double *d_true, const double *err, const double *bias_int,
                        const double *white, const double *lsb, double *resid, double *out,
                        double h)
{
    for (int s = 0; s < 2; s++) {
        const double *d = d_true + 3 * s, *e = err + 9 * s;
        double y[3];
        for (int i = 0; i < 3; i++) {
            double ed = e[3 * i] * d[0] + e[3 * i + 1] * d[1] + e[3 * i + 2] * d[2];
            y[i] = d[i] + ed + bias_int[3 * s + i] + white[3 * s + i];
        }
        if (lsb[s] > 0.0)
            for (int i = 0; i < 3; i++) {
                double acc = resid[3 * s + i] + y[i];
                y[i] = lsb[s] * nearbyint(acc / lsb[s]);
                resid[3 * s + i] = acc - y[i];
            }
        for (int i = 0; i < 3; i++) {
            out[3 * s + i] = y[i];
            out[6 + 3 * s + i] = y[i] / h;
            out[12 + 3 * s + i] = bias_int[3 * s + i] / h;
        }
    }
}
