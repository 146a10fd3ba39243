/* Predictor-corrector tracking of complex parameter homotopies, every path in one call.
 *
 * The homotopy of path j (datum d = idx[j]) is
 *   H(z, t) = W G(z, p(s)) + b(s),  p(s) = p_from[d] + s dp[d],  b(s) = b_from[d] + s db[d],
 *   s(t) = gamma[d] t / (1 + (gamma[d] - 1) t),
 * with t real (the path variable), W the row weights and G a square polynomial system, its
 * evaluation on real pairs generated for lane vectors and compiled in (continuation.c). The step
 * rules are those of continuation.py beside it.
 */
#ifndef SCDK_PTRACK_H
#define SCDK_PTRACK_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Status codes of a path (as in continuation.py). */
enum { SCDK_RUNNING = 0, SCDK_DONE = 1, SCDK_DIVERGED = 2, SCDK_UNDERFLOW = 3, SCDK_STEP_LIMIT = 4 };

/* Return codes of scdk_ptrack. */
enum { SCDK_OK = 0, SCDK_NO_MEMORY = 1, SCDK_BAD_SIZE = 3 };

/* Step control (see TrackerOptions in continuation.py). */
typedef struct {
    double h0, h_min, h_max, eta, trust, theta, tol, floor, noise;
    int64_t max_steps;
    double max_norm;
    int64_t third; /* nonzero: a third Newton iteration where the first two contract */
} scdk_options;

/* Track M paths of the homotopy above from tau0[j] to tau1[j] (t = tau).
 *
 * Complex arrays are interleaved (re, im) doubles, row-major: p_from, dp (D x k), b_from,
 * db (D x n), gamma (D), z (M x n, start points in, end points out). h: initial steps in,
 * last steps out. Outputs per path: tau (in: start, out: reached), status, steps (attempts),
 * accepted. n, k: the sizes the library was compiled for (checked).
 * Returns SCDK_OK or an error code (the outputs are then undefined). */
int scdk_ptrack(int64_t n, int64_t k, const double *weights, const double *p_from,
                const double *dp, const double *b_from, const double *db, const double *gamma,
                int64_t M, const int64_t *idx, double *z, double *tau, const double *tau1,
                double *h, const scdk_options *opt, int64_t *status, int64_t *steps,
                int64_t *accepted);

/* Newton's method on H(., t) = 0 for M points, as newton() in continuation.py: `iterations` steps
 * z <- z - H_z^{-1} H (non-finite components of an update left out), nu (M x iterations): the
 * norm of each update relative to 1 + max|z| before it. t (M): each point's real time. hz:
 * NULL, or (M x n x n, row-major complex) H_z at the final points. cond: NULL, or (M) an
 * upper bound of the 2-norm condition number of each final H_z with its rows and then its
 * columns scaled to unit max modulus (|A|_F |A^-1|_F; infinity or NaN if singular). Other
 * arguments as scdk_ptrack's. Returns SCDK_OK or an error code. */
int scdk_pnewton(int64_t n, int64_t k, const double *weights, const double *p_from,
                 const double *dp, const double *b_from, const double *db, const double *gamma,
                 int64_t M, const int64_t *idx, double *z, const double *t, int64_t iterations,
                 double *nu, double *hz, double *cond);

/* The paths of a query in one call. Each path j is tracked as scdk_ptrack tracks it from
 * tau[j], first to `split` and, when it gets there (status DONE), on to t = 1 as a call of
 * its own from there would track it (its velocity computed afresh, counters and rejection
 * flag reset, its last step size kept), in the same lane: z_mid (M x n) receives its point
 * at the split and mid_steps (M) its step attempts up to there (-1: it stopped before, its
 * outputs those of the first part); steps and accepted count both parts. Then
 * scdk_pnewton's `iterations` steps at t = 1 with the condition bound (no H_z) from the end
 * of each path that got past the split and arrived: into z_end (M x n), nu
 * (M x iterations) and cond (M) at that path's rows (other rows untouched). Other arguments
 * as scdk_ptrack's. Returns SCDK_OK or an error code. */
int scdk_psolve(int64_t n, int64_t k, const double *weights, const double *p_from,
                const double *dp, const double *b_from, const double *db, const double *gamma,
                int64_t M, const int64_t *idx, double *z, double *tau, double *h,
                const scdk_options *opt, int64_t *status, int64_t *steps, int64_t *accepted,
                double split, double *z_mid, int64_t *mid_steps, int64_t iterations,
                double *z_end, double *nu, double *cond);

#ifdef __cplusplus
}
#endif

#endif /* SCDK_PTRACK_H */
