/* Crossings refined by Newton steps (march.c): a step may end the search
 * without an evaluation at its end only when that cannot leave the crossing
 * farther than the tolerance from the zero set (today: the step itself is
 * shorter than the tolerance). The field here bends sharply once along every
 * grid row: a concave kink at distance delta past the root (slope 3 before
 * it, 1 after). The first point tried (linear interpolation between the
 * nodes) can fall past the kink, and a Newton step from there overshoots the
 * root by 2 delta. The crossings must lie within the tolerance of the true
 * zero set, at every delta and position of the root between nodes. */
#include "check.h"
#include "slice.h"
#include "march.h"
#include <stdlib.h>

typedef struct kinked { double a0, tilt, delta, exact; } kinked;

/* The root along row y: x = a0 + tilt y. */
static double root_x(const kinked *k, double y) { return k->a0 + k->tilt * y; }

static int kinked_grad(void *ud, size_t n, const double *x, const double *y, double *out, double *gx, double *gy,
                       gr_err *e) {
  (void)e;
  const kinked *k = ud;
  for (size_t i = 0; i < n; i++) {
    double a = root_x(k, y[i]), xk = a + k->delta;
    double steep = 3 * (x[i] - a), flat = x[i] - xk + 3 * k->delta; /* min: slope 3 before xk, 1 after */
    int s = steep < flat;
    out[i] = s ? steep : flat;
    if (gx) gx[i] = s ? 3 : 1;
    if (gy) gy[i] = s ? -3 * k->tilt : -k->tilt;
  }
  return GR_OK;
}

static int kinked_fn(void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  return kinked_grad(ud, n, x, y, out, NULL, NULL, e);
}

/* Slice the window [0, 0.3] x [0, 3] (grid 0.025 mm, crossing tolerance
 * tol) and return the worst distance of a ring point from the line
 * x = a0 + tilt y. */
static double worst_offset(kinked *k, double tol, int *npts, gr_err *e) {
  gr_slice_opts o = gr_slice_defaults();
  o.tol = tol;
  o.exact = k->exact;
  o.lo[0] = 0;
  o.lo[1] = 0;
  o.hi[0] = 0.3;
  o.hi[1] = 3;
  o.cell = 0.025;
  int nx, ny;
  double hx, hy;
  gr_slice_grid_size(&o, &nx, &ny, &hx, &hy);
  size_t nn = (size_t)nx * ny;
  double *v = malloc(nn * sizeof *v), *xs = malloc(nn * sizeof *xs), *ys = malloc(nn * sizeof *ys);
  if (!v || !xs || !ys) { free(v); free(xs); free(ys); *npts = 0; return INFINITY; }
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      xs[i + (size_t)nx * j] = o.lo[0] + i * hx;
      ys[i + (size_t)nx * j] = o.lo[1] + j * hy;
    }
  kinked_fn(k, nn, xs, ys, v, e);
  gr_rings *r = gr_rings_new();
  double worst = INFINITY;
  *npts = 0;
  if (r && gr_slice_grid(v, &o, kinked_fn, kinked_grad, k, r, e) == GR_OK) {
    worst = 0;
    for (size_t q = 0; q < r->npts; q++) {
      double x = r->xy[2 * q], y = r->xy[2 * q + 1];
      if (x <= o.lo[0] || x >= o.hi[0] || y <= o.lo[1] || y >= o.hi[1]) continue; /* the window's border */
      worst = fmax(worst, fabs(x - root_x(k, y)) / sqrt(1 + k->tilt * k->tilt));
      ++*npts;
    }
  }
  gr_rings_free(r);
  free(v);
  free(xs);
  free(ys);
  return worst;
}

/* Kinks delta = 1 nm * 10^(d / per), d = 0 .. steps, past the root of every
 * row (exact: gr_slice_opts.exact): every crossing within the tolerance of
 * the zero set. */
static void kinked_sweep(int steps, double per, double exact, double tol, const char *what) {
  gr_err e;
  double worst = 0;
  int total = 0;
  for (int d = 0; d <= steps; d++) {
    kinked k = {0.100002, 5e-5, 1e-6 * pow(10, d / per), exact};
    int n;
    double w = worst_offset(&k, tol, &n, &e);
    CHECK(n > 100, "delta %g mm: %d ring points (%s)", k.delta, n, e.msg);
    worst = fmax(worst, w);
    total += n;
  }
  printf("  info: %d crossings of kinked rows%s: farthest %.3g nm from the zero set (tolerance %.3g nm)\n", total,
         what, worst * 1e6, tol * 1e6);
  CHECK(worst <= 1.01 * tol, "a crossing lies %.3g nm from the zero set%s, more than the tolerance %.3g nm",
        worst * 1e6, what, tol * 1e6);
}

TEST(newton_kink_before_root) {
  /* delta from 1 nm to 100 nm; the line tilts so that the root moves off a
   * node along x (u = 2e-6 + 5e-5 y mm past it, 121 rows): the first point
   * tried falls past the kink when u is small. Accepting every step under
   * 0.1 um unchecked puts crossings 32 nm off here. */
  kinked_sweep(40, 20, 0, gr_slice_defaults().tol, "");
}

/* A circle of radius R about c, f = |p - c| - R; its gradient scaled by
 * gscale (1: exact) and the points evaluated with it counted. */
typedef struct circ { double cx, cy, R, gscale; size_t npts; } circ;

static int circ_grad(void *ud, size_t n, const double *x, const double *y, double *out, double *gx, double *gy,
                     gr_err *e) {
  (void)e;
  circ *c = ud;
  if (gx) c->npts += n; /* the crossings' (hidden-boundary probes take the value only) */
  for (size_t i = 0; i < n; i++) {
    double dx = x[i] - c->cx, dy = y[i] - c->cy, r = hypot(dx, dy);
    out[i] = r - c->R;
    if (gx) gx[i] = c->gscale * dx / r;
    if (gy) gy[i] = c->gscale * dy / r;
  }
  return GR_OK;
}

static int circ_fn(void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  return circ_grad(ud, n, x, y, out, NULL, NULL, e);
}

/* The circle sampled on the grid of window [0, 2]^2 with cell `cell` (the
 * caller frees it), its options in *o. */
static double *circle_grid(const circ *c, double cell, gr_slice_opts *o) {
  *o = gr_slice_defaults();
  o->lo[0] = o->lo[1] = 0;
  o->hi[0] = o->hi[1] = 2;
  o->cell = cell;
  o->chord_tol = 0;
  int nx, ny;
  double hx, hy;
  gr_slice_grid_size(o, &nx, &ny, &hx, &hy);
  double *v = malloc((size_t)nx * ny * sizeof *v);
  for (int j = 0; v && j < ny; j++)
    for (int i = 0; i < nx; i++) v[i + (size_t)nx * j] = hypot(o->lo[0] + i * hx - c->cx, o->lo[1] + j * hy - c->cy) - c->R;
  return v;
}

/* Contour the circle on a 0.025 mm grid (no chord pass): the farthest ring
 * point from it (mm), the points evaluated per crossing in *per. */
static double circle_crossings(circ *c, double *per, gr_err *e) {
  gr_slice_opts o;
  double *v = circle_grid(c, 0.025, &o), worst = INFINITY;
  gr_rings *r = gr_rings_new();
  *per = INFINITY;
  c->npts = 0;
  if (v && r && gr_slice_grid(v, &o, circ_fn, circ_grad, c, r, e) == GR_OK && r->npts) {
    worst = 0;
    for (size_t q = 0; q < r->npts; q++)
      worst = fmax(worst, fabs(hypot(r->xy[2 * q] - c->cx, r->xy[2 * q + 1] - c->cy) - c->R));
    *per = (double)c->npts / (double)r->npts;
  }
  gr_rings_free(r);
  free(v);
  return worst;
}

/* Where the field is smooth and its slope right, a crossing ends after one
 * evaluation (the Newton step's error bounded from the parabolas through the
 * edge's ends); where the slope is off by 2 % (a graded thickness's slope
 * left out), the same bound sees it and the crossings still meet the
 * tolerance. */
TEST(newton_one_evaluation_when_smooth) {
  gr_err e;
  double tol = gr_slice_defaults().tol;
  for (int k = 0; k < 2; k++) {
    circ c = {1.0013, 0.9871, 0.3 + 0.4 * k, 1, 0};
    double per, w = circle_crossings(&c, &per, &e);
    printf("  info: circle R %.1f mm: %.2f points per crossing, farthest %.3g nm\n", c.R, per, w * 1e6);
    CHECK(w <= tol, "circle R %g: a crossing %.3g nm off (tolerance %.3g nm)", c.R, w * 1e6, tol * 1e6);
    CHECK(per < 1.5, "circle R %g: %.2f points evaluated per crossing, expected about one (two before)", c.R, per);
    c.gscale = 1.02;
    w = circle_crossings(&c, &per, &e);
    printf("  info: slope 2 %% off: %.2f points per crossing, farthest %.3g nm\n", per, w * 1e6);
    CHECK(w <= tol, "circle R %g, slope 2 %% off: a crossing %.3g nm off (tolerance %.3g nm)", c.R, w * 1e6,
          tol * 1e6);
  }
}

static int always_smooth(void *ud, const double a[2], const double b[2]) {
  (void)ud; (void)a; (void)b;
  return 1;
}

/* A circle's section with the chord pass (0.2 um, grid 0.05 mm), chords
 * judged by their neighbours where `smooth` says so: the farthest any chord
 * strays from the circle (its sagitta, exact for a chord of a circle), and
 * the points evaluated (all calls) in *npts. */
static double circle_chords(circ *c, gr_slice_smooth_fn smooth, size_t *npts, gr_err *e) {
  gr_slice_opts o;
  double *v = circle_grid(c, 0.05, &o), worst = INFINITY;
  gr_rings *r = gr_rings_new();
  o.chord_tol = 2e-4;
  o.smooth = smooth;
  c->npts = 0;
  if (v && r && gr_slice_grid(v, &o, circ_fn, circ_grad, c, r, e) == GR_OK && r->npts) {
    worst = 0;
    for (size_t i = 0; i < r->nrings; i++) {
      size_t len = gr_ring_len(r, i);
      const double *q = gr_ring_xy(r, i);
      for (size_t k = 0; k < len; k++) {
        const double *a = q + 2 * k, *b = q + 2 * ((k + 1) % len);
        double L = hypot(b[0] - a[0], b[1] - a[1]);
        /* ends off the circle by their crossing tolerance at most: the sagitta of the chord */
        worst = fmax(worst, c->R - sqrt(fmax(0, c->R * c->R - 0.25 * L * L)));
      }
    }
  }
  *npts = c->npts;
  gr_rings_free(r);
  free(v);
  return worst;
}

/* Chords of a smooth curve judged by the circles through their neighbours:
 * where the section is smooth, chords within half the tolerance by both
 * circles are not evaluated; every chord of the result still lies within
 * the chord tolerance of the true circle, and fewer points are evaluated. */
TEST(chords_judged_by_neighbours) {
  gr_err e;
  for (int k = 0; k < 2; k++) {
    circ c = {1.0013, 0.9871, 0.3 + 0.4 * k, 1, 0};
    size_t all, fewer;
    double w0 = circle_chords(&c, NULL, &all, &e), w1 = circle_chords(&c, always_smooth, &fewer, &e);
    printf("  info: circle R %.1f mm: %zu points evaluated checking every chord, %zu judging by neighbours; "
           "farthest chord %.3g / %.3g um\n", c.R, all, fewer, w0 * 1e3, w1 * 1e3);
    CHECK(w0 <= 2e-4 && w1 <= 2e-4, "circle R %g: a chord strays %.3g / %.3g um (tolerance 0.2 um)", c.R, w0 * 1e3,
          w1 * 1e3);
    CHECK(fewer < all, "circle R %g: judging chords by their neighbours evaluated %zu points, checking all %zu", c.R,
          fewer, all);
  }
}

/* Crossings from the nodes' cubic (gr_slice_opts.exact): on a circle most
 * crossings are taken from the grid's own values, with no evaluation (on a
 * circle of radius 0.6 mm or more), and every crossing stays within the
 * tolerance of the circle; where the field
 * bends sharply between nodes (the kinked rows above, a kink from 1 nm to
 * 20 um past the root, as the medial surface makes one) the fourth
 * differences see it and the crossing is refined on the field; nodes beyond
 * `exact` (bounds, here clamped values) are not used. */
/* The circles at crossing tolerance tol: every crossing within it of the
 * circle, and (R >= 0.6 mm) most crossings from the nodes' cubic; the
 * points evaluated per crossing into per[k]. */
static void cubic_circles(double tol, double per_out[3]) {
  gr_err e;
  for (int k = 0; k < 3; k++) {
    circ c = {1.0013, 0.9871, 0.3 + 0.3 * k, 1, 0};
    gr_slice_opts o;
    double *v = circle_grid(&c, 0.025, &o);
    gr_rings *r = gr_rings_new();
    CHECK(v && r, "out of memory");
    if (!v || !r) { free(v); gr_rings_free(r); return; }
    o.tol = tol;
    int nx, ny;
    double hx, hy;
    gr_slice_grid_size(&o, &nx, &ny, &hx, &hy);
    /* beyond 3 cells the nodes hold a bound only (clamped): not exact */
    for (size_t q = 0; q < (size_t)nx * ny; q++)
      if (fabs(v[q]) > 3 * hx) v[q] = v[q] < 0 ? -3.5 * hx : 3.5 * hx;
    o.exact = 3 * hx;
    double worst = INFINITY, per = INFINITY;
    if (gr_slice_grid(v, &o, circ_fn, circ_grad, &c, r, &e) == GR_OK && r->npts) {
      worst = 0;
      for (size_t q = 0; q < r->npts; q++)
        worst = fmax(worst, fabs(hypot(r->xy[2 * q] - c.cx, r->xy[2 * q + 1] - c.cy) - c.R));
      per = (double)c.npts / (double)r->npts;
    }
    per_out[k] = per;
    printf("  info: tolerance %g nm, circle R %.1f mm, crossings from the cubic: %.2f points evaluated per crossing, "
           "farthest %.3g nm\n", tol * 1e6, c.R, per, worst * 1e6);
    CHECK(worst <= tol, "circle R %g: a crossing %.3g nm off (tolerance %.3g nm)", c.R, worst * 1e6, tol * 1e6);
    /* R 0.3: f's fourth derivative along the grid lines is near the
     * 1 nm tolerance's limit (about 1 / R^3), most crossings are refined */
    if (k > 0)
      CHECK(per < 0.5, "circle R %g: %.2f points evaluated per crossing, expected most from the cubic", c.R, per);
    gr_rings_free(r);
    free(v);
  }
}

/* At the slices' default tolerance (1 nm) and at the engine's sections'
 * (GR_CROSS_TOL, 10 nm): within each, and the wider one takes more
 * crossings from the cubic (fewer evaluations) on the tightest circle. */
TEST(crossings_from_the_nodes_cubic) {
  double fine[3], wide[3];
  cubic_circles(gr_slice_defaults().tol, fine);
  cubic_circles(GR_CROSS_TOL, wide);
  CHECK(wide[0] < fine[0], "R 0.3 mm: %.2f points per crossing at %g nm, %.2f at %g nm", wide[0],
        GR_CROSS_TOL * 1e6, fine[0], gr_slice_defaults().tol * 1e6);
  kinked_sweep(43, 10, 1, gr_slice_defaults().tol, " with the cubic on"); /* 1 nm to 20 um */
  kinked_sweep(43, 10, 1, GR_CROSS_TOL, " with the cubic on, at GR_CROSS_TOL");
}

/* The hidden-boundary scan (hidden.c): a void sliver narrower than the
 * grid along a line between two columns (or rows), f = |x - s| - w / 2,
 * has every node outside; only the probes between the nodes find it. It
 * must be found wherever it lies: between the first two or the last two
 * columns or rows as well as inside (the scan tests a row's ends apart
 * from its inside, and the last row has no edges along y), with lip = 0
 * and with f's slope bound lip = 1; and not found when the sliver is
 * shallower than the probes' depth (1 um) or absent. */
typedef struct sliver { double s, w; int along_y; } sliver;

static int sliver_fn(void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  (void)e;
  const sliver *c = ud;
  for (size_t i = 0; i < n; i++) out[i] = fabs((c->along_y ? y[i] : x[i]) - c->s) - c->w / 2;
  return GR_OK;
}

TEST(hidden_slivers_at_every_border) {
  enum { N = 12 };
  double h = 0.1, v[N * N];
  for (int along_y = 0; along_y < 2; along_y++)
    for (int gap = 0; gap < N - 1; gap++)
      for (int kind = 0; kind < 3; kind++) { /* a sliver 20 um wide, one 1.6 um wide (0.8 um deep), none */
        sliver c = {(gap + 0.5) * h, kind == 0 ? 0.02 : kind == 1 ? 0.0016 : -0.2, along_y};
        gr_ms_grid g = {N, N, 0, 0, h, h, v, 0};
        for (int j = 0; j < N; j++)
          for (int i = 0; i < N; i++) {
            double x = i * h, y = j * h;
            sliver_fn(&c, 1, &x, &y, v + i + N * j, NULL);
          }
        for (int lip = 0; lip < 2; lip++) {
          int hidden = -1;
          gr_err e;
          gr_err_clear(&e);
          int rc = gr_ms_hidden(&g, lip, NULL, sliver_fn, &c, &hidden, &e);
          CHECK(rc == GR_OK, "scan failed: %s", e.msg);
          CHECK(hidden == (kind == 0), "%s sliver between %s %d and %d, lip %d: hidden %d",
                kind == 0 ? "a 20 um" : kind == 1 ? "a 0.8 um deep" : "no", along_y ? "rows" : "columns", gap,
                gap + 1, lip, hidden);
        }
      }
}

int main(void) {
  RUN(newton_kink_before_root);
  RUN(crossings_from_the_nodes_cubic);
  RUN(newton_one_evaluation_when_smooth);
  RUN(chords_judged_by_neighbours);
  RUN(hidden_slivers_at_every_border);
  DONE();
}
