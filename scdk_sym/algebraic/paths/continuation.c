/* Predictor-corrector tracking of complex parameter homotopies (see continuation.h).
 *
 * One step of a path, as in continuation.py beside it:
 *   predictor: classical RK4 on dz/dt = -H_z^{-1} H_t (the first stage is the velocity kept
 *              from the previous corrector);
 *   corrector: two Newton iterations at the new t; norms nu1, nu2 of the updates relative to
 *              1 + max|z|; accepted when (nu1 <= trust, nu2 <= theta nu1 + floor, nu2 <= tol)
 *              or max(nu1, nu2) <= noise, and everything is finite; the second factorisation
 *              also gives the velocity at the new point; with opt->third, a path whose first
 *              two updates contract (nu1 <= trust, nu2 <= theta nu1 + floor) but whose nu2
 *              exceeds tol makes a third iteration (and takes its velocity), accepted when
 *              nu3 <= theta nu2 + floor and nu3 <= tol;
 *   step control: accepted, h = min(h clip((eta / nu1)^(1/5), 0.25, 2), h_max), the factor at
 *              most 1 right after a rejected step; rejected, h / 2.
 *
 * Lanes: SCDK_LANES paths advance in lock step, one per lane of a GCC vector type, so that
 * each evaluation of G (generated for lane vectors: scdk_sym/kernels/lanes.py) and each
 * elimination serves all of them; every step of every path makes the same five evaluations
 * (six when some lane makes a third Newton iteration: all lanes evaluate it, those that do
 * not need it keep their second iteration's results), so the lanes never wait on each
 * other. Each lane keeps its own step size, time and counters; a lane whose path stops takes
 * the next path, and a path with a first stop (split) goes on from there in its lane. Lane
 * by lane the arithmetic is that of one path alone.
 * A query (scdk_psolve): every path to the split, on to t = 1, then Newton steps at t = 1 on
 * the ends that arrived, in one call.
 * Linear systems: the package's LU with partial pivoting (scdk_lu.h, its lane form: pivot of
 * largest |re| + |im|, as LAPACK); an exactly zero pivot gives NaN solutions, which reject
 * the step.
 *
 * Compiled once per system: SCDK_N (unknowns), SCDK_K (parameters), SCDK_LANES and
 * SCDK_EVAL_FILE (the generated evaluation, defining scdk_eval) are defined by the includer.
 */
#include "continuation.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#if !defined(SCDK_N) || !defined(SCDK_K) || !defined(SCDK_LANES) || !defined(SCDK_EVAL_FILE)
#error "define SCDK_N, SCDK_K, SCDK_LANES and SCDK_EVAL_FILE before compiling continuation.c"
#endif

#include "scdk_lu.h"

#define N SCDK_N
#define K SCDK_K
#define L SCDK_LANES
#define RS (N + 2) /* row stride of the augmented matrix [H_z B], B of one or two columns */

typedef scdk_vd vd;
typedef scdk_vl vl;
typedef double complex cplx;
#define SCDK_SPLAT(x) ((vd){0} + (x))

/* defines static void scdk_eval(const vd *const *arg, vd *const *res):
 * (zr[N], zi[N], pr[K], pi[K]) -> (Gr[N], Gi[N], Jz_r[N x N], Jz_i, Jp_r[N x K], Jp_i),
 * matrices column-major */
#include SCDK_EVAL_FILE

/* N complex values per lane */
typedef struct {
    vd re[N], im[N];
} cvec;

typedef struct {
    /* data of the path in each lane */
    vd pfr[K], pfi[K], dpr[K], dpi[K], bfr[N], bfi[N], dbr[N], dbi[N], gr, gi;
    /* evaluation buffers */
    vd pr[K], pi[K];
    vd G[2 * N], J[2 * N * N], P[2 * N * K];
    /* H and H_t at the last evaluation; H_z goes straight into the augmented matrix */
    cvec H, Ht;
    vd ar[N * RS], ai[N * RS];
    /* path states */
    cvec z, v, k2, k3, k4, zt, zp, d1, z1, x0, x1;
} lanes;

/* H, H_t of every lane at (z, t) into c->H, c->Ht, H_z into the augmented matrix. */
static void homotopy(lanes *c, const double *weights, const cvec *z, const double *t) {
    vd sr, si, dsr, dsi;
    for (int l = 0; l < L; ++l) {
        const cplx g = c->gr[l] + I * c->gi[l];
        const cplx den = 1.0 + (g - 1.0) * t[l];
        const cplx s = g * t[l] / den;
        const cplx ds = g / (den * den);
        sr[l] = creal(s);
        si[l] = cimag(s);
        dsr[l] = creal(ds);
        dsi[l] = cimag(ds);
    }
    for (int i = 0; i < K; ++i) {
        c->pr[i] = c->pfr[i] + (sr * c->dpr[i] - si * c->dpi[i]);
        c->pi[i] = c->pfi[i] + (sr * c->dpi[i] + si * c->dpr[i]);
    }
    const vd *arg[4] = {z->re, z->im, c->pr, c->pi};
    vd *res[6] = {c->G, c->G + N, c->J, c->J + N * N, c->P, c->P + N * K};
    scdk_eval(arg, res);
    const vd *Gr = res[0], *Gi = res[1], *Jr = res[2], *Ji = res[3], *Pr = res[4], *Pi = res[5];
    for (int i = 0; i < N; ++i) {
        const double w = weights[i];
        c->H.re[i] = (w * Gr[i] + c->bfr[i]) + (sr * c->dbr[i] - si * c->dbi[i]);
        c->H.im[i] = (w * Gi[i] + c->bfi[i]) + (sr * c->dbi[i] + si * c->dbr[i]);
        vd accr = SCDK_SPLAT(0.0), acci = SCDK_SPLAT(0.0);
        for (int j = 0; j < K; ++j) {
            accr += Pr[j * N + i] * c->dpr[j] - Pi[j * N + i] * c->dpi[j];
            acci += Pr[j * N + i] * c->dpi[j] + Pi[j * N + i] * c->dpr[j];
        }
        const vd tr = w * accr + c->dbr[i], ti = w * acci + c->dbi[i];
        c->Ht.re[i] = tr * dsr - ti * dsi;
        c->Ht.im[i] = tr * dsi + ti * dsr;
        for (int j = 0; j < N; ++j) {
            c->ar[i * RS + j] = w * Jr[j * N + i];
            c->ai[i * RS + j] = w * Ji[j * N + i];
        }
    }
}

/* Solve H_z X = [a b] (b optional) with the last evaluation's H_z; X into xa (and xb). */
static void solve(lanes *c, const cvec *a, const cvec *b, cvec *xa, cvec *xb) {
    for (int i = 0; i < N; ++i) {
        c->ar[i * RS + N] = a->re[i];
        c->ai[i * RS + N] = a->im[i];
        if (b) {
            c->ar[i * RS + N + 1] = b->re[i];
            c->ai[i * RS + N + 1] = b->im[i];
        }
    }
    scdk_lu_solve_lanes(c->ar, c->ai, N, b ? 2 : 1, RS);
    for (int i = 0; i < N; ++i) {
        xa->re[i] = c->ar[i * RS + N];
        xa->im[i] = c->ai[i * RS + N];
        if (b) {
            xb->re[i] = c->ar[i * RS + N + 1];
            xb->im[i] = c->ai[i * RS + N + 1];
        }
    }
}

/* Velocity -H_z^{-1} H_t of every lane at (z, t) into v. */
static void velocity(lanes *c, const double *weights, const cvec *z, const double *t, cvec *v) {
    homotopy(c, weights, z, t);
    solve(c, &c->Ht, NULL, v, NULL);
    for (int i = 0; i < N; ++i) {
        v->re[i] = -v->re[i];
        v->im[i] = -v->im[i];
    }
}

/* lane mask of the finite values of x */
#define FINITE(x) ((x) - (x) == 0.0)

/* lane l of a: max|dz| / (1 + max|z|); NaN becomes infinity. */
static double rel_norm(const cvec *dz, const cvec *z, int l) {
    double a = 0.0, b = 0.0;
    for (int i = 0; i < N; ++i) {
        const double u = dz->re[i][l] * dz->re[i][l] + dz->im[i][l] * dz->im[i][l];
        const double v = z->re[i][l] * z->re[i][l] + z->im[i][l] * z->im[i][l];
        if (isnan(u) || isnan(v)) return INFINITY;
        if (u > a) a = u;
        if (v > b) b = v;
    }
    const double r = sqrt(a) / (1.0 + sqrt(b));
    return isfinite(r) ? r : INFINITY;
}

static int all_finite(const cvec *z, int l) {
    for (int i = 0; i < N; ++i)
        if (!isfinite(z->re[i][l]) || !isfinite(z->im[i][l])) return 0;
    return 1;
}

static double clip(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* Lane l of the lanes' path data := datum d; its point := z (interleaved complex). */
static void load(lanes *c, int l, int64_t d, const double *p_from, const double *dp,
                 const double *b_from, const double *db, const double *gamma, const double *z) {
    for (int i = 0; i < K; ++i) {
        c->pfr[i][l] = p_from[2 * (d * K + i)];
        c->pfi[i][l] = p_from[2 * (d * K + i) + 1];
        c->dpr[i][l] = dp[2 * (d * K + i)];
        c->dpi[i][l] = dp[2 * (d * K + i) + 1];
    }
    for (int i = 0; i < N; ++i) {
        c->bfr[i][l] = b_from[2 * (d * N + i)];
        c->bfi[i][l] = b_from[2 * (d * N + i) + 1];
        c->dbr[i][l] = db[2 * (d * N + i)];
        c->dbi[i][l] = db[2 * (d * N + i) + 1];
        c->z.re[i][l] = z[2 * i];
        c->z.im[i][l] = z[2 * i + 1];
    }
    c->gr[l] = gamma[2 * d];
    c->gi[l] = gamma[2 * d + 1];
}

/* Zeroed lanes, 64-byte aligned, inside a block *raw to free; NULL without memory. */
static lanes *new_lanes(char **raw) {
    *raw = malloc(sizeof(lanes) + 64);
    if (!*raw) return NULL;
    lanes *c = (lanes *)(*raw + (64 - (uintptr_t)*raw % 64) % 64);
    memset(c, 0, sizeof(lanes));
    return c;
}

/* One step of every lane (see the file's comment); hh: each lane's step (0 in idle lanes);
 * the corrected point in c->zt, the new velocity in -c->x1, the update norms in nu1, nu2. */
static void step(lanes *c, const double *weights, const double *tau, const double *hh,
                 double *nu1, double *nu2) {
    vd h, half;
    double t[L];
    for (int l = 0; l < L; ++l) {
        h[l] = hh[l];
        half[l] = 0.5 * hh[l];
        t[l] = tau[l] + 0.5 * hh[l];
    }
    for (int i = 0; i < N; ++i) {
        c->zt.re[i] = c->z.re[i] + half * c->v.re[i];
        c->zt.im[i] = c->z.im[i] + half * c->v.im[i];
    }
    velocity(c, weights, &c->zt, t, &c->k2);
    for (int i = 0; i < N; ++i) {
        c->zt.re[i] = c->z.re[i] + half * c->k2.re[i];
        c->zt.im[i] = c->z.im[i] + half * c->k2.im[i];
    }
    velocity(c, weights, &c->zt, t, &c->k3);
    for (int l = 0; l < L; ++l) t[l] = tau[l] + hh[l];
    for (int i = 0; i < N; ++i) {
        c->zt.re[i] = c->z.re[i] + h * c->k3.re[i];
        c->zt.im[i] = c->z.im[i] + h * c->k3.im[i];
    }
    velocity(c, weights, &c->zt, t, &c->k4);
    const vd sixth = h / 6.0;
    for (int i = 0; i < N; ++i) {
        const vd pr = c->z.re[i] + sixth * (((c->v.re[i] + 2.0 * c->k2.re[i]) +
                                             2.0 * c->k3.re[i]) + c->k4.re[i]);
        const vd pi = c->z.im[i] + sixth * (((c->v.im[i] + 2.0 * c->k2.im[i]) +
                                             2.0 * c->k3.im[i]) + c->k4.im[i]);
        const vl fin = FINITE(pr) & FINITE(pi);
        c->zp.re[i] = SCDK_SELECT(fin, pr, c->z.re[i]);
        c->zp.im[i] = SCDK_SELECT(fin, pi, c->z.im[i]);
    }
    /* Newton corrector: two iterations; the second also gives the new velocity */
    homotopy(c, weights, &c->zp, t);
    solve(c, &c->H, NULL, &c->d1, NULL);
    for (int i = 0; i < N; ++i) {
        const vl fin = FINITE(c->d1.re[i]) & FINITE(c->d1.im[i]);
        c->z1.re[i] = c->zp.re[i] - SCDK_SELECT(fin, c->d1.re[i], SCDK_SPLAT(0.0));
        c->z1.im[i] = c->zp.im[i] - SCDK_SELECT(fin, c->d1.im[i], SCDK_SPLAT(0.0));
    }
    homotopy(c, weights, &c->z1, t);
    solve(c, &c->H, &c->Ht, &c->x0, &c->x1);
    for (int i = 0; i < N; ++i) {
        c->zt.re[i] = c->z1.re[i] - c->x0.re[i];
        c->zt.im[i] = c->z1.im[i] - c->x0.im[i];
    }
    for (int l = 0; l < L; ++l) {
        nu1[l] = rel_norm(&c->d1, &c->zp, l);
        nu2[l] = rel_norm(&c->x0, &c->z1, l);
    }
}

/* Whether a step's first two updates are accepted. */
static int converged2(const scdk_options *o, double nu1, double nu2) {
    return nu1 <= o->trust && nu2 <= o->theta * nu1 + o->floor && nu2 <= o->tol;
}

/* The third Newton iteration (see the file's comment) of the lanes with more[l], at times t:
 * c->zt and the velocity -c->x1 updated in those lanes, their update norms in nu3. */
static void third(lanes *c, const double *weights, const double *t, const int *more,
                  double *nu3) {
    homotopy(c, weights, &c->zt, t);
    solve(c, &c->H, &c->Ht, &c->d1, &c->k2); /* d1, k2: free after the step */
    for (int l = 0; l < L; ++l) {
        if (!more[l]) continue;
        nu3[l] = rel_norm(&c->d1, &c->zt, l);
        for (int i = 0; i < N; ++i) {
            c->zt.re[i][l] -= c->d1.re[i][l];
            c->zt.im[i][l] -= c->d1.im[i][l];
            c->x1.re[i][l] = c->k2.re[i][l];
            c->x1.im[i][l] = c->k2.im[i][l];
        }
    }
}

/* The per-path state of a lane. */
typedef struct {
    int64_t j;  /* the path in the lane, -1: idle */
    int fresh;  /* its velocity is still to be computed */
    int rejected;
    double tau, tau1, h;
    int64_t steps, accepted, status;
    int first;                      /* on its first part, towards split[j] */
    int64_t before, before_accepted; /* step attempts and accepted steps of its first part */
} lane_state;

/* Start a part of the path of s that ends at time `end` (its counters, rejection flag and
 * status reset, its velocity to be computed afresh, its step size kept); 0 when the part is
 * over at once (status DONE, or STEP_LIMIT without steps), as a call of its own reports it. */
static int begin_part(lane_state *s, const scdk_options *o, double end) {
    s->fresh = 1;
    s->rejected = 0;
    s->tau1 = end;
    s->steps = s->accepted = 0;
    s->status = SCDK_RUNNING;
    if (s->tau >= end || o->max_steps <= 0) {
        s->status = s->tau >= end ? SCDK_DONE : SCDK_STEP_LIMIT;
        return 0;
    }
    return 1;
}

static void store(const lanes *c, int l, double *z) {
    for (int i = 0; i < N; ++i) {
        z[2 * i] = c->z.re[i][l];
        z[2 * i + 1] = c->z.im[i][l];
    }
}

/* Accept or reject the step of lane l (see the file's comment); nu3: the third update's norm
 * when the lane made one, NaN else; 1 when its path stopped. */
static int advance(lanes *c, lane_state *s, const scdk_options *o, double hh, double nu1,
                   double nu2, double nu3, int l) {
    const double t_new = s->tau + hh;
    const int converged = isnan(nu3) ? converged2(o, nu1, nu2)
                                     : nu3 <= o->theta * nu2 + o->floor && nu3 <= o->tol;
    const int at_noise = (nu1 > nu2 ? nu1 : nu2) <= o->noise;
    const int ok = all_finite(&c->zt, l) && all_finite(&c->x1, l) && (converged || at_noise);
    ++s->steps;
    s->accepted += ok;
    const double factor = clip(pow(o->eta / (nu1 > 1e-300 ? nu1 : 1e-300), 0.2), 0.25,
                               s->rejected ? 1.0 : 2.0);
    s->rejected = !ok;
    if (ok) {
        s->h = hh * factor < o->h_max ? hh * factor : o->h_max;
        for (int i = 0; i < N; ++i) {
            c->z.re[i][l] = c->zt.re[i][l];
            c->z.im[i][l] = c->zt.im[i][l];
            c->v.re[i][l] = -c->x1.re[i][l];
            c->v.im[i][l] = -c->x1.im[i][l];
        }
        s->tau = t_new;
    } else {
        s->h = 0.5 * hh;
    }
    double big = 0.0;
    for (int i = 0; i < N; ++i) {
        const double a = c->z.re[i][l] * c->z.re[i][l] + c->z.im[i][l] * c->z.im[i][l];
        if (a > big) big = a;
    }
    if (ok && t_new >= s->tau1)
        s->status = SCDK_DONE;
    else if (big > o->max_norm * o->max_norm)
        s->status = SCDK_DIVERGED;
    else if (s->h < o->h_min)
        s->status = SCDK_UNDERFLOW;
    else if (s->steps >= o->max_steps)
        s->status = SCDK_STEP_LIMIT;
    return s->status != SCDK_RUNNING;
}

/* A call's paths: the homotopy's data and the per-path arrays (as scdk_ptrack's arguments),
 * and an optional first stop: with z_mid, each path is tracked to `split` first and, when it
 * gets there, on to tau1[j] in its lane (see scdk_psolve). */
typedef struct {
    const double *weights, *p_from, *dp, *b_from, *db, *gamma;
    const int64_t *idx;
    double *z, *tau, *h;
    const double *tau1;
    int64_t *status, *steps, *accepted;
    double split;
    double *z_mid;      /* NULL: no first stop */
    int64_t *mid_steps; /* step attempts to the split, -1: not reached */
} paths;

/* The path of lane l stopped its part: the end of a first part that reached the split is kept
 * (z_mid, mid_steps) and the path goes on in the lane (1); otherwise its outputs are stored
 * and the lane is free (0). */
static int stopped(lanes *c, lane_state *s, int l, const scdk_options *opt, const paths *P) {
    const int64_t j = s->j;
    if (s->first && s->status == SCDK_DONE) {
        store(c, l, P->z_mid + 2 * N * j);
        P->mid_steps[j] = s->steps;
        s->before = s->steps;
        s->before_accepted = s->accepted;
        s->first = 0;
        if (begin_part(s, opt, P->tau1[j])) return 1;
    }
    store(c, l, P->z + 2 * N * j);
    P->tau[j] = s->tau;
    P->h[j] = s->h;
    P->status[j] = s->status;
    P->steps[j] = s->before + s->steps;
    P->accepted[j] = s->before_accepted + s->accepted;
    s->j = -1;
    return 0;
}

/* Begin path j in lane state s: its first part (to the split, or to tau1[j]); a path at the
 * split already begins its second part there. 0 when it is over at once (outputs stored as
 * a call of its own reports them). */
static int begin_path(lane_state *s, int64_t j, const scdk_options *opt, const paths *P) {
    *s = (lane_state){j, 1, 0, P->tau[j], P->tau1[j], P->h[j], 0, 0, SCDK_RUNNING, 0, 0, 0};
    if (!P->z_mid) {
        if (begin_part(s, opt, P->tau1[j])) return 1;
    } else {
        P->mid_steps[j] = -1;
        s->first = 1;
        if (begin_part(s, opt, P->split)) return 1;
        if (s->status == SCDK_DONE) { /* at the split already */
            memcpy(P->z_mid + 2 * N * j, P->z + 2 * N * j, 2 * N * sizeof(double));
            P->mid_steps[j] = 0;
            s->first = 0;
            if (begin_part(s, opt, P->tau1[j])) return 1;
        }
    }
    P->steps[j] = P->accepted[j] = 0;
    P->status[j] = s->status;
    s->j = -1;
    return 0;
}

/* Every path of P (M) to its end, SCDK_LANES at a time (see the file's comment). */
static void track_paths(lanes *c, const paths *P, int64_t M, const scdk_options *opt) {
    lane_state s[L];
    int64_t next = 0;
    for (int l = 0; l < L; ++l) s[l].j = -1;
    for (;;) {
        int active = 0, fresh = 0;
        for (int l = 0; l < L; ++l) { /* idle lanes take the next paths */
            while (s[l].j < 0 && next < M) {
                const int64_t j = next++;
                if (begin_path(&s[l], j, opt, P))
                    load(c, l, P->idx[j], P->p_from, P->dp, P->b_from, P->db, P->gamma,
                         P->z + 2 * N * j);
            }
            active += s[l].j >= 0;
            fresh += s[l].j >= 0 && s[l].fresh;
        }
        if (!active) break;
        double t[L], hh[L], nu1[L], nu2[L];
        for (int l = 0; l < L; ++l) t[l] = s[l].tau;
        if (fresh) { /* the velocity at the start of the paths (or parts) just begun */
            velocity(c, P->weights, &c->z, t, &c->zt);
            for (int l = 0; l < L; ++l) {
                if (s[l].j < 0 || !s[l].fresh) continue;
                s[l].fresh = 0;
                for (int i = 0; i < N; ++i) {
                    c->v.re[i][l] = c->zt.re[i][l];
                    c->v.im[i][l] = c->zt.im[i][l];
                }
            }
        }
        for (int l = 0; l < L; ++l) {
            hh[l] = 0.0;
            if (s[l].j < 0) continue;
            const double remaining = s[l].tau1 - s[l].tau;
            hh[l] = s[l].h < remaining ? s[l].h : remaining;
            if (remaining - hh[l] < 1e-3 * hh[l]) hh[l] = remaining; /* no sliver before the end */
        }
        step(c, P->weights, t, hh, nu1, nu2);
        double nu3[L];
        int more[L], any = 0;
        for (int l = 0; l < L; ++l) {
            nu3[l] = NAN;
            more[l] = opt->third && s[l].j >= 0 && !converged2(opt, nu1[l], nu2[l]) &&
                      nu1[l] <= opt->trust && nu2[l] <= opt->theta * nu1[l] + opt->floor &&
                      all_finite(&c->zt, l);
            any |= more[l];
            t[l] = t[l] + hh[l]; /* the step's end, as step() takes it */
        }
        if (any) third(c, P->weights, t, more, nu3);
        for (int l = 0; l < L; ++l)
            if (s[l].j >= 0 && advance(c, &s[l], opt, hh[l], nu1[l], nu2[l], nu3[l], l))
                stopped(c, &s[l], l, opt, P);
    }
}

int scdk_ptrack(int64_t n, int64_t k, const double *weights, const double *p_from,
                const double *dp, const double *b_from, const double *db, const double *gamma,
                int64_t M, const int64_t *idx, double *z, double *tau, const double *tau1,
                double *h, const scdk_options *opt, int64_t *status, int64_t *steps,
                int64_t *accepted) {
    if (n != N || k != K || M < 0) return SCDK_BAD_SIZE;
    char *raw;
    lanes *c = new_lanes(&raw);
    if (!c) return SCDK_NO_MEMORY;
    const paths P = {weights, p_from, dp, b_from, db, gamma, idx, z, tau, h, tau1,
                     status, steps, accepted, 0.0, NULL, NULL};
    track_paths(c, &P, M, opt);
    free(raw);
    return SCDK_OK;
}

/* An upper bound of the 2-norm condition number of the matrix in lane l of the augmented
 * matrix (H_z after the last homotopy call), rows and then columns scaled to unit max modulus
 * (as scaled_cond in homotopy.py): |A|_F |A^-1|_F; infinity or NaN when A is singular. */
/* |a + b i| for the scaling of a condition bound: the plain formula, not hypot (which guards
 * against an overflow of a^2 + b^2 that entries of H_z do not reach; an infinite or zero
 * modulus gives an infinite or NaN bound, which sends the point to the SVD). */
static double modulus(double a, double b) { return sqrt(a * a + b * b); }

static double cond_bound(const lanes *c, int l) {
    double ar[N * N], ai[N * N], br[N * N], bi[N * N], scale;
    int piv[N];
    for (int i = 0; i < N; ++i) {
        scale = 0.0;
        for (int j = 0; j < N; ++j) {
            ar[i * N + j] = c->ar[i * RS + j][l];
            ai[i * N + j] = c->ai[i * RS + j][l];
            const double m = modulus(ar[i * N + j], ai[i * N + j]);
            if (m > scale) scale = m;
        }
        for (int j = 0; j < N; ++j) {
            ar[i * N + j] /= scale;
            ai[i * N + j] /= scale;
        }
    }
    double fro = 0.0;
    for (int j = 0; j < N; ++j) {
        scale = 0.0;
        for (int i = 0; i < N; ++i) {
            const double m = modulus(ar[i * N + j], ai[i * N + j]);
            if (m > scale) scale = m;
        }
        for (int i = 0; i < N; ++i) {
            ar[i * N + j] /= scale;
            ai[i * N + j] /= scale;
            fro += ar[i * N + j] * ar[i * N + j] + ai[i * N + j] * ai[i * N + j];
        }
    }
    if (!scdk_lu_factor(ar, ai, N, N, 1, piv)) return INFINITY;
    double inv = 0.0;
    for (int j = 0; j < N; ++j) { /* column j of A^-1 */
        for (int i = 0; i < N; ++i) {
            br[i] = i == j;
            bi[i] = 0.0;
        }
        scdk_lu_solve(ar, ai, N, N, 1, piv, br, bi, 1, 0);
        for (int i = 0; i < N; ++i) inv += br[i] * br[i] + bi[i] * bi[i];
    }
    return sqrt(fro) * sqrt(inv);
}

/* Newton's method (as scdk_pnewton) on the M points z_in[sel[j]] (j < M; sel NULL: j), at
 * times t[sel[j]], L at a time: results into z_out[sel[j]], nu[sel[j] * iterations + it],
 * hz and cond (each NULL or indexed by sel[j]). */
static void newton_points(lanes *c, const double *weights, const double *p_from,
                          const double *dp, const double *b_from, const double *db,
                          const double *gamma, int64_t M, const int64_t *sel,
                          const int64_t *idx, const double *z_in, double *z_out,
                          const double *t, int64_t iterations, double *nu, double *hz,
                          double *cond) {
    for (int64_t j0 = 0; j0 < M; j0 += L) {
        int64_t path[L];
        double tl[L];
        for (int l = 0; l < L; ++l) { /* a short last group repeats its last point */
            const int64_t j = j0 + l < M ? j0 + l : M - 1;
            path[l] = sel ? sel[j] : j;
            tl[l] = t[path[l]];
            load(c, l, idx[path[l]], p_from, dp, b_from, db, gamma, z_in + 2 * N * path[l]);
        }
        for (int64_t it = 0; it < iterations; ++it) {
            homotopy(c, weights, &c->z, tl);
            solve(c, &c->H, NULL, &c->d1, NULL);
            for (int l = 0; l < L && j0 + l < M; ++l)
                nu[path[l] * iterations + it] = rel_norm(&c->d1, &c->z, l);
            for (int i = 0; i < N; ++i) {
                const vl fin = FINITE(c->d1.re[i]) & FINITE(c->d1.im[i]);
                c->z.re[i] -= SCDK_SELECT(fin, c->d1.re[i], SCDK_SPLAT(0.0));
                c->z.im[i] -= SCDK_SELECT(fin, c->d1.im[i], SCDK_SPLAT(0.0));
            }
        }
        if (hz || cond) homotopy(c, weights, &c->z, tl);
        for (int l = 0; l < L && j0 + l < M; ++l) {
            store(c, l, z_out + 2 * N * path[l]);
            if (cond) cond[path[l]] = cond_bound(c, l);
            if (!hz) continue;
            double *out = hz + 2 * N * N * path[l];
            for (int i = 0; i < N; ++i)
                for (int j = 0; j < N; ++j) {
                    out[2 * (i * N + j)] = c->ar[i * RS + j][l];
                    out[2 * (i * N + j) + 1] = c->ai[i * RS + j][l];
                }
        }
    }
}

int scdk_pnewton(int64_t n, int64_t k, const double *weights, const double *p_from,
                 const double *dp, const double *b_from, const double *db, const double *gamma,
                 int64_t M, const int64_t *idx, double *z, const double *t, int64_t iterations,
                 double *nu, double *hz, double *cond) {
    if (n != N || k != K || M < 0 || iterations < 0) return SCDK_BAD_SIZE;
    char *raw;
    lanes *c = new_lanes(&raw);
    if (!c) return SCDK_NO_MEMORY;
    newton_points(c, weights, p_from, dp, b_from, db, gamma, M, NULL, idx, z, z, t, iterations,
                  nu, hz, cond);
    free(raw);
    return SCDK_OK;
}

int scdk_psolve(int64_t n, int64_t k, const double *weights, const double *p_from,
                const double *dp, const double *b_from, const double *db, const double *gamma,
                int64_t M, const int64_t *idx, double *z, double *tau, double *h,
                const scdk_options *opt, int64_t *status, int64_t *steps, int64_t *accepted,
                double split, double *z_mid, int64_t *mid_steps, int64_t iterations,
                double *z_end, double *nu, double *cond) {
    if (n != N || k != K || M < 0 || iterations < 0) return SCDK_BAD_SIZE;
    double *ones = malloc((size_t)(M + 1) * sizeof(double)); /* tau1, and t of the Newton */
    int64_t *sel = malloc((size_t)(M + 1) * sizeof(int64_t));
    char *raw = NULL;
    lanes *c = ones && sel ? new_lanes(&raw) : NULL;
    if (!c) {
        free(sel);
        free(ones);
        return SCDK_NO_MEMORY;
    }
    for (int64_t j = 0; j < M; ++j) ones[j] = 1.0;
    const paths P = {weights, p_from, dp, b_from, db, gamma, idx, z, tau, h, ones,
                     status, steps, accepted, split, z_mid, mid_steps};
    track_paths(c, &P, M, opt);
    int64_t count = 0; /* Newton at t = 1 from the ends of the paths that got there */
    for (int64_t j = 0; j < M; ++j)
        if (mid_steps[j] >= 0 && status[j] == SCDK_DONE) sel[count++] = j;
    newton_points(c, weights, p_from, dp, b_from, db, gamma, count, sel, idx, z, z_end, ones,
                  iterations, nu, NULL, cond);
    free(raw);
    free(sel);
    free(ones);
    return SCDK_OK;
}
