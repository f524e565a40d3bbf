/* What several kernels share: a 3x3 product and formulas of models.conventions, in the same
 * expressions and the same order as the numpy code (static inline: each C file keeps its
 * own copy). */
#ifndef INS_COSIM_NATIVE_CONVENTIONS_H
#define INS_COSIM_NATIVE_CONVENTIONS_H

#include <math.h>

#define NC_PI 3.141592653589793 /* math.pi */

/* models.conventions.cross: o = a x b (o may alias a or b) */
static inline void nc_cross3(const double *a, const double *b, double *o)
{
    double o0 = a[1] * b[2] - a[2] * b[1];
    double o1 = a[2] * b[0] - a[0] * b[2];
    double o2 = a[0] * b[1] - a[1] * b[0];
    o[0] = o0;
    o[1] = o1;
    o[2] = o2;
}

/* o = a b, 3x3 row-major (o distinct from a and b), summed k = 0, 1, 2 */
static inline void nc_matmul3(const double *a, const double *b, double *o)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            o[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
}

/* models.conventions.euler_to_dcm(_3): C_b_n = Rz(yaw) Ry(pitch) Rx(roll), row-major */
static inline void nc_euler_to_dcm(const double *rpy, double *c)
{
    double cr = cos(rpy[0]), sr = sin(rpy[0]);
    double cp = cos(rpy[1]), sp = sin(rpy[1]);
    double cy = cos(rpy[2]), sy = sin(rpy[2]);
    c[0] = cp * cy;
    c[1] = sr * sp * cy - cr * sy;
    c[2] = cr * sp * cy + sr * sy;
    c[3] = cp * sy;
    c[4] = sr * sp * sy + cr * cy;
    c[5] = cr * sp * sy - sr * cy;
    c[6] = -sp;
    c[7] = sr * cp;
    c[8] = cr * cp;
}

/* models.conventions.wrap_angle of a float: pi - (pi - a) % (2 pi), Python's float % (the
 * remainder takes the divisor's sign), as numpy's np.mod */
static inline double nc_wrap_angle(double a)
{
    double w = 2.0 * NC_PI, m = fmod(NC_PI - a, w);
    if (m != 0.0) {
        if ((w < 0.0) != (m < 0.0))
            m += w;
    } else {
        m = copysign(0.0, w);
    }
    return NC_PI - m;
}

#endif
