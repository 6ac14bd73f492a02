/* vecmath.c: libmvec's vector sine, cosine, exponential and logarithm (2 or
 * 4 values a call, the rest one at a time) against libm's, value by value:
 * within 4 ulp (libmvec's stated bound) for every length, so that no value
 * is skipped or written twice where the vectors end. */
#include "check.h"
#include "vecmath.h"
#include <float.h>
#include <stdlib.h>

/* Largest error of f over n values of lo..hi, in units of the last place of libm's value. */
static double worst_ulps(void (*vf)(size_t, double *), double (*sf)(double), size_t n, double lo, double hi) {
  double *a = malloc((n + 1) * sizeof *a), worst = 0;
  if (!a) return INFINITY;
  for (size_t i = 0; i < n; i++) a[i] = lo + (hi - lo) * (double)(i * 7919 % (n ? n : 1)) / (double)(n ? n : 1);
  a[n] = 12345.0; /* past the end: must stay */
  double *in = malloc((n + 1) * sizeof *in);
  if (!in) { free(a); return INFINITY; }
  for (size_t i = 0; i <= n; i++) in[i] = a[i];
  vf(n, a);
  for (size_t i = 0; i < n; i++) {
    double r = sf(in[i]), ulp = fmax(fabs(r) * DBL_EPSILON, DBL_MIN);
    worst = fmax(worst, fabs(a[i] - r) / ulp);
  }
  if (a[n] != 12345.0) worst = INFINITY;
  free(a);
  free(in);
  return worst;
}

TEST(vector_functions_match_libm) {
  struct { const char *name; void (*vf)(size_t, double *); double (*sf)(double); double lo, hi; } f[] = {
    {"sin", gr_vsin, sin, -40, 40}, {"cos", gr_vcos, cos, -40, 40},
    {"exp", gr_vexp, exp, -30, 30}, {"log", gr_vlog, log, 1e-6, 1e6}};
  for (int k = 0; k < 4; k++) {
    double worst = 0;
    for (size_t n = 0; n <= 9; n++) worst = fmax(worst, worst_ulps(f[k].vf, f[k].sf, n, f[k].lo, f[k].hi));
    worst = fmax(worst, worst_ulps(f[k].vf, f[k].sf, 100003, f[k].lo, f[k].hi));
    printf("  info: %s: within %.2f ulp of libm\n", f[k].name, worst);
    CHECK(worst <= 4, "%s: %.2f ulp from libm's value (libmvec states 4)", f[k].name, worst);
  }
}

TEST(vector_functions_keep_nan_and_inf) {
  double a[5] = {NAN, INFINITY, -INFINITY, 0, -0.0};
  gr_vsin(5, a);
  CHECK(isnan(a[0]) && isnan(a[1]) && isnan(a[2]) && a[3] == 0, "sin of NaN, +-inf, 0: %g %g %g %g", a[0], a[1], a[2],
        a[3]);
  double b[3] = {-1, 0, INFINITY};
  gr_vlog(3, b);
  CHECK(isnan(b[0]) && isinf(b[1]) && b[1] < 0 && isinf(b[2]), "log of -1, 0, inf: %g %g %g", b[0], b[1], b[2]);
}

int main(void) {
  RUN(vector_functions_match_libm);
  RUN(vector_functions_keep_nan_and_inf);
  DONE();
}
