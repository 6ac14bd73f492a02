/* The in-plane offset straight from the edges (offsetdirect.c, issue 14)
 * against analytic offsets (a regular polygon, a square with a square
 * hole, an annulus narrower than 2b that vanishes, a lens that vanishes)
 * and against the grid offset of the same polygons (random spiky stars,
 * sharp wedges with short edges): every vertex of a direct offset lies at
 * distance b from the polygon (to the arcs' chord tolerance), and the two
 * offsets lie within the chord tolerances of each other. Where the raw
 * offset is not simple (a neck narrower than 2b) it declines. */
#include <stdlib.h>
#include "check.h"
#include "slice.h"

#define B 0.025
#define TOL GR_OFFSET_CHORD_TOL
#define CELL 0.025

static void nest(gr_rings *r) {
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_rings_nest(r, &e) == GR_OK, "%s", e.msg);
}

static gr_rings *polygon(double cx, double cy, double R, int n, double phase) {
  gr_rings *r = gr_rings_new();
  for (int k = 0; k < n; k++) {
    double t = phase + 2 * M_PI * k / n;
    gr_rings_point(r, cx + R * cos(t), cy + R * sin(t));
  }
  gr_rings_close(r);
  return r;
}

/* The direct offset of r by B (nested first), the cut rectangle's sides
 * (or NULL) left in place: *done as the function says. */
static gr_rings *direct_cut(gr_rings *r, const double *cut, int *done) {
  nest(r);
  gr_rings *o = gr_rings_new();
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_offset_rings_direct(r, B, TOL, 2 * CELL, NULL, cut, 1, o, done, &e) == GR_OK, "%s", e.msg);
  if (*done) nest(o);
  return o;
}

static gr_rings *direct(gr_rings *r, int *done) { return direct_cut(r, NULL, done); }

static gr_rings *grid(const gr_rings *r) {
  gr_rings *o = gr_rings_new();
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_offset_rings_grid(r, B, CELL, 1, 1e-6, TOL, NULL, o, &e) == GR_OK, "%s", e.msg);
  return o;
}

static double seg_dist(double x, double y, const double *a, const double *b) {
  double ex = b[0] - a[0], ey = b[1] - a[1], L2 = ex * ex + ey * ey;
  double t = L2 > 0 ? ((x - a[0]) * ex + (y - a[1]) * ey) / L2 : 0;
  t = t < 0 ? 0 : t > 1 ? 1 : t;
  return hypot(a[0] + t * ex - x, a[1] + t * ey - y);
}

/* Distance from (x, y) to the rings' edges (brute force). */
static double rings_dist(const gr_rings *r, double x, double y) {
  double best = INFINITY;
  for (size_t i = 0; i < r->nrings; i++) {
    const double *p = gr_ring_xy(r, i);
    size_t n = gr_ring_len(r, i);
    for (size_t k = 0; k < n; k++) best = fmin(best, seg_dist(x, y, p + 2 * k, p + 2 * ((k + 1) % n)));
  }
  return best;
}

/* Largest distance from a vertex or chord middle of a to the edges of b. */
static double one_way(const gr_rings *a, const gr_rings *b) {
  double w = 0;
  for (size_t i = 0; i < a->nrings; i++) {
    const double *p = gr_ring_xy(a, i);
    size_t n = gr_ring_len(a, i);
    for (size_t k = 0; k < n; k++) {
      const double *q = p + 2 * ((k + 1) % n);
      w = fmax(w, rings_dist(b, p[2 * k], p[2 * k + 1]));
      w = fmax(w, rings_dist(b, 0.5 * (p[2 * k] + q[0]), 0.5 * (p[2 * k + 1] + q[1])));
    }
  }
  return w;
}

/* Every vertex of o at distance B from the polygon r, inside it: at most
 * the chord tolerance farther (a mitred reflex vertex), never nearer. */
static void check_on_offset(const gr_rings *r, const gr_rings *o, const char *what) {
  double lo = INFINITY, hi = 0;
  for (size_t k = 0; k < o->npts; k++) {
    double d = rings_dist(r, o->xy[2 * k], o->xy[2 * k + 1]);
    lo = fmin(lo, d);
    hi = fmax(hi, d);
    CHECK(gr_rings_contains(r, o->xy[2 * k], o->xy[2 * k + 1]), "%s: vertex %zu outside the polygon", what, k);
  }
  if (o->npts) CHECK(lo >= B - 1e-9 && hi <= B + TOL, "%s: vertex distances %.9f .. %.9f, b %g", what, lo, hi, B);
}

/* A regular 200-gon of radius 1: the offset is the 200-gon of inradius
 * R cos(pi / n) - B (convex: every corner mitred), area exact. */
TEST(regular_polygon_area) {
  int n = 200, done = 0;
  gr_rings *r = polygon(0.5, 0.5, 1, n, 0.1);
  gr_rings *o = direct(r, &done);
  CHECK(done && o->nrings == 1, "done %d, rings %zu", done, o->nrings);
  double ri = cos(M_PI / n) - B, want = n * ri * ri * tan(M_PI / n);
  CHECK_NEAR(gr_rings_area(o), want, 1e-12);
  check_on_offset(r, o, "200-gon");
  gr_rings_free(r);
  gr_rings_free(o);
}

/* A square of side 1 with a square hole of side 0.4: the outer square
 * shrinks to side 1 - 2B, the hole grows to side 0.4 + 2B with corners
 * rounded by B (arcs as chords within the tolerance). */
TEST(square_with_hole_area) {
  gr_rings *r = gr_rings_new();
  double outer[] = {0, 0, 1, 0, 1, 1, 0, 1}, inner[] = {0.3, 0.3, 0.3, 0.7, 0.7, 0.7, 0.7, 0.3};
  gr_rings_add(r, outer, 4);
  gr_rings_add(r, inner, 4);
  int done = 0;
  gr_rings *o = direct(r, &done);
  CHECK(done && o->nrings == 2, "done %d, rings %zu", done, o->nrings);
  double s = 1 - 2 * B, h = 0.4 + 2 * B, want = s * s - (h * h - (4 - M_PI) * B * B);
  /* chords inside each arc: the hole's area is smaller by at most the
   * segments between chords and arcs (4 quarter arcs, sagitta <= TOL) */
  double a = gr_rings_area(o);
  CHECK(a >= want - 1e-12 && a <= want + 2 * M_PI * B * TOL, "area %.12f, analytic %.12f", a, want);
  check_on_offset(r, o, "square with hole");
  gr_rings_free(r);
  gr_rings_free(o);
}

/* An annulus 0.04 wide (< 2B): the outer circle's raw offset lies inside
 * the hole's, both simple and apart, and the winding numbers leave nothing. */
TEST(narrow_annulus_vanishes) {
  gr_rings *r = polygon(0, 0, 1.04, 400, 0);
  gr_rings *h = polygon(0, 0, 1.0, 400, 0);
  gr_rings_append(r, h, 0, 0);
  int done = 0;
  gr_rings *o = direct(r, &done);
  CHECK(done && o->nrings == 0, "done %d, rings %zu", done, o->nrings);
  gr_rings *g = grid(r);
  CHECK(g->nrings == 0, "grid offset: %zu rings", g->nrings);
  gr_rings_free(r);
  gr_rings_free(h);
  gr_rings_free(o);
  gr_rings_free(g);
}

/* A lens 0.04 thick with sharp tips: nothing left. */
TEST(thin_lens_vanishes) {
  double c = 0.5, w = 0.02, R = (c * c + w * w) / (2 * w), a = asin(c / R);
  int n = 600, done = 0;
  gr_rings *r = gr_rings_new();
  for (int i = 0; i < n; i++) {
    double t = -a + 2 * a * i / n;
    gr_rings_point(r, 1 + R * sin(t), 1 - (R - w) + R * cos(t));
  }
  for (int i = 0; i < n; i++) {
    double t = a - 2 * a * i / n;
    gr_rings_point(r, 1 + R * sin(t), 1 + (R - w) - R * cos(t));
  }
  gr_rings_close(r);
  gr_rings *o = direct(r, &done);
  CHECK(!done || o->nrings == 0, "done %d, rings %zu, area %g", done, o->nrings, gr_rings_area(o));
  gr_rings_free(r);
  gr_rings_free(o);
}


/* A dumbbell (two squares joined by a neck 0.03 wide, < 2B): the raw ring
 * crosses itself with both loops counter-clockwise; the direct offset
 * declines, and the grid's has the two squares' offsets apart. */
TEST(narrow_neck_declines) {
  double p[] = {0, 0, 0.4, 0, 0.4, 0.185, 0.6, 0.185, 0.6, 0, 1, 0, 1, 0.4, 0.6, 0.4, 0.6, 0.215, 0.4, 0.215, 0.4, 0.4, 0, 0.4};
  gr_rings *r = gr_rings_new();
  gr_rings_add(r, p, 12);
  int done = 1;
  gr_rings *o = direct(r, &done);
  CHECK(!done, "done %d with %zu rings", done, o->nrings);
  gr_rings *g = grid(r);
  CHECK(g->nrings == 2, "grid offset: %zu rings", g->nrings);
  gr_rings_free(r);
  gr_rings_free(o);
  gr_rings_free(g);
}

/* A deterministic generator (no libc rand: the same shapes everywhere). */
static double lcg(unsigned long long *s) {
  *s = *s * 6364136223846793005ull + 1442695040888963407ull;
  return (double)(*s >> 11) / 9007199254740992.0;
}

/* Star-shaped rings with smooth waves, spikes narrower than 2B and short
 * edges at sharp corners (the swallowtails the direct offset cuts), some
 * with a hole: where the direct offset is made, its vertices lie at B
 * from the polygon and it agrees with the grid offset to the two chord
 * tolerances (the grid's chords and the arcs' chords); most are made. */
TEST(random_stars_match_the_grid) {
  unsigned long long seed = 14;
  int made = 0, shapes = 60;
  for (int s = 0; s < shapes; s++) {
    int n = 80 + (int)(lcg(&seed) * 300), waves = 2 + (int)(lcg(&seed) * 9);
    double amp = 0.05 + 0.25 * lcg(&seed), spikes = lcg(&seed) < 0.5 ? 0.0 : 0.08;
    gr_rings *r = gr_rings_new();
    for (int k = 0; k < n; k++) {
      double t = 2 * M_PI * k / n, rad = 0.6 * (1 + amp * sin(waves * t + s));
      if (k % 37 == 5) rad += spikes;           /* a spike one vertex wide */
      if (k % 23 == 7) t += 0.3 * M_PI / n;     /* a short edge after it */
      gr_rings_point(r, rad * cos(t), rad * sin(t));
    }
    gr_rings_close(r);
    if (s % 3 == 0) { /* a hole */
      gr_rings *h = polygon(0.05, -0.02, 0.12 + 0.1 * lcg(&seed), 40, lcg(&seed));
      gr_rings_append(r, h, 0, 0);
      gr_rings_free(h);
    }
    int done = 0;
    gr_rings *o = direct(r, &done);
    if (done) {
      made++;
      gr_rings *g = grid(r);
      char what[64];
      snprintf(what, sizeof what, "star %d", s);
      check_on_offset(r, o, what);
      CHECK(o->nrings == g->nrings, "%s: %zu rings, grid %zu", what, o->nrings, g->nrings);
      double ab = one_way(o, g), ba = one_way(g, o), lim = GR_OFFSET_CHORD_TOL + TOL + 1e-7;
      CHECK(ab <= lim && ba <= lim, "%s: direct to grid %.3f um, grid to direct %.3f um", what, 1e3 * ab, 1e3 * ba);
      CHECK_NEAR(gr_rings_area(o), gr_rings_area(g), 2 * lim * (gr_ring_length(g, 0) + 1));
      gr_rings_free(g);
    }
    gr_rings_free(r);
    gr_rings_free(o);
  }
  CHECK(made >= shapes / 2, "direct offsets made for %d of %d shapes", made, shapes);
  printf("    direct offsets made for %d of %d shapes\n", made, shapes);
}

/* The disk x^2 + y^2 < 1 (a 4000-gon) cut to the window x >= -0.5 (and
 * y, x < 2 beyond it): the cut side is no wall and moves out by B, where
 * the section's own offset would have moved it in by B; away from it the
 * offset is the circle of radius 1 - B (to the 4000-gon's 1 - cos(pi/n)). */
TEST(cut_side_moves_out) {
  int n = 4000, done = 0;
  double h = 0.5, cut[4] = {-h, -2, 2, 2}, dev = 1 - cos(M_PI / n);
  gr_rings *disk = polygon(0, 0, 1, n, 0);
  gr_rings *sec = gr_rings_new();
  const double *p = disk->xy;
  /* the section: the disk's points with x > -h, closed along x = -h */
  double ys = sqrt(1 - h * h);
  gr_rings_point(sec, -h, ys);
  gr_rings_point(sec, -h, -ys);
  for (int k = 0; k < n; k++)
    if (p[2 * k] > -h && p[2 * k + 1] < 0) gr_rings_point(sec, p[2 * k], p[2 * k + 1]);
  for (int k = 0; k < n; k++)
    if (p[2 * k] > -h && p[2 * k + 1] >= 0) gr_rings_point(sec, p[2 * k], p[2 * k + 1]);
  gr_rings_close(sec);
  gr_rings *o = direct_cut(sec, cut, &done);
  CHECK(done && o->nrings == 1, "done %d, rings %zu", done, o->nrings);
  double xmin = INFINITY, worst = 0, wmid = 0;
  int away = 0;
  for (size_t k = 0; k < o->npts; k++) {
    double x = o->xy[2 * k], y = o->xy[2 * k + 1];
    const double *q = o->xy + 2 * ((k + 1) % o->npts);
    xmin = fmin(xmin, x);
    if (x > -h + 3 * B && q[0] > -h + 3 * B) { /* farther than the offsets reach from the cut */
      away++;
      worst = fmax(worst, fabs(hypot(x, y) - (1 - B)));
      wmid = fmax(wmid, fabs(hypot(0.5 * (x + q[0]), 0.5 * (y + q[1])) - (1 - B)));
    }
  }
  CHECK_NEAR(xmin, -h - B, 1e-12);
  /* vertices on the 4000-gon's offset; chords within the tolerance of it
   * (the points between simplified away, convex: no arcs) */
  CHECK(away > 50 && worst <= dev + 1e-12 && wmid <= dev + TOL,
        "%d vertices away from the cut, off the circle by %.3g mm, chord middles by %.3g mm", away, worst, wmid);
  gr_rings *u = direct_cut(sec, NULL, &done);
  double umin = INFINITY;
  for (size_t k = 0; k < u->npts; k++) umin = fmin(umin, u->xy[2 * k]);
  CHECK(done && fabs(umin - (-h + B)) < 1e-12, "without the cut: done %d, leftmost x %.9f", done, umin);
  gr_rings_free(disk);
  gr_rings_free(sec);
  gr_rings_free(o);
  gr_rings_free(u);
}

/* The square [0, 1]^2, all four sides on the cut, with a notch 0.02 deep
 * (x < 0.02, 0.2 < y < 0.8) open to its left side: without the cut its
 * offset closes over the notch's mouth (the short stubs of the left side
 * swallowed by the notch's edges) and the direct offset declines; with it
 * the sides move out by B and the notch's edges in by B: the square
 * [-B, 1 + B]^2 less the notch grown by B, round at its two inner
 * corners (chords inside the arcs, within the tolerance). */
TEST(notch_at_the_cut) {
  double p[] = {0, 0, 1, 0, 1, 1, 0, 1, 0, 0.8, 0.02, 0.8, 0.02, 0.2, 0, 0.2};
  double cut[4] = {0, 0, 1, 1};
  gr_rings *r = gr_rings_new();
  gr_rings_add(r, p, 8);
  int done = 1;
  gr_rings *o = direct_cut(r, cut, &done);
  CHECK(done && o->nrings == 1, "with the cut: done %d, rings %zu", done, o->nrings);
  double s = 1 + 2 * B, notch = (0.02 + 2 * B) * (0.6 + 2 * B) - 2 * (1 - M_PI / 4) * B * B;
  double a = gr_rings_area(o), want = s * s - notch;
  CHECK(a >= want && a <= want + 2 * M_PI * B * TOL, "area %.9f, want %.9f", a, want);
  /* the vertices inside the square: at B from the notch's edges (the
   * ring of the notch, closed along its mouth on the cut side) */
  double q[] = {0, 0.8, 0.02, 0.8, 0.02, 0.2, 0, 0.2};
  gr_rings *notch_ring = gr_rings_new();
  gr_rings_add(notch_ring, q, 4);
  int inside = 0;
  for (size_t k = 0; k < o->npts; k++) {
    double x = o->xy[2 * k], y = o->xy[2 * k + 1];
    if (!(x > 0 && x < 1 && y > 0 && y < 1)) continue;
    inside++;
    double d = rings_dist(notch_ring, x, y);
    CHECK(d >= B - 1e-9 && d <= B + TOL, "vertex (%.6f, %.6f) %.9f from the notch", x, y, d);
  }
  CHECK(inside >= 4, "%d vertices inside the square", inside);
  gr_rings_free(notch_ring);
  gr_rings_free(r);
  gr_rings_free(o);
}

/* Two parts of the section on one side of the cut (x = 0), 0.01 apart
 * there, their facing edges slanting away from each other at 45 degrees
 * into the window: the joins of those edges with the moved side lie
 * between the parts' ends on the side (by B they stay on each part's own
 * bisector; moved out by 2B they crossed, and the offset declined): the
 * direct offset is made, two rings, and every vertex farther than 3B from
 * the cut lies at B from the section's edges. */
TEST(slanted_parts_at_the_cut) {
  double g = 0.01, yA = 0.5, yB = yA + g, cut[4] = {0, -3, 3, 4};
  double a[] = {0, -2, 2, -2, 2, yA - 2, 0, yA}, b[] = {0, yB, 2, yB + 2, 2, 3, 0, 3};
  gr_rings *r = gr_rings_new();
  gr_rings_add(r, a, 4);
  gr_rings_add(r, b, 4);
  gr_rings *sec = gr_rings_new();
  gr_rings_copy(sec, r);
  int done = 0;
  gr_rings *o = direct_cut(r, cut, &done);
  CHECK(done && o->nrings == 2, "done %d, rings %zu", done, o->nrings);
  int away = 0;
  for (size_t k = 0; k < o->npts; k++) {
    double x = o->xy[2 * k], y = o->xy[2 * k + 1];
    if (!(x > 3 * B)) continue;
    away++;
    double d = rings_dist(sec, x, y);
    CHECK(fabs(d - B) <= 1e-9, "vertex (%.6f, %.6f) %.9f from the section", x, y, d);
  }
  CHECK(away >= 4, "%d vertices away from the cut", away);
  gr_rings_free(r);
  gr_rings_free(sec);
  gr_rings_free(o);
}

int main(void) {
  RUN(regular_polygon_area);
  RUN(square_with_hole_area);
  RUN(narrow_annulus_vanishes);
  RUN(thin_lens_vanishes);
  RUN(narrow_neck_declines);
  RUN(random_stars_match_the_grid);
  RUN(cut_side_moves_out);
  RUN(notch_at_the_cut);
  RUN(slanted_parts_at_the_cut);
  DONE();
}
