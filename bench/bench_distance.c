/* bench_distance.c: the graded offset field of the paper's graded P cell
 * (L = 2 mm, eq. 8 thickness, H by marching cubes at res 150): evaluation
 * speed on a 150^3 grid and on 50 slice grids of 200 x 200 (exact and mesh
 * modes), and the mesh-vs-exact difference of g near the offset surface at
 * res 40, 80, 150. */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "distance.h"

static const char *T8 = "0.1*(2*sin(pi*(w+1)/4)+1)"; /* eq. (8), w = p_z in [-1, 1) */

static gr_field *graded_p(gr_field *phi, int res, int mode, gr_err *e) {
  gr_offset_opts o = gr_offset_defaults();
  o.surface = phi;
  o.cell = 2;
  for (int a = 0; a < 3; a++) { o.box_lo[a] = 0; o.box_hi[a] = 2; }
  o.res = res;
  o.mode = mode;
  o.kind = GR_OFFSET_SHEET;
  o.thickness_expr = T8;
  return gr_offset_field_new(&o, e);
}

int main(void) {
  gr_err e;
  gr_field *phi = gr_field_tpms("primitive", 2, NULL, 0, &e);
  if (!phi) { fprintf(stderr, "%s\n", e.msg); return 1; }
  const char *mname[2] = {"mesh", "exact"};
  for (int mode = 0; mode < 2; mode++) {
    double t0 = gr_now();
    gr_field *g = graded_p(phi, 150, mode, &e);
    if (!g) { fprintf(stderr, "%s\n", e.msg); return 1; }
    double tb = gr_now() - t0;
    printf("distance graded P (L=2, eq. 8, res 150) %s: build (MC + BVH) %.3f s\n", mname[mode], tb);
    double lo[3] = {0, 0, 0}, hi[3] = {2, 2, 2};
    int n[3] = {150, 150, 150};
    t0 = gr_now();
    gr_grid3 *G = gr_grid3_sample(g, lo, hi, n, &e);
    double t3 = gr_now() - t0;
    if (!G) { fprintf(stderr, "%s\n", e.msg); return 1; }
    gr_grid3_free(G);
    double np3 = 150.0 * 150 * 150;
    printf("  %s 150^3 grid: %.3f s, %.3g points/s\n", mname[mode], t3, np3 / t3);
    double lo2[2] = {0, 0}, hi2[2] = {2, 2};
    int n2[2] = {200, 200};
    t0 = gr_now();
    for (int k = 0; k < 50; k++) {
      gr_grid2 *S = gr_grid2_sample(g, 0.02 + 0.04 * k, lo2, hi2, n2, &e);
      if (!S) { fprintf(stderr, "%s\n", e.msg); return 1; }
      gr_grid2_free(S);
    }
    double t2 = gr_now() - t0;
    printf("  %s 50 slices of 200x200 (z step 40 um): %.3f s, %.3g points/s\n", mname[mode], t2, 50 * 200.0 * 200 / t2);
    gr_field_free(g);
  }
  /* mesh vs exact near the offset surface: points of a 100^3 grid where
   * the exact g (res 150) is within 10 um of 0 */
  int N = 100;
  size_t np = (size_t)N * N * N;
  double *x = malloc(np * sizeof *x), *y = malloc(np * sizeof *y), *z = malloc(np * sizeof *z);
  double *ge = malloc(np * sizeof *ge), *gm = malloc(np * sizeof *gm);
  if (!x || !y || !z || !ge || !gm) { fprintf(stderr, "out of memory\n"); return 1; }
  for (int i = 0; i < N; i++)
    for (int j = 0; j < N; j++)
      for (int k = 0; k < N; k++) {
        size_t id = (size_t)i + (size_t)N * (j + (size_t)N * k);
        x[id] = 0.01 + 1.98 * i / (N - 1);
        y[id] = 0.01 + 1.98 * j / (N - 1);
        z[id] = 0.01 + 1.98 * k / (N - 1);
      }
  gr_field *gx = graded_p(phi, 150, GR_DIST_EXACT, &e);
  if (!gx || gr_field_eval(gx, np, x, y, z, ge, &e)) { fprintf(stderr, "%s\n", e.msg); return 1; }
  gr_field_free(gx);
  size_t k = 0;
  for (size_t i = 0; i < np; i++)
    if (fabs(ge[i]) < 0.01) { x[k] = x[i]; y[k] = y[i]; z[k] = z[i]; ge[k] = ge[i]; k++; }
  int rs[3] = {40, 80, 150};
  for (int r = 0; r < 3; r++) {
    gr_field *g = graded_p(phi, rs[r], GR_DIST_MESH, &e);
    if (!g || gr_field_eval(g, k, x, y, z, gm, &e)) { fprintf(stderr, "%s\n", e.msg); return 1; }
    double mx = 0, sum = 0;
    for (size_t i = 0; i < k; i++) {
      double d = fabs(gm[i] - ge[i]);
      if (d > mx) mx = d;
      sum += d;
    }
    printf("  mesh vs exact at res %d over %zu points with |g| < 10 um: max %.3f um, mean %.3f um\n",
           rs[r], k, mx * 1000, sum / k * 1000);
    gr_field_free(g);
  }
  free(x); free(y); free(z); free(ge); free(gm);
  gr_field_free(phi);
  return 0;
}
