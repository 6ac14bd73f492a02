/* clip.c: clipping to a voxel square, see clip.h. */
#include "clip.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common.h"

/* Liang-Barsky: clip segment p->q to the box; returns 0 if nothing is left,
 * else the parameters t0 <= t1 in [0,1]. */
int gr_clip_seg(double px, double py, double qx, double qy, const double lo[2],
                const double hi[2], double *t0, double *t1) {
  double a = 0, b = 1;
  double dx = qx - px, dy = qy - py;
  double pp[4] = {-dx, dx, -dy, dy};
  double qq[4] = {px - lo[0], hi[0] - px, py - lo[1], hi[1] - py};
  for (int i = 0; i < 4; i++) {
    if (pp[i] == 0) {
      if (qq[i] < 0) return 0;
    } else {
      double r = qq[i] / pp[i];
      if (pp[i] < 0) { if (r > b) return 0; if (r > a) a = r; }
      else { if (r < a) return 0; if (r < b) b = r; }
    }
  }
  *t0 = a;
  *t1 = b;
  return a <= b;
}

int gr_clip_open_dir(int dir) { return dir == GR_DIR_THIN ? GR_DIR_THIN : 2; }

/* Add an open piece of m points, unless it has no length (all its points
 * one: a polyline touching the box at a vertex on its border). */
static int add_piece(gr_layer *out, int kind, int odir, const double *bf, size_t m) {
  size_t k = 1;
  while (k < m && bf[2 * k] == bf[0] && bf[2 * k + 1] == bf[1]) k++;
  return k < m ? gr_layer_add(out, GR_OPEN, kind, 0, odir, bf, m) : GR_OK;
}

/* An edge a-b of a ring whose inside is on its left lies on a side of the
 * box and has the inside beyond it (outside the box): the neighbouring voxel
 * scans it. */
static int edge_outward(double ax, double ay, double bx, double by, const double lo[2], const double hi[2]) {
  if (ax == bx && (ax == lo[0] || ax == hi[0])) return ax == lo[0] ? by > ay : by < ay;
  if (ay == by && (ay == lo[1] || ay == hi[1])) return ay == lo[1] ? bx < ax : bx > ax;
  return 0;
}

/* The first point of a closed ring of n points p[] that lies outside the box;
 * owned: else the point after the first edge dropped as outward; n if none. */
static size_t first_out(const double *p, size_t n, int owned, const double lo[2], const double hi[2]) {
  for (size_t k = 0; k < n; k++)
    if (p[2 * k] < lo[0] || p[2 * k] > hi[0] || p[2 * k + 1] < lo[1] || p[2 * k + 1] > hi[1]) return k;
  for (size_t k = 0; owned && k < n; k++) {
    size_t b = gr_ring_next(k, n);
    if (edge_outward(p[2 * k], p[2 * k + 1], p[2 * b], p[2 * b + 1], lo, hi)) return b;
  }
  return n;
}

/* gr_clip_poly and gr_clip_ring_owned (owned: a closed ring, p already snapped). */
static int clip_poly(const double *p, size_t n, int closed, int kind, int dir, int owned, const double lo[2],
                     const double hi[2], gr_layer *out, double *bf) {
  int odir = gr_clip_open_dir(dir);
  size_t s0 = first_out(p, n, owned, lo, hi);
  if (!closed && s0 < n) s0 = 0; /* an open polyline's pieces follow it from its start */
  if (s0 == n) { /* wholly inside */
    memcpy(bf, p, n * 2 * sizeof(double));
    size_t m = n;
    if (closed) { bf[2 * n] = p[0]; bf[2 * n + 1] = p[1]; m++; }
    return gr_layer_add(out, closed ? GR_CLOSED : GR_OPEN, kind, 0, closed ? dir : odir, bf, m);
  }
  size_t nedges = closed ? n : n - 1, m = 0;
  for (size_t e = 0; e < nedges; e++) {
    size_t a = s0 + e < n ? s0 + e : s0 + e - n, b = gr_ring_next(a, n); /* (s0 < n, e < n) */
    double ax = p[2 * a], ay = p[2 * a + 1], bx = p[2 * b], by = p[2 * b + 1];
    double t0, t1;
    if (!gr_clip_seg(ax, ay, bx, by, lo, hi, &t0, &t1)) continue;
    if (owned && edge_outward(ax, ay, bx, by, lo, hi)) { /* the neighbour's: the piece ends here */
      if (m >= 2 && add_piece(out, kind, odir, bf, m)) return GR_EMEM;
      m = 0;
      continue;
    }
    if (t0 > 0 || m == 0) {
      if (m >= 2 && add_piece(out, kind, odir, bf, m)) return GR_EMEM;
      bf[0] = ax + t0 * (bx - ax);
      bf[1] = ay + t0 * (by - ay);
      m = 1;
    }
    double ex = t1 < 1 ? ax + t1 * (bx - ax) : bx, ey = t1 < 1 ? ay + t1 * (by - ay) : by;
    if (!owned || ex != bf[2 * m - 2] || ey != bf[2 * m - 1]) { /* (owned: an edge touching the box at one point adds none) */
      bf[2 * m] = ex;
      bf[2 * m + 1] = ey;
      m++;
    }
    if (t1 < 1) {
      if (m >= 2 && add_piece(out, kind, odir, bf, m)) return GR_EMEM;
      m = 0;
    }
  }
  if (m >= 2 && add_piece(out, kind, odir, bf, m)) return GR_EMEM;
  return GR_OK;
}

int gr_clip_poly(const double *p, size_t n, int closed, int kind, int dir,
                 const double lo[2], const double hi[2], gr_layer *out,
                 double **buf, size_t *cap) {
  if (closed && n > 1 && p[0] == p[2 * (n - 1)] && p[1] == p[2 * (n - 1) + 1]) n--;
  if (n < 2) return GR_OK;
  if (gr_grow(buf, cap, n + 2, 2 * sizeof(double))) return GR_EMEM;
  return clip_poly(p, n, closed, kind, dir, 0, lo, hi, out, *buf);
}

/* A coordinate within GR_CLIP_SNAP of a box side's: the side's. */
static double snap(double v, double lo, double hi) {
  return fabs(v - lo) <= GR_CLIP_SNAP ? lo : fabs(v - hi) <= GR_CLIP_SNAP ? hi : v;
}

int gr_clip_ring_owned(const double *p, size_t n, int kind, int dir, const double lo[2], const double hi[2],
                       gr_layer *out, double **buf, size_t *cap) {
  if (n > 1 && p[0] == p[2 * (n - 1)] && p[1] == p[2 * (n - 1) + 1]) n--;
  if (n < 2) return GR_OK;
  if (gr_grow(buf, cap, 2 * n + 2, 2 * sizeof(double))) return GR_EMEM;
  double *q = *buf + 2 * (n + 2); /* the snapped ring, after the pieces' room */
  for (size_t k = 0; k < n; k++) {
    q[2 * k] = snap(p[2 * k], lo[0], hi[0]);
    q[2 * k + 1] = snap(p[2 * k + 1], lo[1], hi[1]);
  }
  return clip_poly(q, n, 1, kind, dir, 1, lo, hi, out, *buf);
}

/* Area of the region bounded by `r` inside the box: each ring clipped by Sutherland-Hodgman against the four box edges; the
 * degenerate edges this leaves along the border have no area. */

double gr_clip_area(const gr_rings *r, const double lo[2], const double hi[2]) {
  double total = 0;
  size_t cap = 0;
  double *a = NULL, *b = NULL;
  size_t capb = 0;
  for (size_t i = 0; i < r->nrings; i++) {
    size_t n = gr_ring_len(r, i);
    if (gr_grow(&a, &cap, 2 * n + 8, 2 * sizeof(double)) || gr_grow(&b, &capb, 2 * n + 8, 2 * sizeof(double))) break;
    memcpy(a, gr_ring_xy(r, i), n * 2 * sizeof(double));
    for (int edge = 0; edge < 4 && n > 0; edge++) {
      int ax = edge & 1;          /* 0: x, 1: y */
      int upper = edge >= 2;      /* 0: keep >= lo, 1: keep <= hi */
      double c = upper ? hi[ax] : lo[ax];
      size_t m = 0;
      if (gr_grow(&b, &capb, 2 * n + 8, 2 * sizeof(double))) break;
      for (size_t k = 0; k < n; k++) {
        const double *P = a + 2 * gr_ring_prev(k, n), *Q = a + 2 * k;
        int pin = upper ? P[ax] <= c : P[ax] >= c, qin = upper ? Q[ax] <= c : Q[ax] >= c;
        if (qin != pin) {
          double t = (c - P[ax]) / (Q[ax] - P[ax]);
          b[2 * m] = P[0] + t * (Q[0] - P[0]);
          b[2 * m + 1] = P[1] + t * (Q[1] - P[1]);
          b[2 * m + ax] = c;
          m++;
        }
        if (qin) { b[2 * m] = Q[0]; b[2 * m + 1] = Q[1]; m++; }
      }
      double *t = a; a = b; b = t;
      size_t tc = cap; cap = capb; capb = tc;
      n = m;
      if (gr_grow(&a, &cap, 2 * n + 8, 2 * sizeof(double))) { n = 0; break; }
    }
    double ar = 0;
    for (size_t k = 0, q = n ? n - 1 : 0; k < n; q = k++) ar += a[2 * q] * a[2 * k + 1] - a[2 * k] * a[2 * q + 1];
    total += 0.5 * ar;
  }
  free(a);
  free(b);
  return total;
}

