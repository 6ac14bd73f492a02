/* polydist.c: signed 2-D distance to a set of rings and the in-plane
 * offsets of sections built on it (slice.h: gr_offset_rings*,
 * gr_rings_max_inner_distance, gr_polydist_*). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "march.h"

/* ---- 2-D distance to a polygon set (for offsets) ---- */

typedef struct poly_dist {
  size_t ne;            /* edges */
  double *ab;           /* 4 per edge: ax ay bx by */
  double lo[2];         /* bucket grid origin, mm */
  double bs;            /* bucket size, mm */
  int bx, by;           /* buckets per axis */
  size_t *bstart, *bedge; /* CSR: edges of bucket k are bedge[bstart[k]..bstart[k+1]) */
  int *bb;              /* 4 per edge: the buckets of its box, i0 i1 j0 j1 */
  double b;             /* offset distance, mm: fn returns sd + b */
  const gr_ms_grid *grid; /* sampled sd + b (signs exact, |sd| a lower bound), or NULL */
  struct pd_seen *seen; /* pd_fn's and pd_gfn's edge marks, or NULL */
  unsigned char *cut;   /* per edge: 1 along a window's cut (pd_mark_cut), or NULL */
  double cut_far;       /* a cut edge's distance counts this much more (mm) */
} poly_dist;

/* Marks of the edges one search has measured. An edge is listed in every
 * bucket its bounding box meets, so a search over a few buckets meets an
 * edge several times; measuring it again cannot change the result (its d2
 * is not below the best any more), so a marked edge is skipped. The marks
 * are mutable: only one offset (gr_offset_rings_opt) owns them, for the
 * queries of its own callbacks, which march.c and hidden.c make on the
 * offset's thread one at a time; shared objects (gr_polydist) search
 * without. */
typedef struct pd_seen {
  unsigned *mark; /* per edge: the id of the last search that measured it */
  unsigned id;    /* the current search's id (0 is never one) */
} pd_seen;

static void pd_free(poly_dist *d) {
  free(d->ab); free(d->bstart); free(d->bedge); free(d->bb); free(d->cut);
}

/* fmin and fmax inline, bit for bit as glibc returns them (the first
 * argument when they compare equal, as 0 and -0 do; the other one when one
 * is NaN): the library calls cost more than the comparisons. */
static inline double pd_min(double a, double b) { return a != a ? b : b < a ? b : a; }
static inline double pd_max(double a, double b) { return a != a ? b : b > a ? b : a; }

/* Squared distance from (x, y) to edge p (ax ay bx by) and the nearest
 * point's parameter t along it. */
static inline double edge_d2(const double *p, double x, double y, double *tpar) {
  double ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
  double t = L2 > 0 ? ((x - p[0]) * ex + (y - p[1]) * ey) / L2 : 0;
  if (t < 0) t = 0;
  if (t > 1) t = 1;
  double qx = p[0] + t * ex - x, qy = p[1] + t * ey - y;
  *tpar = t;
  return qx * qx + qy * qy;
}

/* pd_search's modes */
enum { PD_NEAREST, PD_ANY, PD_GROW };

/* pd_search's last ring for radius rmax: the rings out to rmax and one
 * more, and never more than cover all buckets. */
static int pd_kmax(const poly_dist *d, double rmax, int cap) {
  int kmax = (int)ceil(rmax / d->bs) + 1;
  return kmax > cap ? cap : kmax;
}

/* A squared distance d2 to an edge along a window's cut, counted far more
 * (pd_mark_cut's cut_far). */
static inline double pd_far_d2(double d2, double far) {
  double r = sqrt(d2) + far;
  return r * r;
}

/* Measure the edges listed in buckets ka..kb - 1 (consecutive buckets of one
 * row: the CSR lists their edges one bucket after the other, as a walk over
 * the buckets would meet them) against the best so far. Returns 1 when
 * PD_ANY finds an edge within rmax (its d2 in *best). */
static inline int pd_visit(const poly_dist *d, pd_seen *seen, unsigned id, size_t ka, size_t kb, double x,
                           double y, double rmax, int mode, double *best, size_t *edge, double *tpar) {
  for (size_t q = d->bstart[ka]; q < d->bstart[kb]; q++) {
    size_t ed = d->bedge[q];
    if (seen) {
      if (seen->mark[ed] == id) continue;
      seen->mark[ed] = id;
    }
    double t, d2 = edge_d2(d->ab + 4 * ed, x, y, &t);
    if (d->cut && d->cut[ed]) d2 = pd_far_d2(d2, d->cut_far);
    if (d2 < *best) { *best = d2; *edge = ed; *tpar = t; }
    if (mode == PD_ANY && sqrt(d2) <= rmax) { *best = d2; return 1; }
  }
  return 0;
}

/* How far v lies outside [lo, lo + bs] (0 inside). */
static inline double pd_gap(double v, double lo, double bs) {
  return v < lo ? lo - v : v > lo + bs ? v - lo - bs : 0;
}

/* Whether column i's bucket may hold an edge within sqrt(r2) of x along x
 * (r2 < 0: none). */
static inline int pd_near(const poly_dist *d, double x, int i, double r2) {
  double g = pd_gap(x, d->lo[0] + i * d->bs, d->bs);
  return g * g <= r2;
}

/* Narrow the columns [*a, *b] of a row to those pd_near keeps (the first and
 * last kept: the gap grows away from x's column). */
static inline void pd_row_span(const poly_dist *d, double x, double r2, int *a, int *b) {
  if (!(r2 < INFINITY)) return;
  while (*a <= *b && !pd_near(d, x, *a, r2)) (*a)++;
  while (*b >= *a && !pd_near(d, x, *b, r2)) (*b)--;
}

/* Nearest edge to (x, y) among edges within rmax (searching rings of buckets
 * outward: ring k's rows top to bottom, each left to right; a bucket farther
 * from the point than the best edge so far is passed over, as no edge in it
 * can be nearer). Returns the
 * squared distance (INFINITY if none within rmax) and the edge and
 * parameter; ties go to the edge met first. PD_ANY returns at the first edge
 * whose distance is <= rmax (a yes/no query: not the nearest). PD_GROW
 * repeats a search that finds nothing with rmax 4 times larger until it
 * finds an edge: the searches visit the same rings in the same order and
 * each ring leaves the same best, so this continues the failed search where
 * it stopped instead of starting over, with the same result. seen (or NULL)
 * skips edges met before (pd_seen). */
static double pd_search(const poly_dist *d, pd_seen *seen, double x, double y, double rmax, int mode,
                        size_t *edge, double *tpar) {
  double best = INFINITY;
  int ci = (int)floor((x - d->lo[0]) / d->bs), cj = (int)floor((y - d->lo[1]) / d->bs);
  int cap = (d->bx > d->by ? d->bx : d->by) + 2 + abs(ci) + abs(cj);
  int kmax = pd_kmax(d, rmax, cap);
  unsigned id = 0;
  if (seen && (id = ++seen->id) == 0) { /* ids wrapped around: forget all marks */
    memset(seen->mark, 0, d->ne * sizeof *seen->mark);
    id = seen->id = 1;
  }
  for (int k = 0; k <= kmax; k++) {
    int ia = ci - k < 0 ? 0 : ci - k, ib = ci + k >= d->bx ? d->bx - 1 : ci + k;
    int ja = cj - k < 0 ? 0 : cj - k, jb = cj + k >= d->by ? d->by - 1 : cj + k;
    for (int j = ja; j <= jb; j++) {
      size_t row = (size_t)d->bx * j;
      int hit = 0;
      /* buckets farther from the point than the best so far hold no nearer
       * edge (an edge lies in every bucket its box meets): skipped */
      double gy = pd_gap(y, d->lo[1] + j * d->bs, d->bs);
      if (!(gy * gy <= best)) continue;
      if (j == cj - k || j == cj + k) { /* the ring's first or last row: all of it within reach */
        int a = ia, b = ib;
        pd_row_span(d, x, best - gy * gy, &a, &b);
        if (a <= b) hit = pd_visit(d, seen, id, row + a, row + b + 1, x, y, rmax, mode, &best, edge, tpar);
      } else { /* a row between: its two ends */
        if (ci - k >= 0 && ci - k < d->bx && pd_near(d, x, ci - k, best - gy * gy))
          hit = pd_visit(d, seen, id, row + ci - k, row + ci - k + 1, x, y, rmax, mode, &best, edge, tpar);
        if (!hit && ci + k >= 0 && ci + k < d->bx && pd_near(d, x, ci + k, best - gy * gy))
          hit = pd_visit(d, seen, id, row + ci + k, row + ci + k + 1, x, y, rmax, mode, &best, edge, tpar);
      }
      if (hit) return best;
    }
    /* everything not yet searched is farther than k*bs from (x, y) when the
     * point is inside bucket (ci, cj); the search for rmax stops here when
     * that covers the best or rmax, or at its last ring */
    double safe = k * d->bs;
    while (best <= safe * safe || safe > rmax || k >= kmax) {
      if (!(best > rmax * rmax)) return best;
      if (mode != PD_GROW || !(rmax < INFINITY)) return INFINITY;
      rmax *= 4;
      kmax = pd_kmax(d, rmax, cap);
    }
  }
  return INFINITY; /* not reached: the last ring stops the search */
}

/* Inside by the even-odd rule (as the offset grid's signs are): crossings
 * of the horizontal line through (x, y) with the edges on one side of x,
 * read from the bucket row of y, each edge counted in the one bucket that
 * holds its crossing. Unlike a test from the nearest feature alone, this
 * stays right where two rings touch or cross (a window's section whose
 * rings meet along the window's cut): the sign then changes only on an
 * edge, so the signed distance has no jump away from the boundary. */
static int pd_inside(const poly_dist *d, double x, double y) {
  int cj = (int)floor((y - d->lo[1]) / d->bs);
  if (cj < 0 || cj >= d->by) return 0;
  int ci = (int)floor((x - d->lo[0]) / d->bs);
  int right = ci >= d->bx / 2; /* scan towards the nearer end of the row */
  int ia = right ? (ci < 0 ? 0 : ci) : 0, ib = right ? d->bx - 1 : (ci >= d->bx ? d->bx - 1 : ci);
  int odd = 0;
  for (int i = ia; i <= ib; i++) {
    size_t bk = (size_t)i + (size_t)d->bx * cj;
    for (size_t q = d->bstart[bk]; q < d->bstart[bk + 1]; q++) {
      const double *a = d->ab + 4 * d->bedge[q];
      double xc;
      if (!gr_edge_at_y(a[0], a[1], a[2], a[3], y, &xc)) continue;
      const int *bb = d->bb + 4 * d->bedge[q]; /* the box's columns (within the grid) */
      int ic = (int)floor((xc - d->lo[0]) / d->bs);
      ic = ic < bb[0] ? bb[0] : ic > bb[1] ? bb[1] : ic;
      if (ic == i && (right ? xc > x : xc <= x)) odd ^= 1;
    }
  }
  return odd;
}

/* Inside (1), outside (0) or not known (-1) from the sampled grid: a corner
 * C of the grid cell holding (x, y) whose sampled |sd| exceeds its distance
 * to the point has no boundary between them, so the point is on C's side
 * (the grid's signs are the even-odd rule's, as pd_inside's). Near the
 * offset contour, b deep, this spares the row scan. */
static int pd_grid_side(const poly_dist *d, double x, double y) {
  const gr_ms_grid *g = d->grid;
  if (!g) return -1;
  int i = (int)floor((x - g->x0) / g->hx), j = (int)floor((y - g->y0) / g->hy);
  for (int c = 0; c < 4; c++) {
    int ia = i + (c & 1), jb = j + (c >> 1);
    if (ia < 0 || jb < 0 || ia >= g->nx || jb >= g->ny) continue;
    double sd = g->v[ia + (size_t)g->nx * jb] - d->b, dx = x - (g->x0 + ia * g->hx), dy = y - (g->y0 + jb * g->hy);
    if (dx * dx + dy * dy < sd * sd) return sd < 0;
  }
  return -1;
}

/* Exact signed distance (negative inside) of (x, y) to the edges; q (may be
 * NULL) receives the nearest boundary point. +INFINITY without edges. The
 * search starts at 2 bucket sizes and grows 4 times at a time. */
static double pd_signed(const poly_dist *d, pd_seen *seen, double x, double y, double q[2]) {
  if (d->ne == 0) return INFINITY;
  size_t ed = 0;
  double t = 0, d2 = pd_search(d, seen, x, y, 2 * d->bs, PD_GROW, &ed, &t);
  const double *a = d->ab + 4 * ed;
  if (q) { q[0] = a[0] + t * (a[2] - a[0]); q[1] = a[1] + t * (a[3] - a[1]); }
  int in = pd_grid_side(d, x, y);
  if (in < 0) in = pd_inside(d, x, y);
  return in ? -sqrt(d2) : sqrt(d2);
}

/* Marks for the queries of one offset (NULL when out of memory: the
 * searches then measure edges again, with the same results). */
static pd_seen *pd_seen_new(const poly_dist *d, pd_seen *s) {
  s->id = 0;
  s->mark = d->ne ? calloc(d->ne, sizeof *s->mark) : NULL;
  return s->mark ? s : NULL;
}

/* Signed distance (negative inside) + b, exact. */
static int pd_fn(void *ud, size_t n, const double *x, const double *y,
                 double *out, gr_err *e) {
  (void)e;
  const poly_dist *d = ud;
  for (size_t k = 0; k < n; k++) out[k] = pd_signed(d, d->seen, x[k], y[k], NULL) + d->b;
  return GR_OK;
}

/* The same with its gradient: the signed distance's is the unit vector from
 * the nearest boundary point (outward), NaN on the boundary itself (the root
 * finder then brackets instead). Along a line the distance to one edge is
 * linear, so a Newton step lands on the offset in one step there. */
static int pd_gfn(void *ud, size_t n, const double *x, const double *y, double *out, double *gx, double *gy,
                  gr_err *e) {
  (void)e;
  const poly_dist *d = ud;
  for (size_t k = 0; k < n; k++) {
    double q[2] = {NAN, NAN}, sd = pd_signed(d, d->seen, x[k], y[k], q), dx = x[k] - q[0], dy = y[k] - q[1];
    double r = sqrt(dx * dx + dy * dy);
    out[k] = sd + d->b;
    double s = sd < 0 ? -1 / r : 1 / r;
    gx[k] = r > 0 ? s * dx : NAN;
    gy[k] = r > 0 ? s * dy : NAN;
  }
  return GR_OK;
}

static int same_pt(const double *p, size_t a, size_t b) {
  return p[2 * a] == p[2 * b] && p[2 * a + 1] == p[2 * b + 1];
}

/* Build edges and the bucket grid (bucket size about bs) of nested rings r. */
static int pd_build(poly_dist *d, const gr_rings *r, double bs, gr_err *e) {
  memset(d, 0, sizeof *d);
  d->ab = malloc(4 * r->npts * sizeof *d->ab + 1);
  if (!d->ab) return gr_fail(e, GR_EMEM, "out of memory: %zu edges", r->npts);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t i = 0; i < r->nrings; i++) {
    size_t n = gr_ring_len(r, i);
    const double *p = gr_ring_xy(r, i);
    /* edges between distinct consecutive points only: a repeated point (a
     * section passing exactly through a grid node, a snapped face corner)
     * would make a zero-length edge, which has no direction */
    size_t s0 = 0;
    while (s0 < n && same_pt(p, s0, (s0 + n - 1) % n)) s0++;
    for (size_t c = 0; c < n && s0 < n; c++) {
      size_t k = s0 + c < n ? s0 + c : s0 + c - n, k1 = k + 1 < n ? k + 1 : 0;
      if (same_pt(p, k, k1)) continue;
      double *a = d->ab + 4 * d->ne++;
      a[0] = p[2 * k]; a[1] = p[2 * k + 1]; a[2] = p[2 * k1]; a[3] = p[2 * k1 + 1];
      for (int q = 0; q < 2; q++) { lo[q] = pd_min(lo[q], a[q]); hi[q] = pd_max(hi[q], a[q]); }
    }
  }
  if (d->ne == 0) lo[0] = lo[1] = hi[0] = hi[1] = 0; /* no edges: one bucket */
  double w = fmax(hi[0] - lo[0], hi[1] - lo[1]);
  if (!(bs > 0)) bs = w / 16;
  /* at most ~4 buckets per edge and 4M buckets */
  double maxb = fmin(4.0 * (double)d->ne + 16, 4e6);
  while (((hi[0] - lo[0]) / bs + 1) * ((hi[1] - lo[1]) / bs + 1) > maxb) bs *= 1.5;
  if (!(bs > 0)) bs = 1;
  d->bs = bs;
  d->lo[0] = lo[0]; d->lo[1] = lo[1];
  d->bx = (int)floor((hi[0] - lo[0]) / bs) + 1;
  d->by = (int)floor((hi[1] - lo[1]) / bs) + 1;
  size_t nb = (size_t)d->bx * d->by;
  d->bstart = calloc(nb + 1, sizeof *d->bstart);
  d->bb = malloc(4 * d->ne * sizeof *d->bb + 1);
  if (!d->bstart || !d->bb) return gr_fail(e, GR_EMEM, "out of memory: %zu buckets", nb);
  for (size_t ed = 0; ed < d->ne; ed++) {
    const double *a = d->ab + 4 * ed;
    int *bb = d->bb + 4 * ed;
    bb[0] = (int)floor((pd_min(a[0], a[2]) - lo[0]) / bs);
    bb[1] = (int)floor((pd_max(a[0], a[2]) - lo[0]) / bs);
    bb[2] = (int)floor((pd_min(a[1], a[3]) - lo[1]) / bs);
    bb[3] = (int)floor((pd_max(a[1], a[3]) - lo[1]) / bs);
    if (bb[1] >= d->bx) bb[1] = d->bx - 1;
    if (bb[3] >= d->by) bb[3] = d->by - 1;
  }
  for (int pass = 0; pass < 2; pass++) {
    for (size_t ed = 0; ed < d->ne; ed++) {
      const int *bb = d->bb + 4 * ed;
      for (int j = bb[2]; j <= bb[3]; j++)
        for (int i = bb[0]; i <= bb[1]; i++) {
          size_t bk = (size_t)i + (size_t)d->bx * j;
          if (pass == 0) d->bstart[bk + 1]++;
          else d->bedge[d->bstart[bk]++] = ed;
        }
    }
    if (pass == 0) {
      for (size_t k = 0; k < nb; k++) d->bstart[k + 1] += d->bstart[k];
      d->bedge = malloc(d->bstart[nb] * sizeof *d->bedge + 1);
      if (!d->bedge) return gr_fail(e, GR_EMEM, "out of memory: %zu bucket entries", d->bstart[nb]);
    } else {
      for (size_t k = nb; k > 0; k--) d->bstart[k] = d->bstart[k - 1];
      d->bstart[0] = 0;
    }
  }
  return GR_OK;
}

/* A template's section is cut to a window whose sides are no walls (the
 * section goes on beyond them): the edges lying along a side of cut (x0 y0
 * x1 y1, to 1e-8 mm) are marked, and their distance counts far more (all
 * but a thousandth of b), so that the offset by b runs along the side
 * instead of b inside it (a strip of width b there, narrower than the
 * coarse grid, would have the strip search sample the grid again at one
 * cell); the grid's nodes on the side, whose sign is the even-odd rule's
 * on an edge, are outside either way. 0, or -1 out of memory. */
static int pd_mark_cut(poly_dist *d, const double *cut, double b) {
  d->cut_far = b * (1 - 1e-3);
  size_t n = 0;
  if (!cut || d->ne == 0) return 0;
  if (!(d->cut = calloc(d->ne, 1))) return -1;
  for (size_t ed = 0; ed < d->ne; ed++) {
    const double *a = d->ab + 4 * ed;
    for (int c = 0; c < 4 && !d->cut[ed]; c++)
      d->cut[ed] = fabs(a[c & 1] - cut[c]) <= 1e-8 && fabs(a[2 + (c & 1)] - cut[c]) <= 1e-8;
    n += d->cut[ed];
  }
  if (n == 0) {
    free(d->cut);
    d->cut = NULL;
  }
  return 0;
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* The grid rows j (y = y0 + j hy) an edge with ends at heights ya, yb may
 * cross, [*j0, *j1] (a superset, clamped to the grid; empty when j0 > j1). */
static void pd_edge_rows(const gr_ms_grid *g, double ya, double yb, int *j0, int *j1) {
  double lo = (pd_min(ya, yb) - g->y0) / g->hy, hi = (pd_max(ya, yb) - g->y0) / g->hy;
  *j0 = !(lo > 0) ? 0 : lo > g->ny ? g->ny : (int)floor(lo);
  *j1 = !(hi < g->ny - 1) ? g->ny - 1 : hi < 0 ? -1 : (int)ceil(hi);
}

/* Crossings of the grid's rows with the edges, per row (CSR: row j's x in
 * xs[rs[j]..rs[j+1])), each edge visiting only the rows in its height range;
 * the test per row is the even-odd rule's. NULL (with e) when out of memory. */
static double *pd_row_crossings(const poly_dist *d, const gr_ms_grid *g, size_t *rs, gr_err *e) {
  memset(rs, 0, ((size_t)g->ny + 1) * sizeof *rs);
  double *xs = NULL;
  for (int pass = 0; pass < 2; pass++) {
    for (size_t ed = 0; ed < d->ne; ed++) {
      const double *a = d->ab + 4 * ed;
      int j0, j1;
      pd_edge_rows(g, a[1], a[3], &j0, &j1);
      for (int j = j0; j <= j1; j++) {
        double y = g->y0 + j * g->hy;
        double xc;
        if (!gr_edge_at_y(a[0], a[1], a[2], a[3], y, &xc)) continue;
        if (pass == 0) rs[j + 1]++;
        else xs[rs[j]++] = xc;
      }
    }
    if (pass == 0) {
      for (int j = 0; j < g->ny; j++) rs[j + 1] += rs[j];
      xs = malloc((rs[g->ny] + 1) * sizeof *xs);
      if (!xs) return gr_fail(e, GR_EMEM, "out of memory: %zu row crossings", rs[g->ny]), NULL;
    } else {
      for (int j = g->ny; j > 0; j--) rs[j] = rs[j - 1];
      rs[0] = 0;
    }
  }
  return xs;
}

/* Squared distances of the nodes of grid rows j0..j1 to one edge p (ax ay bx
 * by), lowered into v where smaller. Only nodes within rmax of the edge can
 * matter (pd_sample clamps larger distances to rmax), so each row visits only
 * the nodes of the columns i0..i1 (the edge's box grown by rmax) that lie in
 * the disk of radius rr + L/2 around the edge's middle and in the band of
 * half-width rr around its line (unless the edge is nearly horizontal: the
 * band's columns would not be bounded), both holding all points within rr
 * of the edge. rr exceeds rmax by far more than the rounding of d2 and of
 * the columns, so a node left out has d2 > rmax^2.
 * The value is the expression of edge_d2 (bit for bit): a node before the
 * edge's start (t <= 0) or past its end (t >= 1) needs no division, and its
 * parts along y are the row's. xn[i] is node i's x. */
static void pd_sample_edge(const double *p, const gr_ms_grid *g, const double *xn, int i0, int i1, int j0,
                           int j1, double rr, double *v) {
  double ax = p[0], ay = p[1], ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
  double bx = ax + ex, by = ay + ey; /* p[0] + t * ex at t = 1, as edge_d2 has it */
  double L = sqrt(L2), ihx = 1 / g->hx;
  double cx = ax + 0.5 * ex, cy = ay + 0.5 * ey, R = rr + 0.5 * L, R2 = R * R;
  /* the band along row j: columns u0 + j du .. u1 + j du (x - ax between
   * ((y - ay) ex -+ rr L) / ey) */
  int band = fabs(ey) > 1e-3 * L;
  double du = 0, u0 = 0, u1 = 0;
  if (band) {
    double c = ax - g->x0 + (g->y0 - ay) * ex / ey, w = rr * L / fabs(ey);
    du = g->hy * ex / ey * ihx;
    u0 = (c - w) * ihx;
    u1 = (c + w) * ihx;
  }
  /* the rows the disk spans: ceil and floor inside [j0, j1] as below */
  double ra = (cy - R - g->y0) / g->hy, rb = (cy + R - g->y0) / g->hy;
  if (ra > j0) j0 = ra > j1 ? j1 + 1 : (int)ra + ((int)ra < ra);
  if (rb < j1) j1 = rb < j0 ? j0 - 1 : (int)rb;
  for (int j = j0; j <= j1; j++) {
    double y = g->y0 + j * g->hy, dy = y - cy, s = R2 - dy * dy;
    if (!(s >= 0)) continue; /* the row misses the disk */
    double hw = sqrt(s), lo = (cx - hw - g->x0) * ihx, hi = (cx + hw - g->x0) * ihx;
    if (band) {
      double bl = u0 + j * du, bh = u1 + j * du;
      if (bl > lo) lo = bl;
      if (bh < hi) hi = bh;
    }
    /* ceil(lo) and floor(hi) where they fall inside [i0, i1] (>= 0 there:
     * the conversion truncates down) */
    int ia = i0, ib = i1;
    if (lo > ia) ia = lo > ib ? ib + 1 : (int)lo + ((int)lo < lo);
    if (hi < ib) ib = hi < ia ? ia - 1 : (int)hi;
    double ny = (y - ay) * ey, qy0 = ay - y, qy1 = by - y, c0 = qy0 * qy0, c1 = qy1 * qy1;
    double *row = v + (size_t)g->nx * j;
    for (int i = ia; i <= ib; i++) {
      double x = xn[i], num = (x - ax) * ex + ny, d2;
      if (num <= 0) { /* t = 0 (num / L2 <= 0): the start */
        double qx = ax - x;
        d2 = qx * qx + c0;
      } else if (num >= L2) { /* t = 1 (num / L2 >= 1): the end */
        double qx = bx - x;
        d2 = qx * qx + c1;
      } else {
        double t = num / L2, qx = ax + t * ex - x, qy = ay + t * ey - y;
        d2 = qx * qx + qy * qy;
      }
      if (d2 < row[i]) row[i] = d2;
    }
  }
}

/* The same for an edge whose L2 is 0 or not finite (edge_d2's t is 0 or
 * NaN there), and for an edge along a window's cut, whose distance counts
 * far more (pd_mark_cut; 0 otherwise): the plain expression over the whole
 * box. */
static void pd_sample_edge_plain(const double *p, const gr_ms_grid *g, const double *xn, int i0, int i1, int j0,
                                 int j1, double far, double *v) {
  double ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
  for (int j = j0; j <= j1; j++) {
    double y = g->y0 + j * g->hy;
    double *row = v + (size_t)g->nx * j;
    for (int i = i0; i <= i1; i++) {
      double x = xn[i];
      double t = L2 > 0 ? ((x - p[0]) * ex + (y - p[1]) * ey) / L2 : 0;
      t = t < 0 ? 0 : t > 1 ? 1 : t;
      double qx = p[0] + t * ex - x, qy = p[1] + t * ey - y, d2 = qx * qx + qy * qy;
      if (far > 0) d2 = pd_far_d2(d2, far);
      if (d2 < row[i]) row[i] = d2;
    }
  }
}

/* Sort a row's crossings: insertion sort for the few a row mostly has
 * (qsort's call overhead dominates there); the order of equal values
 * cannot change the parity count. */
static void pd_sort_row(double *x, size_t n) {
  if (n > 24) { qsort(x, n, sizeof *x, cmp_double); return; }
  for (size_t k = 1; k < n; k++) {
    double s = x[k];
    size_t m = k;
    for (; m > 0 && x[m - 1] > s; m--) x[m] = x[m - 1];
    x[m] = s;
  }
}

/* Sample sd + b on the grid g (v allocated by the caller): the sign by the
 * even-odd rule along each row (exact), the distance from the buckets
 * within rmax (clamped to rmax farther away). */
static int pd_sample(const poly_dist *d, const gr_ms_grid *g, double *v,
                     double rmax, gr_err *e) {
  size_t *rs = malloc(((size_t)g->ny + 1) * sizeof *rs);
  double *xn = malloc(((size_t)g->nx + 1) * sizeof *xn);
  if (!rs || !xn) { free(rs); free(xn); return gr_fail(e, GR_EMEM, "out of memory: %d rows", g->ny); }
  double *xs = pd_row_crossings(d, g, rs, e);
  if (!xs) { free(rs); free(xn); return e->code; }
  for (int i = 0; i < g->nx; i++) xn[i] = g->x0 + i * g->hx;
  /* squared distances: each edge updates the nodes within rmax of it */
  size_t nn = (size_t)g->nx * g->ny;
  for (size_t k = 0; k < nn; k++) v[k] = INFINITY;
  /* the margin of pd_sample_edge's bounds over rmax: far above the rounding
   * of d2 and of the bounds, which grows with the coordinates' magnitude */
  double mag = fabs(g->x0) + fabs(g->y0) + (g->nx - 1) * g->hx + (g->ny - 1) * g->hy;
  double rr = rmax + 1e-7 * (rmax + mag);
  for (size_t ed = 0; ed < d->ne; ed++) {
    const double *p = d->ab + 4 * ed;
    double ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
    int i0 = (int)floor((pd_min(p[0], p[2]) - rmax - g->x0) / g->hx), i1 = (int)ceil((pd_max(p[0], p[2]) + rmax - g->x0) / g->hx);
    int j0 = (int)floor((pd_min(p[1], p[3]) - rmax - g->y0) / g->hy), j1 = (int)ceil((pd_max(p[1], p[3]) + rmax - g->y0) / g->hy);
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 > g->nx - 1) i1 = g->nx - 1;
    if (j1 > g->ny - 1) j1 = g->ny - 1;
    int far = d->cut && d->cut[ed];
    if (!far && L2 > 0 && isfinite(L2) && isfinite(rr)) pd_sample_edge(p, g, xn, i0, i1, j0, j1, rr, v);
    else pd_sample_edge_plain(p, g, xn, i0, i1, j0, j1, far ? d->cut_far : 0, v);
  }
  /* signs by scan-line parity */
  double r2 = rmax * rmax;
  for (int j = 0; j < g->ny; j++) {
    double *row = xs + rs[j], *vr = v + (size_t)g->nx * j;
    size_t nc = rs[j + 1] - rs[j];
    pd_sort_row(row, nc);
    size_t c = 0;
    for (int i = 0; i < g->nx; i++) {
      while (c < nc && row[c] <= xn[i]) c++;
      double dist = vr[i] <= r2 ? sqrt(vr[i]) : rmax;
      vr[i] = ((c & 1) ? -dist : dist) + d->b;
    }
  }
  free(xs);
  free(rs);
  free(xn);
  return GR_OK;
}

/* Grid over the bounding box of r with cell <= cell; fails if too large. */
static int bbox_grid(const gr_rings *r, double cell, gr_ms_grid *g, gr_err *e) {
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < r->npts; k++)
    for (int c = 0; c < 2; c++) { lo[c] = pd_min(lo[c], r->xy[2 * k + c]); hi[c] = pd_max(hi[c], r->xy[2 * k + c]); }
  for (int c = 0; c < 2; c++)
    if (!isfinite(lo[c]) || !isfinite(hi[c])) return gr_fail(e, GR_ENUM, "rings have a non-finite coordinate");
  for (int c = 0; c < 2; c++) if (hi[c] - lo[c] < cell) { double m = 0.5 * (lo[c] + hi[c]); lo[c] = m - cell / 2; hi[c] = m + cell / 2; }
  int rc = gr_ms_check_window(lo, hi, cell, 1, e);
  if (rc) return rc;
  g->nx = (int)ceil((hi[0] - lo[0]) / cell) + 1;
  g->ny = (int)ceil((hi[1] - lo[1]) / cell) + 1;
  g->x0 = lo[0]; g->y0 = lo[1];
  g->exact = 0; /* crossings always refined on the distance */
  g->hx = (hi[0] - lo[0]) / (g->nx - 1);
  g->hy = (hi[1] - lo[1]) / (g->ny - 1);
  return GR_OK;
}

/* The offset's grid over src's box at step cell sampled into *v (freed and
 * allocated again; d built on the first call). */
static int offset_sample(const gr_rings *src, poly_dist *d, double cell, gr_ms_grid *g, double **v, gr_err *e) {
  int rc = bbox_grid(src, cell, g, e);
  if (rc) return rc;
  free(*v);
  *v = malloc((size_t)g->nx * g->ny * sizeof **v);
  if (!*v) return gr_fail(e, GR_EMEM, "out of memory: offset grid %d x %d", g->nx, g->ny);
  g->v = *v;
  return pd_sample(d, g, *v, d->b + 2 * fmax(g->hx, g->hy), e);
}

/* Sharp corners of the offset cut by a chord. The chord pass accepts a
 * chord whose middle's root lies within chord_tol of it; where the chord
 * cuts a corner (the offset lines of two edges meeting, at a convex vertex
 * of the section) off-centre, the corner itself can lie up to twice as far.
 * There the chords on either side run along the two offset lines, so the
 * corner is near where their lines meet (gr_ms_chord_corner); where that
 * lies ahead of both, within a chord's length and more than CORNER_MIN off
 * the chord, and the lines turn by CORNER_COS or more, the corner is solved
 * exactly: the offset lines of the chord
 * ends' nearest edges (n.x = n.q + b, n the unit vector from an end's
 * nearest boundary point q to it) meet there. It is put in when the
 * distance there is b within CORNER_ON (along an arc, around a vertex of
 * the section, the two tangents meet off the curve: nothing is put in). */
#define CORNER_MIN 5e-5
#define CORNER_ON 1e-6
#define CORNER_COS 0.866 /* corners that turn by 30 degrees or more: the section's
                            polygon turns a little at every vertex, and its offset with it */

/* The corner of chord a-b from its ends' nearest boundary points (0: the
 * offset lines are near parallel). */
static int corner_exact(poly_dist *d, const double *a, const double *b, double c[2]) {
  double qa[2], qb[2];
  pd_signed(d, d->seen, a[0], a[1], qa);
  pd_signed(d, d->seen, b[0], b[1], qb);
  double nax = a[0] - qa[0], nay = a[1] - qa[1], nbx = b[0] - qb[0], nby = b[1] - qb[1];
  double la = hypot(nax, nay), lb = hypot(nbx, nby);
  if (!(la > 0 && lb > 0)) return 0;
  nax /= la; nay /= la; nbx /= lb; nby /= lb;
  double ra = nax * qa[0] + nay * qa[1] + d->b, rb = nbx * qb[0] + nby * qb[1] + d->b;
  double det = nax * nby - nay * nbx;
  if (!(fabs(det) > 1e-6)) return 0;
  c[0] = (ra * nby - rb * nay) / det;
  c[1] = (nax * rb - nbx * ra) / det;
  return 1;
}

static int offset_corners(gr_rings *r, poly_dist *d, gr_err *e) {
  size_t n = r->npts, m = 0;
  double *cx = malloc((n + 1) * sizeof *cx), *cy = malloc((n + 1) * sizeof *cy), *f = malloc((n + 1) * sizeof *f);
  size_t *at = malloc((n + 1) * sizeof *at);
  gr_rings *o = gr_rings_new();
  int rc = cx && cy && f && at && o ? GR_OK : gr_fail(e, GR_EMEM, "out of memory: offset corners");
  for (size_t i = 0; i < r->nrings && !rc; i++) {
    size_t len = gr_ring_len(r, i);
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < len && len >= 4; k++) {
      const double *a = p + 2 * k, *b = p + 2 * gr_ring_next(k, len);
      const double *a0 = p + 2 * gr_ring_prev(k, len), *b1 = p + 2 * gr_ring_at(k, 2, len);
      /* most vertices: the neighbouring chords turn by less (no corner) */
      double tx = a[0] - a0[0], ty = a[1] - a0[1], vx = b1[0] - b[0], vy = b1[1] - b[1];
      double turn = (tx * vx + ty * vy) / (hypot(tx, ty) * hypot(vx, vy)); /* cos of the corner's turn */
      if (!(turn < CORNER_COS)) continue;
      double c[2], ux = b[0] - a[0], uy = b[1] - a[1], L = hypot(ux, uy);
      gr_ms_chord_corner(a0, a, b, b1, c);
      if (!(L > 0) || !isfinite(c[0])) continue;
      double h = ((c[0] - a[0]) * uy - (c[1] - a[1]) * ux) / L; /* > 0: right of a-b, outside */
      double sa = (c[0] - a[0]) * tx + (c[1] - a[1]) * ty;
      double sb = vx * (b[0] - c[0]) + vy * (b[1] - c[1]);
      if (!(h > CORNER_MIN && h < L && sa > 0 && sb > 0) || !corner_exact(d, a, b, c)) continue;
      cx[m] = c[0]; cy[m] = c[1]; at[m++] = r->start[i] + k;
    }
  }
  if (!rc && m == 0) goto done;
  if (!rc) rc = pd_fn(d, m, cx, cy, f, e);
  size_t q = 0, put = 0;
  for (size_t k = 0; k < m && !rc; k++) put += fabs(f[k]) <= CORNER_ON;
  if (!put) goto done; /* none on the offset: the rings stay as they are */
  put = 0;
  for (size_t i = 0; i < r->nrings && !rc; i++) {
    size_t len = gr_ring_len(r, i);
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < len && !rc; k++) {
      rc = gr_rings_point(o, p[2 * k], p[2 * k + 1]) ? gr_fail(e, GR_EMEM, "out of memory: offset corners") : GR_OK;
      for (; q < m && at[q] < r->start[i] + k; q++) {}
      if (!rc && q < m && at[q] == r->start[i] + k && fabs(f[q]) <= CORNER_ON) {
        rc = gr_rings_point(o, cx[q], cy[q]) ? gr_fail(e, GR_EMEM, "out of memory: offset corners") : GR_OK;
        put++;
      }
    }
    if (!rc && gr_rings_close(o)) rc = gr_fail(e, GR_EMEM, "out of memory: offset corners");
  }
  if (!rc && put) {
    gr_rings t = *r;
    *r = *o;
    *o = t;
  }
done:
  free(cx); free(cy); free(f); free(at);
  gr_rings_free(o);
  return rc;
}

/* The offset straight from the edges (direct: 1, 2 simplified; where
 * simple) or on the grid. */
static int offset_rings(const gr_rings *in, double b, double cell, double coarse, double tol, double chord_tol,
                        const double *box, const double *cut, int direct, gr_rings *out, gr_err *e) {
  if (!(b >= 0) || !isfinite(b)) return gr_fail(e, GR_EARG, "offset distance b must be >= 0, got %g", b);
  if (!(cell > 0) || !isfinite(cell)) return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (!(coarse >= 1) || !isfinite(coarse)) return gr_fail(e, GR_EARG, "coarse must be >= 1, got %g", coarse);
  if (!(tol > 0) || !isfinite(tol)) return gr_fail(e, GR_EARG, "tol must be > 0, got %g", tol);
  if (!(chord_tol >= 0) || !isfinite(chord_tol)) return gr_fail(e, GR_EARG, "chord_tol must be >= 0, got %g", chord_tol);
  gr_rings *src = gr_rings_new();
  if (!src) return gr_fail(e, GR_EMEM, "out of memory copying rings");
  int rc = gr_rings_copy(src, in) ? gr_fail(e, GR_EMEM, "out of memory copying rings") : GR_OK;
  if (!rc) rc = gr_rings_nest(src, e);
  if (rc || b == 0 || src->nrings == 0) {
    if (!rc) rc = gr_rings_copy(out, src) ? gr_fail(e, GR_EMEM, "out of memory copying rings") : GR_OK;
    if (!rc) rc = gr_rings_nest(out, e);
    gr_rings_free(src);
    return rc;
  }
  if (direct) { /* straight from the edges where the raw offset is simple */
    int done = 0;
    rc = gr_offset_rings_direct(src, b, chord_tol, coarse * cell, box, cut, direct > 1, out, &done, e);
    if (rc || done) {
      if (!rc) rc = gr_rings_nest(out, e);
      gr_rings_free(src);
      return rc;
    }
  }
  poly_dist d;
  gr_ms_grid g;
  double *v = NULL;
  rc = bbox_grid(src, coarse * cell, &g, e);
  if (rc) { gr_rings_free(src); return rc; }
  rc = pd_build(&d, src, fmax(g.hx, g.hy), e);
  if (!rc && pd_mark_cut(&d, cut, b)) rc = gr_fail(e, GR_EMEM, "out of memory: %zu edges", d.ne);
  d.b = b;
  pd_seen seen;
  if (!rc) d.seen = pd_seen_new(&d, &seen);
  if (!rc) rc = offset_sample(src, &d, coarse * cell, &g, &v, e);
  /* a strip hidden between the coarse grid's nodes: sampled again at cell
   * (a sweep of the edges, cheaper than refining node by node) */
  int hidden = 1; /* (unhide's first probes are gr_ms_hidden's: not made twice) */
  if (!rc && coarse > 1) rc = gr_ms_hidden(&g, 1, box, pd_fn, &d, &hidden, e);
  if (!rc && hidden && coarse > 1) rc = offset_sample(src, &d, cell, &g, &v, e);
  double *fine = NULL; /* the grid sampled again where a strip hides between nodes */
  if (!rc && hidden) rc = gr_ms_unhide(&g, 1, box, pd_fn, &d, &fine, e);
  if (!rc) {
    gr_rings_clear(out);
    d.grid = &g; /* its signs now decide most refined points' sides */
    rc = gr_ms_contour(&g, pd_fn, pd_gfn, &d, 1, tol, out, e);
  }
  if (!rc && chord_tol > 0) {
    gr_ms_win w = {0, {0, 0}, {0, 0}, 4 * fmax(g.hx, g.hy), 0, NULL};
    rc = gr_ms_chord_refine(out, pd_fn, pd_gfn, &d, tol, chord_tol, &w, e);
    if (!rc) rc = offset_corners(out, &d, e);
  }
  if (!rc) rc = gr_rings_nest(out, e);
  free(fine);
  free(v);
  if (d.seen) free(d.seen->mark);
  pd_free(&d);
  gr_rings_free(src);
  return rc;
}

int gr_offset_rings_opt(const gr_rings *in, double b, double cell, double tol,
                        double chord_tol, const double *box, gr_rings *out, gr_err *e) {
  return offset_rings(in, b, cell, 1, tol, chord_tol, box, NULL, 1, out, e);
}

int gr_offset_rings_coarse(const gr_rings *in, double b, double cell, double coarse, double tol,
                           double chord_tol, const double *box, const double *cut, gr_rings *out, gr_err *e) {
  return offset_rings(in, b, cell, coarse, tol, chord_tol, box, cut, 2, out, e);
}

int gr_offset_rings_grid(const gr_rings *in, double b, double cell, double coarse, double tol,
                         double chord_tol, const double *box, gr_rings *out, gr_err *e) {
  return offset_rings(in, b, cell, coarse, tol, chord_tol, box, NULL, 0, out, e);
}

int gr_offset_rings(const gr_rings *in, double b, double cell, gr_rings *out,
                    gr_err *e) {
  return gr_offset_rings_opt(in, b, cell, 1e-6, 0, NULL, out, e);
}

double gr_rings_max_inner_distance(const gr_rings *in, double cell, gr_err *e) {
  if (!(cell > 0) || !isfinite(cell)) { gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell); return -1; }
  if (!in || in->nrings == 0) return 0;
  gr_rings *src = gr_rings_new();
  if (!src || gr_rings_copy(src, in)) { gr_rings_free(src); gr_fail(e, GR_EMEM, "out of memory copying rings"); return -1; }
  poly_dist d;
  gr_ms_grid g;
  double *v = NULL, best = 0;
  int rc = gr_rings_nest(src, e);
  if (!rc) rc = bbox_grid(src, cell, &g, e);
  if (rc) { gr_rings_free(src); return -1; }
  double w = fmax((g.nx - 1) * g.hx, (g.ny - 1) * g.hy);
  rc = pd_build(&d, src, fmax(4 * cell, w / 64), e);
  d.b = 0;
  if (!rc) {
    v = malloc((size_t)g.nx * g.ny * sizeof *v);
    if (!v) rc = gr_fail(e, GR_EMEM, "out of memory: grid %d x %d", g.nx, g.ny);
  }
  if (!rc) rc = pd_sample(&d, &g, v, 2 * w + 1, e);
  if (!rc)
    for (size_t k = 0; k < (size_t)g.nx * g.ny; k++) best = pd_max(best, -v[k]);
  free(v);
  pd_free(&d);
  gr_rings_free(src);
  return rc ? -1 : best;
}

struct gr_polydist { poly_dist d; };

gr_polydist *gr_polydist_new(const gr_rings *r, double bucket, gr_err *e) {
  gr_polydist *p = calloc(1, sizeof *p);
  if (!p) { gr_fail(e, GR_EMEM, "out of memory"); return NULL; }
  if (pd_build(&p->d, r, bucket, e)) { pd_free(&p->d); free(p); return NULL; }
  return p;
}

void gr_polydist_free(gr_polydist *p) {
  if (!p) return;
  pd_free(&p->d);
  free(p);
}

double gr_polydist_at(const gr_polydist *p, double x, double y, double q[2]) { return pd_signed(&p->d, NULL, x, y, q); }

int gr_polydist_within(const gr_polydist *p, double x, double y, double r, size_t *hint) {
  size_t ed;
  double t;
  if (p->d.ne == 0 || !(r >= 0)) return 0;
  if (hint && *hint < p->d.ne && sqrt(edge_d2(p->d.ab + 4 * *hint, x, y, &t)) <= r) return 1;
  double d2 = pd_search(&p->d, NULL, x, y, r, PD_ANY, &ed, &t);
  if (!(isfinite(d2) && sqrt(d2) <= r)) return 0;
  if (hint) *hint = ed;
  return 1;
}

int gr_polydist_grid(const gr_polydist *p, double x0, double y0, double h, int nx, int ny,
                     double rmax, double *v, gr_err *e) {
  gr_ms_grid g = {nx, ny, x0, y0, h, h, NULL, 0};
  return pd_sample(&p->d, &g, v, rmax, e);
}
