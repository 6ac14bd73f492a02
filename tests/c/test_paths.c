/* test_paths.c: ring primitives. Douglas-Peucker simplification
 * (gr_rings_simplify) keeps every dropped point within its tolerance of the
 * simplified ring and needs about as many chords as a circle's analytic
 * count; collinear runs collapse to their corners; repeated points do not
 * upset it. Ring neighbours wrap (gr_ring_next / gr_ring_prev). Nesting
 * orients outer rings counter-clockwise and holes clockwise. A contour lying
 * along the side two voxel squares share is clipped into one of them only. */
#include "check.h"
#include "paths.h"
#include "clip.h"
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

/* Length of the pieces in l, and how much of it lies on the line x = 1. */
static double pieces_len(const gr_layer *l, double *on_side) {
  double len = 0;
  *on_side = 0;
  for (size_t b = 0; b < l->nb; b++) {
    const double *p = l->xy + 2 * l->b[b].start;
    for (size_t k = 0; k + 1 < l->b[b].n; k++) {
      double d = hypot(p[2 * k + 2] - p[2 * k], p[2 * k + 3] - p[2 * k + 1]);
      len += d;
      if (fabs(p[2 * k] - 1) < 1e-9 && fabs(p[2 * k + 2] - 1) < 1e-9) *on_side += d;
    }
  }
  return len;
}

TEST(clip_ring_owned_shared_side) {
  /* squares A = [0,1]^2 and B = [1,2] x [0,1] share the side x = 1. A
   * counter-clockwise rectangle [1, 1.6] x [0.2, 0.8] (inside B) and a
   * clockwise hole [0.5, 1] x [0.2, 0.8] (B's solid lies beyond its side x =
   * 1: the side bounds B's section), each side at x = 1 + s for s within the
   * snap (rounding between two voxels' templates): the side goes to B alone,
   * every edge of the ring is clipped into exactly one square, and the
   * pieces have no repeated points. gr_clip_poly keeps the side in both. */
  const double lo[2][2] = {{0, 0}, {1, 0}}, hi[2][2] = {{1, 1}, {2, 1}};
  const double shift[3] = {0, 4e-10, -4e-10};
  double *buf = NULL;
  size_t cap = 0;
  for (int ring = 0; ring < 2; ring++)
    for (int v = 0; v < 3; v++) {
      double x0 = ring ? 0.5 : 1 + shift[v], x1 = ring ? 1 + shift[v] : 1.6;
      /* counter-clockwise (ring 0) or clockwise (ring 1) */
      double pts[10] = {x0, 0.2, x1, 0.2, x1, 0.8, x0, 0.8, x0, 0.2};
      if (ring) { pts[2] = x0; pts[3] = 0.8; pts[6] = x1; pts[7] = 0.2; }
      double perim = 2 * (x1 - x0) + 1.2, side[2], len[2], plain_side = 0;
      for (int q = 0; q < 2; q++) {
        gr_layer *l = gr_layer_new(0), *m = gr_layer_new(0);
        CHECK(gr_clip_ring_owned(pts, 5, GR_CONTOUR, ring ? 0 : 1, lo[q], hi[q], l, &buf, &cap) == GR_OK, "clip");
        len[q] = pieces_len(l, &side[q]);
        for (size_t b = 0; b < l->nb; b++)
          for (size_t k = 0; k + 1 < l->b[b].n; k++) {
            const double *p = l->xy + 2 * (l->b[b].start + k);
            CHECK(p[0] != p[2] || p[1] != p[3], "ring %d shift %d square %d: a repeated point", ring, v, q);
          }
        double sd;
        CHECK(gr_clip_poly(pts, 5, 1, GR_CONTOUR, 1, lo[q], hi[q], m, &buf, &cap) == GR_OK, "clip");
        pieces_len(m, &sd);
        plain_side += sd;
        gr_layer_free(l);
        gr_layer_free(m);
      }
      CHECK(fabs(side[0]) < 1e-12, "ring %d shift %d: A keeps %g of the side", ring, v, side[0]);
      CHECK(fabs(side[1] - 0.6) < 1e-9, "ring %d shift %d: B keeps %g of the side (0.6)", ring, v, side[1]);
      CHECK(fabs(len[0] + len[1] - perim) < 1e-9, "ring %d shift %d: pieces %g + %g, the ring %g", ring, v, len[0],
            len[1], perim);
      if (v == 0) CHECK(fabs(plain_side - 1.2) < 1e-9, "ring %d: gr_clip_poly keeps %g of the side (both)", ring, plain_side);
    }
  free(buf);
}

int main(void) {
  RUN(simplify_circle_within_tolerance);
  RUN(simplify_square_to_corners);
  RUN(ring_neighbours_wrap);
  RUN(nest_orients_holes);
  RUN(clip_ring_owned_shared_side);
  DONE();
}
