/* bench_field.c: field evaluation throughput (points per second) for TPMS
 * surfaces, an expression field, a combination, and grid sampling. */
#include <stdio.h>
#include <stdlib.h>
#include "field.h"

static double *x, *y, *z, *out;
enum { N = 1 << 20 };

static void run(const char *label, gr_field *f, int grad) {
  gr_err e = {0};
  double *gx = malloc(N * sizeof *gx), *gy = malloc(N * sizeof *gy), *gz = malloc(N * sizeof *gz);
  double t0 = gr_now();
  int rc = grad ? gr_field_grad(f, N, x, y, z, gx, gy, gz, &e) : gr_field_eval(f, N, x, y, z, out, &e);
  double dt = gr_now() - t0;
  if (rc) printf("%s: error %s\n", label, e.msg);
  else printf("field %-40s %s %7.1f Mpoints/s\n", label, grad ? "grad" : "eval", N / dt / 1e6);
  free(gx); free(gy); free(gz);
}

int main(void) {
  x = malloc(N * sizeof *x); y = malloc(N * sizeof *y); z = malloc(N * sizeof *z);
  out = malloc(N * sizeof *out);
  for (int i = 0; i < N; i++) {
    x[i] = 10.0 * rand() / RAND_MAX; y[i] = 10.0 * rand() / RAND_MAX; z[i] = 10.0 * rand() / RAND_MAX;
  }
  gr_err e = {0};
  for (int s = 0; s < gr_tpms_count(); s++) {
    gr_field *f = gr_field_tpms(gr_tpms_name(s), 2, NULL, 0, &e);
    run(gr_field_describe(f), f, 0);
    if (s < 2) run(gr_field_describe(f), f, 1);
    gr_field_free(f);
  }
  gr_field *ex = gr_field_expr("cos(2*pi*x/2)+cos(2*pi*y/2)+cos(2*pi*z/2)", &e);
  run("expr primitive", ex, 0);
  run("expr primitive (central differences)", ex, 1);
  gr_field *a = gr_field_tpms("gyroid", 2, NULL, 0, &e), *b = gr_field_tpms("diamond", 2, NULL, 0, &e);
  gr_field *w = gr_field_expr("x/10", &e);
  gr_field *bl = gr_field_blend(a, b, w);
  run("blend(gyroid, diamond, x/10)", bl, 0);
  double lo[3] = {0, 0, 0}, hi[3] = {10, 10, 10};
  int n[3] = {200, 200, 200};
  double t0 = gr_now();
  gr_grid3 *g = gr_grid3_sample(a, lo, hi, n, &e);
  double dt = gr_now() - t0;
  printf("grid3 sample gyroid 200^3: %.3f s, %.1f Msamples/s\n", dt, 8e6 / dt / 1e6);
  gr_grid3_free(g);
  gr_field_free(ex); gr_field_free(a); gr_field_free(b); gr_field_free(w); gr_field_free(bl);
  free(x); free(y); free(z); free(out);
  return 0;
}
