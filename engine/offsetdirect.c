/* offsetdirect.c: the inward offset of a set of rings straight from their
 * edges, where that is simple (slice.h: gr_offset_rings_direct).
 *
 * Each edge moves by b to its left (inside, for nested rings). Where two
 * moved edges turn left (a convex vertex) they meet at their lines'
 * intersection, the offset's exact corner; where they turn right (a reflex
 * vertex) the offset runs on the arc of radius b around the vertex, put in
 * as chords within the chord tolerance (or, for a small turn, as the lines'
 * intersection, which lies off the arc by b (1 / cos(turn / 2) - 1), at
 * most half the tolerance). Every other point lies on the offset lines
 * themselves: the offset of the polygon, exact but for the arcs' chords.
 *
 * A template's section is cut to a window around its voxel; the cut's
 * sides are no walls, and the part goes on beyond them. Edges along them
 * move out instead of in (by CUT_OUT b: as if the section went on past the
 * window), so that a boundary running near the window's side, or a corner
 * of the window clipping a sliver off the section, leaves the offset
 * simple; only the offset beyond the voxel changes. Rings lying wholly
 * farther than 2b outside the box where the offset is needed are left out.
 *
 * An edge whose moved copy runs backwards between its two mitred corners
 * (a short edge at a sharp corner; the run of short edges of a window's
 * border meeting the section at a shallow angle) is swallowed: its
 * neighbours' lines meet instead, the swallowtail's loop cut off (prune).
 * Then the region of the offset is where the winding number of the raw
 * rings is positive (Chen and McMains, "Polygon offsetting by computing
 * winding numbers", 2005): where no two raw segments meet, the rings are
 * simple and disjoint, and a ring bounds that region exactly when the
 * winding number on its left is 1 (keep_winding): an annulus narrower than
 * 2b, whose outer ring's offset lies inside its hole's, leaves nothing.
 * Anything else (rings whose offsets cross: a wall or neck narrower than
 * 2b, two rings nearer than 2b; the sides of a spike closing over it;
 * segments touching) declines, and the grid offset of polydist.c takes
 * over: 1 to 13 in 100 template layers of graded P, gyroid and diamond
 * sheets. The templates' rings are then simplified (SIMPLIFY_SHARE): they
 * follow the section's vertices, denser than the offset needs. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "slice.h"

/* Segments nearer than this (mm) count as meeting. */
#define DIRECT_EPS 1e-8
/* A cut's sides move out by this many b. By b, the join of an edge with a
 * side lies b from both lines, on a bisector at their vertex, and within
 * 1.5 b of it for an edge meeting the side at up to 90 degrees; moved out
 * farther, an edge's line meets the side's farther along, and two
 * components close together on one side had their joins cross beyond the
 * window: the offset declined (a thick graded diamond sheet, T = 0.26 +
 * 0.04 sin(x/3) cos(y/2.5): 3.6 % of template layers by 2 b, 1.8 % by b;
 * gyroid 2.4 % and 0.2 %). No offset of the section reaches the moved
 * side but along the side itself (an edge b from it moves onto it). */
#define CUT_OUT 1.0
/* The chord tolerance's shares: arcs' chords (and a small turn's mitre at
 * half of it), and the simplification of the rings after (Douglas-Peucker
 * on points of the offset, whose chords lie on it but across arcs): a
 * chord of the result lies within their sum of the polygon's offset. */
#define ARC_SHARE 0.4
#define SIMPLIFY_SHARE 0.6

/* One edge of a ring being offset; its join is the corner at its start
 * (between the previous live edge and it). */
typedef struct oedge {
  double p[2];       /* the edge's start (a vertex of the ring) */
  double u[2], n[2]; /* unit direction, left normal */
  double a[2];       /* a point of its offset line: p + b n (on a cut: p - CUT_OUT b n) */
  int cut;           /* the edge lies on the window's cut: it moves out */
  int prev, next;    /* live neighbours */
  int arc;           /* the join is an arc around p (a reflex vertex) */
  double s[2];       /* the join's point where this edge's offset starts */
  double e[2];       /* the join's point where the previous edge's ends */
} oedge;

/* The distinct points of ring i (consecutive repeats dropped, also across
 * the closing segment) into p; their count. */
static size_t distinct_points(const gr_rings *r, size_t i, double *p) {
  const double *q = gr_ring_xy(r, i);
  size_t n = gr_ring_len(r, i), m = 0;
  for (size_t k = 0; k < n; k++) {
    if (m > 0 && q[2 * k] == p[2 * m - 2] && q[2 * k + 1] == p[2 * m - 1]) continue;
    p[2 * m] = q[2 * k];
    p[2 * m + 1] = q[2 * k + 1];
    m++;
  }
  while (m > 1 && p[0] == p[2 * m - 2] && p[1] == p[2 * m - 1]) m--;
  return m;
}

static double cross2(const double *u, const double *v) { return u[0] * v[1] - u[1] * v[0]; }

/* Whether the edge p-q lies along a side of the cut (x0 y0 x1 y1, or NULL),
 * to DIRECT_EPS (the window's far sides are grid nodes, x0 + (n - 1) h,
 * which may round off the side given). */
static int on_cut(const double *cut, const double *p, const double *q) {
  if (!cut) return 0;
  for (int c = 0; c < 4; c++)
    if (fabs(p[c & 1] - cut[c]) <= DIRECT_EPS && fabs(q[c & 1] - cut[c]) <= DIRECT_EPS) return 1;
  return 0;
}

/* Where the offset lines of f and g meet (their directions turning left by
 * cr > 0): into s and e. */
static void lines_meet(const oedge *f, oedge *g, double cr) {
  double w[2] = {g->a[0] - f->a[0], g->a[1] - f->a[1]}, t = cross2(w, g->u) / cr;
  g->s[0] = g->e[0] = f->a[0] + t * f->u[0];
  g->s[1] = g->e[1] = f->a[1] + t * f->u[1];
}

/* The edges of a ring of n distinct points and their original joins: 1,
 * or 0 when a vertex turns back on itself or a cut side meets an edge
 * turning right. tol: the chord tolerance. */
static int edges_init(const double *p, size_t n, double b, double tol, const double *cut, oedge *E) {
  for (size_t k = 0; k < n; k++) {
    oedge *g = E + k;
    const double *q = p + 2 * gr_ring_next(k, n);
    double dx = q[0] - p[2 * k], dy = q[1] - p[2 * k + 1], L = gr_len2d(dx, dy);
    g->p[0] = p[2 * k]; g->p[1] = p[2 * k + 1];
    double iL = 1 / L;
    g->u[0] = dx * iL; g->u[1] = dy * iL;
    g->n[0] = -g->u[1]; g->n[1] = g->u[0];
    g->cut = on_cut(cut, p + 2 * k, q);
    double sh = g->cut ? -CUT_OUT * b : b;
    g->a[0] = g->p[0] + sh * g->n[0]; g->a[1] = g->p[1] + sh * g->n[1];
    g->prev = (int)gr_ring_prev(k, n);
    g->next = (int)gr_ring_next(k, n);
  }
  /* a right turn's mitre is off the arc by b (1 / cos(t / 2) - 1), cos(t / 2)
   * = sqrt((1 + cos t) / 2): within tol / 2 when (1 + cos t) / 2 >= cmin */
  double cmin = 1 / ((1 + 0.5 * tol / b) * (1 + 0.5 * tol / b));
  for (size_t k = 0; k < n; k++) {
    oedge *g = E + k;
    const oedge *f = E + g->prev;
    double cr = cross2(f->u, g->u), dt = f->u[0] * g->u[0] + f->u[1] * g->u[1];
    if (!(dt > -0.999999)) return 0; /* a U-turn (or NaN) */
    g->arc = 0;
    if (f->cut || g->cut) { /* along the cut, or where an edge meets it */
      if (f->cut && g->cut && fabs(cr) <= 1e-12 && dt > 0) { g->s[0] = g->e[0] = g->a[0]; g->s[1] = g->e[1] = g->a[1]; }
      else if (cr > 1e-9) lines_meet(f, g, cr);
      else return 0;
      continue;
    }
    /* a right turn by t: the lines meet b (1 / cos(t / 2) - 1) off the arc */
    g->arc = !(cr >= 0 || 0.5 * (1 + dt) >= cmin);
    if (g->arc) {
      g->e[0] = g->p[0] + b * f->n[0]; g->e[1] = g->p[1] + b * f->n[1];
      g->s[0] = g->a[0]; g->s[1] = g->a[1];
    } else { /* the lines' intersection, p + b (n1 + n2) / (1 + cos turn) */
      double m = b / (1 + dt);
      g->s[0] = g->e[0] = g->p[0] + m * (f->n[0] + g->n[0]);
      g->s[1] = g->e[1] = g->p[1] + m * (f->n[1] + g->n[1]);
    }
  }
  return 1;
}

/* Swallow the edges whose offset runs backwards (or not at all) between two
 * mitred joins (the neighbours' lines meet instead), repeatedly. Returns the live edges
 * left (< 3: the ring closes up) with *first one of them, -1 to decline
 * (such an edge at an arc, or neighbours turning right: the sides of a
 * spike narrower than 2b). An edge is live while its previous one links to
 * it. stack: 3 n ints. */
static int prune(oedge *E, int n, int *stack, int *first) {
  int live = n, top = 0;
  for (int k = n - 1; k >= 0; k--) stack[top++] = k;
  while (top > 0 && live >= 3) {
    int k = stack[--top];
    if (E[E[k].prev].next != k) continue; /* swallowed before (its neighbours link past it) */
    oedge *g = E + k, *c = E + g->next;
    double run = (c->e[0] - g->s[0]) * g->u[0] + (c->e[1] - g->s[1]) * g->u[1];
    if (run > DIRECT_EPS) continue; /* (one of no length, as where a window's corner pulls back by a border edge's length, goes too) */
    if (g->arc || c->arc) { live = -1; break; }
    oedge *a = E + g->prev;
    double den = cross2(a->u, c->u);
    if (!(den > 1e-9)) { live = -1; break; } /* the sides of a spike closing over it */
    lines_meet(a, c, den);
    a->next = g->next;
    c->prev = g->prev;
    live--;
    stack[top++] = g->prev;
    stack[top++] = g->next;
  }
  for (int k = 0; k < n && live > 0; k++)
    if (E[E[k].prev].next == k) { *first = k; break; }
  return live;
}

/* Append the live edges' joins from `first` on as one ring of out: 0, or
 * -1 out of memory. th: the largest arc step (radians). */
static int emit_ring(const oedge *E, int first, double b, double th, gr_rings *out) {
  int k = first;
  do {
    const oedge *g = E + k;
    if (g->arc) {
      const oedge *f = E + g->prev;
      double half = 0.5 * atan2(-cross2(f->u, g->u), f->u[0] * g->u[0] + f->u[1] * g->u[1]);
      int s = (int)ceil(2 * half / th);
      if (gr_rings_point(out, g->e[0], g->e[1])) return -1;
      for (int j = 1; j < s; j++) { /* f's normal turned right by j / s of the turn */
        double an = -2 * half * j / s, cs = cos(an), sn = sin(an);
        if (gr_rings_point(out, g->p[0] + b * (cs * f->n[0] - sn * f->n[1]), g->p[1] + b * (sn * f->n[0] + cs * f->n[1])))
          return -1;
      }
    }
    if (gr_rings_point(out, g->s[0], g->s[1])) return -1;
    k = g->next;
  } while (k != first);
  return gr_rings_close(out) ? -1 : 0;
}

/* Raw offset of each ring of in into raw: 1 done, 0 declined, -1 out of memory. */
/* Whether the n points p lie wholly more than r outside box (or box is NULL: no). */
static int far_outside(const double *p, size_t n, const double *box, double r) {
  if (!box) return 0;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < n; k++)
    for (int c = 0; c < 2; c++) { lo[c] = gr_lo(lo[c], p[2 * k + c]); hi[c] = gr_hi(hi[c], p[2 * k + c]); }
  return hi[0] < box[0] - r || hi[1] < box[1] - r || lo[0] > box[2] + r || lo[1] > box[3] + r;
}

static int raw_rings(const gr_rings *in, double b, double tol, const double *box, const double *cut, gr_rings *raw) {
  size_t cap = in->npts + 1;
  double *p = malloc(2 * cap * sizeof *p), th = tol < b ? 2 * acos(1 - tol / b) : M_PI;
  oedge *E = malloc(cap * sizeof *E);
  int *stack = malloc(3 * cap * sizeof *stack), ok = 1;
  if (!p || !E || !stack) ok = -1;
  for (size_t i = 0; i < in->nrings && ok == 1; i++) {
    size_t n = distinct_points(in, i, p);
    if (n < 3 || far_outside(p, n, box, 2 * b)) continue; /* no area, or too far to matter */
    if (!edges_init(p, n, b, tol, cut, E)) { ok = 0; break; }
    int first = 0, live = prune(E, (int)n, stack, &first);
    if (live < 0 || (live < 3 && gr_ring_area(in, i) < 0)) ok = 0; /* a hole cannot close up */
    else if (live >= 3 && emit_ring(E, first, b, th, raw)) ok = -1;
  }
  free(p); free(E); free(stack);
  return ok;
}

static double orient(const double *a, const double *b, const double *c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether segments a0-a1 and b0-b1 cross or come within DIRECT_EPS. */
static int seg_meet(const double *a0, const double *a1, const double *b0, const double *b1) {
  if (gr_hi(a0[0], a1[0]) + DIRECT_EPS < gr_lo(b0[0], b1[0]) || gr_hi(b0[0], b1[0]) + DIRECT_EPS < gr_lo(a0[0], a1[0]) ||
      gr_hi(a0[1], a1[1]) + DIRECT_EPS < gr_lo(b0[1], b1[1]) || gr_hi(b0[1], b1[1]) + DIRECT_EPS < gr_lo(a0[1], a1[1]))
    return 0; /* boxes apart */
  double o1 = orient(a0, a1, b0), o2 = orient(a0, a1, b1), o3 = orient(b0, b1, a0), o4 = orient(b0, b1, a1);
  if (((o1 < 0 && o2 > 0) || (o1 > 0 && o2 < 0)) && ((o3 < 0 && o4 > 0) || (o3 > 0 && o4 < 0))) return 1;
  double e2 = DIRECT_EPS * DIRECT_EPS;
  return gr_seg_dist2(b0, a0, a1) < e2 || gr_seg_dist2(b1, a0, a1) < e2 || gr_seg_dist2(a0, b0, b1) < e2 ||
         gr_seg_dist2(a1, b0, b1) < e2;
}

/* Whether two segments of the rings r meet (neighbours at their shared end
 * apart), tested pairwise within buckets of about bs: 1, 0, or -1 out of
 * memory. */
static int rings_meet(const gr_rings *r, double bs) {
  size_t ns = r->npts;
  if (ns == 0) return 0;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < ns; k++)
    for (int c = 0; c < 2; c++) { lo[c] = gr_lo(lo[c], r->xy[2 * k + c]); hi[c] = gr_hi(hi[c], r->xy[2 * k + c]); }
  while (((hi[0] - lo[0]) / bs + 1) * ((hi[1] - lo[1]) / bs + 1) > 4.0 * (double)ns + 16) bs *= 1.5;
  int bx = (int)floor((hi[0] - lo[0]) / bs) + 1, by = (int)floor((hi[1] - lo[1]) / bs) + 1;
  /* by the reciprocal: any rule monotonic in x and y puts two segments
   * within DIRECT_EPS in a bucket together, and the clamps keep it inside */
  double ibs = 1 / bs;
  size_t nb = (size_t)bx * by, *cnt = calloc(nb + 1, sizeof *cnt), *list = NULL;
  /* nxt[s]: the point after s on its ring: segment s runs from s to nxt[s],
   * and two segments are neighbours when one's nxt is the other */
  size_t *nxt = malloc(ns * sizeof *nxt);
  int *box = malloc(4 * ns * sizeof *box), res = -1;
  if (!cnt || !box || !nxt) goto done;
  gr_rings_successors(r, nxt);
  for (size_t s = 0; s < ns; s++) {
    const double *a = r->xy + 2 * s, *b = r->xy + 2 * nxt[s];
    int *o = box + 4 * s;
    o[0] = (int)floor((gr_lo(a[0], b[0]) - DIRECT_EPS - lo[0]) * ibs);
    o[1] = (int)floor((gr_hi(a[0], b[0]) + DIRECT_EPS - lo[0]) * ibs);
    o[2] = (int)floor((gr_lo(a[1], b[1]) - DIRECT_EPS - lo[1]) * ibs);
    o[3] = (int)floor((gr_hi(a[1], b[1]) + DIRECT_EPS - lo[1]) * ibs);
    o[0] = o[0] < 0 ? 0 : o[0]; o[2] = o[2] < 0 ? 0 : o[2];
    o[1] = o[1] >= bx ? bx - 1 : o[1]; o[3] = o[3] >= by ? by - 1 : o[3];
    for (int j = o[2]; j <= o[3]; j++)
      for (int i = o[0]; i <= o[1]; i++) cnt[(size_t)i + (size_t)bx * j + 1]++;
  }
  for (size_t k = 0; k < nb; k++) cnt[k + 1] += cnt[k];
  if (!(list = malloc(cnt[nb] * sizeof *list + 1))) goto done;
  for (size_t s = 0; s < ns; s++) {
    const int *o = box + 4 * s;
    for (int j = o[2]; j <= o[3]; j++)
      for (int i = o[0]; i <= o[1]; i++) list[cnt[(size_t)i + (size_t)bx * j]++] = s;
  }
  for (size_t k = nb; k > 0; k--) cnt[k] = cnt[k - 1]; /* back to the starts */
  cnt[0] = 0;
  res = 0;
  for (size_t k = 0; k < nb && !res; k++)
    for (size_t x = cnt[k]; x < cnt[k + 1] && !res; x++)
      for (size_t y = x + 1; y < cnt[k + 1] && !res; y++) {
        size_t u = list[x], v = list[y];
        if (nxt[u] == v || nxt[v] == u) continue;
        res = seg_meet(r->xy + 2 * u, r->xy + 2 * nxt[u], r->xy + 2 * v, r->xy + 2 * nxt[v]);
      }
done:
  free(cnt); free(list); free(box); free(nxt);
  return res;
}

/* Keep the raw rings that bound the region of positive winding number
 * (winding 1 on their left): into out. */
static int keep_winding(const gr_rings *raw, gr_rings *out, gr_err *e) {
  size_t n = raw->nrings;
  double *area = malloc((n + 1) * sizeof *area), *box = malloc(4 * (n + 1) * sizeof *box);
  if (!area || !box) { free(area); free(box); return gr_fail(e, GR_EMEM, "offset: out of memory"); }
  for (size_t i = 0; i < n; i++) {
    area[i] = gr_ring_area(raw, i);
    gr_ring_box(raw, i, box + 4 * i);
  }
  int rc = GR_OK;
  gr_rings_clear(out);
  for (size_t i = 0; i < n && !rc; i++) {
    if (!(area[i] != 0)) continue;
    const double *v = gr_ring_xy(raw, i);
    int w = area[i] > 0;
    for (size_t j = 0; j < n; j++) {
      const double *q = box + 4 * j;
      if (j == i || !(area[j] != 0) || v[0] < q[0] || v[0] > q[2] || v[1] < q[1] || v[1] > q[3]) continue;
      if (gr_ring_contains(raw, j, v[0], v[1])) w += area[j] > 0 ? 1 : -1;
    }
    if (w == 1 && gr_rings_add(out, v, gr_ring_len(raw, i))) rc = gr_fail(e, GR_EMEM, "offset: out of memory");
  }
  free(area);
  free(box);
  return rc;
}

int gr_offset_rings_direct(const gr_rings *in, double b, double chord_tol, double bucket, const double *box,
                           const double *cut, int simplify, gr_rings *out, int *done, gr_err *e) {
  *done = 0;
  if (!(b > 0) || !(chord_tol > 0) || !(bucket > 0)) return GR_OK;
  gr_rings *raw = gr_rings_new();
  int ok = raw ? raw_rings(in, b, simplify ? ARC_SHARE * chord_tol : chord_tol, box, cut, raw) : -1;
  if (ok == 1) {
    int m = rings_meet(raw, bucket);
    ok = m < 0 ? -1 : !m;
  }
  int rc = ok < 0 ? gr_fail(e, GR_EMEM, "offset: out of memory") : GR_OK;
  if (ok == 1 && !(rc = keep_winding(raw, out, e))) {
    /* the section's vertices are denser than the offset needs (its own
     * chords are held to 0.2 um; straight runs along a face or a cut keep
     * every grid crossing): fewer points to contour, assemble and write */
    if (simplify && gr_rings_simplify(out, SIMPLIFY_SHARE * chord_tol)) rc = gr_fail(e, GR_EMEM, "offset: out of memory");
    *done = !rc;
  }
  gr_rings_free(raw);
  return rc;
}
