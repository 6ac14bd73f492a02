/* gr_polydist_within (issue 14): the yes/no query "is the boundary within r"
 * agrees with |gr_polydist_at| <= r everywhere, with and without an edge
 * hint carried from query to query (any edge, often a wrong one), and with
 * the analytic distance to a unit square and to a square with a square
 * hole. */
#include "check.h"
#include "slice.h"

static gr_rings *squares(int hole) {
  gr_rings *r = gr_rings_new();
  double outer[] = {0, 0, 1, 0, 1, 1, 0, 1}, inner[] = {0.3, 0.3, 0.3, 0.7, 0.7, 0.7, 0.7, 0.3};
  for (int k = 0; k < 4; k++) gr_rings_point(r, outer[2 * k], outer[2 * k + 1]);
  gr_rings_close(r);
  if (hole) {
    for (int k = 0; k < 4; k++) gr_rings_point(r, inner[2 * k], inner[2 * k + 1]);
    gr_rings_close(r);
  }
  gr_err e;
  gr_err_clear(&e);
  gr_rings_nest(r, &e);
  return r;
}

TEST(within_matches_the_distance) {
  for (int hole = 0; hole < 2; hole++) {
    gr_rings *r = squares(hole);
    gr_err e;
    gr_err_clear(&e);
    gr_polydist *pd = gr_polydist_new(r, 0.05, &e);
    CHECK(pd != NULL, "%s", e.msg);
    int bad = 0, badh = 0, n = 0;
    size_t hint = (size_t)-1;
    const double radii[] = {0, 0.01, 0.05, 0.13, 0.4, 2};
    for (int i = 0; i <= 60 && pd; i++)
      for (int j = 0; j <= 60; j++)
        for (int k = 0; k < 6; k++) {
          double x = -0.7 + i * 0.04, y = -0.7 + j * 0.04, rr = radii[k];
          int want = fabs(gr_polydist_at(pd, x, y, NULL)) <= rr;
          bad += gr_polydist_within(pd, x, y, rr, NULL) != want;
          badh += gr_polydist_within(pd, x, y, rr, &hint) != want;
          n++;
        }
    CHECK(bad == 0, "hole %d: %d of %d queries disagree with |distance| <= r", hole, bad, n);
    CHECK(badh == 0, "hole %d, with hints: %d of %d queries disagree with |distance| <= r", hole, badh, n);
    gr_polydist_free(pd);
    gr_rings_free(r);
  }
}

TEST(within_analytic) {
  gr_rings *r = squares(1);
  gr_err e;
  gr_err_clear(&e);
  gr_polydist *pd = gr_polydist_new(r, 0.05, &e);
  CHECK(pd != NULL, "%s", e.msg);
  if (pd) {
    /* (0.15, 0.5): 0.15 from the outer square, 0.15 from the hole */
    CHECK(!gr_polydist_within(pd, 0.15, 0.5, 0.149, NULL), "0.15 from both boundaries");
    CHECK(gr_polydist_within(pd, 0.15, 0.5, 0.151, NULL), "0.15 from both boundaries");
    /* (0.5, 0.5): the hole's centre, 0.2 from its sides */
    CHECK(!gr_polydist_within(pd, 0.5, 0.5, 0.199, NULL), "0.2 from the hole");
    CHECK(gr_polydist_within(pd, 0.5, 0.5, 0.201, NULL), "0.2 from the hole");
    /* (3, 0.5): 2 to the right of the square, far outside the buckets */
    CHECK(!gr_polydist_within(pd, 3, 0.5, 1.99, NULL), "2 outside");
    CHECK(gr_polydist_within(pd, 3, 0.5, 2.01, NULL), "2 outside");
    CHECK(!gr_polydist_within(pd, 3, 0.5, NAN, NULL), "NaN radius: no");
  }
  gr_polydist_free(pd);
  gr_rings_free(r);
}


/* A section stepping on a face (solid below y = 0.35 left of x = 2, below
 * 0.4 right of it), its reflex corner (2, 0.35) repeated `rep` times, as a
 * section passing exactly through a grid node gives it (gyroid network
 * stepped across x, layer 38 of the quality block: a spurious contour point
 * at 2 b below the corner kept a contour open). */
static const double STEP_XY[] = {1.5, 0, 2.5, 0, 2.5, 0.4, 2, 0.4, 2, 0.35, 1.5, 0.35};
static gr_rings *step_ring(int rep) {
  gr_rings *r = gr_rings_new();
  for (int k = 0; k < 6; k++)
    for (int c = 0; c < (k == 4 ? rep : 1); c++) gr_rings_point(r, STEP_XY[2 * k], STEP_XY[2 * k + 1]);
  gr_rings_close(r);
  return r;
}

/* The analytic signed distance to that section (negative inside). */
static double step_dist(double x, double y) {
  double best = INFINITY;
  for (int k = 0; k < 6; k++) {
    const double *a = STEP_XY + 2 * k, *b = STEP_XY + 2 * ((k + 1) % 6);
    double ex = b[0] - a[0], ey = b[1] - a[1], t = ((x - a[0]) * ex + (y - a[1]) * ey) / (ex * ex + ey * ey);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    best = fmin(best, hypot(a[0] + t * ex - x, a[1] + t * ey - y));
  }
  int in = x > 1.5 && x < 2.5 && y > 0 && y < (x < 2 ? 0.35 : 0.4);
  return in ? -best : best;
}

/* Points around the corner of r (81 x 81, 2.5 um apart) whose side (the
 * sign of gr_polydist_at) differs from the analytic one: *bad of *n; *worst:
 * the largest distance error. */
static void corner_signs(const gr_rings *r, int *bad, int *n, double *worst) {
  gr_err e;
  gr_err_clear(&e);
  gr_polydist *pd = gr_polydist_new(r, 0.025, &e);
  *bad = *n = 0;
  *worst = pd ? 0 : INFINITY;
  for (int i = -40; i <= 40 && pd; i++)
    for (int j = -40; j <= 40; j++) {
      double x = 2 + i * 0.0025, y = 0.35 + j * 0.0025, v = gr_polydist_at(pd, x, y, NULL), w = step_dist(x, y);
      if (fabs(w) < 1e-12) continue;
      ++*n;
      *bad += (v < 0) != (w < 0);
      *worst = fmax(*worst, fabs(fabs(v) - fabs(w)));
    }
  gr_polydist_free(pd);
}

TEST(repeated_corner_points) {
  for (int rep = 1; rep <= 3; rep++) {
    gr_rings *r = step_ring(rep);
    gr_err e;
    gr_err_clear(&e);
    int bad, n;
    double worst;
    corner_signs(r, &bad, &n, &worst);
    CHECK(bad == 0 && worst < 1e-12, "corner repeated %d times: %d of %d signs wrong, distance off by %.3g", rep, bad, n,
          worst);
    /* its offset by b = 0.025 on a grid of 0.025 mm (the corner on a node),
     * chords refined: every point at b from the section, an arc around the
     * corner (points within b + 1 um of it, none nearer) */
    gr_rings *o = gr_rings_new();
    int rc = gr_offset_rings_opt(r, 0.025, 0.025, 1e-6, 2e-4, NULL, o, &e);
    CHECK(rc == 0, "%s", e.msg);
    double off = 0, nearest = INFINITY;
    for (size_t k = 0; k < o->npts; k++) {
      double x = o->xy[2 * k], y = o->xy[2 * k + 1];
      off = fmax(off, fabs(step_dist(x, y) + 0.025));
      nearest = fmin(nearest, hypot(x - 2, y - 0.35));
    }
    CHECK(o->nrings == 1 && off < 1e-6 && fabs(nearest - 0.025) < 1e-6,
          "corner repeated %d times: %zu rings, a point %.3g um off b, nearest to the corner %.4f mm", rep, o->nrings,
          off * 1e3, nearest);
    gr_rings_free(o);
    gr_rings_free(r);
  }
}

/* Rings that cross (a window's section whose void sliver pokes a few um out
 * through the window's cut, as templates can give): the even-odd region is
 * the square [0,1]^2 less the slot x in [-0.01, 0.4],
 * y in [0.45, 0.55], plus the slot's sliver outside the square. The signed
 * distance must be the distance to the nearest edge with the even-odd sign
 * (no jump away from the edges), and every point of the offset by 0.1 must
 * lie at 0.1 from the edges. The nearest-feature sign got 0.12 mm wrong. */
static double seg_dist(double x, double y, double ax, double ay, double bx, double by) {
  double ex = bx - ax, ey = by - ay, t = ((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey);
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  return hypot(ax + t * ex - x, ay + t * ey - y);
}
static double crossed_dist(double x, double y) {
  const double P[2][8] = {{0, 0, 1, 0, 1, 1, 0, 1}, {-0.01, 0.45, 0.4, 0.45, 0.4, 0.55, -0.01, 0.55}};
  double d = INFINITY;
  for (int r = 0; r < 2; r++)
    for (int k = 0; k < 4; k++)
      d = fmin(d, seg_dist(x, y, P[r][2 * k], P[r][2 * k + 1], P[r][(2 * k + 2) % 8], P[r][(2 * k + 3) % 8]));
  int in_sq = x > 0 && x < 1 && y > 0 && y < 1, in_slot = x > -0.01 && x < 0.4 && y > 0.45 && y < 0.55;
  return in_sq != in_slot ? -d : d;
}
TEST(crossing_rings_even_odd) {
  gr_rings *r = gr_rings_new();
  const double sq[] = {0, 0, 1, 0, 1, 1, 0, 1}, slot[] = {-0.01, 0.45, -0.01, 0.55, 0.4, 0.55, 0.4, 0.45};
  for (int k = 0; k < 4; k++) gr_rings_point(r, sq[2 * k], sq[2 * k + 1]);
  gr_rings_close(r);
  for (int k = 0; k < 4; k++) gr_rings_point(r, slot[2 * k], slot[2 * k + 1]);
  gr_rings_close(r);
  gr_err e;
  gr_err_clear(&e);
  gr_polydist *pd = gr_polydist_new(r, 0.05, &e);
  CHECK(pd != NULL, "%s", e.msg);
  double worst = 0;
  for (int i = 0; i <= 130 && pd; i++)
    for (int j = 0; j <= 130; j++) {
      double x = -0.1 + i * 0.009 + 1e-4, y = -0.1 + j * 0.009 + 2e-4;
      worst = fmax(worst, fabs(gr_polydist_at(pd, x, y, NULL) - crossed_dist(x, y)));
    }
  CHECK(worst < 1e-12, "signed distance off the even-odd truth by %.3g mm", worst);
  gr_rings *o = gr_rings_new();
  int rc = gr_offset_rings_opt(r, 0.1, 0.025, 1e-6, 2e-4, NULL, o, &e);
  CHECK(rc == 0, "%s", e.msg);
  double off = 0;
  for (size_t k = 0; k < o->npts; k++) off = fmax(off, fabs(crossed_dist(o->xy[2 * k], o->xy[2 * k + 1]) + 0.1));
  CHECK(o->npts > 0 && off < 1e-6, "offset by 0.1: %zu points, one %.3g um off", o->npts, off * 1e3);
  gr_rings_free(o);
  gr_polydist_free(pd);
  gr_rings_free(r);
}

/* gr_polydist_grid (each edge updates only the nodes of its rmax capsule,
 * row by row) against the point query clamped at rmax, node by node: a
 * 37-gon (every edge slanted) with a rotated square hole, a grid whose
 * spacing is not commensurate with anything, three rmax. */
TEST(grid_matches_point_queries) {
  gr_rings *r = gr_rings_new();
  for (int k = 0; k < 37; k++) gr_rings_point(r, 0.5 + 0.4 * cos(2 * M_PI * k / 37), 0.5 + 0.4 * sin(2 * M_PI * k / 37));
  gr_rings_close(r);
  for (int k = 0; k < 4; k++) gr_rings_point(r, 0.5 + 0.15 * cos(0.3 - M_PI * k / 2), 0.5 + 0.15 * sin(0.3 - M_PI * k / 2));
  gr_rings_close(r);
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_rings_nest(r, &e) == 0, "%s", e.msg);
  gr_polydist *pd = gr_polydist_new(r, 0.03, &e);
  CHECK(pd != NULL, "%s", e.msg);
  enum { NX = 83, NY = 79 };
  static double v[NX * NY];
  const double rmax[3] = {0.013, 0.05, 0.3};
  for (int k = 0; k < 3 && pd; k++) {
    CHECK(gr_polydist_grid(pd, -0.01, 0.003, 0.0131, NX, NY, rmax[k], v, &e) == 0, "%s", e.msg);
    double worst = 0;
    int near = 0;
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        double s = gr_polydist_at(pd, -0.01 + i * 0.0131, 0.003 + j * 0.0131, NULL);
        double want = fabs(s) <= rmax[k] ? s : (s < 0 ? -rmax[k] : rmax[k]);
        near += fabs(s) <= rmax[k];
        worst = fmax(worst, fabs(v[i + NX * j] - want));
      }
    CHECK(worst < 1e-12 && near > 100, "rmax %g: %d nodes within, grid off the point queries by %.3g", rmax[k], near,
          worst);
  }
  gr_polydist_free(pd);
  gr_rings_free(r);
}

/* gr_offset_rings_coarse (the templates' offsets: sampled first on a grid of
 * two cells, again at one where a strip hides): a dumbbell, two squares
 * joined by a wall 2b + 20 um wide, turned by 17 degrees. The offset by b
 * keeps a strip 20 um wide along the wall's middle, narrower than either
 * grid: lost, the offset falls apart into two rings (three without the
 * edge checks and the resampling, and chords 13 um off). Every vertex must lie
 * at b from the polygon (its exact distance, edge by edge) and every chord's
 * middle within the chord tolerance, on the coarse grid as on the fine, and
 * both must enclose the same area. */
static const double DUMB[] = {0, 0, 0.4, 0, 0.4, 0.14, 0.6, 0.14, 0.6, 0, 1, 0,
                              1, 0.4, 0.6, 0.4, 0.6, 0.26, 0.4, 0.26, 0.4, 0.4, 0, 0.4};
#define NDUMB 12
static void dumb_pt(int k, double *x, double *y) {
  double c = cos(17 * M_PI / 180), s = sin(17 * M_PI / 180), u = DUMB[2 * k], v = DUMB[2 * k + 1];
  *x = 0.3 + c * u - s * v;
  *y = 0.1 + s * u + c * v;
}
static double dumb_dist(double x, double y) {
  double d = INFINITY;
  for (int k = 0; k < NDUMB; k++) {
    double ax, ay, bx, by;
    dumb_pt(k, &ax, &ay);
    dumb_pt((k + 1) % NDUMB, &bx, &by);
    d = fmin(d, seg_dist(x, y, ax, ay, bx, by));
  }
  return d;
}
TEST(coarse_grid_keeps_narrow_strips) {
  gr_rings *r = gr_rings_new(), *o[2] = {gr_rings_new(), gr_rings_new()};
  for (int k = 0; k < NDUMB; k++) {
    double x, y;
    dumb_pt(k, &x, &y);
    gr_rings_point(r, x, y);
  }
  gr_rings_close(r);
  gr_err e;
  gr_err_clear(&e);
  const double b = 0.05, cell = 0.025, ctol = 5e-4;
  double area[2] = {0, 0};
  for (int c = 0; c < 2; c++) {
    int rc = gr_offset_rings_grid(r, b, cell, c ? 2 : 1, 1e-6, ctol, NULL, o[c], &e);
    CHECK(rc == 0, "%s", e.msg);
    CHECK(o[c]->nrings == 1, "coarse %d: %zu rings (the strip along the wall lost)", c + 1, o[c]->nrings);
    double worst = 0, wmid = 0;
    for (size_t q = 0; q < o[c]->nrings; q++) {
      const double *p = gr_ring_xy(o[c], q);
      size_t n = gr_ring_len(o[c], q);
      area[c] += gr_ring_area(o[c], q);
      for (size_t k = 0; k < n; k++) {
        const double *a = p + 2 * k, *z = p + 2 * ((k + 1) % n);
        worst = fmax(worst, fabs(dumb_dist(a[0], a[1]) - b));
        wmid = fmax(wmid, fabs(dumb_dist(0.5 * (a[0] + z[0]), 0.5 * (a[1] + z[1])) - b));
      }
    }
    CHECK(o[c]->npts > 0 && worst < 1e-6, "coarse %d: a vertex %.3g um off the offset", c + 1, worst * 1e3);
    CHECK(o[c]->npts > 0 && wmid < ctol, "coarse %d: a chord's middle %.3g um off the offset", c + 1, wmid * 1e3);
  }
  CHECK(fabs(area[0] - area[1]) < 1e-5, "areas %.7f and %.7f mm^2", area[0], area[1]);
  gr_rings_free(o[0]);
  gr_rings_free(o[1]);
  gr_rings_free(r);
}

int main(void) {
  RUN(within_matches_the_distance);
  RUN(within_analytic);
  RUN(repeated_corner_points);
  RUN(crossing_rings_even_odd);
  RUN(grid_matches_point_queries);
  RUN(coarse_grid_keeps_narrow_strips);
  DONE();
}
