/* scdk_lu.h: the one pivoted elimination of scdk_sym's C sources.
 *
 * LU factorisation with partial pivoting, P A = L U, in place (L unit lower triangular below
 * the diagonal, U on and above it), of an n x n matrix, real or complex, and the solves with
 * its factors. Every C source of the package that eliminates uses it: the generated
 * direct-kinematics tracker (real, column-major Jacobians), the complex homotopy tracker
 * (row-major, real and imaginary parts apart) and the interval Krawczyk certificate (the
 * midpoint inverse).
 *
 * Storage: element (i, j) of a matrix is at A[i * rs + j * cs] (column-major: rs = 1, cs = n;
 * row-major: rs = n, cs = 1); a complex matrix keeps its real parts in ar and its imaginary
 * parts at the same places of ai; ai == NULL means a real matrix. Vectors are strided by bs.
 * The pivot of column k is the first of the largest |re| + |im| on and below the diagonal
 * (|a| for a real matrix); rows are swapped whole (LAPACK's convention), the multipliers are
 * those entries times the pivot's reciprocal. A zero or NaN pivot fails the factorisation.
 *
 * The functions are static and always inlined: called with constant sizes and strides (the
 * tracker's fixed-size Jacobians), the compiler unrolls them as if written for that size.
 * Define SCDK_UNROLL (e.g. to _Pragma("GCC unroll 16")) before including to unroll the loops.
 */
#ifndef SCDK_LU_H
#define SCDK_LU_H

#include <math.h>

#ifndef SCDK_UNROLL
#define SCDK_UNROLL
#endif

#if defined(__GNUC__)
#define SCDK_LU_FN static inline __attribute__((always_inline, unused))
#else
#define SCDK_LU_FN static inline
#endif

/* the reciprocal (rr, ri) of the complex number (re, im), as |z|^-2 conj(z) */
#define SCDK_LU_RECIPROCAL(re, im, rr, ri)                                                        \
    do {                                                                                           \
        const double d_ = (re) * (re) + (im) * (im);                                               \
        (rr) = (re) / d_;                                                                          \
        (ri) = -(im) / d_;                                                                         \
    } while (0)

/* |re| + |im| of element (i, j) of the matrix (ar, ai) (|a| of a real one) */
#define SCDK_LU_MAG(i, j)                                                                          \
    (ai ? fabs(ar[(i) * rs + (j) * cs]) + fabs(ai[(i) * rs + (j) * cs])                            \
        : fabs(ar[(i) * rs + (j) * cs]))

/* P A = L U in place (see the file's comment); piv[k]: the row swapped with row k at step k.
 * Returns 1, or 0 when a pivot is zero or NaN (A is then partly factored). */
SCDK_LU_FN int scdk_lu_factor(double *ar, double *ai, int n, int rs, int cs, int *piv) {
    int i, j, k;
    SCDK_UNROLL
    for (k = 0; k < n; ++k) {
        double best = SCDK_LU_MAG(k, k);
        int p = k;
        SCDK_UNROLL
        for (i = k + 1; i < n; ++i) {
            const double v = SCDK_LU_MAG(i, k);
            if (v > best) {
                best = v;
                p = i;
            }
        }
        piv[k] = p;
        if (!(best > 0.0)) return 0;
        if (p != k) {
            SCDK_UNROLL
            for (j = 0; j < n; ++j) {
                double t = ar[k * rs + j * cs];
                ar[k * rs + j * cs] = ar[p * rs + j * cs];
                ar[p * rs + j * cs] = t;
                if (ai) {
                    t = ai[k * rs + j * cs];
                    ai[k * rs + j * cs] = ai[p * rs + j * cs];
                    ai[p * rs + j * cs] = t;
                }
            }
        }
        if (!ai) {
            const double r = 1.0 / ar[k * rs + k * cs];
            SCDK_UNROLL
            for (i = k + 1; i < n; ++i) ar[i * rs + k * cs] *= r;
            SCDK_UNROLL
            for (j = k + 1; j < n; ++j) {
                const double u = ar[k * rs + j * cs];
                SCDK_UNROLL
                for (i = k + 1; i < n; ++i) ar[i * rs + j * cs] -= ar[i * rs + k * cs] * u;
            }
        } else {
            double rr, ri;
            SCDK_LU_RECIPROCAL(ar[k * rs + k * cs], ai[k * rs + k * cs], rr, ri);
            for (i = k + 1; i < n; ++i) {
                const double xr = ar[i * rs + k * cs], xi = ai[i * rs + k * cs];
                const double lr = xr * rr - xi * ri, li = xr * ri + xi * rr;
                ar[i * rs + k * cs] = lr;
                ai[i * rs + k * cs] = li;
                for (j = k + 1; j < n; ++j) {
                    const double ur = ar[k * rs + j * cs], ui = ai[k * rs + j * cs];
                    ar[i * rs + j * cs] -= lr * ur - li * ui;
                    ai[i * rs + j * cs] -= lr * ui + li * ur;
                }
            }
        }
    }
    return 1;
}

/* the determinant from the factors of a successful real scdk_lu_factor */
SCDK_LU_FN double scdk_lu_det(const double *ar, int n, int rs, int cs, const int *piv) {
    double det = 1.0;
    int k;
    SCDK_UNROLL
    for (k = 0; k < n; ++k) {
        const double u = ar[k * rs + k * cs];
        det *= piv[k] != k ? -u : u;
    }
    return det;
}

/* b <- A^-1 b, or A^-T b when transposed (the transpose, not the conjugate), in place, with
 * the factors of a successful scdk_lu_factor (same storage); b's real parts in br, imaginary
 * parts in bi (NULL with a real matrix), stride bs. */
SCDK_LU_FN void scdk_lu_solve(const double *ar, const double *ai, int n, int rs, int cs,
                              const int *piv, double *br, double *bi, int bs, int transposed) {
#define SCDK_A(i, j) ar[(i) * rs + (j) * cs]
#define SCDK_AI(i, j) ai[(i) * rs + (j) * cs]
#define SCDK_SWAP(k)                                                                               \
    do {                                                                                           \
        double t_ = br[(k) * bs];                                                                  \
        br[(k) * bs] = br[piv[k] * bs];                                                            \
        br[piv[k] * bs] = t_;                                                                      \
        if (bi) {                                                                                  \
            t_ = bi[(k) * bs];                                                                     \
            bi[(k) * bs] = bi[piv[k] * bs];                                                        \
            bi[piv[k] * bs] = t_;                                                                  \
        }                                                                                          \
    } while (0)
/* b_k -= a b_j (complex a = (a_r, a_i)) */
#define SCDK_AXPY(k, a_r, a_i, j)                                                                  \
    do {                                                                                           \
        if (bi) {                                                                                  \
            const double ur_ = (a_r), ui_ = (a_i), xr_ = br[(j) * bs], xi_ = bi[(j) * bs];         \
            br[(k) * bs] -= ur_ * xr_ - ui_ * xi_;                                                 \
            bi[(k) * bs] -= ur_ * xi_ + ui_ * xr_;                                                 \
        } else {                                                                                   \
            br[(k) * bs] -= (a_r) * br[(j) * bs];                                                  \
        }                                                                                          \
    } while (0)
/* b_k /= the pivot a_kk */
#define SCDK_DIVIDE(k)                                                                             \
    do {                                                                                           \
        if (bi) {                                                                                  \
            double rr_, ri_;                                                                       \
            const double xr_ = br[(k) * bs], xi_ = bi[(k) * bs];                                   \
            SCDK_LU_RECIPROCAL(SCDK_A(k, k), SCDK_AI(k, k), rr_, ri_);                             \
            br[(k) * bs] = xr_ * rr_ - xi_ * ri_;                                                  \
            bi[(k) * bs] = xr_ * ri_ + xi_ * rr_;                                                  \
        } else {                                                                                   \
            br[(k) * bs] /= SCDK_A(k, k);                                                          \
        }                                                                                          \
    } while (0)
    int j, k;
    if (!transposed) { /* P b, then L, then U */
        SCDK_UNROLL
        for (k = 0; k < n; ++k) SCDK_SWAP(k);
        SCDK_UNROLL
        for (k = 0; k < n; ++k) {
            SCDK_UNROLL
            for (j = k + 1; j < n; ++j) SCDK_AXPY(j, SCDK_A(j, k), ai ? SCDK_AI(j, k) : 0.0, k);
        }
        SCDK_UNROLL
        for (k = n - 1; k >= 0; --k) {
            SCDK_UNROLL
            for (j = k + 1; j < n; ++j) SCDK_AXPY(k, SCDK_A(k, j), ai ? SCDK_AI(k, j) : 0.0, j);
            SCDK_DIVIDE(k);
        }
    } else { /* U^T, then L^T, then P^T */
        for (k = 0; k < n; ++k) {
            for (j = 0; j < k; ++j) SCDK_AXPY(k, SCDK_A(j, k), ai ? SCDK_AI(j, k) : 0.0, j);
            SCDK_DIVIDE(k);
        }
        for (k = n - 1; k >= 0; --k)
            for (j = k + 1; j < n; ++j) SCDK_AXPY(k, SCDK_A(j, k), ai ? SCDK_AI(j, k) : 0.0, j);
        for (k = n - 1; k >= 0; --k) SCDK_SWAP(k);
    }
#undef SCDK_A
#undef SCDK_AI
#undef SCDK_SWAP
#undef SCDK_AXPY
#undef SCDK_DIVIDE
}

#ifdef SCDK_LANES
/* Lanes: SCDK_LANES independent complex systems at once, one per lane of a GCC vector type
 * (scdk_vd), each eliminated with exactly the pivots and operations of scdk_lu_factor and
 * scdk_lu_solve above (the right-hand sides carried along the elimination: the same values
 * as swapping and substituting after it). */
typedef double scdk_vd __attribute__((vector_size(8 * SCDK_LANES)));
typedef long long scdk_vl __attribute__((vector_size(8 * SCDK_LANES)));

/* m ? a : b lane by lane, m a lane mask (all bits set or clear, as vector comparisons give) */
#define SCDK_SELECT(m, a, b) ((scdk_vd)(((scdk_vl)(a) & (m)) | ((scdk_vl)(b) & ~(m))))
/* |x| lane by lane (the sign bit cleared) */
#define SCDK_VABS(x) ((scdk_vd)((scdk_vl)(x) & ((scdk_vl){0} + 0x7fffffffffffffffLL)))

/* Solve A X = B lane by lane: A the complex n x n matrix in the first n columns of the row-major
 * (ar, ai) with row stride rs, B its nrhs columns after them (X replaces B; A is overwritten:
 * U on and above the diagonal, below it nothing of use, as the multipliers are not kept). A
 * lane with a zero or NaN pivot gets NaN solutions. */
SCDK_LU_FN void scdk_lu_solve_lanes(scdk_vd *ar, scdk_vd *ai, int n, int nrhs, int rs) {
    const int w = n + nrhs;
    scdk_vl good = (scdk_vl){0} - 1;
    int i, j, k;
    SCDK_UNROLL
    for (k = 0; k < n; ++k) {
        scdk_vd best = SCDK_VABS(ar[k * rs + k]) + SCDK_VABS(ai[k * rs + k]);
        scdk_vl p = (scdk_vl){0} + k;
        SCDK_UNROLL
        for (i = k + 1; i < n; ++i) {
            const scdk_vd v = SCDK_VABS(ar[i * rs + k]) + SCDK_VABS(ai[i * rs + k]);
            const scdk_vl m = v > best;
            best = SCDK_SELECT(m, v, best);
            p = (p & ~m) | (((scdk_vl){0} + i) & m);
        }
        good &= best > 0.0;
        SCDK_UNROLL
        for (i = k + 1; i < n; ++i) { /* swap rows k and i in the lanes pivoting on row i */
            const scdk_vl m = p == i;
            int any = 0;
            for (j = 0; j < SCDK_LANES; ++j) any |= m[j] != 0;
            if (!any) continue;
            for (j = k; j < w; ++j) { /* the multipliers left of column k: never read */
                scdk_vd t = ar[k * rs + j];
                ar[k * rs + j] = SCDK_SELECT(m, ar[i * rs + j], t);
                ar[i * rs + j] = SCDK_SELECT(m, t, ar[i * rs + j]);
                t = ai[k * rs + j];
                ai[k * rs + j] = SCDK_SELECT(m, ai[i * rs + j], t);
                ai[i * rs + j] = SCDK_SELECT(m, t, ai[i * rs + j]);
            }
        }
        const scdk_vd d = ar[k * rs + k] * ar[k * rs + k] + ai[k * rs + k] * ai[k * rs + k];
        const scdk_vd rr = ar[k * rs + k] / d, ri = -ai[k * rs + k] / d;
        SCDK_UNROLL
        for (i = k + 1; i < n; ++i) {
            const scdk_vd xr = ar[i * rs + k], xi = ai[i * rs + k];
            const scdk_vd lr = xr * rr - xi * ri, li = xr * ri + xi * rr; /* not stored */
            SCDK_UNROLL
            for (j = k + 1; j < w; ++j) {
                const scdk_vd ur = ar[k * rs + j], ui = ai[k * rs + j];
                ar[i * rs + j] -= lr * ur - li * ui;
                ai[i * rs + j] -= lr * ui + li * ur;
            }
        }
    }
    for (int r = n; r < w; ++r) { /* back substitution, column by column */
        SCDK_UNROLL
        for (k = n - 1; k >= 0; --k) {
            scdk_vd br = ar[k * rs + r], bi = ai[k * rs + r];
            SCDK_UNROLL
            for (j = k + 1; j < n; ++j) {
                const scdk_vd ur = ar[k * rs + j], ui = ai[k * rs + j];
                const scdk_vd xr = ar[j * rs + r], xi = ai[j * rs + r];
                br -= ur * xr - ui * xi;
                bi -= ur * xi + ui * xr;
            }
            const scdk_vd d = ar[k * rs + k] * ar[k * rs + k] + ai[k * rs + k] * ai[k * rs + k];
            const scdk_vd rr = ar[k * rs + k] / d, ri = -ai[k * rs + k] / d;
            ar[k * rs + r] = br * rr - bi * ri;
            ai[k * rs + r] = br * ri + bi * rr;
        }
        for (k = 0; k < n; ++k) {
            ar[k * rs + r] = SCDK_SELECT(good, ar[k * rs + r], (scdk_vd){0} + NAN);
            ai[k * rs + r] = SCDK_SELECT(good, ai[k * rs + r], (scdk_vd){0} + NAN);
        }
    }
}
#endif /* SCDK_LANES */

#endif /* SCDK_LU_H */
