/* test_paths.c: ring primitives. Douglas-Peucker simplification
 * (gr_rings_simplify) keeps every dropped point within its tolerance of the
 * simplified ring and needs about as many chords as a circle's analytic
 * count; collinear runs collapse to their corners; repeated points do not
 * upset it. Ring neighbours wrap (gr_ring_next / gr_ring_prev). Nesting
 * orients outer rings counter-clockwise and holes clockwise. */
#include "check.h"
#include "paths.h"
#include <stdlib.h>

/* The largest distance from the points of ring 0 of a to the edges of
 * ring 0 of b. */
static double ring_dev(const gr_rings *a, const gr_rings *b) {
  const double *p = gr_ring_xy(a, 0), *q = gr_ring_xy(b, 0);
  size_t n = gr_ring_len(a, 0), m = gr_ring_len(b, 0);
  double worst = 0;
  for (size_t i = 0; i < n; i++) {
    double best = INFINITY;
    for (size_t k = 0; k < m; k++) {
      double d = gr_seg_dist(p + 2 * i, q + 2 * k, q + 2 * gr_ring_next(k, m));
      if (d < best) best = d;
    }
    if (best > worst) worst = best;
  }
  return worst;
}

static gr_rings *circle(double r, size_t n) {
  gr_rings *g = gr_rings_new();
  for (size_t i = 0; i < n; i++) {
    double a = 2 * M_PI * (double)i / (double)n;
    gr_rings_point(g, r * cos(a), r * sin(a));
  }
  gr_rings_close(g);
  return g;
}

TEST(simplify_circle_within_tolerance) {
  /* radius 1 mm, 4000 points; tolerance 1 um: a chord of angle t lies
   * within 1 - cos(t / 2) of the arc, so at least 2 pi / (2 acos(1 - tol))
   * = 70.2 chords are needed, and Douglas-Peucker's greedy splits should
   * need at most twice that */
  const double tol = 1e-3;
  gr_rings *full = circle(1.0, 4000), *s = circle(1.0, 4000);
  CHECK(gr_rings_simplify(s, tol) == GR_OK, "simplify failed");
  size_t m = gr_ring_len(s, 0);
  double need = 2 * M_PI / (2 * acos(1 - tol));
  CHECK(m >= (size_t)ceil(need) && m <= (size_t)(2 * need), "%zu points for a circle needing %.1f chords", m, need);
  double dev = ring_dev(full, s);
  CHECK(dev <= tol * (1 + 1e-9), "a dropped point lies %.3g mm from the simplified ring (tol %.3g)", dev, tol);
  /* the kept points are points of the ring: on the circle */
  const double *p = gr_ring_xy(s, 0);
  for (size_t k = 0; k < m; k++) CHECK_NEAR(hypot(p[2 * k], p[2 * k + 1]), 1.0, 1e-12);
  gr_rings_free(full);
  gr_rings_free(s);
}

TEST(simplify_square_to_corners) {
  /* a 2 x 1 mm rectangle with a point every 0.01 mm along its sides (and
   * one repeated point): the straight runs go, the four corners stay */
  gr_rings *r = gr_rings_new();
  const double c[5][2] = {{0, 0}, {2, 0}, {2, 1}, {0, 1}, {0, 0}};
  for (int s = 0; s < 4; s++) {
    double len = hypot(c[s + 1][0] - c[s][0], c[s + 1][1] - c[s][1]);
    int n = (int)lround(len / 0.01);
    for (int i = 0; i < n; i++)
      gr_rings_point(r, c[s][0] + (c[s + 1][0] - c[s][0]) * i / n, c[s][1] + (c[s + 1][1] - c[s][1]) * i / n);
    if (s == 1) gr_rings_point(r, 2, 1); /* the next side's first point, twice */
  }
  gr_rings_close(r);
  CHECK(gr_rings_simplify(r, 1e-6) == GR_OK, "simplify failed");
  CHECK(gr_ring_len(r, 0) == 4, "%zu points left, want the 4 corners", gr_ring_len(r, 0));
  const double *p = gr_ring_xy(r, 0);
  for (size_t k = 0; k < gr_ring_len(r, 0); k++) {
    int corner = 0;
    for (int s = 0; s < 4; s++) corner |= p[2 * k] == c[s][0] && p[2 * k + 1] == c[s][1];
    CHECK(corner, "point %zu (%g, %g) is no corner", k, p[2 * k], p[2 * k + 1]);
  }
  CHECK_NEAR(fabs(gr_ring_area(r, 0)), 2.0, 1e-12);
  gr_rings_free(r);
}

TEST(ring_neighbours_wrap) {
  CHECK(gr_ring_next(0, 5) == 1 && gr_ring_next(4, 5) == 0, "next wraps");
  CHECK(gr_ring_prev(0, 5) == 4 && gr_ring_prev(3, 5) == 2, "prev wraps");
  CHECK(gr_ring_next(0, 1) == 0 && gr_ring_prev(0, 1) == 0, "a one-point ring is its own neighbour");
  for (size_t n = 1; n <= 4; n++)
    for (size_t k = 0; k < n; k++)
      for (size_t d = 0; d <= 2 * n + 2; d++)
        CHECK(gr_ring_at(k, d, n) == (k + d) % n, "gr_ring_at(%zu, %zu, %zu) = %zu", k, d, n, gr_ring_at(k, d, n));
  /* successors: two rings of 3 and 2 points */
  gr_rings *r = gr_rings_new();
  gr_rings_point(r, 0, 0); gr_rings_point(r, 1, 0); gr_rings_point(r, 0, 1); gr_rings_close(r);
  gr_rings_point(r, 5, 5); gr_rings_point(r, 6, 5); gr_rings_close(r);
  size_t nxt[5], want[5] = {1, 2, 0, 4, 3};
  gr_rings_successors(r, nxt);
  for (int k = 0; k < 5; k++) CHECK(nxt[k] == want[k], "nxt[%d] = %zu, want %zu", k, nxt[k], want[k]);
  gr_rings_free(r);
}

TEST(nest_orients_holes) {
  /* an annulus given both rings clockwise: nesting makes the outer one
   * counter-clockwise (area > 0) and the hole clockwise, its parent the
   * outer one; the areas keep their size (pi (4 - 1)) */
  gr_rings *r = gr_rings_new();
  for (int k = 0; k < 2; k++) {
    double R = k ? 1.0 : 2.0;
    for (int i = 0; i < 720; i++) {
      double a = -2 * M_PI * i / 720;
      gr_rings_point(r, 5 + R * cos(a), 5 + R * sin(a));
    }
    gr_rings_close(r);
  }
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_rings_nest(r, &e) == GR_OK, "nest failed: %s", e.msg);
  CHECK(gr_ring_area(r, 0) > 0 && gr_ring_area(r, 1) < 0, "areas %g, %g", gr_ring_area(r, 0), gr_ring_area(r, 1));
  CHECK(r->parent[0] == -1 && r->parent[1] == 0, "parents %d, %d", r->parent[0], r->parent[1]);
  double exact = M_PI * (4 - 1);
  CHECK(fabs(gr_rings_area(r) - exact) < 2e-3 * exact, "area %g, the annulus %g", gr_rings_area(r), exact);
  gr_rings_free(r);
}

int main(void) {
  RUN(simplify_circle_within_tolerance);
  RUN(simplify_square_to_corners);
  RUN(ring_neighbours_wrap);
  RUN(nest_orients_holes);
  DONE();
}
