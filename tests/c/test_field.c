/* test_field.c: the TPMS catalogue at analytic points, symmetries, origin
 * and cell handling, gradients against finite differences, the Lipschitz
 * bound, expression / callback / combination fields and grid sampling. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "field.h"

static double rnd(double lo, double hi) { return lo + (hi - lo) * (rand() / (double)RAND_MAX); }

static double ev(const gr_field *f, double x, double y, double z) {
  double v = NAN;
  gr_err e = {0};
  if (gr_field_eval(f, 1, &x, &y, &z, &v, &e)) printf("    eval failed: %s\n", e.msg);
  return v;
}

static void gr1(const gr_field *f, double x, double y, double z, double g[3]) {
  gr_err e = {0};
  if (gr_field_grad(f, 1, &x, &y, &z, g, g + 1, g + 2, &e)) printf("    grad failed: %s\n", e.msg);
}

/* phi written out with libm for each surface at X, Y, Z (doc/contract.md s.2). */
/* The analytic gradient of f at (x, y, z) into g; the count of its components
 * that differ from central differences (relative to 1 + |g|_1). */
static int grad_mismatch(const gr_field *f, double x, double y, double z, double g[3]) {
  double h = 1e-5;
  gr1(f, x, y, z, g);
  double fd[3] = {(ev(f, x + h, y, z) - ev(f, x - h, y, z)) / (2 * h),
                  (ev(f, x, y + h, z) - ev(f, x, y - h, z)) / (2 * h),
                  (ev(f, x, y, z + h) - ev(f, x, y, z - h)) / (2 * h)};
  double scale = 1 + fabs(g[0]) + fabs(g[1]) + fabs(g[2]);
  int bad = 0;
  for (int i = 0; i < 3; i++)
    if (fabs(g[i] - fd[i]) > 1e-6 * scale) bad++;
  return bad;
}

static double ref_phi(int s, double X, double Y, double Z) {
  double cX = cos(X), cY = cos(Y), cZ = cos(Z), sX = sin(X), sY = sin(Y), sZ = sin(Z);
  double c2X = cos(2 * X), c2Y = cos(2 * Y), c2Z = cos(2 * Z);
  double s2X = sin(2 * X), s2Y = sin(2 * Y), s2Z = sin(2 * Z);
  switch (s) {
  case 0: return cX + cY + cZ;
  case 1: return cX * sY + cY * sZ + cZ * sX;
  case 2: return sX * sY * sZ + sX * cY * cZ + cX * sY * cZ + cX * cY * sZ;
  case 3: return 2 * (cX * cY + cY * cZ + cZ * cX) - (c2X + c2Y + c2Z);
  case 4: return 3 * (cX + cY + cZ) + 4 * cX * cY * cZ;
  case 5: return 4 * cX * cY * cZ - (c2X * c2Y + c2Y * c2Z + c2Z * c2X);
  case 6: return c2X * sY * cZ + cX * c2Y * sZ + sX * cY * c2Z;
  case 7: return s2X * cY * sZ + s2Y * cZ * sX + s2Z * cX * sY - (c2X * c2Y + c2Y * c2Z + c2Z * c2X) + 0.3;
  case 8: return 1.1 * (s2X * sZ * cY + s2Y * sX * cZ + s2Z * sY * cX) -
                 0.2 * (c2X * c2Y + c2Y * c2Z + c2Z * c2X) - 0.4 * (c2X + c2Y + c2Z);
  case 9: return 0.6 * (cX * cY + cY * cZ + cZ * cX) - 0.4 * (cX + cY + cZ) + 0.25;
  }
  return NAN;
}

TEST(catalogue_names) {
  CHECK(gr_tpms_count() == 10, "count %d", gr_tpms_count());
  const char *want[10] = {"primitive", "gyroid", "diamond", "iwp", "neovius", "frd",
                          "fischer_koch_s", "lidinoid", "split_p", "octo"};
  for (int i = 0; i < 10; i++) {
    CHECK(strcmp(gr_tpms_name(i), want[i]) == 0, "name %d", i);
    CHECK(gr_tpms_lookup(want[i]) == i, "lookup %s", want[i]);
    CHECK(strstr(gr_tpms_names(), want[i]) != NULL, "names has %s", want[i]);
  }
  CHECK(gr_tpms_lookup("schwarz") == -1, "unknown");
  gr_err e = {0};
  CHECK(gr_field_tpms("schwarz", 2, NULL, 0, &e) == NULL && e.code == GR_EARG, "unknown fails");
  CHECK(strstr(e.msg, "'schwarz'") && strstr(e.msg, "gyroid") && strstr(e.msg, "octo"), "msg '%s'", e.msg);
  CHECK(gr_field_tpms("gyroid", 0, NULL, 0, &e) == NULL && strstr(e.msg, "got 0"), "cell 0: '%s'", e.msg);
  CHECK(gr_field_tpms("gyroid", -1, NULL, 0, &e) == NULL && strstr(e.msg, "got -1"), "cell -1: '%s'", e.msg);
}

TEST(primitive_known_points) {
  gr_err e = {0};
  double o[3] = {1, -2, 0.5};
  gr_field *f = gr_field_tpms("primitive", 2, o, 0, &e);
  CHECK(f != NULL, "%s", e.msg);
  if (!f) return;
  /* cell centre: o + L/2 = 3; corner: -3; face centre of the cell: 1 */
  CHECK_NEAR(ev(f, 2, -1, 1.5), 3, 1e-12);
  CHECK_NEAR(ev(f, 1, -2, 0.5), -3, 1e-12);
  CHECK_NEAR(ev(f, 3, 0, 2.5), -3, 1e-12);
  CHECK_NEAR(ev(f, 1, -1, 1.5), 1, 1e-12);
  CHECK_NEAR(ev(f, 2 + 0.5, -1, 1.5), 2, 1e-12); /* quarter cell: cos(pi/2) = 0 */
  gr_tpms_info info;
  CHECK(gr_field_tpms_info(f, &info) && info.surface == 0 && info.cell == 2 && info.origin[1] == -2,
        "info");
  CHECK(strstr(gr_field_describe(f), "primitive(L=2") != NULL, "describe '%s'", gr_field_describe(f));
  gr_field_free(f);
  /* level shifts the value */
  f = gr_field_tpms("primitive", 4, NULL, 0.5, &e);
  CHECK_NEAR(ev(f, 2, 2, 2), 2.5, 1e-12);
  CHECK_NEAR(ev(f, 0, 0, 0), -3.5, 1e-12);
  gr_field_free(f);
}

TEST(all_surfaces_match_formulas_and_symmetries) {
  srand(2);
  gr_err e = {0};
  for (int s = 0; s < 10; s++) {
    double L = rnd(0.5, 5), o[3] = {rnd(-3, 3), rnd(-3, 3), rnd(-3, 3)};
    gr_field *f = gr_field_tpms(gr_tpms_name(s), L, o, 0, &e);
    CHECK(f != NULL, "%s", e.msg);
    if (!f) continue;
    double w = 2 * M_PI / L;
    int bad = 0, badper = 0, badsym = 0;
    for (int k = 0; k < 500; k++) {
      double x = rnd(-10, 10), y = rnd(-10, 10), z = rnd(-10, 10);
      double v = ev(f, x, y, z);
      double want = ref_phi(s, w * (x - o[0] - L / 2), w * (y - o[1] - L / 2), w * (z - o[2] - L / 2));
      if (fabs(v - want) > 1e-9) bad++;
      /* periodic with period L along each axis */
      if (fabs(ev(f, x + L, y, z) - v) > 1e-9 || fabs(ev(f, x, y - L, z) - v) > 1e-9 ||
          fabs(ev(f, x, y, z + 2 * L) - v) > 1e-9)
        badper++;
      /* point reflection about the cell centre c: p -> 2c - p */
      double cx = o[0] + L / 2, cy = o[1] + L / 2, cz = o[2] + L / 2;
      double r = ev(f, 2 * cx - x, 2 * cy - y, 2 * cz - z);
      /* odd surfaces (only sines to odd total power) flip sign, the rest are even */
      int odd = s == 1 || s == 2;
      int evenc = s == 0 || s == 3 || s == 4 || s == 5 || s == 9;
      if (odd && fabs(r + v) > 1e-9) badsym++;
      if (evenc && fabs(r - v) > 1e-9) badsym++;
    }
    CHECK(bad == 0, "%s: %d points differ from the formula", gr_tpms_name(s), bad);
    CHECK(badper == 0, "%s: %d points not periodic", gr_tpms_name(s), badper);
    CHECK(badsym == 0, "%s: %d points break the central symmetry", gr_tpms_name(s), badsym);
    gr_field_free(f);
  }
  /* gyroid at the centre is 0 (odd), neovius at the centre 3*3+4 = 13 */
  gr_field *g = gr_field_tpms("gyroid", 2, NULL, 0, &e);
  CHECK_NEAR(ev(g, 1, 1, 1), 0, 1e-12);
  gr_field_free(g);
  g = gr_field_tpms("neovius", 2, NULL, 0, &e);
  CHECK_NEAR(ev(g, 1, 1, 1), 13, 1e-12);
  CHECK_NEAR(ev(g, 0, 0, 0), -13, 1e-12);
  gr_field_free(g);
}

TEST(gradients_and_lipschitz) {
  srand(3);
  gr_err e = {0};
  for (int s = 0; s < 10; s++) {
    double L = rnd(0.5, 4), o[3] = {rnd(-2, 2), rnd(-2, 2), rnd(-2, 2)};
    gr_field *f = gr_field_tpms(gr_tpms_name(s), L, o, 0.2, &e);
    if (!f) { CHECK(0, "%s", e.msg); continue; }
    double K = gr_field_lipschitz(f), maxg = 0;
    CHECK(isfinite(K) && K > 0, "%s: K = %g", gr_tpms_name(s), K);
    int bad = 0, over = 0;
    for (int k = 0; k < 2000; k++) {
      double x = rnd(-5, 5), y = rnd(-5, 5), z = rnd(-5, 5), g[3];
      bad += grad_mismatch(f, x, y, z, g);
      double n = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
      if (n > K) over++;
      if (n > maxg) maxg = n;
    }
    CHECK(bad == 0, "%s: %d gradient components differ from finite differences", gr_tpms_name(s), bad);
    CHECK(over == 0, "%s: |grad| exceeded K = %g at %d points", gr_tpms_name(s), K, over);
    /* the bound is not absurdly loose either (within a factor 8 of the max seen) */
    CHECK(maxg > K / 8, "%s: max |grad| %g vs K %g", gr_tpms_name(s), maxg, K);
    gr_field_free(f);
  }
}

/* Stretched cells (gr_field_tpms3): every surface against its formula with
 * X = 2 pi/Lx (x - o_x - Lx/2), Y, Z likewise; period Lx, Ly, Lz per axis;
 * the analytic gradient against differences and under the Lipschitz bound;
 * grid sampling equal to point evaluation; equal lengths give gr_field_tpms
 * exactly; a zero length is refused. */
TEST(stretched_surfaces) {
  srand(4);
  gr_err e = {0};
  for (int s = 0; s < 10; s++) {
    double L[3] = {rnd(0.5, 5), rnd(0.5, 5), rnd(0.5, 5)}, o[3] = {rnd(-3, 3), rnd(-3, 3), rnd(-3, 3)};
    gr_field *f = gr_field_tpms3(gr_tpms_name(s), L, o, 0, &e);
    CHECK(f != NULL, "%s", e.msg);
    if (!f) continue;
    double K = gr_field_lipschitz(f);
    int bad = 0, badper = 0, badg = 0, over = 0;
    for (int k = 0; k < 300; k++) {
      double x = rnd(-10, 10), y = rnd(-10, 10), z = rnd(-10, 10), g[3];
      double v = ev(f, x, y, z);
      double want = ref_phi(s, 2 * M_PI / L[0] * (x - o[0] - L[0] / 2), 2 * M_PI / L[1] * (y - o[1] - L[1] / 2),
                            2 * M_PI / L[2] * (z - o[2] - L[2] / 2));
      if (fabs(v - want) > 1e-9) bad++;
      if (fabs(ev(f, x + L[0], y, z) - v) > 1e-9 || fabs(ev(f, x, y - L[1], z) - v) > 1e-9 ||
          fabs(ev(f, x, y, z + 2 * L[2]) - v) > 1e-9)
        badper++;
      badg += grad_mismatch(f, x, y, z, g);
      if (sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) > K) over++;
    }
    CHECK(bad == 0, "%s stretched: %d points differ from the formula", gr_tpms_name(s), bad);
    CHECK(badper == 0, "%s stretched: %d points not periodic with Lx, Ly, Lz", gr_tpms_name(s), badper);
    CHECK(badg == 0, "%s stretched: %d gradient components differ from differences", gr_tpms_name(s), badg);
    CHECK(over == 0, "%s stretched: |grad| exceeded K = %g at %d points", gr_tpms_name(s), K, over);
    double lo[3] = {-1, 0.5, 2}, hi[3] = {2, 1.5, 4};
    int n[3] = {7, 5, 4}, badgrid = 0;
    gr_grid3 *gs = gr_grid3_sample(f, lo, hi, n, &e);
    CHECK(gs != NULL, "%s", e.msg);
    for (int k = 0; gs && k < n[2]; k++)
      for (int j = 0; j < n[1]; j++)
        for (int i = 0; i < n[0]; i++)
          if (fabs(gs->v[i + n[0] * (j + n[1] * k)] - ev(f, lo[0] + i * gs->hx, lo[1] + j * gs->hy, lo[2] + k * gs->hz)) > 1e-12)
            badgrid++;
    CHECK(badgrid == 0, "%s stretched: %d grid samples differ from points", gr_tpms_name(s), badgrid);
    gr_grid3_free(gs);
    gr_tpms_info info;
    CHECK(gr_field_tpms_info(f, &info) && info.lengths[0] == L[0] && info.lengths[1] == L[1] && info.lengths[2] == L[2],
          "info gives the lengths");
    gr_field_free(f);
  }
  double c3[3] = {1.7, 1.7, 1.7}, z3[3] = {2, 0, 2};
  gr_field *a = gr_field_tpms3("gyroid", c3, NULL, 0.1, &e), *b = gr_field_tpms("gyroid", 1.7, NULL, 0.1, &e);
  int diff = 0;
  for (int k = 0; k < 200; k++) {
    double x = rnd(-5, 5), y = rnd(-5, 5), z = rnd(-5, 5);
    diff += ev(a, x, y, z) != ev(b, x, y, z);
  }
  CHECK(diff == 0, "equal lengths: %d points differ from the cubic field", diff);
  CHECK(gr_field_lipschitz(a) == gr_field_lipschitz(b), "equal lengths: the same bound");
  CHECK(!strcmp(gr_field_describe(a), gr_field_describe(b)), "equal lengths: '%s'", gr_field_describe(a));
  gr_field_free(a);
  gr_field_free(b);
  CHECK(gr_field_tpms3("gyroid", z3, NULL, 0, &e) == NULL && strstr(e.msg, "got 0"), "zero length: '%s'", e.msg);
}

TEST(expression_fields) {
  gr_err e = {0};
  gr_field *f = gr_field_expr("sqrt(x^2+y^2+z^2)-3", &e);
  CHECK(f != NULL, "%s", e.msg);
  if (!f) return;
  CHECK(!isfinite(gr_field_lipschitz(f)), "unknown bound is infinite");
  CHECK_NEAR(ev(f, 0, 0, 0), -3, 1e-15);
  CHECK_NEAR(ev(f, 3, 4, 0), 2, 1e-15);
  double g[3];
  gr1(f, 1, 2, 2, g); /* unit radial direction (1,2,2)/3 */
  CHECK_NEAR(g[0], 1.0 / 3, 1e-7);
  CHECK_NEAR(g[1], 2.0 / 3, 1e-7);
  CHECK_NEAR(g[2], 2.0 / 3, 1e-7);
  gr1(f, 300, 400, 0, g); /* far away: relative step still accurate */
  CHECK_NEAR(g[0], 0.6, 1e-5);
  CHECK_NEAR(g[1], 0.8, 1e-5);
  gr_field_free(f);
  CHECK(gr_field_expr("sin(x", &e) == NULL && strstr(e.msg, "col 6"), "'%s'", e.msg);
  CHECK(gr_field_expr("u + 1", &e) == NULL && strstr(e.msg, "'u'") && strstr(e.msg, "x, y, z"),
        "'%s'", e.msg);
  f = gr_field_expr("log(x)", &e);
  double x = -1, y = 2, z = 3, v;
  CHECK(gr_field_eval(f, 1, &x, &y, &z, &v, &e) == GR_ENUM && strstr(e.msg, "nan at x=-1, y=2, z=3"),
        "'%s'", e.msg);
  gr_field_free(f);
}

static int cb_sphere(void *ud, size_t n, const double *x, const double *y, const double *z,
                     double *out, gr_err *e) {
  double r = *(double *)ud;
  (void)e;
  for (size_t i = 0; i < n; i++) out[i] = sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i]) - r;
  return GR_OK;
}
static int cb_nan(void *ud, size_t n, const double *x, const double *y, const double *z,
                  double *out, gr_err *e) {
  (void)ud; (void)y; (void)z; (void)e;
  for (size_t i = 0; i < n; i++) out[i] = x[i] > 1 ? NAN : 0;
  return GR_OK;
}
static int freed;
static void free_cb(void *ud) { (void)ud; freed++; }

TEST(callback_fields) {
  double r = 2;
  freed = 0;
  gr_field *f = gr_field_callback(cb_sphere, NULL, &r, free_cb, 1, "ball");
  CHECK(f != NULL, "callback");
  CHECK_NEAR(ev(f, 2, 0, 0), 0, 1e-15);
  double g[3];
  gr1(f, 0, 3, 4, g);
  CHECK_NEAR(g[1], 0.6, 1e-7);
  CHECK_NEAR(g[2], 0.8, 1e-7);
  CHECK(strcmp(gr_field_describe(f), "ball") == 0, "describe");
  gr_field *m = gr_field_negate(f);
  gr_field_free(f);
  CHECK(freed == 0, "still referenced by the negation");
  CHECK_NEAR(ev(m, 0, 0, 0), 2, 1e-15);
  gr_field_free(m);
  CHECK(freed == 1, "freed once, got %d", freed);
  gr_field *bad = gr_field_callback(cb_nan, NULL, NULL, NULL, 0, "nanny");
  CHECK(!gr_field_threadsafe(bad), "not thread-safe");
  gr_field *u = gr_field_min(bad, bad);
  CHECK(!gr_field_threadsafe(u), "combination inherits");
  double x[3] = {0, 5, 0}, y[3] = {0, 0, 0}, z[3] = {0, 0, 7}, v[3];
  gr_err e = {0};
  CHECK(gr_field_eval(u, 3, x, y, z, v, &e) == GR_ENUM && strstr(e.msg, "x=5, y=0, z=0"), "'%s'", e.msg);
  gr_field_free(u);
  gr_field_free(bad);
}

TEST(combinations) {
  gr_err e = {0};
  gr_field *a = gr_field_expr("x", &e), *b = gr_field_expr("2*y", &e);
  gr_field *mn = gr_field_min(a, b), *mx = gr_field_max(a, b), *ng = gr_field_negate(a);
  gr_field *wc = gr_field_constant(0.25);
  gr_field *bl = gr_field_blend(a, b, wc);
  double d[3] = {1, 2, 3};
  gr_field *sph = gr_field_expr("sqrt(x^2+y^2+z^2)-1", &e);
  gr_field *tr = gr_field_translate(sph, d);
  gr_field *sc = gr_field_scale(sph, 3);
  CHECK_NEAR(ev(mn, 1, 3, 0), 1, 1e-15);
  CHECK_NEAR(ev(mn, 5, 1, 0), 2, 1e-15);
  CHECK_NEAR(ev(mx, 5, 1, 0), 5, 1e-15);
  CHECK_NEAR(ev(ng, 5, 1, 0), -5, 1e-15);
  CHECK_NEAR(ev(bl, 4, 2, 0), 0.75 * 4 + 0.25 * 4, 1e-15);
  CHECK_NEAR(ev(tr, 1, 2, 3), -1, 1e-15);
  CHECK_NEAR(ev(tr, 1, 2, 5), 1, 1e-15);
  CHECK_NEAR(ev(sc, 3, 0, 0), 0, 1e-15); /* sphere of radius 3 */
  CHECK_NEAR(ev(sc, 0, 0, 0), -3, 1e-15);
  double g[3];
  gr1(mn, 1, 3, 0, g);
  CHECK_NEAR(g[0], 1, 1e-6); CHECK_NEAR(g[1], 0, 1e-6);
  gr1(mn, 5, 1, 0, g);
  CHECK_NEAR(g[0], 0, 1e-6); CHECK_NEAR(g[1], 2, 1e-6);
  gr1(mx, 5, 1, 0, g);
  CHECK_NEAR(g[0], 1, 1e-6);
  gr1(ng, 5, 1, 0, g);
  CHECK_NEAR(g[0], -1, 1e-6);
  gr1(bl, 4, 2, 0, g);
  CHECK_NEAR(g[0], 0.75, 1e-6); CHECK_NEAR(g[1], 0.5, 1e-6);
  gr1(tr, 1, 2, 5, g);
  CHECK_NEAR(g[2], 1, 1e-6);
  gr1(sc, 0, 6, 0, g);
  CHECK_NEAR(g[1], 1, 1e-6);
  /* blend with a varying weight: (1-w) a + w b with w = x/10 clamped */
  gr_field *wv = gr_field_expr("x/10", &e);
  gr_field *bv = gr_field_blend(a, b, wv);
  CHECK_NEAR(ev(bv, 5, 1, 0), 0.5 * 5 + 0.5 * 2, 1e-14);
  CHECK_NEAR(ev(bv, 20, 1, 0), 2, 1e-14);
  CHECK_NEAR(ev(bv, -20, 1, 0), -20, 1e-14);
  /* d/dx [(1 - x/10) x + x/10 * 2y] = 1 - x/5 + 2y/10 at (5,1): 0.2 */
  gr1(bv, 5, 1, 0, g);
  CHECK_NEAR(g[0], 0.2, 1e-6);
  CHECK(!isfinite(gr_field_lipschitz(bv)), "varying weight: no bound");
  /* Lipschitz bounds of combinations of TPMS fields */
  gr_field *t1 = gr_field_tpms("primitive", 2, NULL, 0, &e), *t2 = gr_field_tpms("gyroid", 1, NULL, 0, &e);
  gr_field *tm = gr_field_min(t1, t2), *tb = gr_field_blend(t1, t2, wc), *ts = gr_field_scale(t1, 2);
  CHECK_NEAR(gr_field_lipschitz(tm), gr_field_lipschitz(t2), 1e-12);
  CHECK_NEAR(gr_field_lipschitz(tb), gr_field_lipschitz(t2), 1e-12);
  CHECK_NEAR(gr_field_lipschitz(ts), gr_field_lipschitz(t1), 1e-12);
  /* batch larger than a chunk, min against pointwise min */
  enum { N = 1000 };
  double *x = malloc(N * sizeof *x), *y = malloc(N * sizeof *y), *z = malloc(N * sizeof *z);
  double *v = malloc(N * sizeof *v);
  srand(4);
  for (int i = 0; i < N; i++) { x[i] = rnd(-3, 3); y[i] = rnd(-3, 3); z[i] = rnd(-3, 3); }
  CHECK(gr_field_eval(tm, N, x, y, z, v, &e) == GR_OK, "%s", e.msg);
  int bad = 0;
  for (int i = 0; i < N; i++)
    if (fabs(v[i] - fmin(ev(t1, x[i], y[i], z[i]), ev(t2, x[i], y[i], z[i]))) > 1e-14) bad++;
  CHECK(bad == 0, "%d batch values differ", bad);
  CHECK(strstr(gr_field_describe(tm), "min(primitive") != NULL, "'%s'", gr_field_describe(tm));
  CHECK(gr_field_scale(t1, 0) == NULL, "scale 0 refused");
  free(x); free(y); free(z); free(v);
  gr_field *all[] = {a, b, mn, mx, ng, wc, bl, sph, tr, sc, wv, bv, t1, t2, tm, tb, ts};
  for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) gr_field_free(all[i]);
  gr_field_free(NULL);
}

TEST(grid_sampling) {
  gr_err e = {0};
  gr_field *f = gr_field_expr("x + 10*y + 100*z", &e);
  double lo[3] = {0, -1, 2}, hi[3] = {1, 1, 3};
  int n[3] = {5, 3, 2};
  gr_grid3 *g = gr_grid3_sample(f, lo, hi, n, &e);
  CHECK(g != NULL, "%s", e.msg);
  if (g) {
    CHECK(g->nx == 5 && g->ny == 3 && g->nz == 2, "dims");
    CHECK_NEAR(g->hx, 0.25, 1e-15);
    int bad = 0;
    for (int k = 0; k < 2; k++)
      for (int j = 0; j < 3; j++)
        for (int i = 0; i < 5; i++) {
          double want = 0.25 * i + 10 * (-1 + j) + 100 * (2 + k);
          if (fabs(g->v[i + 5 * (j + 3 * k)] - want) > 1e-12) bad++;
        }
    CHECK(bad == 0, "%d samples wrong", bad);
  }
  gr_grid3_free(g);
  /* larger than one sampling chunk */
  int n2[2] = {101, 77};
  double lo2[2] = {-1, -2}, hi2[2] = {1, 2};
  gr_grid2 *p = gr_grid2_sample(f, 0.5, lo2, hi2, n2, &e);
  CHECK(p != NULL, "%s", e.msg);
  if (p) {
    int bad = 0;
    for (int j = 0; j < 77; j++)
      for (int i = 0; i < 101; i++) {
        double want = (-1 + i * 0.02) + 10 * (-2 + j * 4.0 / 76) + 50;
        if (fabs(p->v[i + 101 * j] - want) > 1e-11) bad++;
      }
    CHECK(bad == 0, "%d samples wrong", bad);
  }
  gr_grid2_free(p);
  /* TPMS grids (their own fast path) agree with point evaluation */
  for (int s = 0; s < gr_tpms_count(); s++) {
    double o[3] = {0.3, -0.2, 0.1};
    gr_field *t = gr_field_tpms(gr_tpms_name(s), 1.7, o, 0.1, &e);
    double tlo[3] = {-1, -2, 0.5}, thi[3] = {2, 1, 2.5};
    int tn[3] = {13, 11, 7};
    gr_grid3 *tg = gr_grid3_sample(t, tlo, thi, tn, &e);
    gr_grid2 *tp = gr_grid2_sample(t, 0.77, tlo, thi, tn, &e);
    int bad = 0;
    for (int k = 0; k < 7; k++)
      for (int j = 0; j < 11; j++)
        for (int i = 0; i < 13; i++) {
          double px = tlo[0] + i * 0.25, py = tlo[1] + j * 0.3, pz = tlo[2] + k * (2.0 / 6);
          if (fabs(tg->v[i + 13 * (j + 11 * k)] - ev(t, px, py, pz)) > 1e-12) bad++;
          if (k == 0 && fabs(tp->v[i + 13 * j] - ev(t, px, py, 0.77)) > 1e-12) bad++;
        }
    CHECK(bad == 0, "%s: %d grid samples differ from eval", gr_tpms_name(s), bad);
    gr_grid3_free(tg);
    gr_grid2_free(tp);
    gr_field_free(t);
  }
  int big[3] = {2000, 2000, 2000};
  CHECK(gr_grid3_sample(f, lo, hi, big, &e) == NULL && e.code == GR_EMEM, "big refused");
  CHECK(strstr(e.msg, "2000 x 2000 x 2000") && strstr(e.msg, "61035 MB"), "'%s'", e.msg);
  int one[3] = {1, 5, 5};
  CHECK(gr_grid3_sample(f, lo, hi, one, &e) == NULL && e.code == GR_EARG && strstr(e.msg, "got 1"),
        "'%s'", e.msg);
  double hi_bad[3] = {0, 1, 3};
  CHECK(gr_grid3_sample(f, lo, hi_bad, n, &e) == NULL && e.code == GR_EARG, "hi == lo refused");
  gr_grid3_free(NULL);
  gr_grid2_free(NULL);
  gr_field_free(f);
}

/* gr_field_plane (marching cubes samples H's field a plane at a time with
 * it): the values gr_field_eval gives at the same points, bit for bit, for
 * every catalogue TPMS in a cubic and a stretched cell with a level, and an
 * expression field (chunked evaluation); bad arguments refused. */
TEST(plane_sampling) {
  gr_err e = {0};
  enum { NX = 37, NY = 29 };
  double lo[2] = {-0.7, 0.3}, h[2] = {0.061, 0.047}, z = 0.913, px[NX * NY], py[NX * NY], pz[NX * NY];
  double got[NX * NY], want[NX * NY];
  int n[2] = {NX, NY};
  for (int j = 0; j < NY; j++)
    for (int i = 0; i < NX; i++) px[i + NX * j] = lo[0] + i * h[0], py[i + NX * j] = lo[1] + j * h[1], pz[i + NX * j] = z;
  for (int s = 0; s <= gr_tpms_count(); s++)
    for (int st = 0; st < 2; st++) {
      double cell[3] = {2, st ? 3 : 2, st ? 2.5 : 2}, o[3] = {0.3, -0.2, 0.1};
      gr_field *f = s < gr_tpms_count() ? gr_field_tpms3(gr_tpms_name(s), cell, o, 0.2, &e)
                                        : gr_field_expr("sin(x) * y + 0.1 * z", &e);
      CHECK(f != NULL, "%s", e.msg);
      if (!f) continue;
      int ok = gr_field_plane(f, z, lo, h, n, got, &e) == GR_OK && gr_field_eval(f, NX * NY, px, py, pz, want, &e) == GR_OK;
      CHECK(ok, "%s", e.msg);
      int bad = 0;
      for (int k = 0; k < NX * NY && ok; k++) bad += memcmp(&got[k], &want[k], sizeof got[k]) != 0;
      CHECK(bad == 0, "%s (%s cell): %d of %d plane samples differ from gr_field_eval",
            s < gr_tpms_count() ? gr_tpms_name(s) : "expression", st ? "stretched" : "cubic", bad, NX * NY);
      if (s == 0 && st == 0) {
        int zero[2] = {0, 5};
        CHECK(gr_field_plane(f, z, lo, h, zero, got, &e) == GR_EARG && strstr(e.msg, "0 x 5"), "'%s'", e.msg);
        CHECK(gr_field_plane(f, z, lo, h, n, NULL, &e) == GR_EARG, "no output refused");
      }
      gr_field_free(f);
    }
}

/* Several threads evaluate one shared combination at once; each must get the
 * serial result (no shared mutable state in fields or expressions). */
enum { TN = 20000, NTHREADS = 4 };
typedef struct job { const gr_field *f; const double *x, *y, *z; double *out; int rc; } job;
static void *job_run(void *p) {
  job *j = p;
  gr_err e = {0};
  j->rc = gr_field_eval(j->f, TN, j->x, j->y, j->z, j->out, &e);
  return NULL;
}

TEST(concurrent_evaluation) {
  gr_err e = {0};
  gr_field *a = gr_field_tpms("gyroid", 2, NULL, 0, &e), *b = gr_field_expr("sin(x)*y - z/3", &e);
  gr_field *w = gr_field_expr("x/6 + 0.5", &e), *f = gr_field_blend(a, b, w);
  CHECK(gr_field_threadsafe(f), "thread-safe");
  double *x = malloc(TN * sizeof *x), *y = malloc(TN * sizeof *y), *z = malloc(TN * sizeof *z);
  double *ref = malloc(TN * sizeof *ref), *out[NTHREADS];
  srand(5);
  for (int i = 0; i < TN; i++) { x[i] = rnd(-3, 3); y[i] = rnd(-3, 3); z[i] = rnd(-3, 3); }
  CHECK(gr_field_eval(f, TN, x, y, z, ref, &e) == GR_OK, "%s", e.msg);
  pthread_t th[NTHREADS];
  job jobs[NTHREADS];
  for (int t = 0; t < NTHREADS; t++) {
    out[t] = malloc(TN * sizeof *out[t]);
    jobs[t] = (job){f, x, y, z, out[t], -1};
    pthread_create(&th[t], NULL, job_run, &jobs[t]);
  }
  for (int t = 0; t < NTHREADS; t++) {
    pthread_join(th[t], NULL);
    CHECK(jobs[t].rc == GR_OK, "thread %d failed", t);
    CHECK(memcmp(out[t], ref, TN * sizeof *ref) == 0, "thread %d differs from the serial result", t);
    free(out[t]);
  }
  free(x); free(y); free(z); free(ref);
  gr_field_free(a); gr_field_free(b); gr_field_free(w); gr_field_free(f);
}

/* gr_field_hess_fd: the stretched gyroid's and primitive's Hessians against
 * their second derivatives written out (X = w (x - o - L/2), w = 2 pi / L per
 * axis); an expression's against its exact Hessian. */
TEST(hessian) {
  srand(11);
  gr_err e = {0};
  double L[3] = {1.7, 2.4, 3.1}, o[3] = {0.3, -0.2, 1.1}, w[3];
  for (int a = 0; a < 3; a++) w[a] = 2 * M_PI / L[a];
  gr_field *gy = gr_field_tpms3("gyroid", L, o, 0.2, &e), *pr = gr_field_tpms3("primitive", L, o, 0, &e);
  gr_field *ex = gr_field_expr("x*x*y + z*y - 2*z*z*z", &e);
  CHECK(gy && pr && ex, "%s", e.msg);
  if (!gy || !pr || !ex) return;
  int bad = 0, bade = 0, badv = 0;
  double worst = 0, worste = 0;
  for (int k = 0; k < 200; k++) {
    double p[3] = {rnd(-4, 4), rnd(-4, 4), rnd(-4, 4)}, X[3], sn[3], cs[3];
    for (int a = 0; a < 3; a++) {
      X[a] = w[a] * (p[a] - o[a] - L[a] / 2);
      sn[a] = sin(X[a]);
      cs[a] = cos(X[a]);
    }
    /* gyroid: phi = cx sy + cy sz + cz sx; primitive: cx + cy + cz */
    double Hg[3][3] = {{-cs[0] * sn[1] - cs[2] * sn[0], -sn[0] * cs[1], -sn[2] * cs[0]},
                       {-sn[0] * cs[1], -cs[0] * sn[1] - cs[1] * sn[2], -sn[1] * cs[2]},
                       {-sn[2] * cs[0], -sn[1] * cs[2], -cs[1] * sn[2] - cs[2] * sn[0]}};
    double Hp[3][3] = {{-cs[0], 0, 0}, {0, -cs[1], 0}, {0, 0, -cs[2]}};
    double He[3][3] = {{2 * p[1], 2 * p[0], 0}, {2 * p[0], 0, 1}, {0, 1, -12 * p[2]}};
    const gr_field *fs[3] = {gy, pr, ex};
    for (int q = 0; q < 3; q++) {
      double v, g[3], hs[3][3], gg[3];
      if (gr_field_hess_fd(fs[q], p, 1e-6, &v, g, hs, &e)) { bad++; continue; }
      gr1(fs[q], p[0], p[1], p[2], gg);
      if (fabs(v - ev(fs[q], p[0], p[1], p[2])) > 1e-12 || fabs(g[0] - gg[0]) + fabs(g[1] - gg[1]) + fabs(g[2] - gg[2]) > 1e-9)
        badv++;
      for (int a = 0; a < 3; a++)
        for (int c = 0; c < 3; c++) {
          double want = q == 2 ? He[a][c] : w[a] * w[c] * (q == 0 ? Hg : Hp)[a][c];
          double err = fabs(hs[a][c] - want) / (1 + fabs(want));
          if (q < 2 && err > worst) worst = err;
          if (q == 2 && err > worste) worste = err;
          if (err > (q == 2 ? 1e-2 : 1e-4)) *(q == 2 ? &bade : &bad) += 1;
        }
    }
  }
  CHECK(badv == 0, "%d values or gradients differ from gr_field_eval / gr_field_grad", badv);
  /* forward differences with h = 1e-6 mm: error about h |third derivative| / 2, 2.5e-5 relative here */
  CHECK(bad == 0, "%d TPMS Hessian entries off the analytic ones by > 1e-4 (worst relative %.3g)", bad, worst);
  /* an expression's gradient is itself by central differences: coarser */
  CHECK(bade == 0, "%d expression Hessian entries off by > 1e-2 (worst relative %.3g)", bade, worste);
  double v, g[3], hs[3][3], p0[3] = {0, 0, 0};
  CHECK(gr_field_hess_fd(gy, p0, 0, &v, g, hs, &e) == GR_EARG, "a step of 0 is refused");
  gr_field_free(gy);
  gr_field_free(pr);
  gr_field_free(ex);
}

/* gr_field_move_grad: a point followed through a chain of moves (small ones
 * by the angle-addition rule, a large one by libm) gives the value and
 * gradient that gr_field_eval_grad gives at the point reached, for every
 * catalogue surface (stretched cell, shifted level) and for an expression. */
TEST(moved_points) {
  srand(12);
  gr_err e = {0};
  double L[3] = {1.7, 2.4, 3.1}, o[3] = {0.3, -0.2, 1.1};
  const char *names[] = {"primitive", "gyroid", "diamond", "iwp", "neovius", "frd", "fischer_koch_s", "lidinoid",
                         "split_p", "octo"};
  int bad = 0, tried = 0;
  double worst = 0;
  for (int s = 0; s <= 10; s++) {
    gr_field *f = s < 10 ? gr_field_tpms3(names[s], L, o, 0.1, &e) : gr_field_expr("x*x*y + z*y - 2*z*z*z", &e);
    CHECK(f != NULL, "%s", e.msg);
    if (!f) continue;
    for (int k = 0; k < 50; k++) {
      double p[3] = {rnd(-4, 4), rnd(-4, 4), rnd(-4, 4)}, v, g[3], hs[3][3];
      gr_field_at at;
      if (gr_field_hess_fd_at(f, p, 1e-6, &v, g, hs, &at, &e)) { bad++; continue; }
      /* steps from 1e-9 mm to 0.2 mm: both sides of the 0.1-radian switch */
      const double sizes[5] = {1e-9, 1e-5, 3e-3, 0.02, 0.2};
      for (int m = 0; m < 5; m++) {
        double dp[3] = {rnd(-1, 1) * sizes[m], rnd(-1, 1) * sizes[m], rnd(-1, 1) * sizes[m]}, gm[3], gw[3], vm, vw;
        for (int a = 0; a < 3; a++) p[a] += dp[a];
        tried++;
        if (gr_field_move_grad(f, &at, dp, &vm, gm, &e) ||
            gr_field_eval_grad(f, 1, &p[0], &p[1], &p[2], &vw, &gw[0], &gw[1], &gw[2], &e)) { bad++; continue; }
        double err = fabs(vm - vw);
        for (int a = 0; a < 3; a++) err = fmax(err, fabs(gm[a] - gw[a]) + fabs(at.p[a] - p[a]));
        worst = fmax(worst, err);
        if (err > 1e-11) bad++;
      }
    }
    gr_field_free(f);
  }
  CHECK(bad == 0, "%d of %d moved points differ from gr_field_eval_grad by > 1e-11 (worst %.3g)", bad, tried, worst);
}

/* gr_field_grad_at_n (the sines and cosines of a batch at once, from
 * libmvec) against gr_field_grad_at point by point: value and gradient
 * within 1e-13 for every surface and batch lengths 1-300, the remembered
 * point and phases right (moving on from them gives gr_field_grad_at's
 * value at the new point), and an expression field through the same call. */
TEST(gradients_at_many_points) {
  gr_err e;
  enum { N = 300 };
  double p[3 * N], v[N], g[3 * N], o[3] = {-0.3, 0.2, 0.7};
  gr_field_at at[N];
  for (int i = 0; i < N; i++)
    for (int a = 0; a < 3; a++) p[3 * i + a] = -5 + 10.0 * ((i * 37 + a * 101) % 997) / 997.0;
  double worst = 0, worst_move = 0;
  for (int s = 0; s < 10; s++) {
    gr_field *f = gr_field_tpms(gr_tpms_name(s), 2.3, o, 0.1, &e);
    CHECK(f != NULL, "%s: %s", gr_tpms_name(s), e.msg);
    if (!f) continue;
    for (int n = 1; n <= N; n += n < 9 ? 1 : 97) {
      CHECK(gr_field_grad_at_n(f, (size_t)n, p, v, g, at, &e) == GR_OK, "%s, %d points: %s", gr_tpms_name(s), n, e.msg);
      for (int i = 0; i < n; i++) {
        double v1, g1[3];
        gr_field_at a1;
        gr_field_grad_at(f, p + 3 * i, &v1, g1, &a1, &e);
        worst = fmax(worst, fabs(v[i] - v1));
        for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(g[3 * i + c] - g1[c]));
        double dp[3] = {1e-3, -2e-3, 5e-4}, q[3] = {p[3 * i] + dp[0], p[3 * i + 1] + dp[1], p[3 * i + 2] + dp[2]};
        double vm, gm[3], v2, g2[3];
        gr_field_move_grad(f, &at[i], dp, &vm, gm, &e);
        gr_field_grad_at(f, q, &v2, g2, &a1, &e);
        worst_move = fmax(worst_move, fabs(vm - v2));
      }
    }
    gr_field_free(f);
  }
  printf("  info: batch against point by point: %.3g (value, gradient), %.3g after a move\n", worst, worst_move);
  CHECK(worst < 1e-13, "batched values or gradients differ by %g", worst);
  CHECK(worst_move < 1e-12, "a move from the batch's phases differs by %g", worst_move);
  gr_field *x = gr_field_expr("x*x + 2*y - z", &e);
  CHECK(x && gr_field_grad_at_n(x, 3, p, v, g, at, &e) == GR_OK, "expression field: %s", e.msg);
  if (x) {
    double want = p[3] * p[3] + 2 * p[4] - p[5];
    CHECK(fabs(v[1] - want) < 1e-12 && fabs(g[3] - 2 * p[3]) < 1e-5 && fabs(g[4] - 2) < 1e-5,
          "expression field at point 2: %g (want %g), gradient %g %g", v[1], want, g[3], g[4]);
  }
  gr_field_free(x);
}

/* Many points in one call take their sines and cosines from the vector math
 * library (vecmath.h), a chunk at a time: values and gradients must match
 * the formulas (libm, one point at a time) at every point of a batch longer
 * than a chunk, whatever its length modulo the vector width, and a point
 * evaluated alone must give its batch's value to the bit. */
TEST(batches_match_formulas) {
  srand(5);
  gr_err e = {0};
  enum { N = 1003 };
  static double x[N], y[N], z[N], v[N], v2[N], gx[N], gy[N], gz[N], hx[N], hy[N], hz[N];
  for (int s = 0; s < 10; s++) {
    double L = rnd(0.5, 5), o[3] = {rnd(-3, 3), rnd(-3, 3), rnd(-3, 3)}, w = 2 * M_PI / L, lv = rnd(-0.3, 0.3);
    gr_field *f = gr_field_tpms(gr_tpms_name(s), L, o, lv, &e);
    CHECK(f != NULL, "%s", e.msg);
    if (!f) continue;
    for (int i = 0; i < N; i++) { x[i] = rnd(-50, 50); y[i] = rnd(-50, 50); z[i] = rnd(-50, 50); }
    int ok = !gr_field_eval(f, N, x, y, z, v, &e) && !gr_field_eval_grad(f, N, x, y, z, v2, gx, gy, gz, &e) &&
             !gr_field_grad(f, N, x, y, z, hx, hy, hz, &e);
    CHECK(ok, "%s: %s", gr_tpms_name(s), e.msg);
    double dv = 0, dg = 0, dsame = 0;
    for (int i = 0; i < N && ok; i++) {
      double X = w * (x[i] - o[0] - L / 2), Y = w * (y[i] - o[1] - L / 2), Z = w * (z[i] - o[2] - L / 2), k = 1e-6;
      dv = fmax(dv, fabs(v[i] - (ref_phi(s, X, Y, Z) - lv)));
      double fd[3] = {(ref_phi(s, X + k, Y, Z) - ref_phi(s, X - k, Y, Z)) / (2 * k) * w,
                      (ref_phi(s, X, Y + k, Z) - ref_phi(s, X, Y - k, Z)) / (2 * k) * w,
                      (ref_phi(s, X, Y, Z + k) - ref_phi(s, X, Y, Z - k)) / (2 * k) * w};
      dg = fmax(dg, fmax(fabs(gx[i] - fd[0]), fmax(fabs(gy[i] - fd[1]), fabs(gz[i] - fd[2]))));
      dsame = fmax(dsame, fmax(fabs(v2[i] - v[i]), fmax(fabs(hx[i] - gx[i]), fmax(fabs(hy[i] - gy[i]), fabs(hz[i] - gz[i])))));
    }
    CHECK(dv < 1e-12, "%s: values off the formula by %g", gr_tpms_name(s), dv); /* a few ulp of values up to 13 */
    /* a point's value does not depend on the batch it comes in: alone, the same bits */
    int moved = 0;
    for (int i = 0; i < N && ok; i += 7) {
      double one = ev(f, x[i], y[i], z[i]);
      moved += memcmp(&one, &v[i], sizeof one) != 0;
    }
    CHECK(moved == 0, "%s: %d points evaluated alone differ from their batch's value", gr_tpms_name(s), moved);
    CHECK(dg < 1e-7 * (1 + w), "%s: gradients off the formula's differences by %g", gr_tpms_name(s), dg);
    CHECK(dsame == 0, "%s: eval, eval_grad and grad disagree by %g", gr_tpms_name(s), dsame);
    gr_field_free(f);
  }
}

int main(void) {
  RUN(catalogue_names);
  RUN(primitive_known_points);
  RUN(all_surfaces_match_formulas_and_symmetries);
  RUN(gradients_and_lipschitz);
  RUN(stretched_surfaces);
  RUN(expression_fields);
  RUN(callback_fields);
  RUN(combinations);
  RUN(grid_sampling);
  RUN(plane_sampling);
  RUN(concurrent_evaluation);
  RUN(hessian);
  RUN(moved_points);
  RUN(gradients_at_many_points);
  RUN(batches_match_formulas);
  DONE();
}
