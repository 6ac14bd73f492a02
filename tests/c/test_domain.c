/* test_domain.c: a domain field made a signed distance (domain.h), against
 * the analytic distance to a cylinder written squared, batched over many
 * points (inside and outside the band), a field that is a distance already
 * kept as it is, and NaN from the domain reported as the domain's; the
 * domain on a plane grid near its boundary only (gr_domain_grid) against
 * the domain evaluated at every node. */
#include <math.h>
#include <string.h>
#include "domain.h"
#include "check.h"

TEST(cylinder_squared) {
  gr_err e;
  gr_err_clear(&e);
  gr_field *f = gr_field_expr("100*((x-5)^2+(y-5)^2-16)", &e);
  gr_field *d = gr_domain_distance(f, 1.5, 2, NULL, &e);
  CHECK(d != NULL, "%s", e.msg);
  enum { N = 300 };
  double x[N], y[N], z[N], out[N];
  for (int i = 0; i < N; i++) {
    double r = 2.7 + 3.0 * i / (N - 1), a = 0.37 * i;
    x[i] = 5 + r * cos(a), y[i] = 5 + r * sin(a), z[i] = 0.1 * i;
  }
  CHECK(gr_field_eval(d, N, x, y, z, out, &e) == GR_OK, "%s", e.msg);
  int near = 0;
  for (int i = 0; i < N; i++) {
    double r = hypot(x[i] - 5, y[i] - 5), est = fabs(r * r - 16) / (2 * r);
    CHECK((out[i] < 0) == (r < 4), "sign at r = %g", r);
    if (est < 1.5) {
      near++;
      CHECK_NEAR(out[i], r - 4, 1e-9);
    } else {
      CHECK(fabs(out[i]) >= 1.5, "beyond the band: |%g| >= 1.5 at r = %g", out[i], r);
    }
  }
  CHECK(near > 100 && near < N, "points in the band: %d", near);
  gr_field_free(d);
  gr_field_free(f);
}

TEST(distance_kept_nan_named) {
  gr_err e;
  gr_err_clear(&e);
  gr_field *s = gr_field_constant(0);
  gr_field_set_lipschitz(s, 1);
  gr_field *d = gr_domain_distance(s, 1, 2, NULL, &e);
  CHECK(d == s, "a field with Lipschitz bound 1 is kept");
  gr_field_free(d);
  gr_field_free(s);
  gr_field *f = gr_field_expr("sqrt(x-1)-0.5", &e);
  d = gr_domain_distance(f, 1, 2, NULL, &e);
  double x = 0.5, y = 0, z = 0, v;
  CHECK(gr_field_eval(d, 1, &x, &y, &z, &v, &e) != GR_OK, "NaN refused");
  CHECK(strncmp(e.msg, "domain: ", 8) == 0, "message: %s", e.msg);
  CHECK(gr_domain_distance(f, 0, 2, NULL, &e) == NULL && e.code == GR_EARG, "band 0 refused");
  gr_field_free(d);
  gr_field_free(f);
}

/* Over a box: planes and spheres joined by min, max and abs are distances
 * already (kept: the same field); a squared form and a scaled distance are
 * wrapped, and the scaled one then gives the distance in mm. */
TEST(distance_probed_over_box) {
  gr_err e;
  gr_err_clear(&e);
  const double box[6] = {0, 0, 0, 10, 10, 6};
  const char *kept[] = {"min(max(abs(x-5)-4,abs(y-2)-1,abs(z-3)-3),max(abs(x-5)-1,abs(y-6)-4,abs(z-3)-3))",
                        "max(sqrt((x-5)^2+(y-5)^2)-4,abs(z-3)-2)"};
  for (int i = 0; i < 2; i++) {
    gr_field *f = gr_field_expr(kept[i], &e);
    gr_field *d = gr_domain_distance(f, 1, 2, box, &e);
    CHECK(d == f, "a distance already is kept: %s", kept[i]);
    gr_field_free(d);
    gr_field_free(f);
  }
  gr_field *f = gr_field_expr("3*(sqrt((x-5)^2+(y-5)^2)-4)", &e);
  gr_field *d = gr_domain_distance(f, 1, 2, box, &e);
  CHECK(d != NULL && d != f, "a scaled distance is wrapped");
  double x = 5 + 3.7, y = 5, z = 1, v = 0;
  CHECK(d && gr_field_eval(d, 1, &x, &y, &z, &v, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(v, -0.3, 1e-9);
  gr_field_free(d);
  gr_field_free(f);
  const double empty[6] = {0, 0, 0, 10, 0, 6};
  f = gr_field_expr("x^2-1", &e);
  CHECK(gr_domain_distance(f, 1, 2, empty, &e) == NULL && e.code == GR_EARG, "an empty box refused: %s", e.msg);
  gr_field_free(f);
}


/* gr_domain_grid against d at every node: the same sign everywhere, the
 * exact value at the nodes not marked far and within skin + 3h of the
 * boundary, elsewhere a magnitude between skin + 3h and |d|; at a point of
 * each cell with four far corners, |d| > skin + 1.5h with their sign.
 * Returns the share of nodes not evaluated (far). */
static double grid_check(const gr_field *d, double skin, int NX, int NY, const char *what) {
  gr_err e;
  gr_err_clear(&e);
  enum { N = 202 * 198 };
  double x0 = 0.013, y0 = -0.021, hx = 0.05, hy = 0.0501, z = 0.3, near = skin + 3 * 0.0501;
  static double dv[N], full[N], x[N], y[N], zz[N], cx[N], cy[N], cv[N];
  static unsigned char far[N];
  static int cn[N];
  if (NX * NY > N) return 0;
  for (int j = 0; j < NY; j++)
    for (int i = 0; i < NX; i++) x[i + NX * j] = x0 + i * hx, y[i + NX * j] = y0 + j * hy, zz[i + NX * j] = z;
  CHECK(gr_domain_grid(d, skin, z, x0, y0, hx, hy, NX, NY, dv, far, &e) == GR_OK, "%s: %s", what, e.msg);
  CHECK(gr_field_eval(d, NX * NY, x, y, zz, full, &e) == GR_OK, "%s: %s", what, e.msg);
  int bad_sign = 0, bad_near = 0, bad_far = 0, skipped = 0, nc = 0, bad_cell = 0;
  for (int n = 0; n < NX * NY; n++) {
    bad_sign += (dv[n] < 0) != (full[n] < 0);
    if (!far[n] || fabs(full[n]) <= near) bad_near += dv[n] != full[n];
    else bad_far += !(fabs(dv[n]) <= fabs(full[n]) + 1e-12 && fabs(dv[n]) > near);
    skipped += far[n];
  }
  /* a point of every cell with four far corners (at 0.3, 0.8 of the cell) */
  for (int j = 0; j + 1 < NY; j++)
    for (int i = 0; i + 1 < NX; i++) {
      int n = i + NX * j;
      if (far[n] && far[n + 1] && far[n + NX] && far[n + NX + 1])
        cx[nc] = x[n] + 0.3 * hx, cy[nc] = y[n] + 0.8 * hy, cn[nc++] = n;
    }
  CHECK(gr_field_eval(d, nc, cx, cy, zz, cv, &e) == GR_OK, "%s: %s", what, e.msg);
  for (int k = 0; k < nc; k++) bad_cell += !(fabs(cv[k]) > skin + 1.5 * hy && (cv[k] < 0) == (dv[cn[k]] < 0));
  CHECK(bad_sign == 0, "%s: %d nodes with the wrong sign", what, bad_sign);
  CHECK(bad_near == 0, "%s: %d nodes evaluated or within %g mm of the boundary not exact", what, bad_near, near);
  CHECK(bad_far == 0, "%s: %d far nodes outside (%g mm, |d|]", what, bad_far, near);
  CHECK(bad_cell == 0, "%s: %d of %d points in far cells within skin + 1.5h or of another sign", what, bad_cell, nc);
  printf("    %s: %.0f %% of the nodes not evaluated\n", what, 100.0 * skipped / (NX * NY));
  return (double)skipped / (NX * NY);
}

TEST(grid_near_boundary_only) {
  gr_err e;
  gr_err_clear(&e);
  /* an expression that is a distance (bound from its gradients) */
  gr_field *f = gr_field_expr("sqrt((x-5)^2+(y-5)^2)-4", &e);
  double s = grid_check(f, 0.3, 202, 198, "cylinder expression");
  CHECK(s > 0.6, "cylinder expression: %.0f %% of the nodes not evaluated", 100 * s);
  /* the same with a known bound 1, no skin */
  gr_field_set_lipschitz(f, 1);
  s = grid_check(f, 0, 202, 198, "cylinder, bound 1");
  CHECK(s > 0.8, "cylinder, bound 1: %.0f %% not evaluated", 100 * s);
  gr_field_free(f);
  /* the distance wrapper of a squared form (its zero set meshed over a box) */
  f = gr_field_expr("(x-2.5)^2+(y-2.5)^2-2.25", &e);
  const double box[6] = {0, 0, 0, 5, 5, 0.6};
  gr_field *d = gr_domain_distance(f, 0.8, 2, box, &e);
  CHECK(d && gr_domain_is_distance(d), "wrapped: %s", e.msg);
  s = d ? grid_check(d, 0.1, 101, 99, "distance wrapper") : 0;
  CHECK(s > 0.4, "distance wrapper: %.0f %% not evaluated", 100 * s);
  gr_field_free(d);
  gr_field_free(f);
  /* NaN at block centres past the window's last nodes: every node evaluated */
  f = gr_field_expr("sqrt(10.07-x)-2", &e);
  s = grid_check(f, 0.3, 202, 198, "NaN past the window");
  CHECK(s == 0, "NaN past the window: %.0f %% not evaluated", 100 * s);
  gr_field_free(f);
}

int main(void) {
  RUN(cylinder_squared);
  RUN(distance_probed_over_box);
  RUN(distance_kept_nan_named);
  RUN(grid_near_boundary_only);
  DONE();
}
