/* test_domain.c: a domain field made a signed distance (domain.h), against
 * the analytic distance to a cylinder written squared, batched over many
 * points (inside and outside the band), a field that is a distance already
 * kept as it is, and NaN from the domain reported as the domain's; the
 * domain on a plane grid near its boundary only (gr_domain_grid) against
 * the domain evaluated at every node; the local key of an STL domain's
 * boundary (gr_domain_local_key): equal for boxes translated along a face,
 * whatever the triangulation, different where the boundary differs. */
#include <math.h>
#include <string.h>
#include "domain.h"
#include "solid.h"
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

/* The box lo..hi as a closed mesh; split: its bottom face (z = lo) cut into
 * four triangles about its centre instead of two. */
static gr_mesh *box_mesh(const double lo[3], const double hi[3], int split) {
  static const int F[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                               {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  gr_mesh *m = gr_mesh_new();
  for (int v = 0; v < 8; v++) gr_mesh_add_vertex(m, v & 1 ? hi[0] : lo[0], v & 2 ? hi[1] : lo[1], v & 4 ? hi[2] : lo[2]);
  for (int f = split ? 2 : 0; f < 12; f++) gr_mesh_add_face(m, F[f][0], F[f][1], F[f][2]);
  if (split) { /* bottom, seen from below: 0, 2, 3, 1 */
    gr_mesh_add_vertex(m, 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]);
    static const int R[4] = {0, 2, 3, 1};
    for (int k = 0; k < 4; k++) gr_mesh_add_face(m, 8, R[k], R[(k + 1) % 4]);
  }
  return m;
}

static gr_field *box_solid(double lo0, double lo1, int split) {
  double lo[3] = {lo0, lo1, 0}, hi[3] = {12, 4, 2};
  gr_mesh *m = box_mesh(lo, hi, split);
  gr_err e;
  gr_err_clear(&e);
  gr_field *f = gr_solid_field(m, &e);
  CHECK(f != NULL, "%s", e.msg);
  gr_mesh_free(m);
  return f;
}

/* key of f in the window lo..hi about origin (ox, oy, oz); "" when none */
static void key_at(const gr_field *f, const double lo[3], const double hi[3], double ox, double oy, double oz, char k[65]) {
  double o[3] = {ox, oy, oz};
  gr_err e;
  gr_err_clear(&e);
  int rc = gr_domain_local_key(f, lo, hi, o, k, &e);
  CHECK(rc >= 0, "%s", e.msg);
  if (rc != 1) k[0] = 0;
}

TEST(local_key_of_a_box) {
  gr_field *A = box_solid(0, 0, 0), *B = box_solid(0, 0, 1), *C = box_solid(0, 1e-5, 0);
  /* a voxel's window: 2 mm grown by 1 mm, z by 0.5 mm (the box is 2 mm high) */
  double lo[3] = {-1, -1, -0.5}, hi[3] = {3, 3, 2.5};
  char a2[65], a4[65], a5[65], a0[65], b2[65], b5[65], c2[65], x[65];
  key_at(A, lo, hi, 2, 0, 0, a2);
  key_at(A, lo, hi, 4, 0, 0, a4);
  key_at(A, lo, hi, 5, 0, 0, a5);
  key_at(A, lo, hi, 0, 0, 0, a0);
  key_at(B, lo, hi, 2, 0, 0, b2);
  key_at(B, lo, hi, 5, 0, 0, b5); /* its window holds the split face's centre vertex (6, 2, 0) */
  key_at(C, lo, hi, 2, 0, 0, c2);
  CHECK(strlen(a2) == 64, "a box of an STL solid has a key");
  CHECK(!strcmp(a2, a4) && !strcmp(a2, a5), "windows translated along the faces y = 0, z = 0 and 2 share a key");
  CHECK(strcmp(a2, a0) != 0, "the window at x = 0 holds the face x = 0 too: another key");
  CHECK(!strcmp(a2, b2) && !strcmp(a2, b5), "the bottom cut into four triangles is the same boundary");
  CHECK(strcmp(a2, c2) != 0, "the face y = 0 moved by 10 nm is another boundary");
  /* windows with no boundary: inside ones share, an outside one differs */
  double l2[3] = {0, 0, 0}, h2[3] = {0.5, 0.5, 0.5};
  char in1[65], in2[65];
  key_at(A, l2, h2, 5, 1.5, 0.7, in1);
  key_at(A, l2, h2, 7, 1.5, 0.7, in2);
  key_at(A, l2, h2, 20, 1.5, 0.7, x);
  CHECK(strlen(in1) == 64 && !strcmp(in1, in2), "two windows wholly inside share a key");
  CHECK(strcmp(in1, x) != 0, "a window wholly outside has another key");
  /* an expression domain has none */
  gr_err e;
  gr_err_clear(&e);
  gr_field *ex = gr_field_expr("x - 5", &e);
  key_at(ex, lo, hi, 2, 0, 0, x);
  CHECK(x[0] == 0, "an expression domain has no key");
  gr_field_free(ex);
  gr_field_free(A);
  gr_field_free(B);
  gr_field_free(C);
}

int main(void) {
  RUN(cylinder_squared);
  RUN(distance_probed_over_box);
  RUN(distance_kept_nan_named);
  RUN(grid_near_boundary_only);
  RUN(local_key_of_a_box);
  DONE();
}
