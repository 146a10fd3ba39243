/* newton.c: a plain warm-started Newton tracker of a 6-6 Stewart-Gough platform.
 *
 * The conventional method, written by hand for the benchmark (benchmarks/track_hexapod.py):
 * unknowns the platform position p [m] and orientation R; leg residual
 * f_i = |p + R b_i - a_i| - theta_i [m]; analytic Jacobian rows [u_i, (R b_i) x u_i] with
 * u_i the unit leg vector; each iteration solves the 6x6 system by Gaussian elimination with
 * partial pivoting, adds dp to p and turns R by the rotation vector dw (base frame).
 * Every sample starts from the previous pose (warm start). No branch control: near a
 * singular orientation it may continue on the mirror solution.
 */
#include <math.h>
#include <string.h>

/* solve the 6x6 system M x = b (M row-major, overwritten); returns 0 if singular */
static int solve6(double M[6][6], double *b) {
    int i, j, k;
    for (k = 0; k < 6; ++k) {
        int p = k;
        double best = fabs(M[k][k]);
        for (i = k + 1; i < 6; ++i)
            if (fabs(M[i][k]) > best) {
                best = fabs(M[i][k]);
                p = i;
            }
        if (!(best > 0.0)) return 0;
        if (p != k) {
            double t;
            for (j = k; j < 6; ++j) {
                t = M[k][j];
                M[k][j] = M[p][j];
                M[p][j] = t;
            }
            t = b[k];
            b[k] = b[p];
            b[p] = t;
        }
        for (i = k + 1; i < 6; ++i) {
            double f = M[i][k] / M[k][k];
            for (j = k + 1; j < 6; ++j) M[i][j] -= f * M[k][j];
            b[i] -= f * b[k];
        }
    }
    for (k = 5; k >= 0; --k) {
        for (j = k + 1; j < 6; ++j) b[k] -= M[k][j] * b[j];
        b[k] /= M[k][k];
    }
    return 1;
}

/* R <- exp([w]) R (row-major 3x3), Rodrigues' formula */
static void turn(double R[9], const double *w) {
    double angle = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    double K[9], K2[9], E[9], out[9], s, c;
    int i, j, k;
    if (angle == 0.0) return;
    K[0] = 0.0, K[1] = -w[2] / angle, K[2] = w[1] / angle;
    K[3] = w[2] / angle, K[4] = 0.0, K[5] = -w[0] / angle;
    K[6] = -w[1] / angle, K[7] = w[0] / angle, K[8] = 0.0;
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) {
            K2[3 * i + j] = 0.0;
            for (k = 0; k < 3; ++k) K2[3 * i + j] += K[3 * i + k] * K[3 * k + j];
        }
    s = sin(angle);
    c = 1.0 - cos(angle);
    for (i = 0; i < 9; ++i) E[i] = (i % 4 == 0 ? 1.0 : 0.0) + s * K[i] + c * K2[i];
    for (i = 0; i < 3; ++i)
        for (j = 0; j < 3; ++j) {
            out[3 * i + j] = 0.0;
            for (k = 0; k < 3; ++k) out[3 * i + j] += E[3 * i + k] * R[3 * k + j];
        }
    memcpy(R, out, sizeof out);
}

/* URDF rpy (R = Rz(yaw) Ry(pitch) Rx(roll)) -> R, and back */
static void rpy_to_R(const double *a, double R[9]) {
    double cr = cos(a[0]), sr = sin(a[0]), cp = cos(a[1]), sp = sin(a[1]);
    double cy = cos(a[2]), sy = sin(a[2]);
    R[0] = cy * cp, R[1] = cy * sp * sr - sy * cr, R[2] = cy * sp * cr + sy * sr;
    R[3] = sy * cp, R[4] = sy * sp * sr + cy * cr, R[5] = sy * sp * cr - cy * sr;
    R[6] = -sp, R[7] = cp * sr, R[8] = cp * cr;
}

static void R_to_rpy(const double R[9], double *a) {
    a[0] = atan2(R[7], R[8]);
    a[1] = atan2(-R[6], hypot(R[0], R[3]));
    a[2] = atan2(R[3], R[0]);
}

/* Track n readings (thetas: n x 6 leg lengths, row-major) from the pose x0 = (p, rpy).
 * A, B: 6 x 3 base and platform anchors (row-major). out: n x 6 poses (p, rpy).
 * Returns the total number of Newton iterations, or -1 - i if sample i did not reach tol
 * within max_iter iterations (its pose and the later ones are left unset). */
long newton_track(const double *A, const double *B, const double *x0, long n,
                  const double *thetas, double *out, double tol, int max_iter) {
    double p[3], R[9];
    long i, total = 0;
    int it, j, k;
    memcpy(p, x0, sizeof p);
    rpy_to_R(x0 + 3, R);
    for (i = 0; i < n; ++i) {
        const double *theta = thetas + 6 * i;
        int done = 0;
        for (it = 0; it < max_iter; ++it) {
            double M[6][6], f[6], worst = 0.0;
            for (j = 0; j < 6; ++j) {
                const double *b = B + 3 * j, *a = A + 3 * j;
                double rb[3], d[3], len;
                for (k = 0; k < 3; ++k) rb[k] = R[3 * k] * b[0] + R[3 * k + 1] * b[1] + R[3 * k + 2] * b[2];
                for (k = 0; k < 3; ++k) d[k] = p[k] + rb[k] - a[k];
                len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                f[j] = -(len - theta[j]);
                if (!(fabs(f[j]) <= worst)) worst = fabs(f[j]);
                for (k = 0; k < 3; ++k) M[j][k] = d[k] / len;
                M[j][3] = rb[1] * M[j][2] - rb[2] * M[j][1];
                M[j][4] = rb[2] * M[j][0] - rb[0] * M[j][2];
                M[j][5] = rb[0] * M[j][1] - rb[1] * M[j][0];
            }
            if (worst < tol) {
                done = 1;
                break;
            }
            if (!solve6(M, f)) break;
            for (k = 0; k < 3; ++k) p[k] += f[k];
            turn(R, f + 3);
            ++total;
        }
        if (!done) return -1 - i;
        memcpy(out + 6 * i, p, sizeof p);
        R_to_rpy(R, out + 6 * i + 3);
    }
    return total;
}
