/* A 1 kHz leg control loop on the generated C transmission alone.
 *
 * Every tick (1 ms of a 2 s sine motion of every motor around home) the loop reads the motor
 * values, computes the output joints (scdk_forward, warm-started from the last tick), the
 * Jacobian d outputs / d motors (scdk_jacobian) and the motor torques that hold a set of
 * output torques (scdk_torques), as a controller working in the leg's serial joint space does.
 * Outside the timed part it checks the inverse map (scdk_inverse gives the motors back) and
 * keeps the worst margin (scdk_margin: how far from singular the leg was).
 *
 * Generated with: scdk codegen MODEL --outputs NAME1,NAME2,... --out DIR (prefix scdk);
 * build: see the Makefile (make transmission). Reads nothing from disk.
 */
#include <math.h>
#include <stdio.h>
#include <time.h>

#include "scdk_transmission.h"

#define TICKS 2000   /* 2 s at 1 kHz */
#define DT 1e-3      /* s */
#define AMPLITUDE 0.1 /* rad (or length unit) around home */
#define PI 3.14159265358979323846

/* motor j at time t [s]: home + A (sin(2 pi f_j t + phi_j) - sin(phi_j)), and its velocity */
static void motion(double t, double *theta, double *dtheta) {
    int j;
    for (j = 0; j < SCDK_NMOTORS; ++j) {
        const double f = 0.5 + 0.25 * j, phase = 0.7 * j, w = 2 * PI * f;
        theta[j] = scdk_home_motors[j] + AMPLITUDE * (sin(w * t + phase) - sin(phase));
        dtheta[j] = AMPLITUDE * w * cos(w * t + phase);
    }
}

static void print_vector(const char *name, const double *v, int n) {
    int i;
    printf("  %s = [", name);
    for (i = 0; i < n; ++i) printf("%s%+.5f", i ? ", " : "", v[i]);
    printf("]\n");
}

int main(void) {
    static scdk_transmission tr; /* large (two tracker states): not on the stack */
    double theta[SCDK_NMOTORS], dtheta[SCDK_NMOTORS], q[SCDK_NOUTPUTS], dq[SCDK_NOUTPUTS];
    double J[SCDK_NOUTPUTS * SCDK_NMOTORS], tau_out[SCDK_NOUTPUTS], tau[SCDK_NMOTORS];
    double back[SCDK_NMOTORS], worst = INFINITY, round_trip = 0.0, seconds = 0.0, slowest = 0.0;
    int worst_block = 0, worst_tick = 0, singular = 0, i, j, status;

    status = scdk_transmission_init(&tr, NULL, NULL);
    if (status != SCDK_OK) {
        printf("init failed: %s\n", scdk_transmission_status_string(status));
        return 1;
    }
    for (i = 0; i < SCDK_NOUTPUTS; ++i) tau_out[i] = 5.0 * cos(i); /* N m held at the joints */
    for (i = 1; i <= TICKS; ++i) {
        const double t = i * DT;
        double value, elapsed;
        int block;
        clock_t t0;
        motion(t, theta, dtheta);
        /* the controller's work: outputs, Jacobian, motor torques */
        t0 = clock();
        status = scdk_forward(&tr, theta, SCDK_NMOTORS, q, SCDK_NOUTPUTS);
        if (status >= 0) status = scdk_jacobian(&tr, J, SCDK_NOUTPUTS * SCDK_NMOTORS);
        if (status >= 0) status = scdk_torques(&tr, tau_out, SCDK_NOUTPUTS, tau, SCDK_NMOTORS);
        elapsed = (double)(clock() - t0) / CLOCKS_PER_SEC;
        seconds += elapsed;
        if (elapsed > slowest) slowest = elapsed;
        if (status == SCDK_ERR_SINGULAR) {
            ++singular; /* a controller would hold its last torques here */
        } else if (status < 0) {
            printf("tick %d: %s\n", i, scdk_transmission_status_string(status));
            return 1;
        }
        /* checks, outside the timed part */
        scdk_margin(&tr, &value, &block, NULL, 0);
        if (value < worst) {
            worst = value;
            worst_block = block;
            worst_tick = i;
        }
        status = scdk_inverse(&tr, q, SCDK_NOUTPUTS, back, SCDK_NMOTORS);
        if (status < 0) {
            printf("tick %d: inverse: %s\n", i, scdk_transmission_status_string(status));
            return 1;
        }
        for (j = 0; j < SCDK_NMOTORS; ++j)
            if (fabs(back[j] - theta[j]) > round_trip) round_trip = fabs(back[j] - theta[j]);
        if (i % 500 == 0) {
            scdk_velocities(&tr, dtheta, SCDK_NMOTORS, dq, SCDK_NOUTPUTS);
            printf("t = %.3f s (margin %.2e)\n", t, value);
            print_vector("outputs [rad]   ", q, SCDK_NOUTPUTS);
            print_vector("velocity [rad/s]", dq, SCDK_NOUTPUTS);
            print_vector("motor torque [Nm]", tau, SCDK_NMOTORS);
        }
    }
    printf("%d ticks: forward + jacobian + torques %.1f us per tick (slowest %.1f us; budget "
           "1000 us)\n",
           TICKS, 1e6 * seconds / TICKS, 1e6 * slowest);
    printf("worst margin %.3e at t = %.3f s in block %d %s (singular ticks: %d)\n", worst,
           worst_tick * DT, worst_block, scdk_block_names[worst_block], singular);
    printf("inverse(forward(theta)) - theta: at most %.1e\n", round_trip);
    return round_trip < 1e-9 && singular == 0 ? 0 : 1;
}
