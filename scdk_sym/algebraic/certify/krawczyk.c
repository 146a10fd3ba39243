/* Krawczyk tests of many points at once in binary64 interval arithmetic (see krawczyk.h).
 *
 * Soundness rests on IEEE 754 binary64 arithmetic in round-to-nearest (the default mode):
 * +, -, *, / return the exact result correctly rounded, within half a unit in the last place,
 * so the neighbouring binary64 numbers (nextafter) below and above bound the exact result.
 * Every interval operation below rounds each bound that way; negation and the choice of
 * bounds are exact. sin and cos are enclosed from these operations alone (a reduction by an
 * enclosure of pi/2, a Taylor polynomial and the bound of its rest, the extrema the
 * interval may hold), never from the C library's. The library is compiled without contraction into fused multiply-adds
 * and without value-changing optimisations (krawczyk_c.py's flags). A bound that is not
 * finite, or a divisor interval holding 0, fails the evaluation: the point is then left
 * to the ball-arithmetic test (krawczyk_arb.py), never proven here.
 */
#include "krawczyk.h"
#include "scdk_lu.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    double lo, hi;
} ival;

/* nextafter(x, -inf) and nextafter(x, +inf) by the ordering of the binary64 encodings
 * (consecutive magnitudes have consecutive codes); NaN stays NaN, and -inf below / +inf above
 * give a NaN, which the finiteness checks reject. */
static inline double down(double x) {
    uint64_t u;
    if (x != x) return x;
    if (x == 0.0) return -4.9406564584124654e-324; /* the largest binary64 below 0 */
    memcpy(&u, &x, sizeof u);
    u = x > 0.0 ? u - 1 : u + 1;
    memcpy(&x, &u, sizeof u);
    return x;
}

static inline double up(double x) { return -down(-x); }

static ival point(double x) {
    ival r = {x, x};
    return r;
}

static ival iadd(ival a, ival b) {
    ival r = {down(a.lo + b.lo), up(a.hi + b.hi)};
    return r;
}

static ival isub(ival a, ival b) {
    ival r = {down(a.lo - b.hi), up(a.hi - b.lo)};
    return r;
}

static ival ineg(ival a) {
    ival r = {-a.hi, -a.lo};
    return r;
}

static double min4(double a, double b, double c, double d) {
    const double x = a < b ? a : b, y = c < d ? c : d;
    return x < y ? x : y;
}

static double max4(double a, double b, double c, double d) {
    const double x = a > b ? a : b, y = c > d ? c : d;
    return x > y ? x : y;
}

/* Finite operands only (every caller checks them): no 0 * inf, and no NaN that the
 * comparisons of min4 and max4 would drop. An overflow gives an infinite product, whose
 * outward step is NaN or infinite: the caller's finiteness check rejects it. */
static ival imul(ival a, ival b) {
    const double p1 = a.lo * b.lo, p2 = a.lo * b.hi, p3 = a.hi * b.lo, p4 = a.hi * b.hi;
    ival r = {down(min4(p1, p2, p3, p4)), up(max4(p1, p2, p3, p4))};
    return r;
}

/* A binary64 number times an interval. */
static ival pmul(double y, ival a) {
    ival r;
    if (y >= 0.0) {
        r.lo = down(y * a.lo);
        r.hi = up(y * a.hi);
    } else {
        r.lo = down(y * a.hi);
        r.hi = up(y * a.lo);
    }
    return r;
}

static ival isq(ival a) {
    ival r;
    if (a.lo >= 0.0) {
        r.lo = down(a.lo * a.lo);
        r.hi = up(a.hi * a.hi);
    } else if (a.hi <= 0.0) {
        r.lo = down(a.hi * a.hi);
        r.hi = up(a.lo * a.lo);
    } else {
        const double u = a.lo * a.lo, v = a.hi * a.hi;
        r.lo = 0.0;
        r.hi = up(u > v ? u : v);
    }
    return r;
}

/* a / b for b not holding 0 (checked by the caller). */
static ival idiv(ival a, ival b) {
    const double q1 = a.lo / b.lo, q2 = a.lo / b.hi, q3 = a.hi / b.lo, q4 = a.hi / b.hi;
    ival r = {down(min4(q1, q2, q3, q4)), up(max4(q1, q2, q3, q4))};
    return r;
}

static int finite(ival a) { return isfinite(a.lo) && isfinite(a.hi); }

/* sin and cos from correctly rounded operations only. pi/2 lies between the binary64 number
 * PIO2_LO (the literal rounds to 0x3FF921FB54442D18, below pi/2) and the next one up. */
#define PIO2_LO 1.5707963267948966
/* largest |x| whose reduction is done (beyond: the hull [-1, 1]) */
#define TRIG_RANGE 1048576.0
/* Taylor terms after the first (the rest: below 1e-19 for |r| <= pi/4, 1e-17 for |r| <= 1) */
#define TRIG_TERMS 8

static ival pio2(void) {
    ival r = {PIO2_LO, up(PIO2_LO)};
    return r;
}

/* sin (odd) or cos (!odd) over the interval r, |r| <= 1: the Taylor polynomial in interval
 * arithmetic (each coefficient from an exact integer division rounded outward) plus the
 * Lagrange bound of the rest, at most the next term in magnitude. */
static ival taylor(ival r, int odd) {
    const ival r2 = isq(r);
    ival term = odd ? r : point(1.0), sum = term;
    for (int i = 1; i <= TRIG_TERMS; ++i) {
        const double d = odd ? (2.0 * i) * (2.0 * i + 1) : (2.0 * i - 1) * (2.0 * i);
        term = idiv(imul(term, r2), point(d));
        sum = i % 2 ? isub(sum, term) : iadd(sum, term);
    }
    const double d = odd ? (2.0 * TRIG_TERMS + 2) * (2.0 * TRIG_TERMS + 3)
                         : (2.0 * TRIG_TERMS + 1) * (2.0 * TRIG_TERMS + 2);
    const ival next = idiv(imul(term, r2), point(d));
    const double rest = up(fabs(next.lo) > fabs(next.hi) ? fabs(next.lo) : fabs(next.hi));
    const ival bound = {-rest, rest};
    return iadd(sum, bound);
}

/* sin(x + shift pi/2) enclosed, x binary64 (shift 0: sin, 1: cos): x = r + k pi/2 with
 * k = round(x / (pi/2)) (any integer k is sound; this one keeps |r| <= pi/4 + tiny). */
static ival trig_point(double x, int shift) {
    const ival hull = {-1.0, 1.0};
    if (!(fabs(x) < TRIG_RANGE)) return x == x ? hull : point(x);
    const double k = nearbyint(x / PIO2_LO);
    const ival r = isub(point(x), pmul(k, pio2()));
    if (!(fabs(r.lo) <= 1.0 && fabs(r.hi) <= 1.0)) return hull;
    const int q = (int)((((long long)k + shift) % 4 + 4) % 4);
    const ival v = taylor(r, q % 2 == 0); /* q: 0 sin r, 1 cos r, 2 -sin r, 3 -cos r */
    return q >= 2 ? ineg(v) : v;
}

/* sin (shift 0) or cos (shift 1) over the interval x: the hull of the enclosures at its ends
 * and of the extreme value (-1)^j at every critical point (1 - shift + 2 j) pi/2 the interval
 * may hold (the function is monotone between them); [-1, 1] for an interval 1 or more wide. */
static ival itrig(ival x, int shift) {
    const ival hull = {-1.0, 1.0};
    if (!(x.hi - x.lo < 1.0 && fabs(x.lo) < TRIG_RANGE && fabs(x.hi) < TRIG_RANGE)) return hull;
    const ival a = trig_point(x.lo, shift), b = trig_point(x.hi, shift);
    ival r = {a.lo < b.lo ? a.lo : b.lo, a.hi > b.hi ? a.hi : b.hi};
    const double j0 = floor(x.lo / (2 * PIO2_LO)) - 2, j1 = floor(x.hi / (2 * PIO2_LO)) + 2;
    for (double j = j0; j <= j1; ++j) {
        const ival c = pmul(1.0 - shift + 2.0 * j, pio2());
        if (c.lo <= x.hi && c.hi >= x.lo) {
            if (fmod(j, 2.0) == 0.0)
                r.hi = 1.0;
            else
                r.lo = -1.0;
        }
    }
    if (r.lo < -1.0) r.lo = -1.0;
    if (r.hi > 1.0) r.hi = 1.0;
    return r;
}

/* ---- The replays: KL points at once, one per lane of a GCC vector of doubles. Each lane
 * makes the interval operations above on its own point, in the tape's order (a branch's
 * bounds are all computed and the lane's taken), so a point's values do not depend on its
 * lane or its neighbours; a lane whose evaluation meets a bound that is not finite or a
 * divisor holding 0 is marked bad (its values are then not used). */
#ifndef SCDK_KLANES /* one register of doubles of the instruction set compiled for */
#if defined(__AVX512F__)
#define SCDK_KLANES 8
#elif defined(__AVX__)
#define SCDK_KLANES 4
#else
#define SCDK_KLANES 2
#endif
#endif
#define KL SCDK_KLANES
typedef double kvd __attribute__((vector_size(8 * KL)));
typedef long long kvl __attribute__((vector_size(8 * KL)));
typedef struct {
    kvd lo, hi;
} vival;

#define KSEL(m, a, b) ((kvd)(((kvl)(a) & (m)) | ((kvl)(b) & ~(m))))
#define KSPLAT(x) ((kvd){0} + (x))

static inline kvd vdown(kvd x) { /* down() lane by lane */
    const kvl pos = x > 0.0, neg = x < 0.0, zero = x == 0.0;
    kvl u;
    memcpy(&u, &x, sizeof u);
    u = u + pos - neg; /* masks are -1: u - 1 where x > 0, u + 1 where x < 0; NaN unchanged */
    kvd r;
    memcpy(&r, &u, sizeof r);
    return KSEL(zero, KSPLAT(-4.9406564584124654e-324), r);
}

static inline kvd vup(kvd x) { return -vdown(-x); }
static inline kvd vmin2(kvd a, kvd b) { return KSEL(a < b, a, b); }
static inline kvd vmax2(kvd a, kvd b) { return KSEL(a > b, a, b); }
static inline kvl vfinite(vival a) { return (a.lo - a.lo == 0.0) & (a.hi - a.hi == 0.0); }

static inline vival vadd(vival a, vival b) {
    vival r = {vdown(a.lo + b.lo), vup(a.hi + b.hi)};
    return r;
}

static inline vival vsub(vival a, vival b) {
    vival r = {vdown(a.lo - b.hi), vup(a.hi - b.lo)};
    return r;
}

static inline vival vmul(vival a, vival b) {
    const kvd p1 = a.lo * b.lo, p2 = a.lo * b.hi, p3 = a.hi * b.lo, p4 = a.hi * b.hi;
    vival r = {vdown(vmin2(vmin2(p1, p2), vmin2(p3, p4))),
               vup(vmax2(vmax2(p1, p2), vmax2(p3, p4)))};
    return r;
}

static inline vival vdiv(vival a, vival b) {
    const kvd q1 = a.lo / b.lo, q2 = a.lo / b.hi, q3 = a.hi / b.lo, q4 = a.hi / b.hi;
    vival r = {vdown(vmin2(vmin2(q1, q2), vmin2(q3, q4))),
               vup(vmax2(vmax2(q1, q2), vmax2(q3, q4)))};
    return r;
}

static inline vival vsq(vival a) {
    const kvd ll = a.lo * a.lo, hh = a.hi * a.hi;
    const kvl m1 = a.lo >= 0.0, m2 = ~m1 & (a.hi <= 0.0);
    vival r = {KSEL(m1, vdown(ll), KSEL(m2, vdown(hh), KSPLAT(0.0))),
               KSEL(m1, vup(hh), KSEL(m2, vup(ll), vup(KSEL(ll > hh, ll, hh))))};
    return r;
}

static inline vival vabs(vival a) {
    const kvl m1 = a.lo >= 0.0, m2 = ~m1 & (a.hi <= 0.0);
    vival r = {KSEL(m1, a.lo, KSEL(m2, -a.hi, KSPLAT(0.0))),
               KSEL(m1, a.hi, KSEL(m2, -a.lo, KSEL(-a.lo > a.hi, -a.lo, a.hi)))};
    return r;
}

static inline vival vsign(vival a) {
    vival r = {KSEL(a.lo > 0.0, KSPLAT(1.0), KSEL(a.lo < 0.0, KSPLAT(-1.0), KSPLAT(0.0))),
               KSEL(a.hi < 0.0, KSPLAT(-1.0), KSEL(a.hi > 0.0, KSPLAT(1.0), KSPLAT(0.0)))};
    return r;
}

static inline kvl vholds_zero(vival a) { return (a.lo <= 0.0) & (a.hi >= 0.0); }

/* Replay a tape on x (n) and p (k) intervals of KL points into out (n_out); the lanes whose
 * evaluation failed are set in the returned mask. */
static kvl vreplay(const scdk_tape *t, const vival *x, const vival *p, vival *w, vival *out) {
    kvl bad = (kvl){0};
    for (int64_t i = 0; i < t->n_out; ++i) out[i].lo = out[i].hi = KSPLAT(0.0);
    for (int64_t s = 0; s < t->L; ++s) {
        const int64_t a = t->a[s], b = t->b[s], o = t->o[s];
        vival r;
        switch (t->op[s]) {
        case SCDK_I_CONST: r.lo = r.hi = KSPLAT(t->c[s]); break;
        case SCDK_I_INPUT: r = a == 0 ? x[b] : p[b]; break;
        case SCDK_I_OUTPUT: out[o] = w[a]; continue;
        case SCDK_I_ASSIGN: r = w[a]; break;
        case SCDK_I_NEG: r.lo = -w[a].hi; r.hi = -w[a].lo; break;
        case SCDK_I_SQ: r = vsq(w[a]); break;
        case SCDK_I_TWICE: r = vadd(w[a], w[a]); break;
        case SCDK_I_INV: {
            const vival one = {KSPLAT(1.0), KSPLAT(1.0)};
            bad |= vholds_zero(w[a]);
            r = vdiv(one, w[a]);
            break;
        }
        case SCDK_I_FABS: r = vabs(w[a]); break;
        case SCDK_I_SIGN: r = vsign(w[a]); break;
        case SCDK_I_SIN:
        case SCDK_I_COS:
            for (int l = 0; l < KL; ++l) {
                const ival v = {w[a].lo[l], w[a].hi[l]};
                const ival y = itrig(v, t->op[s] == SCDK_I_COS);
                r.lo[l] = y.lo;
                r.hi[l] = y.hi;
            }
            break;
        case SCDK_I_ADD: r = vadd(w[a], w[b]); break;
        case SCDK_I_SUB: r = vsub(w[a], w[b]); break;
        case SCDK_I_MUL: r = vmul(w[a], w[b]); break;
        case SCDK_I_DIV:
            bad |= vholds_zero(w[b]);
            r = vdiv(w[a], w[b]);
            break;
        default: return (kvl){0} - 1;
        }
        bad |= ~vfinite(r);
        w[o] = r;
    }
    return bad;
}

/* Replay a tape in plain binary64 on x (n) and p (k) of KL points into out (n_out), for the
 * preconditioner only (any approximate inverse keeps the test sound): sin and cos from the C
 * library, no check (a value that is not finite fails the inversion). */
static void vreplay_float(const scdk_tape *t, const kvd *x, const kvd *p, kvd *w, kvd *out) {
    for (int64_t i = 0; i < t->n_out; ++i) out[i] = KSPLAT(0.0);
    for (int64_t s = 0; s < t->L; ++s) {
        const int64_t a = t->a[s], b = t->b[s], o = t->o[s];
        kvd r;
        switch (t->op[s]) {
        case SCDK_I_CONST: r = KSPLAT(t->c[s]); break;
        case SCDK_I_INPUT: r = a == 0 ? x[b] : p[b]; break;
        case SCDK_I_OUTPUT: out[o] = w[a]; continue;
        case SCDK_I_ASSIGN: r = w[a]; break;
        case SCDK_I_NEG: r = -w[a]; break;
        case SCDK_I_SQ: r = w[a] * w[a]; break;
        case SCDK_I_TWICE: r = w[a] + w[a]; break;
        case SCDK_I_INV: r = 1.0 / w[a]; break;
        case SCDK_I_FABS: r = (kvd)((kvl)w[a] & ((kvl){0} + 0x7fffffffffffffffLL)); break;
        case SCDK_I_SIGN:
            r = KSEL(w[a] > 0.0, KSPLAT(1.0), KSEL(w[a] < 0.0, KSPLAT(-1.0), KSPLAT(0.0)));
            break;
        case SCDK_I_SIN:
        case SCDK_I_COS:
            for (int l = 0; l < KL; ++l)
                r[l] = t->op[s] == SCDK_I_SIN ? sin(w[a][l]) : cos(w[a][l]);
            break;
        case SCDK_I_ADD: r = w[a] + w[b]; break;
        case SCDK_I_SUB: r = w[a] - w[b]; break;
        case SCDK_I_MUL: r = w[a] * w[b]; break;
        case SCDK_I_DIV: r = w[a] / w[b]; break;
        default: r = KSPLAT(NAN);
        }
        w[o] = r;
    }
}

/* Y ~ A^-1 (n x n row-major) from the package's LU with partial pivoting (scdk_lu.h; piv:
 * n ints), and the infinity-norm condition estimate |A| |Y|; 0 on success. A is overwritten. */
static int invert(double *A, double *Y, int64_t n, int *piv, double *cond) {
    double na = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        double s = 0.0;
        for (int64_t j = 0; j < n; ++j) s += fabs(A[i * n + j]);
        if (s > na) na = s;
        for (int64_t j = 0; j < n; ++j) Y[i * n + j] = i == j ? 1.0 : 0.0;
    }
    if (!scdk_lu_factor(A, NULL, (int)n, (int)n, 1, piv)) return 1;
    for (int64_t j = 0; j < n; ++j) /* column j of Y: A^-1 e_j */
        scdk_lu_solve(A, NULL, (int)n, (int)n, 1, piv, Y + j, NULL, (int)n, 0);
    double ny = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        double s = 0.0;
        for (int64_t j = 0; j < n; ++j) s += fabs(Y[i * n + j]);
        if (s > ny) ny = s;
    }
    *cond = na * ny;
    return isfinite(*cond) ? 0 : 1;
}

typedef struct {
    const scdk_tape *value, *jacobian;
    int64_t n, k;
    ival *P;
    ival *out, *X, *mid, *newton, *C, *K, *D, *B; /* D = B - c, B: the proven enclosure */
    double *A, *Y, *pm, *c;                       /* pm: the parameters' midpoints */
    vival *v1w, *v1x, *v1p, *v1out;               /* one point's replays (every lane on it) */
    kvd *f1w, *f1x, *f1p, *f1out;
    vival *vw, *vout, *vm, *vx, *vp; /* a group's replays, one point per lane */
    kvd *fw, *fa, *fx, *fp;
    ival *Nl, *Xl; /* each lane's Newton point and box X */
    double *Yl;    /* each lane's Y */
    int *piv;
    ival *iv; /* the blocks the pointers above point into */
    double *dv;
    char *vraw;
} work;

/* The tape at one point x (n intervals) and s->P (every lane on them, lane 0 read) into out
 * (n_out); 0 on success. */
static int replay(work *s, const scdk_tape *t, const ival *x, ival *out) {
    for (int64_t i = 0; i < s->n; ++i) {
        s->v1x[i].lo = KSPLAT(x[i].lo);
        s->v1x[i].hi = KSPLAT(x[i].hi);
    }
    for (int64_t i = 0; i < s->k; ++i) {
        s->v1p[i].lo = KSPLAT(s->P[i].lo);
        s->v1p[i].hi = KSPLAT(s->P[i].hi);
    }
    const kvl bad = vreplay(t, s->v1x, s->v1p, s->v1w, s->v1out);
    for (int64_t i = 0; i < t->n_out; ++i) {
        out[i].lo = s->v1out[i].lo[0];
        out[i].hi = s->v1out[i].hi[0];
    }
    return bad[0] != 0;
}

/* The tape in plain binary64 at one point x (n) and s->pm into out (n_out). */
static void replay_float(work *s, const scdk_tape *t, const double *x, double *out) {
    for (int64_t i = 0; i < s->n; ++i) s->f1x[i] = KSPLAT(x[i]);
    for (int64_t i = 0; i < s->k; ++i) s->f1p[i] = KSPLAT(s->pm[i]);
    vreplay_float(t, s->f1x, s->f1p, s->f1w, s->f1out);
    for (int64_t i = 0; i < t->n_out; ++i) out[i] = s->f1out[i][0];
}

/* Y ~ A^-1 from the Jacobian in s->A (overwritten); 0 on success (the condition estimate
 * below max_cond). */
static int inverse_of(work *s, double max_cond) {
    double cond;
    if (invert(s->A, s->Y, s->n, s->piv, &cond)) return 1;
    return cond < max_cond ? 0 : 1;
}

/* Y ~ J(c)^-1 (the Jacobian at the point c and the parameters' midpoints, in binary64);
 * 0 on success. */
static int inverse_at(work *s, const double *c, double max_cond) {
    replay_float(s, s->jacobian, c, s->A);
    return inverse_of(s, max_cond);
}

/* newton = c - Y f(c) into s->newton from f(c) in s->out; 0 on success. */
static int newton_tail(work *s, const double *c) {
    const int64_t n = s->n;
    for (int64_t i = 0; i < n; ++i) {
        ival acc = point(c[i]);
        for (int64_t j = 0; j < n; ++j) acc = isub(acc, pmul(s->Y[i * n + j], s->out[j]));
        if (!finite(acc)) return 1;
        s->newton[i] = acc;
    }
    return 0;
}

/* newton = c - Y f(c) into s->newton; 0 on success. */
static int newton_point(work *s, const double *c) {
    for (int64_t i = 0; i < s->n; ++i) s->mid[i] = point(c[i]);
    if (replay(s, s->value, s->mid, s->out)) return 1;
    return newton_tail(s, c);
}

/* K = newton + (I - Y J(B)) (B - c) into s->K from J(B) in s->out; 0 on success. */
static int krawczyk_tail(work *s, const ival *B, const double *c) {
    const int64_t n = s->n;
    for (int64_t i = 0; i < n; ++i)
        for (int64_t j = 0; j < n; ++j) {
            ival acc = point(i == j ? 1.0 : 0.0);
            for (int64_t l = 0; l < n; ++l)
                acc = isub(acc, pmul(s->Y[i * n + l], s->out[l * n + j]));
            if (!finite(acc)) return 1; /* imul below takes finite operands only */
            s->C[i * n + j] = acc;
        }
    for (int64_t j = 0; j < n; ++j) {
        s->D[j] = isub(B[j], point(c[j]));
        if (!finite(s->D[j])) return 1;
    }
    for (int64_t i = 0; i < n; ++i) {
        ival acc = s->newton[i];
        for (int64_t j = 0; j < n; ++j) acc = iadd(acc, imul(s->C[i * n + j], s->D[j]));
        if (!finite(acc)) return 1;
        s->K[i] = acc;
    }
    return 0;
}

/* K = newton + (I - Y J(B)) (B - c) over the box B into s->K; 0 on success. */
static int krawczyk_operator(work *s, const ival *B, const double *c) {
    if (replay(s, s->jacobian, B, s->out)) return 1;
    return krawczyk_tail(s, B, c);
}

static double largest_radius(const ival *B, int64_t n) {
    double w = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        const double r = 0.5 * (B[i].hi - B[i].lo);
        if (r > w) w = r;
    }
    return w;
}

/* The largest radius of the interval Newton point s->newton. */
static double newton_radius(const work *s) {
    return largest_radius(s->newton, s->n);
}

/* Shrink the proven enclosure B (n) by Krawczyk steps centred on its midpoint, while each
 * step at least halves its largest radius and that radius exceeds twice the last interval
 * Newton point's (s->newton's: a step's enclosure holds a Newton point about that wide, so
 * it cannot halve the radius then). */
static void tighten_box(work *s, ival *B, double *c, int64_t steps) {
    const int64_t n = s->n;
    const double eps = 2.220446049250313e-16;
    for (int64_t t = 0; t < steps; ++t) {
        double big = 0.0;
        for (int64_t i = 0; i < n; ++i) {
            c[i] = 0.5 * B[i].lo + 0.5 * B[i].hi;
            if (c[i] < B[i].lo) c[i] = B[i].lo;
            if (c[i] > B[i].hi) c[i] = B[i].hi;
            if (fabs(c[i]) > big) big = fabs(c[i]);
        }
        const double width = largest_radius(B, n);
        if (width <= 64 * eps * (1 + big) || width <= 2 * newton_radius(s)) return;
        if (inverse_at(s, c, INFINITY) || newton_point(s, c) || krawczyk_operator(s, B, c)) return;
        for (int64_t i = 0; i < n; ++i) { /* the zero lies in B and in K */
            const double lo = s->K[i].lo > B[i].lo ? s->K[i].lo : B[i].lo;
            const double hi = s->K[i].hi < B[i].hi ? s->K[i].hi : B[i].hi;
            if (lo > hi) return;
            s->K[i].lo = lo;
            s->K[i].hi = hi;
        }
        const double shrunk = largest_radius(s->K, n);
        if (!(shrunk < width)) return;
        for (int64_t i = 0; i < n; ++i) B[i] = s->K[i];
        if (!(shrunk <= 0.5 * width)) return; /* at the rounding's floor: more steps gain little */
    }
}

/* The work space of scdk_ikrawczyk: one block of intervals, one of doubles, one of vectors
 * (64-byte aligned); 0 on success. */
static int work_new(work *s, const scdk_tape *value, const scdk_tape *jacobian, int64_t n,
                    int64_t k) {
    const int64_t W = value->W > jacobian->W ? value->W : jacobian->W;
    s->value = value;
    s->jacobian = jacobian;
    s->n = n;
    s->k = k;
    const size_t ni = (size_t)(2 * n * n + 6 * n + k + 1 + 2 * KL * n);
    const size_t nd = (size_t)(2 * n * n + n + k + 1 + KL * n * n);
    const size_t nv = (size_t)(2 * (W + 1) + 2 * n * n + 3 * n + 2 * (k + 1));
    s->iv = malloc(ni * sizeof(ival));
    s->dv = malloc(nd * sizeof(double));
    s->vraw = malloc(nv * (sizeof(vival) + sizeof(kvd)) + 64);
    s->piv = malloc((size_t)n * sizeof(int));
    if (!s->iv || !s->dv || !s->vraw || !s->piv) return 1;
    s->out = s->iv;
    s->X = s->out + n * n;
    s->mid = s->X + n;
    s->newton = s->mid + n;
    s->K = s->newton + n;
    s->B = s->K + n;
    s->D = s->B + n;
    s->C = s->D + n;
    s->P = s->C + n * n;
    s->Nl = s->P + k + 1;
    s->Xl = s->Nl + KL * n;
    s->A = s->dv;
    s->Y = s->A + n * n;
    s->c = s->Y + n * n;
    s->pm = s->c + n;
    s->Yl = s->pm + k + 1;
    s->vw = (vival *)(s->vraw + (64 - (uintptr_t)s->vraw % 64) % 64);
    s->vout = s->vw + W + 1;
    s->vm = s->vout + n * n;
    s->vx = s->vm + n;
    s->vp = s->vx + n;
    s->v1w = s->vp + k + 1;
    s->v1out = s->v1w + W + 1;
    s->v1x = s->v1out + n * n;
    s->v1p = s->v1x + n;
    s->fw = (kvd *)(s->v1p + k + 1);
    s->fa = s->fw + W + 1;
    s->fx = s->fa + n * n;
    s->fp = s->fx + n;
    s->f1w = s->fp + k + 1;
    s->f1out = s->f1w + W + 1;
    s->f1x = s->f1out + n * n;
    s->f1p = s->f1x + n;
    return 0;
}

static void work_free(work *s) {
    free(s->iv);
    free(s->dv);
    free(s->vraw);
    free(s->piv);
}

/* Lane l's point mq after the group's J(m) and f(m) replays (bad_f: the lanes where f(m)
 * failed): Y, the Newton point and the box X (radii into rq), kept for the lane; 1 when the
 * point can go on to the Krawczyk operator. */
static int lane_box(work *s, int l, const double *mq, double *rq, double tiny, double max_cond,
                    kvl bad_f) {
    const int64_t n = s->n;
    for (int64_t i = 0; i < n * n; ++i) s->A[i] = s->fa[i][l];
    if (inverse_of(s, max_cond) || bad_f[l]) return 0;
    for (int64_t i = 0; i < n; ++i) {
        s->out[i].lo = s->vout[i].lo[l];
        s->out[i].hi = s->vout[i].hi[l];
    }
    if (newton_tail(s, mq)) return 0;
    double delta = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        const double d = fabs(0.5 * s->newton[i].lo + 0.5 * s->newton[i].hi - mq[i]);
        if (d > delta) delta = d;
    }
    for (int64_t i = 0; i < n; ++i) {
        const double ri = 2 * delta + 4 * (0.5 * (s->newton[i].hi - s->newton[i].lo));
        rq[i] = ri > tiny ? ri : tiny;
        s->Xl[l * n + i].lo = s->vx[i].lo[l] = down(mq[i] - rq[i]);
        s->Xl[l * n + i].hi = s->vx[i].hi[l] = up(mq[i] + rq[i]);
        s->Nl[l * n + i] = s->newton[i];
    }
    memcpy(s->Yl + l * n * n, s->Y, (size_t)(n * n) * sizeof(double));
    return 1;
}

/* Lane l's point mq after the group's J(X) replay: the Krawczyk operator, the inside test
 * and the tightening, from the lane's own state; 1 when proven (the enclosure into bq). */
static int lane_test(work *s, int l, const double *mq, double *bq, int64_t tighten) {
    const int64_t n = s->n;
    for (int64_t i = 0; i < s->k; ++i) { /* the point's own state, for the steps below */
        s->P[i].lo = s->vp[i].lo[l];
        s->P[i].hi = s->vp[i].hi[l];
        s->pm[i] = s->fp[i][l];
    }
    memcpy(s->Y, s->Yl + l * n * n, (size_t)(n * n) * sizeof(double));
    for (int64_t i = 0; i < n; ++i) {
        s->newton[i] = s->Nl[l * n + i];
        s->X[i] = s->Xl[l * n + i];
    }
    for (int64_t i = 0; i < n * n; ++i) {
        s->out[i].lo = s->vout[i].lo[l];
        s->out[i].hi = s->vout[i].hi[l];
    }
    if (krawczyk_tail(s, s->X, mq)) return 0;
    for (int64_t i = 0; i < n; ++i)
        if (!(s->K[i].lo > s->X[i].lo && s->K[i].hi < s->X[i].hi)) return 0;
    for (int64_t i = 0; i < n; ++i) s->B[i] = s->K[i];
    tighten_box(s, s->B, s->c, tighten);
    for (int64_t i = 0; i < n; ++i) {
        bq[2 * i] = s->B[i].lo;
        bq[2 * i + 1] = s->B[i].hi;
    }
    return 1;
}

int scdk_ikrawczyk(const scdk_tape *value, const scdk_tape *jacobian, int64_t n, int64_t k,
                   int64_t N, const double *m, const double *p_lo, const double *p_hi,
                   int64_t p_stride, int64_t tighten, double tiny, double max_cond,
                   int64_t *status, double *r, double *box) {
    if (n <= 0 || k < 0 || N < 0 || value->n_out != n || jacobian->n_out != n * n)
        return SCDK_K_BAD_SIZE;
    work s;
    if (work_new(&s, value, jacobian, n, k)) {
        work_free(&s);
        return SCDK_K_NO_MEMORY;
    }
    /* KL points at a time: their three tape replays in the lanes, the rest point by point;
     * each point's outcome is the one it gets in any lane, alone or not */
    for (int64_t q0 = 0; q0 < N; q0 += KL) {
        const int cnt = N - q0 < KL ? (int)(N - q0) : KL;
        int ok[KL];
        for (int l = 0; l < KL; ++l) { /* a short last group repeats its last point */
            const int64_t q = q0 + (l < cnt ? l : cnt - 1);
            for (int64_t i = 0; i < k; ++i) {
                s.vp[i].lo[l] = p_lo[q * p_stride + i];
                s.vp[i].hi[l] = p_hi[q * p_stride + i];
                s.fp[i][l] = 0.5 * s.vp[i].lo[l] + 0.5 * s.vp[i].hi[l];
            }
            for (int64_t i = 0; i < n; ++i)
                s.vm[i].lo[l] = s.vm[i].hi[l] = s.fx[i][l] = m[q * n + i];
        }
        vreplay_float(jacobian, s.fx, s.fp, s.fw, s.fa);              /* J(m) for Y */
        const kvl bad_f = vreplay(value, s.vm, s.vp, s.vw, s.vout); /* f(m) */
        for (int l = 0; l < KL; ++l) {
            const int64_t q = q0 + l;
            ok[l] = 0;
            for (int64_t i = 0; i < n; ++i) s.vx[i].lo[l] = s.vx[i].hi[l] = s.vm[i].lo[l];
            if (l >= cnt) continue;
            status[q] = SCDK_K_NOT_PROVEN;
            for (int64_t i = 0; i < n; ++i) {
                r[q * n + i] = NAN;
                box[2 * q * n + 2 * i] = box[2 * q * n + 2 * i + 1] = NAN;
            }
            ok[l] = lane_box(&s, l, m + q * n, r + q * n, tiny, max_cond, bad_f);
        }
        const kvl bad_j = vreplay(jacobian, s.vx, s.vp, s.vw, s.vout); /* J(X) */
        for (int l = 0; l < cnt; ++l) {
            const int64_t q = q0 + l;
            if (ok[l] && !bad_j[l] && lane_test(&s, l, m + q * n, box + 2 * q * n, tighten))
                status[q] = SCDK_K_PROVEN;
        }
    }
    work_free(&s);
    return SCDK_K_OK;
}

/* Lane `to` of X (n) and P (k) on x and p scaled by 1 + lane 2^-10 (lane 0: as given). */
static void ireplay_lane(vival *X, vival *P, int64_t n, int64_t k, const double *x,
                         const double *p, int to, int lane) {
    const double scale = 1.0 + lane * 0.0009765625;
    for (int64_t i = 0; i < n; ++i) {
        X[i].lo[to] = x[2 * i] * scale;
        X[i].hi[to] = x[2 * i + 1] * scale;
    }
    for (int64_t i = 0; i < k; ++i) {
        P[i].lo[to] = p[2 * i] * scale;
        P[i].hi[to] = p[2 * i + 1] * scale;
    }
}

int scdk_ireplay(const scdk_tape *t, int64_t n, int64_t k, const double *x, const double *p,
                 double *out, int64_t lanes) {
    if (n < 0 || k < 0 || t->W < 0 || t->n_out < 0) return SCDK_K_BAD_SIZE;
    const size_t nv = (size_t)(n + k + t->W + 2 * t->n_out + 1);
    char *vraw = malloc(nv * sizeof(vival) + 64);
    if (!vraw) return SCDK_K_NO_MEMORY;
    vival *X = (vival *)(vraw + (64 - (uintptr_t)vraw % 64) % 64);
    vival *P = X + n, *w = P + k, *o = w + t->W, *first = o + t->n_out;
    for (int l = 0; l < KL; ++l) ireplay_lane(X, P, n, k, x, p, l, lanes ? l : 0);
    const kvl bad = vreplay(t, X, P, w, first);
    const int failed = bad[0] != 0;
    for (int64_t i = 0; i < t->n_out; ++i) {
        out[2 * i] = failed ? NAN : first[i].lo[0];
        out[2 * i + 1] = failed ? NAN : first[i].hi[0];
    }
    int differ = 0; /* lane l against its inputs in every lane */
    for (int l = 1; lanes && l < KL; ++l) {
        for (int j = 0; j < KL; ++j) ireplay_lane(X, P, n, k, x, p, j, l);
        const kvl alone = vreplay(t, X, P, w, o);
        differ |= (alone[0] != 0) != (bad[l] != 0);
        for (int64_t i = 0; i < t->n_out && !bad[l]; ++i)
            differ |= memcmp(&o[i].lo[0], &first[i].lo[l], sizeof(double)) != 0 ||
                      memcmp(&o[i].hi[0], &first[i].hi[l], sizeof(double)) != 0;
    }
    free(vraw);
    if (differ) return SCDK_K_LANES_DIFFER;
    return failed ? SCDK_K_FAILED : SCDK_K_OK;
}
