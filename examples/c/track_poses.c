/* Track a pose sequence of a Stewart-Gough platform with the generated C tracker alone.
 *
 * The program builds a smooth 6-dof pose sequence around the home pose, computes the leg
 * lengths of every pose with the generated inverse-kinematics step (scdk_ik_solve), feeds
 * them to the tracker one by one (scdk_tracker_step), and compares the tracked platform
 * coordinates with the poses. It also shows that a NaN reading is refused with a status.
 *
 * Build: see the Makefile (only the generated files and the C library are needed).
 */
#include <math.h>
#include <stdio.h>
#include <time.h>

#include "scdk_tracker.h"

#if SCDK_NX != 6
#error "this example expects a workspace x, y, z, roll, pitch, yaw (e.g. models/stewart_gough)"
#endif

#define SAMPLES 2000
#define PI 3.14159265358979323846

/* pose number i of SAMPLES: x = home + amp (sin(2 pi f t + phase) - sin(phase)) */
static void pose(int i, double *x) {
    static const double amp[6] = {0.04, 0.04, 0.03, 0.10, 0.10, 0.20}; /* m, rad */
    static const double freq[6] = {1.0, 2.0, 1.5, 1.0, 2.5, 0.5};
    static const double phase[6] = {0.0, 0.5, 1.0, 1.5, 2.0, 2.5};
    double t = (double)i / (SAMPLES - 1);
    int j;
    for (j = 0; j < 6; ++j)
        x[j] = scdk_home_x[j] + amp[j] * (sin(2 * PI * freq[j] * t + phase[j]) - sin(phase[j]));
}

/* 4x4 placement (column-major) of x = [x, y, z, roll, pitch, yaw]: R = Rz(yaw) Ry(pitch) Rx(roll) */
static void placement(const double *x, double *T) {
    double cr = cos(x[3]), sr = sin(x[3]), cp = cos(x[4]), sp = sin(x[4]);
    double cy = cos(x[5]), sy = sin(x[5]);
    double R[3][3] = {{cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr},
                      {sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr},
                      {-sp, cp * sr, cp * cr}};
    int r, c;
    for (c = 0; c < 3; ++c) {
        for (r = 0; r < 3; ++r) T[r + 4 * c] = R[r][c];
        T[3 + 4 * c] = 0.0;
    }
    for (r = 0; r < 3; ++r) T[r + 12] = x[r];
    T[15] = 1.0;
}

int main(void) {
    scdk_state st;
    double y[SCDK_NY], c[SCDK_NC_ALLOC], theta[SCDK_NTHETA], x[SCDK_NX], xp[SCDK_NX], T[16];
    double err = 0.0, seconds = 0.0, nan_theta[SCDK_NTHETA];
    int counts[3] = {0, 0, 0};
    int i, j, status;

    status = scdk_tracker_init(&st, scdk_home_y, SCDK_NY, scdk_home_c, SCDK_NC,
                               scdk_home_theta, SCDK_NTHETA, NULL);
    if (status != SCDK_OK) {
        printf("init failed: %s\n", scdk_status_string(status));
        return 1;
    }
    for (i = 1; i < SAMPLES; ++i) {
        clock_t t0;
        pose(i, xp);
        placement(xp, T);
        /* leg lengths of the pose: inverse kinematics from the current configuration */
        scdk_tracker_get(&st, y, SCDK_NY, c, SCDK_NC, NULL, 0);
        for (j = 0; j < SCDK_NTHETA; ++j) theta[j] = st.theta[j];
        status = scdk_ik_solve(y, SCDK_NY, theta, SCDK_NTHETA, c, SCDK_NC, T, 20, 1e-13);
        if (status != SCDK_OK) {
            printf("pose %d: inverse kinematics failed: %s\n", i, scdk_status_string(status));
            return 1;
        }
        /* direct kinematics: the tracker sees only the leg lengths */
        t0 = clock();
        status = scdk_tracker_step(&st, theta, SCDK_NTHETA);
        seconds += (double)(clock() - t0) / CLOCKS_PER_SEC;
        if (status < 0) {
            printf("pose %d: tracker failed: %s\n", i, scdk_status_string(status));
            return 1;
        }
        ++counts[status];
        scdk_tracker_get(&st, NULL, 0, NULL, 0, x, SCDK_NX);
        for (j = 0; j < SCDK_NX; ++j)
            if (fabs(x[j] - xp[j]) > err) err = fabs(x[j] - xp[j]);
    }
    printf("tracked %d poses: max |x - x_pose| = %.1e (m, rad; expected below 1e-9)\n",
           SAMPLES - 1, err);
    printf("steps: %d cheap, %d along the SC curve, %d from the prediction; %.1f us per step\n",
           counts[SCDK_OK], counts[SCDK_OK_PATH], counts[SCDK_OK_PREDICTED],
           1e6 * seconds / (SAMPLES - 1));
    for (j = 0; j < SCDK_NTHETA; ++j) nan_theta[j] = st.theta[j];
    nan_theta[2] = NAN;
    status = scdk_tracker_step(&st, nan_theta, SCDK_NTHETA);
    printf("a NaN leg length is refused: status %d (%s)\n", status, scdk_status_string(status));
    return err < 1e-9 && status == SCDK_ERR_NONFINITE ? 0 : 1;
}
