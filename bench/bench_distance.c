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

/* deterministic uniform numbers in [0, 1) */
static double uni(unsigned long long *s) {
  *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
  return (double)(*s >> 11) / 9007199254740992.0;
}

static gr_field *graded_p(gr_field *phi, int res, int mode, gr_err *e) {
  gr_offset_opts o = gr_offset_defaults();
  o.surface = phi;
  o.cell[0] = o.cell[1] = o.cell[2] = 2;
  for (int a = 0; a < 3; a++) { o.box_lo[a] = 0; o.box_hi[a] = 2; }
  o.res = res;
  o.mode = mode;
  o.kind = GR_OFFSET_SHEET;
  o.thickness_expr = T8;
  return gr_offset_field_new(&o, e);
}

int main(int argc, char **argv) {
  int quick = argc > 1 && argv[1][0] == 'q'; /* "q": skip the speed part */
  gr_err e;
  gr_field *phi = gr_field_tpms("primitive", 2, NULL, 0, &e);
  if (!phi) { fprintf(stderr, "%s\n", e.msg); return 1; }
  const char *mname[2] = {"mesh", "exact"};
  for (int mode = 0; mode < 2 && !quick; mode++) {
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
  /* mesh vs exact near the offset surface: points s + T(s) n or s - T(s) n
   * for points s of H (bisection on phi along random segments), z in
   * [0.1, 1.9] away from eq. 8's jump of T at the cell faces z = 0, 2.
   * (Points chosen by |g| < eps from a grid would also pick far points:
   * beyond the narrow band the field returns a positive lower bound.) */
  size_t k = 20000;
  double *x = malloc(k * sizeof *x), *y = malloc(k * sizeof *y), *z = malloc(k * sizeof *z);
  double *ge = malloc(k * sizeof *ge), *gm = malloc(k * sizeof *gm);
  if (!x || !y || !z || !ge || !gm) { fprintf(stderr, "out of memory\n"); return 1; }
  unsigned long long seed = 1;
  for (size_t i = 0; i < k;) {
    double a[3], b[3], fa, fb, dir[3];
    for (int c = 0; c < 3; c++) { a[c] = 2 * uni(&seed); dir[c] = uni(&seed) - 0.5; }
    double dl = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    for (int c = 0; c < 3; c++) b[c] = a[c] + 0.5 * dir[c] / dl;
    if (gr_field_eval(phi, 1, &a[0], &a[1], &a[2], &fa, &e) || gr_field_eval(phi, 1, &b[0], &b[1], &b[2], &fb, &e)) return 1;
    if ((fa < 0) == (fb < 0)) continue;
    for (int it = 0; it < 50; it++) {
      double m[3] = {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2])}, fm;
      if (gr_field_eval(phi, 1, &m[0], &m[1], &m[2], &fm, &e)) return 1;
      if ((fm < 0) == (fa < 0)) { a[0] = m[0]; a[1] = m[1]; a[2] = m[2]; fa = fm; }
      else { b[0] = m[0]; b[1] = m[1]; b[2] = m[2]; }
    }
    if (a[2] < 0.1 || a[2] > 1.9) continue;
    double n[3];
    if (gr_field_grad(phi, 1, &a[0], &a[1], &a[2], &n[0], &n[1], &n[2], &e)) return 1;
    double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(nl > 1)) continue;
    double w = fmod(a[2], 2.0) - 1, T = 0.1 * (2 * sin(3.14159265358979323846 * (w + 1) / 4) + 1), sg = (i % 2) ? 1 : -1;
    x[i] = a[0] + sg * T * n[0] / nl;
    y[i] = a[1] + sg * T * n[1] / nl;
    z[i] = a[2] + sg * T * n[2] / nl;
    i++;
  }
  gr_field *gx = graded_p(phi, 150, GR_DIST_EXACT, &e);
  if (!gx || gr_field_eval(gx, k, x, y, z, ge, &e)) { fprintf(stderr, "%s\n", e.msg); return 1; }
  gr_field_free(gx);
  double gmax = 0;
  for (size_t i = 0; i < k; i++) gmax = fmax(gmax, fabs(ge[i]));
  printf("  %zu points on the offset surfaces (|g_exact| max %.3g um)\n", k, gmax * 1000);
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
    printf("  mesh vs exact (exact at res 150) at res %d: max %.3f um, mean %.3f um\n",
           rs[r], mx * 1000, sum / k * 1000);
    gr_field_free(g);
  }
  free(x); free(y); free(z); free(ge); free(gm);
  gr_field_free(phi);
  return 0;
}
