/* Predictor-corrector tracking of complex parameter homotopies (see ptrack.h).
 *
 * One step of a path, as in scdk_sym/algebraic/tracker.py:
 *   predictor: classical RK4 on dz/dt = -H_z^{-1} H_t (the first stage is the velocity kept
 *              from the previous corrector);
 *   corrector: two Newton iterations at the new t; norms nu1, nu2 of the updates relative to
 *              1 + max|z|; accepted when (nu1 <= trust, nu2 <= theta nu1 + floor, nu2 <= tol)
 *              or max(nu1, nu2) <= noise, and everything is finite; the second factorisation
 *              also gives the velocity at the new point;
 *   step control: accepted, h = min(h clip((eta / nu1)^(1/5), 0.25, 2), h_max), the factor at
 *              most 1 right after a rejected step; rejected, h / 2.
 * Linear systems: the package's LU with partial pivoting (scdk_lu.h: pivot of largest
 * |re| + |im|, as LAPACK); an exactly zero pivot gives NaN solutions, which reject the step.
 */
#include "ptrack.h"
#include "scdk_lu.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef double complex cplx;

typedef struct {
    scdk_eval_fn eval;
    int64_t n, k;
    const double *weights;
    const cplx *p_from, *dp, *b_from, *db, *gamma;
    /* evaluation buffers (real pairs) */
    const double *arg[4];
    double *res[6];
    double *in, *out, *work;
    long long *iw;
    /* homotopy values at the last evaluation: H (n), Ht (n); H_z is written straight into
     * the first n columns of the augmented matrix of the next solve */
    cplx *H, *Ht;
    /* linear algebra */
    cplx *rhs;
    double *ar, *ai; /* augmented matrix [H_z B] of the solve, n x (n + nrhs), row-major */
    int *piv;        /* its pivots */
} context;

static double abs2(cplx a) { return creal(a) * creal(a) + cimag(a) * cimag(a); }


/* H, H_t of datum d at (z, t) into c->H, c->Ht, and H_z into the augmented matrix of a solve
 * with nrhs right-hand sides (see solve); returns 0 or SCDK_EVAL_FAILED. */
static int homotopy(context *c, const cplx *z, double t, int64_t d, int64_t nrhs) {
    const int64_t n = c->n, k = c->k;
    const cplx g = c->gamma[d];
    const cplx den = 1.0 + (g - 1.0) * t;
    const cplx s = g * t / den;
    const cplx ds = g / (den * den);
    const cplx *dp = c->dp + d * k, *pf = c->p_from + d * k;
    const cplx *db = c->db + d * n, *bf = c->b_from + d * n;
    double *zr = c->in, *zi = zr + n, *pr = zi + n, *pi = pr + k;
    for (int64_t i = 0; i < n; ++i) {
        zr[i] = creal(z[i]);
        zi[i] = cimag(z[i]);
    }
    for (int64_t i = 0; i < k; ++i) {
        const cplx p = pf[i] + s * dp[i];
        pr[i] = creal(p);
        pi[i] = cimag(p);
    }
    if (c->eval(c->arg, c->res, c->iw, c->work, 0)) return SCDK_EVAL_FAILED;
    const double *Gr = c->res[0], *Gi = c->res[1], *Jr = c->res[2], *Ji = c->res[3];
    const double *Pr = c->res[4], *Pi = c->res[5];
    for (int64_t i = 0; i < n; ++i) {
        const double w = c->weights[i];
        c->H[i] = w * (Gr[i] + I * Gi[i]) + bf[i] + s * db[i];
        cplx acc = 0.0;
        for (int64_t j = 0; j < k; ++j) acc += (Pr[j * n + i] + I * Pi[j * n + i]) * dp[j];
        c->Ht[i] = (w * acc + db[i]) * ds;
    }
    const int64_t W = n + nrhs;
    for (int64_t i = 0; i < n; ++i) {
        const double w = c->weights[i];
        double *ar = c->ar + i * W, *ai = c->ai + i * W;
        for (int64_t j = 0; j < n; ++j) {
            ar[j] = w * Jr[j * n + i];
            ai[j] = w * Ji[j * n + i];
        }
    }
    return 0;
}

/* Solve Hz X = B for nrhs (1 or 2) right-hand sides B (n x nrhs column-major, in rhs; X
 * replaces it), Hz as the last homotopy call with the same nrhs left it: the package's LU with
 * partial pivoting (scdk_lu.h) on the augmented matrix [Hz B], row-major with separate real
 * and imaginary parts (contiguous rows), B's columns solved in place. */
static void solve(context *c, int64_t nrhs) {
    const int n = (int)c->n, W = n + (int)nrhs;
    double *ar = c->ar, *ai = c->ai;
    if (!scdk_lu_factor(ar, ai, n, W, 1, c->piv)) { /* exactly singular (or NaN): no solution */
        for (int64_t i = 0; i < c->n * nrhs; ++i) c->rhs[i] = NAN;
        return;
    }
    for (int r = 0; r < (int)nrhs; ++r) {
        cplx *x = c->rhs + r * n;
        double *br = ar + n + r, *bi = ai + n + r;
        for (int i = 0; i < n; ++i) {
            br[i * W] = creal(x[i]);
            bi[i * W] = cimag(x[i]);
        }
        scdk_lu_solve(ar, ai, n, W, 1, c->piv, br, bi, W, 0);
        for (int i = 0; i < n; ++i) x[i] = br[i * W] + I * bi[i * W];
    }
}

/* max|dz| / (1 + max|z|); NaN becomes infinity. */
static double rel_norm(const cplx *dz, const cplx *z, int64_t n) {
    double a = 0.0, b = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        const double u = abs2(dz[i]), v = abs2(z[i]);
        if (isnan(u) || isnan(v)) return INFINITY;
        if (u > a) a = u;
        if (v > b) b = v;
    }
    const double r = sqrt(a) / (1.0 + sqrt(b));
    return isfinite(r) ? r : INFINITY;
}

static int all_finite(const cplx *z, int64_t n) {
    for (int64_t i = 0; i < n; ++i)
        if (!isfinite(creal(z[i])) || !isfinite(cimag(z[i]))) return 0;
    return 1;
}

/* Velocity -H_z^{-1} H_t at (z, t) into v. */
static int velocity(context *c, const cplx *z, double t, int64_t d, cplx *v) {
    const int64_t n = c->n;
    if (homotopy(c, z, t, d, 1)) return SCDK_EVAL_FAILED;
    memcpy(c->rhs, c->Ht, (size_t)n * sizeof(cplx));
    solve(c, 1);
    for (int64_t i = 0; i < n; ++i) v[i] = -c->rhs[i];
    return 0;
}

static double clip(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* Track one path; z, v: its point and velocity (updated). */
static int track_path(context *c, const scdk_options *o, int64_t d, cplx *z, double *tau_io,
                      double tau1, double *h_io, int64_t *status, int64_t *steps,
                      int64_t *accepted, cplx *buf) {
    const int64_t n = c->n;
    cplx *v = buf, *k2 = v + n, *k3 = k2 + n, *k4 = k3 + n, *zt = k4 + n, *zp = zt + n;
    cplx *d1 = zp + n, *z1 = d1 + n;
    double tau = *tau_io, h = *h_io;
    int64_t st = tau >= tau1 ? SCDK_DONE : SCDK_RUNNING, nsteps = 0, nacc = 0;
    int rejected = 0; /* the last step was rejected */
    if (velocity(c, z, tau, d, v)) return SCDK_EVAL_FAILED;
    for (int64_t it = 0; it < o->max_steps && st == SCDK_RUNNING; ++it) {
        const double remaining = tau1 - tau;
        double hh = h < remaining ? h : remaining;
        if (remaining - hh < 1e-3 * hh) hh = remaining; /* no sliver before the end */
        /* RK4 predictor */
        for (int64_t i = 0; i < n; ++i) zt[i] = z[i] + 0.5 * hh * v[i];
        if (velocity(c, zt, tau + 0.5 * hh, d, k2)) return SCDK_EVAL_FAILED;
        for (int64_t i = 0; i < n; ++i) zt[i] = z[i] + 0.5 * hh * k2[i];
        if (velocity(c, zt, tau + 0.5 * hh, d, k3)) return SCDK_EVAL_FAILED;
        for (int64_t i = 0; i < n; ++i) zt[i] = z[i] + hh * k3[i];
        if (velocity(c, zt, tau + hh, d, k4)) return SCDK_EVAL_FAILED;
        for (int64_t i = 0; i < n; ++i) {
            const cplx p = z[i] + (hh / 6.0) * (v[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            zp[i] = (isfinite(creal(p)) && isfinite(cimag(p))) ? p : z[i];
        }
        /* Newton corrector: two iterations; the second also gives the new velocity */
        const double t_new = tau + hh;
        if (homotopy(c, zp, t_new, d, 1)) return SCDK_EVAL_FAILED;
        memcpy(c->rhs, c->H, (size_t)n * sizeof(cplx));
        solve(c, 1);
        for (int64_t i = 0; i < n; ++i) {
            d1[i] = c->rhs[i];
            const int fin = isfinite(creal(d1[i])) && isfinite(cimag(d1[i]));
            z1[i] = zp[i] - (fin ? d1[i] : 0.0);
        }
        if (homotopy(c, z1, t_new, d, 2)) return SCDK_EVAL_FAILED;
        memcpy(c->rhs, c->H, (size_t)n * sizeof(cplx));
        memcpy(c->rhs + n, c->Ht, (size_t)n * sizeof(cplx));
        solve(c, 2);
        const cplx *X0 = c->rhs, *X1 = c->rhs + n;
        const double nu1 = rel_norm(d1, zp, n), nu2 = rel_norm(X0, z1, n);
        for (int64_t i = 0; i < n; ++i) zt[i] = z1[i] - X0[i]; /* corrected point */
        const int converged = nu1 <= o->trust && nu2 <= o->theta * nu1 + o->floor && nu2 <= o->tol;
        const int at_noise = (nu1 > nu2 ? nu1 : nu2) <= o->noise;
        const int ok = all_finite(zt, n) && all_finite(X1, n) && (converged || at_noise);
        ++nsteps;
        nacc += ok;
        const double factor = clip(pow(o->eta / (nu1 > 1e-300 ? nu1 : 1e-300), 0.2), 0.25,
                                   rejected ? 1.0 : 2.0);
        rejected = !ok;
        if (ok) {
            h = hh * factor < o->h_max ? hh * factor : o->h_max;
            for (int64_t i = 0; i < n; ++i) {
                z[i] = zt[i];
                v[i] = -X1[i];
            }
            tau = t_new;
        } else {
            h = 0.5 * hh;
        }
        double big = 0.0;
        for (int64_t i = 0; i < n; ++i) {
            const double a = abs2(z[i]);
            if (a > big) big = a;
        }
        if (ok && t_new >= tau1)
            st = SCDK_DONE;
        else if (big > o->max_norm * o->max_norm)
            st = SCDK_DIVERGED;
        else if (h < o->h_min)
            st = SCDK_UNDERFLOW;
    }
    *status = st == SCDK_RUNNING ? SCDK_STEP_LIMIT : st;
    *tau_io = tau;
    *h_io = h;
    *steps = nsteps;
    *accepted = nacc;
    return 0;
}

int scdk_ptrack(scdk_eval_fn eval, int64_t sz_iw, int64_t sz_w, int64_t n, int64_t k,
                const double *weights, const double *p_from, const double *dp,
                const double *b_from, const double *db, const double *gamma, int64_t M,
                const int64_t *idx, double *z, double *tau, const double *tau1, double *h,
                const scdk_options *opt, int64_t *status, int64_t *steps, int64_t *accepted) {
    if (n <= 0 || k < 0 || M < 0 || sz_iw < 0 || sz_w < 0) return SCDK_BAD_SIZE;
    context c;
    c.eval = eval;
    c.n = n;
    c.k = k;
    c.weights = weights;
    c.p_from = (const cplx *)p_from;
    c.dp = (const cplx *)dp;
    c.b_from = (const cplx *)b_from;
    c.db = (const cplx *)db;
    c.gamma = (const cplx *)gamma;
    const size_t nin = (size_t)(2 * n + 2 * k), nout = (size_t)(2 * n + 2 * n * n + 2 * n * k);
    c.in = malloc((nin + nout + (size_t)sz_w + 1) * sizeof(double));
    c.iw = malloc(((size_t)sz_iw + 1) * sizeof(long long));
    cplx *cbuf = malloc((size_t)(2 * n + 2 * n + 8 * n + n * (n + 2)) * sizeof(cplx));
    c.piv = malloc((size_t)n * sizeof(int));
    if (!c.in || !c.iw || !cbuf || !c.piv) {
        free(c.in);
        free(c.iw);
        free(cbuf);
        free(c.piv);
        return SCDK_NO_MEMORY;
    }
    c.out = c.in + nin;
    c.work = c.out + nout;
    c.arg[0] = c.in;
    c.arg[1] = c.in + n;
    c.arg[2] = c.in + 2 * n;
    c.arg[3] = c.in + 2 * n + k;
    c.res[0] = c.out;
    c.res[1] = c.out + n;
    c.res[2] = c.out + 2 * n;
    c.res[3] = c.res[2] + n * n;
    c.res[4] = c.res[3] + n * n;
    c.res[5] = c.res[4] + n * k;
    c.H = cbuf;
    c.Ht = c.H + n;
    c.rhs = c.Ht + n;
    cplx *path = c.rhs + 2 * n;
    c.ar = (double *)(path + 8 * n);
    c.ai = c.ar + n * (n + 2);
    int rc = SCDK_OK;
    for (int64_t j = 0; j < M && rc == SCDK_OK; ++j)
        rc = track_path(&c, opt, idx[j], (cplx *)z + j * n, tau + j, tau1[j], h + j, status + j,
                        steps + j, accepted + j, path);
    free(c.in);
    free(c.iw);
    free(cbuf);
    free(c.piv);
    return rc;
}
