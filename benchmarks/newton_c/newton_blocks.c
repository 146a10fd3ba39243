/* A plain warm-started Newton tracker in C on one block of a closure system (the baseline of
 * benchmarks/gepetto_legs.py): at each reading, Newton steps from the previous sample's
 * unknowns on the block's rows g(y, theta, c) = 0, with the block's CasADi-generated closure
 * kernel (g and J_p) and a dense LU with partial pivoting. No branch control, no chart
 * re-centring (the chart c stays at the start's): what a conventional tracker does.
 */
#include <math.h>
#include <string.h>

typedef long long casadi_int;
typedef int (*closure_fn)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

/* Solve A x = b in place (A: n x n column-major, overwritten; b: n, overwritten by x). */
static int lu_solve(int n, double *A, double *b) {
  for (int k = 0; k < n; ++k) {
    int p = k;
    double best = fabs(A[k + k * n]);
    for (int i = k + 1; i < n; ++i) {
      double v = fabs(A[i + k * n]);
      if (v > best) { best = v; p = i; }
    }
    if (best == 0.0) return 1;
    if (p != k) {
      for (int j = 0; j < n; ++j) {
        double t = A[k + j * n]; A[k + j * n] = A[p + j * n]; A[p + j * n] = t;
      }
      double t = b[k]; b[k] = b[p]; b[p] = t;
    }
    for (int i = k + 1; i < n; ++i) {
      double f = A[i + k * n] / A[k + k * n];
      if (f == 0.0) continue;
      for (int j = k + 1; j < n; ++j) A[i + j * n] -= f * A[k + j * n];
      b[i] -= f * b[k];
    }
  }
  for (int i = n - 1; i >= 0; --i) {
    double s = b[i];
    for (int j = i + 1; j < n; ++j) s -= A[i + j * n] * b[j];
    b[i] = s / A[i + i * n];
  }
  return 0;
}

/* Track N readings: thetas (N x k, row-major), y (m, in: the start, out: the last sample),
 * ys (N x m, row-major) every sample; work: arg/res pointer arrays and iw/w buffers of the
 * closure kernel, g (m) and J (m x m) scratch. Returns the total Newton iterations, or -1
 * when a step is singular or does not converge in max_iter. */
int newton_block(closure_fn f, int m, int k, const double *c, const double *thetas, int N,
                 double *y, double *ys, int max_iter, double tol, const double **arg,
                 double **res, casadi_int *iw, double *w, double *g, double *J) {
  int iterations = 0;
  for (int s = 0; s < N; ++s) {
    const double *theta = thetas + (long)s * k;
    int done = 0;
    for (int it = 0; it < max_iter; ++it) {
      arg[0] = y; arg[1] = theta; arg[2] = c;
      res[0] = g; res[1] = J;
      if (f(arg, res, iw, w, 0)) return -1;
      for (int i = 0; i < m; ++i) g[i] = -g[i];
      if (lu_solve(m, J, g)) return -1;
      double step = 0.0;
      for (int i = 0; i < m; ++i) { y[i] += g[i]; step = fmax(step, fabs(g[i])); }
      ++iterations;
      if (step < tol) { done = 1; break; }
    }
    if (!done) return -1;
    memcpy(ys + (long)s * m, y, sizeof(double) * m);
  }
  return iterations;
}
