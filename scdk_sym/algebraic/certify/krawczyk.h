/* Krawczyk tests of many points at once in binary64 interval arithmetic (see krawczyk.c).
 *
 * A square system f(x, p) = 0 and its Jacobian are given as two tapes: the instruction lists
 * of CasADi SX Functions (x[n], p[k]) -> f[n] and (x[n], p[k]) -> J (n x n, row-major),
 * restricted to operations whose binary64 result is the correctly rounded exact result
 * (+, -, *, /, squares, negation, doubling, reciprocal, |.| and its sign) and to sin and cos,
 * enclosed from those alone (krawczyk.c). Every interval operation rounds to nearest and then
 * moves each bound one binary64 number outward, so each result encloses the exact value over
 * the operand intervals.
 */
#ifndef SCDK_IKRAWCZYK_H
#define SCDK_IKRAWCZYK_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Tape operation codes (the Python side maps CasADi opcodes to these). */
enum {
    SCDK_I_CONST = 0,  /* w[o] = c */
    SCDK_I_INPUT = 1,  /* w[o] = input a (0: x, 1: p), dense entry b */
    SCDK_I_OUTPUT = 2, /* out[o] = w[a] (dense entry o of the output) */
    SCDK_I_ASSIGN = 3, /* w[o] = w[a] */
    SCDK_I_NEG = 4,
    SCDK_I_SQ = 5,
    SCDK_I_TWICE = 6,
    SCDK_I_INV = 7,
    SCDK_I_FABS = 8,
    SCDK_I_ADD = 9, /* w[o] = w[a] + w[b] */
    SCDK_I_SUB = 10,
    SCDK_I_MUL = 11,
    SCDK_I_DIV = 12,
    SCDK_I_SIGN = 13, /* exact: -1, 0 or 1 */
    SCDK_I_SIN = 14,
    SCDK_I_COS = 15
};

/* One tape: L instructions (op, a, b, o, c), a work vector of W intervals, an output of
 * n_out dense entries (zero where the tape writes nothing). */
typedef struct {
    int64_t L, W, n_out;
    const int64_t *op, *a, *b, *o;
    const double *c;
} scdk_tape;

/* Outcomes of scdk_ikrawczyk per point. */
enum { SCDK_K_NOT_PROVEN = 0, SCDK_K_PROVEN = 1 };

/* Return codes of scdk_ikrawczyk. */
enum {
    SCDK_K_OK = 0,
    SCDK_K_NO_MEMORY = 1,
    SCDK_K_BAD_SIZE = 2,
    SCDK_K_FAILED = 3,
    SCDK_K_LANES_DIFFER = 4
};

/* The Krawczyk test of N points m (N x n) for the parameters in [p_lo, p_hi] (k each):
 * Y ~ J(m)^-1 in binary64 (the Jacobian tape replayed in plain binary64 at m and the
 * parameters' midpoints, then LU; any approximate inverse keeps the test sound; no test when
 * its condition estimate |J|_inf |Y|_inf is not below max_cond), then
 *   X = [m - r, m + r] (bounds rounded outward), r_i = 2 max|mid(N) - m| + 4 rad(N_i) (at
 *   least tiny), N = m - Y f(m),
 *   K(X) = N + (I - Y J(X)) (X - m);
 * proven when K(X) lies in the interior of X: X then holds exactly one zero of f(., p) for
 * every p in the parameter box, and it lies in K(X). A proven enclosure is then shrunk by at
 * most `tighten` Krawczyk steps centred on its midpoint while its largest radius exceeds
 * 64 eps (1 + max|mid|) and twice the last interval Newton point's, and decreases (each
 * intersected with the previous enclosure; a step that does not halve it is the last).
 * Point q's parameter box is [p_lo + q p_stride, p_hi + q p_stride] (k each; p_stride 0:
 * one box for all points).
 * Outputs per point: status (SCDK_K_*), r (n, the radii of X), box (n x 2, [lo, hi] of the
 * enclosure of the zero when proven; NaN otherwise). Any non-finite bound, a divisor
 * interval holding 0 or a failed inversion leaves a point not proven (or ends its
 * tightening). */
int scdk_ikrawczyk(const scdk_tape *value, const scdk_tape *jacobian, int64_t n, int64_t k,
                   int64_t N, const double *m, const double *p_lo, const double *p_hi,
                   int64_t p_stride, int64_t tighten, double tiny, double max_cond,
                   int64_t *status, double *r, double *box);

/* The tape replayed once on x (n x 2) and p (k x 2) intervals [lo, hi] into out (n_out x 2)
 * (every lane of the replay on them). lanes != 0: lane 0 on x and p and lane l on them scaled
 * by 1 + l 2^-10, each lane checked against a replay with its inputs in every lane (the same
 * failure, the same bits: a point's values do not depend on its lane); out is lane 0's.
 * Returns SCDK_K_OK, SCDK_K_FAILED (a bound not finite or a divisor holding 0: out is NaN),
 * SCDK_K_LANES_DIFFER or an error code. */
int scdk_ireplay(const scdk_tape *t, int64_t n, int64_t k, const double *x, const double *p,
                 double *out, int64_t lanes);

#ifdef __cplusplus
}
#endif

#endif /* SCDK_IKRAWCZYK_H */
