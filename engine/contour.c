/* contour.c: the contours of a section along its in-plane offsets, the
 * thin-wall scans of what they miss, and gr_hatch_layer (contours + hatch
 * infill of the hatch region), see hatch.h. */
#include "hatch.h"
#include "slice.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* gr_offset_rings_coarse lives in polydist.c; a weak reference lets this file
 * link (with a simple miter offset as fallback) while polydist.c is not there. */
#pragma weak gr_offset_rings_coarse

/* Fallback offset (used while polydist.c's gr_offset_rings is not linked):
 * each vertex moves to the intersection of its two edges' lines shifted by b
 * to the left (inside, for correctly oriented rings). Exact for convex
 * polygons; a ring whose area changes sign or vanishes is dropped. */
int gr_hatch_miter_offset(const gr_rings *in, double b, double cell, const double *box, const double *cut,
                          gr_rings *out, gr_err *e) {
  (void)cell;
  (void)box;
  (void)cut;
  gr_rings_clear(out);
  for (size_t r = 0; r < in->nrings; r++) {
    const double *p = gr_ring_xy(in, r);
    size_t n = gr_ring_len(in, r);
    if (n < 3) continue;
    double a0 = gr_ring_area(in, r);
    size_t s0 = out->npts;
    for (size_t i = 0; i < n; i++) {
      size_t h = gr_ring_prev(i, n), j = gr_ring_next(i, n);
      double ax = p[2 * i] - p[2 * h], ay = p[2 * i + 1] - p[2 * h + 1];
      double bx = p[2 * j] - p[2 * i], by = p[2 * j + 1] - p[2 * i + 1];
      double la = hypot(ax, ay), lb = hypot(bx, by);
      if (la == 0 || lb == 0) continue;
      double nax = -ay / la, nay = ax / la, nbx = -by / lb, nby = bx / lb;
      double mx = nax + nbx, my = nay + nby, m2 = mx * mx + my * my;
      double k = m2 > 1e-12 ? 2.0 * b / m2 : b;
      if (m2 <= 1e-12) { mx = nax; my = nay; }
      if (gr_rings_point(out, p[2 * i] + k * mx, p[2 * i + 1] + k * my))
        return gr_fail(e, GR_EMEM, "offset: out of memory");
    }
    if (gr_rings_close(out)) return gr_fail(e, GR_EMEM, "offset: out of memory");
    if (out->nrings && out->start[out->nrings - 1] == s0) {
      double a1 = gr_ring_area(out, out->nrings - 1);
      if (a1 * a0 <= 0 || (a0 > 0 && a1 > a0)) { /* collapsed outer */
        out->nrings--;
        out->npts = s0;
      }
    }
  }
  return GR_OK;
}

/* The default offset (the templates' too): polydist.c's, crossings to 1e-6
 * mm, chords refined to the offsets' chord tolerance (slice.h):
 * where the section has a corner (a crease of a thick sheet, a step at a
 * face, a domain's face meeting the lattice) the offset runs on an arc of
 * radius b around it, which a chord between two crossings of the grid cut
 * by up to 3 um; elsewhere a chord's midpoint check passes at once.
 * Its grid is first OFFSET_GRID slice cells: the grid decides only which
 * cells the offset crosses (every crossing is solved on the exact polygon
 * distance and every chord refined), so a coarser grid moves no contour
 * beyond the chord tolerance and halves the crossings to solve and the
 * nodes to sample. Where its edge checks (hidden.c) find a strip narrower
 * than that grid (a wall just over 2b wide, the sharp tip of an offset),
 * the grid is sampled again at one slice cell and refined from there as
 * before. */
#define OFFSET_GRID 2.0
static int offset_default(const gr_rings *in, double b, double cell, const double *box, const double *cut,
                          gr_rings *out, gr_err *e) {
  return gr_offset_rings_coarse(in, b, cell, OFFSET_GRID, 1e-6, GR_OFFSET_CHORD_TOL, box, cut, out, e);
}

static gr_offset_fn pick_offset(const gr_hatch_opts *o) {
  if (o->offset) return o->offset;
  if (gr_offset_rings_coarse) return offset_default;
  return gr_hatch_miter_offset;
}

static int ring_depth(const gr_rings *r, size_t i) {
  int d = 0;
  for (int p = r->parent ? r->parent[i] : -1; p >= 0; p = r->parent[p]) d++;
  return d;
}

/* Distance from (x, y) to the nearest edge of rings `which` of r. */
static double dist_edges(const gr_rings *r, const size_t *which, size_t nw, double x, double y) {
  double best = INFINITY;
  for (size_t w = 0; w < nw; w++) {
    const double *p = gr_ring_xy(r, which[w]);
    size_t n = gr_ring_len(r, which[w]);
    for (size_t a = 0, b = n - 1; a < n; b = a++) {
      double ex = p[2 * a] - p[2 * b], ey = p[2 * a + 1] - p[2 * b + 1];
      double px = x - p[2 * b], py = y - p[2 * b + 1];
      double l2 = ex * ex + ey * ey, t = l2 > 0 ? (px * ex + py * ey) / l2 : 0;
      if (t < 0) t = 0;
      if (t > 1) t = 1;
      double dx = px - t * ex, dy = py - t * ey, d2 = dx * dx + dy * dy;
      if (d2 < best) best = d2;
    }
  }
  return sqrt(best);
}

/* Thin-wall fallback for a component too small for the thin-wall grid to
 * see (no grid node inside it): a centre line through its deepest sampled
 * point along the longer principal axis of its outer ring. */
static int thin_fallback(const gr_rings *sec, size_t outer, const gr_hatch_opts *o,
                         gr_layer *cl, gr_hatch_report *rep, gr_err *e) {
  size_t *which = malloc((sec->nrings + 1) * sizeof *which), nw = 0;
  gr_rings *comp = gr_rings_new();
  int rc = GR_OK;
  if (!which || !comp) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  which[nw++] = outer;
  for (size_t i = 0; i < sec->nrings; i++)
    if (sec->parent[i] == (int)outer) which[nw++] = i;
  for (size_t w = 0; w < nw; w++)
    if (gr_rings_add(comp, gr_ring_xy(sec, which[w]), gr_ring_len(sec, which[w]))) {
      rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done;
    }
  if ((rc = gr_rings_nest(comp, e))) goto done;
  /* deepest point by sampling the bounding box */
  const double *p = gr_ring_xy(sec, outer);
  size_t n = gr_ring_len(sec, outer);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 2; c++) {
      if (p[2 * i + c] < lo[c]) lo[c] = p[2 * i + c];
      if (p[2 * i + c] > hi[c]) hi[c] = p[2 * i + c];
    }
  double w = hi[0] - lo[0], h = hi[1] - lo[1];
  double best = -1, bx = 0.5 * (lo[0] + hi[0]), by = 0.5 * (lo[1] + hi[1]);
  /* coarse grid over the bounding box (finer until it meets the inside),
   * then two refinements around the best sample */
  double wlo[2] = {lo[0], lo[1]}, whi[2] = {hi[0], hi[1]};
  int N = 24;
  for (int pass = 0; pass < 8; pass++) {
    double sx = (whi[0] - wlo[0]) / N, sy = (whi[1] - wlo[1]) / N;
    for (int j = 0; j < N; j++)
      for (int i = 0; i < N; i++) {
        double x = wlo[0] + (i + 0.5) * sx, y = wlo[1] + (j + 0.5) * sy;
        if (!gr_rings_contains(comp, x, y)) continue;
        double dm = INFINITY;
        for (size_t r = 0; r < comp->nrings; r++) {
          size_t one = r;
          dm = fmin(dm, dist_edges(comp, &one, 1, x, y));
        }
        if (dm > best) { best = dm; bx = x; by = y; }
      }
    if (best < 0) {
      if (N >= 384) break;
      N *= 2;
      continue;
    }
    if (pass >= 2 && N == 12) break;
    wlo[0] = bx - 2 * sx; whi[0] = bx + 2 * sx;
    wlo[1] = by - 2 * sy; whi[1] = by + 2 * sy;
    N = 12;
    if (w <= 0 || h <= 0) break;
  }
  rep->thin_walls++;
  cl->thin_walls++;
  /* centre line: principal axis of the outer ring's vertices */
  double cx = 0, cy = 0, sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < n; i++) { cx += p[2 * i]; cy += p[2 * i + 1]; }
  cx /= (double)n; cy /= (double)n;
  for (size_t i = 0; i < n; i++) {
    double dx = p[2 * i] - cx, dy = p[2 * i + 1] - cy;
    sxx += dx * dx; syy += dy * dy; sxy += dx * dy;
  }
  double th = 0.5 * atan2(2 * sxy, sxx - syy), ux = cos(th), uy = sin(th);
  double seg[4];
  double reach = hypot(w, h);
  for (int sgn = 0; sgn < 2; sgn++) {
    double dir = sgn ? -1 : 1, a = 0, b = reach;
    for (int it = 0; it < 50; it++) { /* last inside distance along the axis */
      double m = 0.5 * (a + b);
      if (gr_rings_contains(comp, bx + dir * m * ux, by + dir * m * uy)) a = m; else b = m;
    }
    seg[2 * sgn] = bx + dir * a * ux;
    seg[2 * sgn + 1] = by + dir * a * uy;
  }
  if (gr_layer_add(cl, GR_OPEN, GR_CONTOUR, o->laser, GR_DIR_THIN, seg, 2)) {
    rc = gr_fail(e, GR_EMEM, "hatch: out of memory");
    goto done;
  }
  rep->thin_scans++;
  rep->thin_length += hypot(seg[2] - seg[0], seg[3] - seg[1]);
done:
  free(which);
  gr_rings_free(comp);
  return rc;
}

/* ---- thin walls: centre lines of the slivers the contour at b misses ----
 * On a grid of cell h over the section: D = exact signed distance to the
 * boundary (negative inside); the core is {-D >= b} (what the offset by b
 * keeps); the contour's track (radius b) and the hatches melt the points
 * within b of the core. The inside nodes farther than b from the core form
 * the slivers (8-connected components). Each sliver's centre line is traced
 * from its deepest node along the ridge of the exact distance (predict a
 * step along the line, then move to the deepest point across it) until the
 * wall gets thinner than h/8 (a tip), the line reaches the core's melt, a line
 * already traced, or closes on itself; at a tip it is cut back where the
 * wall is narrower than THIN_MIN (half width) or within THIN_TIP of the tip. */
#define THIN_CELL 16   /* grid cell h = d / THIN_CELL */
#define THIN_NODES 4000000.0 /* larger grids get a coarser cell (17 bytes a node) */
#define THIN_MIN 16    /* scanned where the half width is >= d / THIN_MIN */
#define THIN_TIP 0.8   /* ... and at least THIN_TIP * b from a tip */
#define THIN_TRACES 16 /* traces per sliver (branches) */

typedef struct thin_grid {
  const gr_polydist *pd;
  double x0, y0, h, b;
  int nx, ny;
  double *D;            /* signed distance at nodes, mm */
  double *cov;          /* squared distance to the nearest core node, cells^2 */
  unsigned char *mark;  /* 1 sliver node, 2 visited (flood), 4 claimed by a trace */
} thin_grid;

typedef gr_trip thin_line; /* x, y, depth (-D) per point */
#define tl_push gr_trip_push

/* 1D squared distance transform of f (n samples) into d: the lower envelope
 * of the parabolas (q - p)^2 + f[p]; v, z scratch of n and n + 1. f holds 0
 * or THIN_FAR (no core), so every value stays exact. */
#define THIN_FAR 1e12
static void edt_1d(const double *f, int n, double *d, int *v, double *z) {
  int k = 0;
  v[0] = 0;
  z[0] = -INFINITY;
  z[1] = INFINITY;
  for (int q = 1; q < n; q++) {
    double s = ((f[q] + (double)q * q) - (f[v[k]] + (double)v[k] * v[k])) / (2.0 * (q - v[k]));
    while (s <= z[k]) {
      k--;
      s = ((f[q] + (double)q * q) - (f[v[k]] + (double)v[k] * v[k])) / (2.0 * (q - v[k]));
    }
    k++;
    v[k] = q;
    z[k] = s;
    z[k + 1] = INFINITY;
  }
  k = 0;
  for (int q = 0; q < n; q++) {
    while (z[k + 1] < q) k++;
    double dq = (double)(q - v[k]);
    d[q] = fmin(dq * dq + f[v[k]], THIN_FAR);
  }
}

/* cov = squared distance (cells) of every node to the nearest core node. */
static int core_distance(thin_grid *g) {
  int n = g->nx > g->ny ? g->nx : g->ny;
  double *f = calloc((size_t)n, sizeof *f), *d = malloc((size_t)n * sizeof *d);
  double *z = malloc((size_t)(n + 1) * sizeof *z);
  int *v = malloc((size_t)n * sizeof *v);
  if (!f || !d || !z || !v) { free(f); free(d); free(z); free(v); return GR_EMEM; }
  for (size_t k = 0; k < (size_t)g->nx * g->ny; k++) g->cov[k] = -g->D[k] >= g->b ? 0 : THIN_FAR;
  for (int i = 0; i < g->nx; i++) {
    for (int j = 0; j < g->ny; j++) f[j] = g->cov[i + (size_t)g->nx * j];
    edt_1d(f, g->ny, d, v, z);
    for (int j = 0; j < g->ny; j++) g->cov[i + (size_t)g->nx * j] = d[j];
  }
  for (int j = 0; j < g->ny; j++) {
    double *row = g->cov + (size_t)g->nx * j;
    memcpy(f, row, (size_t)g->nx * sizeof *f);
    edt_1d(f, g->nx, d, v, z);
    memcpy(row, d, (size_t)g->nx * sizeof *d);
  }
  free(f); free(d); free(z); free(v);
  return GR_OK;
}

static long node_at(const thin_grid *g, double x, double y) {
  long i = lround((x - g->x0) / g->h), j = lround((y - g->y0) / g->h);
  if (i < 0 || j < 0 || i >= g->nx || j >= g->ny) return -1;
  return i + (long)g->nx * j;
}

/* Depth (-signed distance) of p + u n, and the deepest such point for
 * |u| <= r (golden section: the depth across a thin wall is unimodal). */
static double depth_at(const thin_grid *g, double x, double y) { return -gr_polydist_at(g->pd, x, y, NULL); }

static double ridge(const thin_grid *g, double px, double py, double nx, double ny, double r,
                    double *ox, double *oy) {
  const double gr = 0.5 * (sqrt(5.0) - 1);
  double a = -r, c = r;
  double u1 = c - gr * (c - a), u2 = a + gr * (c - a);
  double f1 = depth_at(g, px + u1 * nx, py + u1 * ny), f2 = depth_at(g, px + u2 * nx, py + u2 * ny);
  for (int it = 0; it < 40 && c - a > 1e-4 * g->h; it++) {
    if (f1 < f2) { a = u1; u1 = u2; f1 = f2; u2 = a + gr * (c - a); f2 = depth_at(g, px + u2 * nx, py + u2 * ny); }
    else { c = u2; u2 = u1; f2 = f1; u1 = c - gr * (c - a); f1 = depth_at(g, px + u1 * nx, py + u1 * ny); }
  }
  double u = 0.5 * (a + c);
  *ox = px + u * nx;
  *oy = py + u * ny;
  return depth_at(g, *ox, *oy);
}

/* March from (x, y) (on the ridge, depth dep) along direction (tx, ty);
 * appends the points after the start to t; *tip = 1 when the line ran out
 * at a tip of the wall, 2 when it closed back onto its start, else 0 (it
 * reached the core's melt, a claimed node or the grid's edge). */
static int march(const thin_grid *g, double x, double y, double dep, double tx, double ty,
                 thin_line *t, int *tip) {
  double s = 2 * g->h, x0 = x, y0 = y, arc = 0;
  long maxsteps = 4L * (g->nx + g->ny);
  *tip = 0;
  for (long it = 0; it < maxsteps; it++) {
    double px = x + s * tx, py = y + s * ty, nx = -ty, ny = tx, qx, qy;
    double nd = ridge(g, px, py, nx, ny, fmax(2 * dep, 2 * g->h) + s, &qx, &qy);
    double dx = qx - x, dy = qy - y, L = hypot(dx, dy);
    if (nd < g->h / 8 || !(L > 0)) { *tip = 1; return GR_OK; }
    double ux = dx / L, uy = dy / L;
    if (ux * tx + uy * ty < 0.5) { *tip = 1; return GR_OK; } /* a corner or a fork: stop */
    long k = node_at(g, qx, qy);
    if (k < 0) return GR_OK;
    arc += L;
    if (arc > 4 * g->b && hypot(qx - x0, qy - y0) < 1.5 * s) { *tip = 2; return tl_push(t, x0, y0, dep); }
    if (tl_push(t, qx, qy, nd)) return GR_EMEM;
    if (g->cov[k] * g->h * g->h <= g->b * g->b || (g->mark[k] & 4)) return GR_OK;
    x = qx; y = qy; dep = nd; tx = ux; ty = uy;
  }
  return GR_OK;
}

/* Drop points from the end of t (the tip end): within tipm (arc) of the
 * last point, or shallower than wmin. */
static void trim_tip(thin_line *t, double tipm, double wmin) {
  double arc = 0;
  while (t->n > 0) {
    size_t m = t->n - 1;
    if (arc >= tipm && t->p[3 * m + 2] >= wmin) break;
    if (m > 0) arc += hypot(t->p[3 * m] - t->p[3 * m - 3], t->p[3 * m + 1] - t->p[3 * m - 2]);
    t->n--;
  }
}

static void tl_reverse(thin_line *t) {
  for (size_t i = 0, j = t->n ? t->n - 1 : 0; i < j; i++, j--)
    for (int c = 0; c < 3; c++) {
      double v = t->p[3 * i + c];
      t->p[3 * i + c] = t->p[3 * j + c];
      t->p[3 * j + c] = v;
    }
}

/* One centre line through the ridge point nearest node k: the two marches,
 * trimmed at tips, joined into `out` (points in order). Claims the nodes
 * within b of every traced point, trimmed or not. */
static int trace(thin_grid *g, long k, double tipm, double wmin, thin_line *out) {
  thin_line a = {0}, c = {0};
  double x = g->x0 + (double)(k % g->nx) * g->h, y = g->y0 + (double)(k / g->nx) * g->h, q[2];
  int rc = GR_OK, tipa, tipc;
  gr_polydist_at(g->pd, x, y, q);
  double nx = x - q[0], ny = y - q[1], L = hypot(nx, ny);
  if (!(L > 0)) { nx = 1; ny = 0; } else { nx /= L; ny /= L; }
  double dep = ridge(g, x, y, nx, ny, -g->D[k] + 2 * g->h, &x, &y);
  out->n = 0;
  if ((rc = march(g, x, y, dep, -ny, nx, &a, &tipa))) goto done;
  tipc = 0;
  if (tipa != 2 && (rc = march(g, x, y, dep, ny, -nx, &c, &tipc))) goto done;
  /* claim */
  int R = (int)ceil(g->b / g->h);
  for (int side = 0; side < 3; side++) {
    const thin_line *t = side == 0 ? &a : &c;
    size_t n = side == 2 ? 1 : t->n;
    for (size_t m = 0; m < n; m++) {
      double px = side == 2 ? x : t->p[3 * m], py = side == 2 ? y : t->p[3 * m + 1];
      long ci = lround((px - g->x0) / g->h), cj = lround((py - g->y0) / g->h);
      for (long j = cj - R; j <= cj + R; j++)
        for (long i = ci - R; i <= ci + R; i++) {
          if (i < 0 || j < 0 || i >= g->nx || j >= g->ny) continue;
          double ex = g->x0 + (double)i * g->h - px, ey = g->y0 + (double)j * g->h - py;
          if (ex * ex + ey * ey <= g->b * g->b) g->mark[i + (long)g->nx * j] |= 4;
        }
    }
  }
  /* the whole line: a reversed, the start, c; then cut back at tips */
  for (size_t m = a.n; m-- > 0;)
    if ((rc = tl_push(out, a.p[3 * m], a.p[3 * m + 1], a.p[3 * m + 2]))) goto done;
  if ((rc = tl_push(out, x, y, dep))) goto done;
  for (size_t m = 0; m < c.n; m++)
    if ((rc = tl_push(out, c.p[3 * m], c.p[3 * m + 1], c.p[3 * m + 2]))) goto done;
  if (tipc == 1) trim_tip(out, tipm, wmin);
  if (tipa == 1) { tl_reverse(out); trim_tip(out, tipm, wmin); tl_reverse(out); }
done:
  free(a.p); free(c.p);
  return rc;
}

/* Append a traced line as a thin-wall scan (a single point twice). */
static int emit_thin(const thin_line *t, const gr_hatch_opts *o, gr_layer *cl, gr_hatch_report *rep,
                     gr_err *e) {
  size_t n = t->n < 2 ? 2 : t->n;
  double *xy = malloc(2 * n * sizeof *xy);
  if (!xy) return gr_fail(e, GR_EMEM, "hatch: out of memory");
  for (size_t m = 0; m < n; m++) {
    size_t k = m < t->n ? m : t->n - 1;
    xy[2 * m] = t->p[3 * k];
    xy[2 * m + 1] = t->p[3 * k + 1];
  }
  int rc = gr_layer_add(cl, GR_OPEN, GR_CONTOUR, o->laser, GR_DIR_THIN, xy, n);
  free(xy);
  if (rc) return gr_fail(e, GR_EMEM, "hatch: out of memory");
  rep->thin_scans++;
  rep->thin_length += gr_block_length(cl, &cl->b[cl->nb - 1]);
  return GR_OK;
}

static int in_box(const double box[4], double x, double y) {
  return x >= box[0] && y >= box[1] && x <= box[2] && y <= box[3];
}

/* The core's edges for all_covered, by their first point's global index g
 * (nxt[g]: the point after g in its ring). A query tries the edge that
 * answered the last one and its neighbours first (consecutive samples
 * along the section mostly lie beside consecutive core edges), then scans
 * all edges; after CORE_SCANS scans (a layer with many uncovered samples)
 * the bucketed polygon distance takes over. */
#define CORE_SCANS 32
static const int CORE_TRY[] = {0, 1, -1, 2, -2};
typedef struct core_edges {
  const gr_rings *r;
  size_t *nxt, hint, scans, pdhint;
  double b;
  gr_polydist *pd;
} core_edges;

static int core_edge_within(const core_edges *c, size_t g, const double *p, double r) {
  return gr_seg_dist2(p, c->r->xy + 2 * g, c->r->xy + 2 * c->nxt[g]) <= r * r;
}

/* Whether one of the core edges near the hint (CORE_TRY) is within r of p
 * and, unless q is NULL, of q too (then of the whole segment pq: the
 * distance to a segment is convex along a line); the hint becomes it. 0
 * says nothing about the other edges. */
static int core_near_hint(core_edges *c, const double *p, const double *q, double r) {
  size_t n = c->r->npts;
  for (size_t k = 0; k < sizeof CORE_TRY / sizeof *CORE_TRY && n; k++) {
    size_t g = c->hint + n + (size_t)(ptrdiff_t)CORE_TRY[k];
    while (g >= n) g -= n; /* (hint < n, |CORE_TRY| <= 2: no division) */
    if (core_edge_within(c, g, p, r) && (!q || core_edge_within(c, g, q, r))) return c->hint = g, 1;
  }
  return 0;
}

/* Whether p is within r of some core edge: 1, 0, or -1 (out of memory). */
static int core_within(core_edges *c, const double *p, double r, gr_err *e) {
  size_t n = c->r->npts;
  if (n == 0) return 0;
  if (core_near_hint(c, p, NULL, r)) return 1;
  if (c->scans < CORE_SCANS) {
    c->scans++;
    const double *P = c->r->xy;
    for (size_t g = 0; g < n; g++) {
      const double *a = P + 2 * g, *b = P + 2 * c->nxt[g];
      if (gr_lo(a[0], b[0]) - r > p[0] || gr_hi(a[0], b[0]) + r < p[0] || gr_lo(a[1], b[1]) - r > p[1] ||
          gr_hi(a[1], b[1]) + r < p[1])
        continue;
      if (core_edge_within(c, g, p, r)) return c->hint = g, 1;
    }
    return 0;
  }
  if (!c->pd && !(c->pd = gr_polydist_new(c->r, c->b, e))) return -1;
  return gr_polydist_within(c->pd, p[0], p[1], r, &c->pdhint);
}

/* Is every point of the section within b (+ tol) of the core {depth >= b},
 * whose boundary is `core` (the offset by b)? The melt of the contour at b
 * is the core grown by b, which lies inside the section and touches only the
 * component of its core, so a sliver shows as section boundary farther than
 * b from the core's rings. Boundary samples every tol, each within tol/2 of
 * the rest: a yes means no sliver deeper than tol, and the grid is skipped
 * (most layers of a lattice). A section edge whose ends lie within b + tol/2
 * of one core edge has all its samples there. */
static int all_covered(const gr_rings *sec, const gr_rings *core, double b, double tol, const double *box,
                       double fail[4], gr_err *e) {
  fail[0] = fail[1] = INFINITY;
  fail[2] = fail[3] = -INFINITY;
  core_edges c = {core, malloc((core->npts + 1) * sizeof *c.nxt), 0, 0, (size_t)-1, b, NULL};
  if (!c.nxt) return gr_fail(e, GR_EMEM, "hatch: out of memory"), -1;
  gr_rings_successors(core, c.nxt);
  int ok = 1;
  double r = b + 0.5 * tol;
  for (size_t i = 0; i < sec->nrings && ok >= 0; i++) {
    const double *p = gr_ring_xy(sec, i);
    size_t n = gr_ring_len(sec, i);
    for (size_t a = 0; a < n && ok >= 0; a++) {
      const double *q = p + 2 * gr_ring_next(a, n);
      if (core_near_hint(&c, p + 2 * a, q, r)) continue;
      int m = (int)ceil(gr_len2d(q[0] - p[2 * a], q[1] - p[2 * a + 1]) / tol);
      for (int k = 0; k < m; k++) {
        double t = (double)k / m, x[2] = {p[2 * a] + t * (q[0] - p[2 * a]), p[2 * a + 1] + t * (q[1] - p[2 * a + 1])};
        if (!in_box(box, x[0], x[1])) continue;
        int w = core_within(&c, x, r, e);
        if (w < 0) { ok = -1; break; }
        if (w) continue;
        ok = 0; /* an uncovered boundary sample: where the slivers are */
        fail[0] = fmin(fail[0], x[0]); fail[1] = fmin(fail[1], x[1]);
        fail[2] = fmax(fail[2], x[0]); fail[3] = fmax(fail[3], x[1]);
      }
    }
  }
  gr_polydist_free(c.pd);
  free(c.nxt);
  return ok;
}

/* Thin-wall scans of the nested section sec into cl (GR_OPEN, GR_CONTOUR,
 * dir GR_DIR_THIN); every sliver scanned counts in thin_walls. A sliver that
 * is a whole component (no core) is always scanned, its wall limits relaxed. */
static int thin_walls(const gr_rings *sec, const gr_rings *core, const gr_hatch_opts *o, double b, gr_layer *cl,
                      gr_hatch_report *rep, gr_err *e) {
  thin_grid g;
  memset(&g, 0, sizeof g);
  double d = o->spacing, lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  if (!(b > 0) || sec->npts == 0) return GR_OK;
  for (size_t k = 0; k < sec->npts; k++)
    for (int c = 0; c < 2; c++) { lo[c] = gr_lo(lo[c], sec->xy[2 * k + c]); hi[c] = gr_hi(hi[c], sec->xy[2 * k + c]); }
  double h = fmin(d / THIN_CELL, b / 4);
  double fail[4], inner[4];
  int cov = all_covered(sec, core, b, h, o->thin_box, fail, e);
  if (cov < 0) return e->code;
  if (cov) return GR_OK;
  /* the grid covers the uncovered boundary grown by 3b: slivers lie within
   * 2b of it (inner), and every core node within b of those is on the grid */
  for (int c = 0; c < 2; c++) {
    inner[c] = fail[c] - 2 * b;
    inner[c + 2] = fail[c + 2] + 2 * b;
    lo[c] = fmax(lo[c], fail[c] - 3 * b - 4 * h);
    hi[c] = fmin(hi[c], fail[c + 2] + 3 * b + 4 * h);
  }
  double area = (hi[0] - lo[0] + 4 * h) * (hi[1] - lo[1] + 4 * h);
  if (area / (h * h) > THIN_NODES) h = sqrt(area / THIN_NODES);
  g.h = h; g.b = b;
  g.x0 = lo[0] - 2 * h; g.y0 = lo[1] - 2 * h;
  g.nx = (int)ceil((hi[0] - lo[0]) / h) + 5;
  g.ny = (int)ceil((hi[1] - lo[1]) / h) + 5;
  size_t nn = (size_t)g.nx * g.ny;
  long *stack = NULL, *comp = NULL;
  thin_line line = {0};
  gr_polydist *pd = gr_polydist_new(sec, 4 * b, e);
  int rc = GR_OK;
  if (!pd) return e->code;
  g.pd = pd;
  g.D = malloc(nn * sizeof *g.D);
  g.cov = malloc(nn * sizeof *g.cov);
  g.mark = calloc(nn, 1);
  if (!g.D || !g.cov || !g.mark) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory (thin-wall grid %d x %d)", g.nx, g.ny); goto done; }
  if ((rc = gr_polydist_grid(pd, g.x0, g.y0, h, g.nx, g.ny, 2 * b + 4 * h, g.D, e))) goto done;
  if (core_distance(&g)) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  size_t nsl = 0; /* sliver nodes: each is flooded once */
  for (size_t k = 0; k < nn; k++) {
    double x = g.x0 + (double)(k % (size_t)g.nx) * h, y = g.y0 + (double)(k / (size_t)g.nx) * h;
    if (g.D[k] < 0 && g.cov[k] * h * h > b * b && in_box(inner, x, y)) {
      g.mark[k] = 1;
      nsl++;
    }
  }
  stack = malloc((nsl + 1) * sizeof *stack);
  comp = malloc((nsl + 1) * sizeof *comp);
  if (!stack || !comp) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory (%zu sliver nodes)", nsl); goto done; }
  double wmin = d / THIN_MIN, tipm = THIN_TIP * b;
  for (size_t k0 = 0; k0 < nn; k0++) {
    if (g.mark[k0] != 1) continue;
    /* flood the sliver; is it attached to melted (covered) inside nodes? */
    size_t ns = 0, nc = 0;
    int attached = 0;
    stack[ns++] = (long)k0;
    g.mark[k0] |= 2;
    while (ns) {
      long k = stack[--ns];
      comp[nc++] = k;
      long i = k % g.nx, j = k / g.nx;
      for (long dj = -1; dj <= 1; dj++)
        for (long di = -1; di <= 1; di++) {
          long ii = i + di, jj = j + dj;
          if (ii < 0 || jj < 0 || ii >= g.nx || jj >= g.ny) continue;
          long q = ii + (long)g.nx * jj;
          if (g.mark[q] & 1) {
            if (!(g.mark[q] & 2)) { g.mark[q] |= 2; stack[ns++] = q; }
          } else if (g.D[q] < 0) attached = 1;
        }
    }
    int reach = 0;
    for (size_t m = 0; m < nc && !reach; m++) {
      double x = g.x0 + (double)(comp[m] % g.nx) * h, y = g.y0 + (double)(comp[m] / g.nx) * h;
      reach = in_box(o->thin_box, x, y);
    }
    if (!reach) continue; /* a sliver of the cut, not a wall */
    double dmax = 0;
    for (size_t m = 0; m < nc; m++) dmax = fmax(dmax, -g.D[comp[m]]);
    /* a whole thin component is always scanned: limits relaxed to its size */
    double wm = attached ? wmin : fmin(wmin, 0.5 * dmax), tm = attached ? tipm : fmin(tipm, 0.5 * dmax);
    int scanned = 0;
    for (int tr = 0; tr < THIN_TRACES; tr++) {
      long best = -1;
      double bd = -INFINITY;
      for (size_t m = 0; m < nc; m++)
        if (!(g.mark[comp[m]] & 4) && -g.D[comp[m]] > bd) { bd = -g.D[comp[m]]; best = comp[m]; }
      if (best < 0 || bd < wm) break;
      if ((rc = trace(&g, best, tm, wm, &line))) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
      if (line.n == 0) continue;
      if ((rc = emit_thin(&line, o, cl, rep, e))) goto done;
      scanned = 1;
    }
    if (scanned || !attached) { rep->thin_walls++; cl->thin_walls++; }
    if (!scanned && !attached) { /* too small for a line: a dot at its deepest node */
      long best = comp[0];
      for (size_t m = 0; m < nc; m++) if (g.D[comp[m]] < g.D[best]) best = comp[m];
      line.n = 0;
      if (tl_push(&line, g.x0 + (double)(best % g.nx) * h, g.y0 + (double)(best / g.nx) * h, -g.D[best])) {
        rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done;
      }
      if ((rc = emit_thin(&line, o, cl, rep, e))) goto done;
    }
  }
done:
  free(g.D); free(g.cov); free(g.mark); free(stack); free(comp);
  free(line.p);
  gr_polydist_free(pd);
  return rc;
}

/* Mark the deepest outer ring of sec (depth, bounding boxes box) that
 * contains point q. */
static void mark_hit(const gr_rings *sec, const int *depth, const double *box, const double *q, char *hit) {
  int best = -1, bd = -1;
  for (size_t r = 0; r < sec->nrings; r++) {
    const double *bb = box + 4 * r;
    if ((depth[r] & 1) || depth[r] <= bd || q[0] < bb[0] || q[0] > bb[2] || q[1] < bb[1] || q[1] > bb[3])
      continue;
    if (gr_ring_contains(sec, r, q[0], q[1])) { best = (int)r; bd = depth[r]; }
  }
  if (best >= 0) hit[best] = 1;
}

/* A point of offset ring i inside the section: its first vertex, or with a
 * cut (whose sides the offset moved out) its first vertex strictly inside
 * the cut's rectangle (NULL: none; the ring runs wholly beyond the cut). */
static const double *ring_point_inside(const gr_rings *ofs, size_t i, const double *cut) {
  const double *p = gr_ring_xy(ofs, i);
  size_t n = gr_ring_len(ofs, i);
  for (size_t k = 0; k < n; k++)
    if (!cut || (p[2 * k] > cut[0] && p[2 * k] < cut[2] && p[2 * k + 1] > cut[1] && p[2 * k + 1] < cut[3]))
      return p + 2 * k;
  return NULL;
}

/* Emit every ring of r as a closed contour block. */
static int emit_rings(const gr_rings *r, const gr_hatch_opts *o, gr_layer *cl,
                      gr_hatch_report *rep, gr_err *e) {
  double *pts = NULL;
  size_t cap = 0;
  for (size_t i = 0; i < r->nrings; i++) {
    size_t m = gr_ring_len(r, i);
    if (m < 2) continue;
    if (gr_grow(&pts, &cap, 2 * (m + 1), sizeof *pts)) { free(pts); return gr_fail(e, GR_EMEM, "hatch: out of memory"); }
    memcpy(pts, gr_ring_xy(r, i), m * 2 * sizeof *pts);
    pts[2 * m] = pts[0];
    pts[2 * m + 1] = pts[1];
    if (gr_layer_add(cl, GR_CLOSED, GR_CONTOUR, o->laser, gr_ring_area(r, i) > 0 ? 1 : 0, pts, m + 1)) {
      free(pts);
      return gr_fail(e, GR_EMEM, "hatch: out of memory");
    }
    rep->contours++;
  }
  free(pts);
  return GR_OK;
}

/* Contours and thin-wall scans of section into cl, and the hatch region
 * (the inward offset by h) into reg: the offsets are computed once each and
 * the region is handed back, not hatched. rep is reset first. */
static int contours_region(const gr_rings *section, const gr_hatch_opts *o, gr_layer *cl, gr_rings *reg,
                           gr_hatch_report *rep, gr_err *e) {
  memset(rep, 0, sizeof *rep);
  int rc = gr_hatch_check(o, e);
  if (rc) return rc;
  double d = o->spacing, b = isnan(o->beam_offset) ? d / 2 : o->beam_offset;
  double cell = isnan(o->cell) ? d / 4 : o->cell;
  int nc = o->contours;
  double h = nc == 0 ? b + o->gap : b + (nc - 1) * d + o->gap;
  rep->hatch_offset = h;
  gr_offset_fn off = pick_offset(o);
  const double *cut = isnan(o->cut[0]) ? NULL : o->cut;
  gr_rings *sec = gr_rings_new(), *ofs = gr_rings_new();
  char *hit = NULL;
  int *depth = NULL;
  double *box = NULL;
  if (!sec || !ofs) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  if (gr_rings_copy(sec, section)) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  if ((rc = gr_rings_nest(sec, e))) goto done;
  /* offset by b: the first contour, and the thin-wall test */
  if ((rc = off(sec, b, cell, o->thin_box, cut, ofs, e))) goto done;
  if (nc > 0 && (rc = emit_rings(ofs, o, cl, rep, e))) goto done;
  /* which components did the offset by b reach? (deepest outer ring
   * containing a point of each offset ring; bounding boxes first) */
  hit = calloc(sec->nrings + 1, 1);
  depth = malloc((sec->nrings + 1) * sizeof *depth);
  box = malloc((sec->nrings + 1) * 4 * sizeof *box);
  if (!hit || !depth || !box) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  for (size_t r = 0; r < sec->nrings; r++) {
    depth[r] = ring_depth(sec, r);
    gr_ring_box(sec, r, box + 4 * r);
  }
  for (size_t i = 0; i < ofs->nrings; i++) {
    const double *q = ring_point_inside(ofs, i, cut);
    if (q) mark_hit(sec, depth, box, q, hit);
  }
  /* a component reaching the cut goes on beyond it: no sliver of its own
   * (its offset may run wholly outside the cut, where the sides moved out) */
  for (size_t r = 0; r < sec->nrings && cut; r++)
    if (!(depth[r] & 1) && (box[4 * r] <= cut[0] + 1e-9 || box[4 * r + 1] <= cut[1] + 1e-9 ||
                            box[4 * r + 2] >= cut[2] - 1e-9 || box[4 * r + 3] >= cut[3] - 1e-9))
      hit[r] = 1;
  /* slivers the contour misses: centre lines; a component neither reached
   * nor seen by them gets the fallback line */
  size_t tb0 = cl->nb;
  if ((rc = thin_walls(sec, ofs, o, b, cl, rep, e))) goto done;
  for (size_t k = tb0; k < cl->nb; k++) mark_hit(sec, depth, box, cl->xy + 2 * cl->b[k].start, hit);
  for (size_t r = 0; r < sec->nrings; r++) {
    const double *bb = box + 4 * r;
    if (bb[2] < o->thin_box[0] || bb[3] < o->thin_box[1] || bb[0] > o->thin_box[2] || bb[1] > o->thin_box[3]) continue;
    if (!(depth[r] & 1) && !hit[r] && fabs(gr_ring_area(sec, r)) > 0)
      if ((rc = thin_fallback(sec, r, o, cl, rep, e))) goto done;
  }
  double last = b; /* the offset held in ofs */
  for (int i = 1; i < nc; i++) {
    last = b + i * d;
    if ((rc = off(sec, last, cell, o->thin_box, cut, ofs, e))) goto done;
    if ((rc = emit_rings(ofs, o, cl, rep, e))) goto done;
  }
  if (h == last) { /* default gap: the hatch region is the last contour */
    gr_rings t = *reg; /* take the offset's arrays, hand reg's back to be freed */
    *reg = *ofs;
    *ofs = t;
  } else if ((rc = off(sec, h, cell, o->thin_box, cut, reg, e))) goto done;
done:
  free(hit); free(depth); free(box);
  gr_rings_free(sec); gr_rings_free(ofs);
  return rc;
}

int gr_hatch_layer(const gr_rings *section, const gr_hatch_opts *o, gr_layer *out,
                   gr_hatch_report *rep, gr_err *e) {
  gr_hatch_report dummy;
  if (!rep) rep = &dummy;
  memset(rep, 0, sizeof *rep);
  if (!section || !out) return gr_fail(e, GR_EARG, "hatch: section and layer must not be NULL");
  gr_rings *reg = gr_rings_new();
  gr_layer *cl = gr_layer_new(out->z), *hl = gr_layer_new(out->z);
  int rc = (!reg || !cl || !hl) ? gr_fail(e, GR_EMEM, "hatch: out of memory") : GR_OK;
  if (rc == GR_OK) rc = contours_region(section, o, cl, reg, rep, e);
  if (rc == GR_OK) rc = gr_hatch_region(reg, o, hl, rep, e);
  if (rc == GR_OK) {
    out->thin_walls += cl->thin_walls;
    cl->thin_walls = 0;
    gr_layer *first = o->contour_first ? cl : hl, *second = o->contour_first ? hl : cl;
    if (gr_layer_append(out, first, 0, 0) || gr_layer_append(out, second, 0, 0))
      rc = gr_fail(e, GR_EMEM, "hatch: out of memory");
  }
  gr_rings_free(reg);
  gr_layer_free(cl); gr_layer_free(hl);
  return rc;
}

int gr_hatch_contours(const gr_rings *section, const gr_hatch_opts *o, gr_layer *out, gr_rings *region,
                      gr_hatch_report *rep, gr_err *e) {
  gr_hatch_report dummy;
  if (!rep) rep = &dummy;
  memset(rep, 0, sizeof *rep);
  if (!section || !out || !region) return gr_fail(e, GR_EARG, "hatch: section, layer and region must not be NULL");
  gr_layer *cl = gr_layer_new(out->z);
  int rc = cl ? contours_region(section, o, cl, region, rep, e) : gr_fail(e, GR_EMEM, "hatch: out of memory");
  if (rc == GR_OK) {
    out->thin_walls += cl->thin_walls;
    cl->thin_walls = 0;
    if (gr_layer_append(out, cl, 0, 0)) rc = gr_fail(e, GR_EMEM, "hatch: out of memory");
  }
  gr_layer_free(cl);
  return rc;
}
