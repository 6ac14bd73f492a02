/* test_hatch.c: the hatch primitive against analytic truth. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "hatch.h"
#include "verify.h"

static const double PI = 3.14159265358979323846;

static gr_rings *rect(double x0, double y0, double x1, double y1) {
  gr_rings *r = gr_rings_new();
  double p[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
  gr_rings_add(r, p, 4);
  return r;
}

/* L shape: [0,2]x[0,2] minus [1,2]x[1,2], shifted by (sx, sy). */
static gr_rings *lshape(double sx, double sy) {
  gr_rings *r = gr_rings_new();
  double p[12] = {0, 0, 2, 0, 2, 1, 1, 1, 1, 2, 0, 2};
  for (int i = 0; i < 6; i++) { p[2 * i] += sx; p[2 * i + 1] += sy; }
  gr_rings_add(r, p, 6);
  return r;
}

static void add_circle(gr_rings *r, double cx, double cy, double R, int n, int ccw) {
  for (int i = 0; i < n; i++) {
    double t = 2 * PI * i / n * (ccw ? 1 : -1);
    gr_rings_point(r, cx + R * cos(t), cy + R * sin(t));
  }
  gr_rings_close(r);
}

static double dist_to_edges(const gr_rings *r, double x, double y) {
  double best = INFINITY;
  for (size_t i = 0; i < r->nrings; i++) {
    const double *p = gr_ring_xy(r, i);
    size_t n = gr_ring_len(r, i);
    for (size_t a = 0, b = n - 1; a < n; b = a++) {
      double ex = p[2 * a] - p[2 * b], ey = p[2 * a + 1] - p[2 * b + 1];
      double qx = x - p[2 * b], qy = y - p[2 * b + 1];
      double t = (qx * ex + qy * ey) / (ex * ex + ey * ey);
      t = t < 0 ? 0 : t > 1 ? 1 : t;
      best = fmin(best, hypot(qx - t * ex, qy - t * ey));
    }
  }
  return best;
}

static int inside_or_on(const gr_rings *r, double x, double y) {
  return gr_rings_contains(r, x, y) || dist_to_edges(r, x, y) < 1e-9;
}

/* Strict crossing of segment p-q with any ring edge (touching excluded). */
static int crosses_edges(const gr_rings *r, double px, double py, double qx, double qy) {
  for (size_t i = 0; i < r->nrings; i++) {
    const double *p = gr_ring_xy(r, i);
    size_t n = gr_ring_len(r, i);
    for (size_t a = 0, b = n - 1; a < n; b = a++) {
      double ax = p[2 * b], ay = p[2 * b + 1], bx = p[2 * a], by = p[2 * a + 1];
      double d1 = (qx - px) * (ay - py) - (qy - py) * (ax - px);
      double d2 = (qx - px) * (by - py) - (qy - py) * (bx - px);
      double d3 = (bx - ax) * (py - ay) - (by - ay) * (px - ax);
      double d4 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax);
      double eps = 1e-12;
      if (((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps)) &&
          ((d3 > eps && d4 < -eps) || (d3 < -eps && d4 > eps)))
        return 1;
    }
  }
  return 0;
}

static gr_hatch_opts base(double d, double angle) {
  gr_hatch_opts o = gr_hatch_defaults();
  o.spacing = d;
  o.angle = angle;
  o.alternate = 0;
  return o;
}

TEST(square_count_and_length) {
  /* lines y = k*0.1 with 0.027 <= y < 1.027: k = 1..10, each 1 mm long */
  gr_rings *r = rect(0.013, 0.027, 1.013, 1.027);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.1, 0);
  gr_hatch_report rep = {0};
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  CHECK(s.vectors[GR_HATCH] == 10, "got %zu vectors", s.vectors[GR_HATCH]);
  CHECK(rep.hatches == 10, "report %zu", rep.hatches);
  CHECK_NEAR(s.length[GR_HATCH], 10.0, 1e-9);
  for (size_t i = 0; i < l->npts; i += 2) {
    double y = l->xy[2 * i + 1];
    CHECK_NEAR(y / 0.1, round(y / 0.1), 1e-9);
    CHECK_NEAR(fabs(l->xy[2 * i + 2] - l->xy[2 * i]), 1.0, 1e-12);
  }
  gr_layer_free(l);
  gr_rings_free(r);
}

TEST(diagonal_length_is_area_over_d) {
  gr_rings *r = rect(0.0123, 0.0071, 2.0123, 2.0071);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.05, 45);
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  CHECK_NEAR(s.length[GR_HATCH], 4.0 / 0.05, 0.01 * 80);
  /* every vector on a global line n.p = k d, n = (-sin a, cos a) */
  double c = cos(PI / 4), sn = sin(PI / 4);
  for (size_t i = 0; i < l->npts; i++) {
    double v = (-l->xy[2 * i] * sn + l->xy[2 * i + 1] * c) / 0.05;
    CHECK_NEAR(v, round(v), 1e-9);
  }
  gr_layer_free(l);
  gr_rings_free(r);
}

TEST(vectors_inside_nonconvex) {
  gr_rings *r = lshape(0.01, 0.02);
  for (int a = 0; a < 180; a += 30) {
    gr_layer *l = gr_layer_new(0);
    gr_hatch_opts o = base(0.07, a + 0.5);
    gr_err e;
    CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
    gr_layer_stats s;
    gr_layer_stats_get(l, &s);
    CHECK_NEAR(s.length[GR_HATCH], 3.0 / 0.07, 0.02 * 3.0 / 0.07);
    for (size_t i = 0; i + 1 < l->npts; i += 2) {
      const double *p = l->xy + 2 * i;
      CHECK(inside_or_on(r, p[0], p[1]) && inside_or_on(r, p[2], p[3]), "endpoint outside");
      CHECK(gr_rings_contains(r, 0.5 * (p[0] + p[2]), 0.5 * (p[1] + p[3])), "midpoint outside at %d deg", a);
      CHECK(!crosses_edges(r, p[0], p[1], p[2], p[3]), "vector crosses boundary");
    }
    gr_layer_free(l);
  }
  gr_rings_free(r);
}

TEST(rotation_sequence) {
  CHECK_NEAR(gr_hatch_angle(0, 45, 67), 45, 1e-12);
  CHECK_NEAR(gr_hatch_angle(1, 45, 67), 112, 1e-12);
  CHECK_NEAR(gr_hatch_angle(2, 45, 67), 179, 1e-12);
  CHECK_NEAR(gr_hatch_angle(3, 45, 67), 246, 1e-12);
  CHECK_NEAR(gr_hatch_angle(5, 45, 67), 20, 1e-12);
  CHECK_NEAR(gr_hatch_angle(-1, 45, 67), 338, 1e-12);
  CHECK_NEAR(gr_hatch_angle(1, 0, 90), 90, 1e-12);
  CHECK_NEAR(gr_hatch_angle(4, 0, 90), 0, 1e-12);
  CHECK_NEAR(gr_hatch_angle(1000001, 0, 90), 90, 1e-9);
}

TEST(alternate_reverses_every_other_line) {
  gr_rings *r = rect(0.013, 0.027, 1.013, 1.027);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.1, 0);
  o.alternate = 1;
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
  int n = 0;
  for (size_t i = 0; i + 1 < l->npts; i += 2) {
    long k = lround(l->xy[2 * i + 1] / 0.1);
    double dx = l->xy[2 * i + 2] - l->xy[2 * i];
    CHECK((k % 2 == 0) == (dx > 0), "line %ld dx %g", k, dx);
    n++;
  }
  CHECK(n == 10, "%d vectors", n);
  gr_layer_free(l);
  gr_rings_free(r);
}

static void check_zigzag(const gr_rings *r, double d, double angle, size_t *nblocks, size_t *nvec) {
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(d, angle);
  o.pattern = GR_ZIGZAG;
  gr_hatch_report rep = {0};
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  *nblocks = l->nb;
  *nvec = rep.hatches;
  size_t links = 0;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *B = &l->b[b];
    CHECK(B->shape == GR_OPEN && B->kind == GR_HATCH && B->dir == 2, "block %zu", b);
    CHECK(B->n % 2 == 0, "odd polyline");
    const double *p = l->xy + 2 * B->start;
    for (size_t k = 0; k + 1 < B->n; k++) {
      const double *q = p + 2 * k;
      for (int f = 1; f < 4; f++) {
        double x = q[0] + f * 0.25 * (q[2] - q[0]), y = q[1] + f * 0.25 * (q[3] - q[1]);
        CHECK(inside_or_on(r, x, y), "point %g,%g of segment %zu outside", x, y, k);
      }
      CHECK(!crosses_edges(r, q[0], q[1], q[2], q[3]), "segment crosses boundary");
      if (k % 2 == 1) links++;
    }
  }
  CHECK(links == rep.links, "links %zu vs %zu", links, rep.links);
  gr_layer_free(l);
}

TEST(zigzag_stays_inside) {
  size_t nb, nv;
  gr_rings *L = lshape(0.01, 0.02);
  check_zigzag(L, 0.1, 0, &nb, &nv);
  /* the L at 0 degrees: 20 lines; lines through the upper arm all link, so
   * few polylines (not one per vector) */
  CHECK(nv == 20, "%zu vectors", nv);
  CHECK(nb <= 3, "%zu polylines", nb);
  check_zigzag(L, 0.07, 33, &nb, &nv);
  CHECK(nb < nv / 3, "%zu polylines for %zu vectors", nb, nv);
  gr_rings_free(L);
  gr_rings *A = gr_rings_new();
  add_circle(A, 0.003, 0.001, 1.0, 200, 1);
  add_circle(A, 0.003, 0.001, 0.5, 100, 0);
  check_zigzag(A, 0.05, 20, &nb, &nv);
  /* links beside the convex hole would cross it: only the caps join up */
  CHECK(nb >= 2 && nb < nv / 2, "%zu polylines for %zu vectors", nb, nv);
  gr_rings_free(A);
}

TEST(islands_alternate_and_clip) {
  gr_rings *r = rect(0.003, 0.007, 4.003, 3.507);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.1, 0);
  o.pattern = GR_ISLAND;
  o.island = 1;
  o.island_origin[0] = 0;
  o.island_origin[1] = 0;
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  CHECK_NEAR(s.length[GR_HATCH], 4.0 * 3.5 / 0.1, 0.02 * 140);
  int seen[2] = {0, 0};
  for (size_t i = 0; i + 1 < l->npts; i += 2) {
    const double *p = l->xy + 2 * i;
    double mx = 0.5 * (p[0] + p[2]), my = 0.5 * (p[1] + p[3]);
    long I = (long)floor(mx), J = (long)floor(my);
    for (int k = 0; k < 2; k++) {
      CHECK(p[2 * k] >= I - 1e-9 && p[2 * k] <= I + 1 + 1e-9, "x outside island");
      CHECK(p[2 * k + 1] >= J - 1e-9 && p[2 * k + 1] <= J + 1 + 1e-9, "y outside island");
    }
    int even = ((I + J) & 1) == 0;
    if (even) CHECK(fabs(p[3] - p[1]) < 1e-9, "even island not along x");
    else CHECK(fabs(p[2] - p[0]) < 1e-9, "odd island not along y");
    seen[even]++;
  }
  CHECK(seen[0] > 0 && seen[1] > 0, "both directions");
  gr_layer_free(l);
  gr_rings_free(r);
}

/* Hatching two adjacent squares separately gives the union's vectors split
 * at the shared edge: same lines, endpoints meeting exactly. */
TEST(global_line_family) {
  double sx = 0.0031, sy = 0.0047;
  gr_rings *A = rect(sx, sy, 1 + sx, 1 + sy), *B = rect(1 + sx, sy, 2 + sx, 1 + sy);
  gr_rings *U = rect(sx, sy, 2 + sx, 1 + sy);
  gr_layer *la = gr_layer_new(0), *lb = gr_layer_new(0), *lu = gr_layer_new(0);
  gr_hatch_opts o = base(0.05, 30);
  gr_err e;
  CHECK(gr_hatch_region(A, &o, la, NULL, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_hatch_region(B, &o, lb, NULL, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_hatch_region(U, &o, lu, NULL, &e) == GR_OK, "%s", e.msg);
  gr_layer_stats a, b, u;
  gr_layer_stats_get(la, &a);
  gr_layer_stats_get(lb, &b);
  gr_layer_stats_get(lu, &u);
  CHECK_NEAR(a.length[GR_HATCH] + b.length[GR_HATCH], u.length[GR_HATCH], 1e-9);
  /* each A vector ending on x = 1 + sx meets a B vector starting there, and
   * together they are one union vector */
  int met = 0;
  for (size_t i = 0; i + 1 < la->npts; i += 2) {
    const double *p = la->xy + 2 * i;
    if (fabs(p[2] - (1 + sx)) > 1e-12) continue;
    int found = 0;
    for (size_t j = 0; j + 1 < lb->npts && !found; j += 2) {
      const double *q = lb->xy + 2 * j;
      if (q[0] == p[2] && q[1] == p[3]) {
        found = 1;
        int inu = 0;
        for (size_t k = 0; k + 1 < lu->npts; k += 2) {
          const double *w = lu->xy + 2 * k;
          if (fabs(w[0] - p[0]) < 1e-12 && fabs(w[1] - p[1]) < 1e-12 && fabs(w[2] - q[2]) < 1e-12 && fabs(w[3] - q[3]) < 1e-12) inu = 1;
        }
        CHECK(inu, "joined vector not in the union");
      }
    }
    CHECK(found, "A vector end (%g, %g) has no B partner", p[2], p[3]);
    met += found;
  }
  CHECK(met > 5, "%d meetings", met);
  gr_layer_free(la); gr_layer_free(lb); gr_layer_free(lu);
  gr_rings_free(A); gr_rings_free(B); gr_rings_free(U);
}

TEST(min_length_drops_and_counts) {
  /* triangle: line y = k/10 (k = 1..10) has length 1.005 - y */
  gr_rings *r = gr_rings_new();
  double p[6] = {0, 0.005, 1, 0.005, 0, 1.005};
  gr_rings_add(r, p, 3);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.1, 0);
  o.min_length = 0.3;
  gr_hatch_report rep = {0};
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.hatches == 7, "%zu kept", rep.hatches);
  CHECK(rep.dropped == 3, "%zu dropped", rep.dropped);
  CHECK_NEAR(rep.dropped_length, 0.205 + 0.105 + 0.005, 1e-9);
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  CHECK_NEAR(s.length[GR_HATCH], 0.905 + 0.805 + 0.705 + 0.605 + 0.505 + 0.405 + 0.305, 1e-9);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* Square with miter offset: one contour at b, hatch region at b too. */
TEST(layer_contour_and_region) {
  gr_rings *r = rect(0.013, 0.027, 2.013, 2.027);
  gr_layer *l = gr_layer_new(0.5);
  gr_hatch_opts o = base(0.1, 0);
  o.offset = gr_hatch_miter_offset;
  gr_hatch_report rep;
  gr_err e;
  CHECK(gr_hatch_layer(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.contours == 1 && rep.thin_walls == 0, "%zu contours", rep.contours);
  CHECK_NEAR(rep.hatch_offset, 0.05, 1e-12);
  CHECK(l->nb >= 2 && l->b[0].kind == GR_CONTOUR && l->b[0].shape == GR_CLOSED && l->b[0].dir == 1, "contour first");
  const gr_block *c = &l->b[0];
  CHECK(c->n == 5, "%zu points", c->n);
  CHECK_NEAR(gr_block_length(l, c), 4 * 1.9, 1e-9);
  for (size_t k = 0; k < c->n; k++) CHECK_NEAR(dist_to_edges(r, l->xy[2 * (c->start + k)], l->xy[2 * (c->start + k) + 1]), 0.05, 1e-9);
  /* hatch region [0.063, 1.963] x [0.077, 1.977]: lines k = 1..19, 1.9 long */
  gr_layer_stats s;
  gr_layer_stats_get(l, &s);
  CHECK(s.vectors[GR_HATCH] == 19, "%zu hatches", s.vectors[GR_HATCH]);
  CHECK_NEAR(s.length[GR_HATCH], 19 * 1.9, 1e-9);
  CHECK_NEAR(l->z, 0.5, 0);
  /* contour_first = 0 puts hatches first; 2 contours at b and b + d */
  gr_layer_clear(l, 0);
  o.contour_first = 0;
  o.contours = 2;
  CHECK(gr_hatch_layer(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.contours == 2, "%zu contours", rep.contours);
  CHECK_NEAR(rep.hatch_offset, 0.15, 1e-12);
  /* gap moves the hatch region: 0.05 + 0.03 */
  gr_layer_clear(l, 0);
  o.contours = 1;
  o.gap = 0.03;
  CHECK(gr_hatch_layer(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(rep.hatch_offset, 0.08, 1e-12);
  gr_layer_stats_get(l, &s);
  CHECK(s.vectors[GR_HATCH] == 18, "%zu hatches with gap", s.vectors[GR_HATCH]);
  CHECK_NEAR(s.length[GR_HATCH], 18 * (2 - 0.16), 1e-9);
  CHECK(l->b[0].kind == GR_HATCH && l->b[l->nb - 1].kind == GR_CONTOUR, "hatches first");
  gr_layer_free(l);
  gr_rings_free(r);
}

/* A strip 0.06 wide cannot hold a contour at b = 0.05: thin-wall scan. */
TEST(thin_wall_scanned_and_counted) {
  gr_rings *r = rect(0.013, 0.027, 2.013, 2.027);
  double p[8] = {3, 0, 5, 0, 5, 0.06, 3, 0.06};
  gr_rings_add(r, p, 4);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(0.1, 0);
  o.offset = gr_hatch_miter_offset;
  gr_hatch_report rep;
  gr_err e;
  CHECK(gr_hatch_layer(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.thin_walls == 1 && l->thin_walls == 1, "thin walls %d/%d", rep.thin_walls, l->thin_walls);
  int instrip = 0;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *B = &l->b[b];
    const double *q = l->xy + 2 * B->start;
    if (B->kind != GR_CONTOUR || q[0] < 2.5) continue;
    instrip++;
    double len = gr_block_length(l, B);
    /* a centre line, cut back 0.8 b from each end (the fork of the medial
     * axis into the end's corners included): about 2 - 0.05 mm */
    CHECK(B->shape == GR_OPEN && B->dir == GR_DIR_THIN, "thin-wall scan tagged (shape %d dir %d)", B->shape, B->dir);
    CHECK(len > 1.9 && len < 1.97, "thin-wall scan %g mm", len);
    for (size_t k = 0; k < B->n; k++)
      CHECK(fabs(q[2 * k + 1] - 0.03) < (q[2 * k] > 3.05 && q[2 * k] < 4.95 ? 1e-6 : 0.015), "(%g, %g) off the centre line",
            q[2 * k], q[2 * k + 1]);
    for (size_t k = 0; k < B->n; k++)
      CHECK(q[2 * k] > 3 && q[2 * k] < 5 && q[2 * k + 1] > 0 && q[2 * k + 1] < 0.06, "outside strip");
  }
  CHECK(instrip == 1, "%d strip scans", instrip);
  /* a diagonal strip (30 degrees, 0.04 wide) alone: scanned inside it */
  gr_rings *dg = gr_rings_new();
  double c = cos(PI / 6), sn = sin(PI / 6), q[8] = {0, 0, 2, 0, 2, 0.04, 0, 0.04};
  for (int k = 0; k < 4; k++) gr_rings_point(dg, 1 + q[2 * k] * c - q[2 * k + 1] * sn, 1 + q[2 * k] * sn + q[2 * k + 1] * c);
  gr_rings_close(dg);
  gr_layer_clear(l, 0);
  CHECK(gr_hatch_layer(dg, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.thin_walls == 1 && l->nb == 1, "diagonal: %d thin walls, %zu blocks", rep.thin_walls, l->nb);
  if (l->nb == 1) {
    CHECK(gr_block_length(l, &l->b[0]) > 1.9 && gr_block_length(l, &l->b[0]) < 1.97, "diagonal scan %g mm",
          gr_block_length(l, &l->b[0]));
    for (size_t k = 0; k < l->b[0].n; k++)
      CHECK(gr_rings_contains(dg, l->xy[2 * k], l->xy[2 * k + 1]), "diagonal scan point outside");
  }
  gr_rings_free(dg);
  /* the default offset (whatever is linked) also scans the strip */
  gr_layer_clear(l, 0);
  o.offset = NULL;
  CHECK(gr_hatch_layer(r, &o, l, &rep, &e) == GR_OK, "%s", e.msg);
  CHECK(rep.thin_walls == 1, "default offset: thin walls %d", rep.thin_walls);
  gr_layer_free(l);
  gr_rings_free(r);
}


/* Lens of two circle arcs: chord 2c along y = cy, half thickness w < b in the
 * middle. Its half width at distance x from the middle is
 * sqrt(R^2 - x^2) - (R - w), R = (c^2 + w^2) / (2w). */
static gr_rings *lens(double cx, double cy, double c, double w, int n) {
  double R = (c * c + w * w) / (2 * w), a = asin(c / R);
  gr_rings *r = gr_rings_new();
  for (int i = 0; i < n; i++) {
    double t = -a + 2 * a * i / n;
    gr_rings_point(r, cx + R * sin(t), cy - (R - w) + R * cos(t));
  }
  for (int i = 0; i < n; i++) {
    double t = a - 2 * a * i / n;
    gr_rings_point(r, cx + R * sin(t), cy + (R - w) - R * cos(t));
  }
  gr_rings_close(r);
  return r;
}

static size_t count_thin(const gr_layer *l, size_t *idx) {
  size_t n = 0;
  for (size_t b = 0; b < l->nb; b++)
    if (l->b[b].dir == GR_DIR_THIN) {
      if (idx) idx[n < 8 ? n : 7] = b;
      n++;
    }
  return n;
}

/* Hatch r at spacing d (b = d/2, thin walls only within box if not NULL,
 * defaults otherwise) into a new layer; the thin-wall scans' block indices
 * into ib (up to 8), their number into nthin. */
static gr_layer *hatch_thin_in(const gr_rings *r, double d, const double *box, gr_hatch_report *rep, size_t *nthin,
                               size_t *ib) {
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = base(d, 0);
  if (box) memcpy(o.thin_box, box, sizeof o.thin_box);
  gr_err e;
  CHECK(gr_hatch_layer(r, &o, l, rep, &e) == GR_OK, "%s", e.msg);
  *nthin = count_thin(l, ib);
  return l;
}

static gr_layer *hatch_thin(const gr_rings *r, double d, gr_hatch_report *rep, size_t *nthin, size_t *ib) {
  return hatch_thin_in(r, d, NULL, rep, nthin, ib);
}

/* A comb: a bar [0, W] x [0, 0.5] with n teeth w wide and 0.5 long on
 * top, 0.2 apart. */
static gr_rings *comb(int n, double w) {
  gr_rings *r = gr_rings_new();
  double W = 0.2 * n + 0.2;
  gr_rings_point(r, 0, 0);
  gr_rings_point(r, W, 0);
  gr_rings_point(r, W, 0.5);
  for (int j = n - 1; j >= 0; j--) {
    double x = 0.2 + 0.2 * j;
    gr_rings_point(r, x + w, 0.5);
    gr_rings_point(r, x + w, 1);
    gr_rings_point(r, x, 1);
    gr_rings_point(r, x, 0.5);
  }
  gr_rings_point(r, 0, 0.5);
  gr_rings_close(r);
  return r;
}

/* Many corners: the section boundary near each convex corner is farther
 * than b from the contour's core, so the coverage check has many samples
 * to place (past its first 32 scans it asks the bucketed distance): teeth
 * narrower than 2b get one scan each, inside the tooth; wide ones none. */
TEST(thin_teeth_of_a_comb) {
  double d = 0.05, b = d / 2;
  enum { N = 24 };
  size_t ib[8], nt;
  gr_hatch_report rep;
  gr_rings *r = comb(N, 0.03);
  gr_layer *l = hatch_thin(r, d, &rep, &nt, ib);
  CHECK(nt == N && rep.thin_walls == N, "%zu thin scans, %d thin walls, %d teeth", nt, rep.thin_walls, N);
  int seen[N] = {0};
  for (size_t t = 0; t < l->nb; t++) {
    const gr_block *B = &l->b[t];
    const double *q = l->xy + 2 * B->start;
    if (B->dir != GR_DIR_THIN) continue;
    int j = (int)floor((q[0] - 0.2) / 0.2 + 0.5);
    CHECK(j >= 0 && j < N, "scan at x = %g", q[0]);
    if (j < 0 || j >= N) continue;
    seen[j]++;
    double x = 0.2 + 0.2 * j, lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < B->n; k++) {
      CHECK(q[2 * k] > x && q[2 * k] < x + 0.03, "tooth %d: point at x = %g", j, q[2 * k]);
      lo = fmin(lo, q[2 * k + 1]);
      hi = fmax(hi, q[2 * k + 1]);
    }
    /* from about where the bar's contour melts to 0.8 b short of the tip */
    CHECK(lo > 0.5 - b && lo < 0.5 + 2 * b && hi > 1 - 2 * b && hi < 1, "tooth %d: scan y %g..%g", j, lo, hi);
  }
  for (int j = 0; j < N; j++) CHECK(seen[j] == 1, "tooth %d scanned %d times", j, seen[j]);
  gr_layer_free(l);
  gr_rings_free(r);
  r = comb(N, 0.12);
  l = hatch_thin(r, d, &rep, &nt, ib);
  CHECK(nt == 0 && rep.thin_walls == 0 && rep.contours == 1, "wide teeth: %zu thin scans, %zu contours", nt, rep.contours);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* Two strips 1 mm long, 0.03 mm wide (< 2b at d = 0.05), at y = 0 and y = 0.5. */
static gr_rings *two_walls(void) {
  gr_rings *r = rect(0, 0, 1, 0.03);
  double p[8] = {0, 0.5, 1, 0.5, 1, 0.53, 0, 0.53};
  gr_rings_add(r, p, 4);
  return r;
}

/* Verify l over r with track d, offset d/2, pixel d/20. */
static gr_verify_result verify_d(const gr_rings *r, const gr_layer *l, double d) {
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = d;
  vo.offset = d / 2;
  vo.pixel = d / 20;
  gr_verify_result vr;
  gr_err e;
  CHECK(gr_verify_layer(r, l, &vo, &vr, &e) == GR_OK, "%s", e.msg);
  return vr;
}

/* A lens narrower than 2b gets one centre line on its chord, ending where
 * the half width drops below d/16 (the analytic length), no contour. */
TEST(thin_lens_centre_line) {
  double d = 0.05, c = 0.5, w = 0.02;
  gr_rings *r = lens(1, 1, c, w, 600);
  gr_hatch_report rep;
  size_t ib[8], nt;
  gr_layer *l = hatch_thin(r, d, &rep, &nt, ib);
  CHECK(nt == 1 && l->nb == 1, "%zu thin scans of %zu blocks", nt, l->nb);
  CHECK(rep.thin_walls == 1 && rep.thin_scans == 1 && rep.contours == 0 && rep.hatches == 0,
        "thin walls %d, scans %zu, contours %zu, hatches %zu", rep.thin_walls, rep.thin_scans, rep.contours, rep.hatches);
  if (l->nb == 1) {
    const gr_block *B = &l->b[0];
    const double *q = l->xy + 2 * B->start;
    double R = (c * c + w * w) / (2 * w), wm = d / 16;
    double xs = sqrt(R * R - (R - w + wm) * (R - w + wm)); /* half width wm there */
    double len = gr_block_length(l, B);
    CHECK(B->kind == GR_CONTOUR && B->shape == GR_OPEN, "kind %d shape %d", B->kind, B->shape);
    CHECK_NEAR(len, 2 * xs, 2 * d / 8);
    CHECK_NEAR(rep.thin_length, len, 1e-12);
    for (size_t k = 0; k < B->n; k++) {
      CHECK(fabs(q[2 * k + 1] - 1) < 2e-5, "point %zu off the chord by %g", k, q[2 * k + 1] - 1);
      CHECK(gr_rings_contains(r, q[2 * k], q[2 * k + 1]), "point %zu outside the lens", k);
    }
    /* nearly all of the lens melts; verify counts the line apart */
    gr_verify_result vr = verify_d(r, l, d);
    CHECK(vr.pore < 0.01, "pore %g", vr.pore);
    CHECK(vr.contour_points == 0 && vr.max_dev == 0 && vr.thin_scans == 1 && vr.thin_points == B->n,
          "contour points %zu, dev %g, thin scans %zu, points %zu", vr.contour_points, vr.max_dev, vr.thin_scans,
          vr.thin_points);
    CHECK_NEAR(vr.thin_length, len, 1e-9);
  }
  gr_layer_free(l);
  gr_rings_free(r);
}

/* A disc (radius 0.5) with a thin tail (0.03 x 0.4, half width 0.015 < b):
 * a contour at b on the disc, a centre line in the tail from the contour's
 * melt to 0.8 b before the tail's end; the layer melts all but a sliver. */
TEST(thin_tail_on_thick_body) {
  double d = 0.05, b = d / 2, R = 0.5, hw = 0.015, x1 = 0.9;
  gr_rings *r = gr_rings_new();
  int n = 720;
  double a0 = asin(hw / R);
  for (int i = 0; i <= n; i++) {
    double t = a0 + (2 * PI - 2 * a0) * i / n;
    gr_rings_point(r, R * cos(t), R * sin(t));
  }
  gr_rings_point(r, x1, -hw);
  gr_rings_point(r, x1, hw);
  gr_rings_close(r);
  gr_hatch_report rep;
  size_t ib[8], nt;
  gr_layer *l = hatch_thin(r, d, &rep, &nt, ib);
  CHECK(nt == 1, "%zu thin scans", nt);
  CHECK(rep.thin_walls == 1 && rep.contours == 1 && rep.hatches > 0, "thin walls %d, contours %zu, hatches %zu",
        rep.thin_walls, rep.contours, rep.hatches);
  if (nt == 1) {
    const gr_block *B = &l->b[ib[0]];
    const double *q = l->xy + 2 * B->start;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < B->n; k++) {
      lo = fmin(lo, q[2 * k]);
      hi = fmax(hi, q[2 * k]);
      CHECK(fabs(q[2 * k + 1]) < 1e-5, "point %zu off the tail's axis by %g", k, q[2 * k + 1]);
    }
    /* the contour at b (radius R - b) melts up to x = R within the tail
     * (half width 0.015): the line starts about there, ends 0.8 b early */
    CHECK(lo > R - b && lo < R + b, "line starts at x = %g", lo);
    CHECK_NEAR(hi, x1 - 0.8 * b, d / 8);
  }
  for (size_t k = 0; k < l->nb; k++)
    if (l->b[k].kind == GR_CONTOUR && l->b[k].dir != GR_DIR_THIN)
      CHECK(l->b[k].shape == GR_CLOSED, "disc contour closed");
  gr_verify_result vr = verify_d(r, l, d);
  CHECK(vr.pore < 0.002, "pore %g", vr.pore);
  CHECK(vr.max_dev < 1e-3, "contour deviation %g (thin line excluded)", vr.max_dev);
  CHECK(vr.thin_scans == 1 && vr.contour_points > 100, "thin scans %zu, contour points %zu", vr.thin_scans,
        vr.contour_points);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* Two thin walls apart: two centre lines, two thin walls counted; a wall
 * thinner than d/8 everywhere (a whole component) still gets a scan. */
TEST(thin_walls_apart_and_tiny) {
  double d = 0.05;
  gr_rings *r = two_walls();
  gr_hatch_report rep;
  size_t nt;
  gr_layer *l = hatch_thin(r, d, &rep, &nt, NULL);
  CHECK(nt == 2 && rep.thin_walls == 2 && l->thin_walls == 2 && rep.contours == 0,
        "%zu thin scans, %d thin walls, %zu contours", nt, rep.thin_walls, rep.contours);
  CHECK(rep.thin_length > 2 * 0.95 && rep.thin_length < 2.0, "thin length %g", rep.thin_length);
  gr_rings_free(r);
  gr_layer_free(l);
  r = rect(0, 0, 0.4, 0.005); /* 5 um wide: below the d/8 limit everywhere */
  l = hatch_thin(r, d, &rep, &nt, NULL);
  CHECK(nt == 1 && rep.thin_walls == 1, "tiny wall: %zu scans, %d thin walls", nt, rep.thin_walls);
  for (size_t k = 0; k < l->npts; k++)
    CHECK(gr_rings_contains(r, l->xy[2 * k], l->xy[2 * k + 1]), "tiny wall scan point %zu outside", k);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* thin_box: of two thin walls, only the one reaching the box is scanned and
 * counted (a window cut from a larger section has slivers along its cut);
 * a thick square with a sliver outside the box gets no thin scan at all. */
TEST(thin_walls_only_where_they_reach_the_box) {
  double d = 0.05;
  gr_rings *r = two_walls();
  gr_hatch_report rep;
  size_t nt;
  const double upper[4] = {0.2, 0.4, 0.8, 1.0};
  gr_layer *l = hatch_thin_in(r, d, upper, &rep, &nt, NULL);
  CHECK(nt == 1 && rep.thin_walls == 1, "%zu thin scans, %d thin walls", nt, rep.thin_walls);
  for (size_t b = 0; b < l->nb; b++)
    if (l->b[b].dir == GR_DIR_THIN)
      for (size_t k = 0; k < l->b[b].n; k++)
        CHECK(fabs(l->xy[2 * (l->b[b].start + k) + 1] - 0.515) < 1e-3, "the scanned wall is the upper one");
  gr_layer_free(l);
  gr_rings_free(r);
  r = rect(0, 0, 1, 1);
  double s[8] = {2, 0, 3, 0, 3, 0.02, 2, 0.02}; /* a 20 um sliver beside it */
  gr_rings_add(r, s, 4);
  const double square[4] = {-0.1, -0.1, 1.1, 1.1}, wider[4] = {-0.1, -0.1, 2.5, 1.1};
  l = hatch_thin_in(r, d, square, &rep, &nt, NULL);
  CHECK(nt == 0 && rep.thin_walls == 0 && rep.contours == 1, "sliver outside the box ignored: %d", rep.thin_walls);
  gr_layer_free(l);
  l = hatch_thin_in(r, d, wider, &rep, &nt, NULL); /* now it reaches the box */
  CHECK(rep.thin_walls == 1, "sliver reaching the box scanned: %d", rep.thin_walls);
  gr_layer_free(l);
  gr_rings_free(r);
}

TEST(bad_input) {
  gr_rings *r = rect(0, 0, 1, 1);
  gr_layer *l = gr_layer_new(0);
  gr_err e;
  gr_hatch_opts o = base(-0.05, 0);
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_EARG, "spacing");
  CHECK(strstr(e.msg, "spacing") && strstr(e.msg, "-0.05"), "%s", e.msg);
  o = base(0.1, NAN);
  CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "angle"), "%s", e.msg);
  o = base(0.1, 0);
  o.contours = -1;
  CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "contours"), "%s", e.msg);
  o = base(0.1, 0);
  o.pattern = GR_ISLAND;
  o.island = 0;
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "island"), "%s", e.msg);
  o = base(0.1, 0);
  o.beam_offset = -1;
  CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "beam_offset"), "%s", e.msg);
  o = base(0.1, 0);
  o.min_length = NAN;
  CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "min_length"), "%s", e.msg);
  o = base(1e-9, 0);
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_EARG && strstr(e.msg, "lines"), "%s", e.msg);
  CHECK(l->nb == 0, "nothing added on error");
  /* an empty region is fine and gives nothing */
  gr_rings *z = gr_rings_new();
  o = base(0.1, 0);
  CHECK(gr_hatch_layer(z, &o, l, NULL, &e) == GR_OK && l->nb == 0, "%s", e.msg);
  gr_rings_free(z);
  gr_layer_free(l);
  gr_rings_free(r);
}

int main(void) {
  RUN(square_count_and_length);
  RUN(diagonal_length_is_area_over_d);
  RUN(vectors_inside_nonconvex);
  RUN(rotation_sequence);
  RUN(alternate_reverses_every_other_line);
  RUN(zigzag_stays_inside);
  RUN(islands_alternate_and_clip);
  RUN(global_line_family);
  RUN(min_length_drops_and_counts);
  RUN(layer_contour_and_region);
  RUN(thin_wall_scanned_and_counted);
  RUN(thin_lens_centre_line);
  RUN(thin_tail_on_thick_body);
  RUN(thin_teeth_of_a_comb);
  RUN(thin_walls_apart_and_tiny);
  RUN(thin_walls_only_where_they_reach_the_box);
  RUN(bad_input);
  DONE();
}
