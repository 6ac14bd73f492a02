/* march.c: marching squares with refined crossings, see march.h. */
#include "march.h"
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Evaluate fn at n points in chunks (keeps scratch buffers of callers small). */
int gr_ms_eval(gr_slice_fn fn, void *ud, size_t n, const double *x,
                    const double *y, double *out, gr_err *e) {
  for (size_t s = 0; s < n; s += MS_CHUNK) {
    size_t m = n - s < MS_CHUNK ? n - s : MS_CHUNK;
    int rc = fn(ud, m, x + s, y + s, out + s, e);
    if (rc) return rc;
  }
  return GR_OK;
}

/* A bound (in t) on the error of the Newton step from the first point t of
 * the edge [0, 1] (value f, slope dt) with the ends' values fa, fb. The
 * parabolas through the point (with its slope) and either end have second
 * derivatives ca, cb: f's curvature is taken as the larger, and the slope's
 * own error as what makes them differ (for a parabola with a wrong slope
 * ca - cb = 2 dslope / (t (1 - t))): the step's error is then
 * (|f''| step^2 / 2 + |dslope| |step|) / |dt|, with NEWTON_SAFETY to spare.
 * Where f is smooth over the edge and its slope right this lets a crossing
 * end after one evaluation instead of two; a kink or jump between the nodes
 * (the medial surface), or a slope that leaves out a graded T's, shows in
 * ca and cb and the step is checked as before. */
#define NEWTON_SAFETY 4.0
static double newton_error(double fa, double fb, double t, double f, double dt, double step) {
  if (!(t > 0 && t < 1)) return INFINITY;
  double ca = 2 * (fa - f + dt * t) / (t * t), cb = 2 * (fb - f - dt * (1 - t)) / ((1 - t) * (1 - t));
  double c = fmax(fabs(ca), fabs(cb)), ds = 0.5 * fabs(ca - cb) * t * (1 - t);
  double err = NEWTON_SAFETY * (0.5 * c * step * step + ds * fabs(step)) / fabs(dt);
  return isfinite(err) ? err : INFINITY;
}

/* Batched root finding on n segments P_k + t (Q_k - P_k), t in [0,1], with
 * fp < 0 <= fq given. Each pass evaluates once on all unconverged segments.
 * Without gfn: Illinois (modified regula falsi), stopping when the bracket is
 * shorter than tol (mm), so the returned point is within tol of a root. With
 * gfn (value and gradient): Newton steps kept inside the bracket (Illinois
 * where a step leaves it), stopping when the Newton step is below tol, or,
 * for the first step, when its error bound is (newton_error, from the
 * segment's end values fp, fq). P, Q: 2n coordinates; out: 2n coordinates. */
static int roots_batch(gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, size_t n, const double *P,
                       const double *Q, const double *fp, const double *fq,
                       int refine, double tol, double *out, gr_err *e) {
  if (n == 0) return GR_OK;
  /* one block for the per-segment arrays (this runs once a contour and
   * once a chord pass, on a few hundred to many thousand segments) */
  double *ta = malloc(12 * n * sizeof *ta);
  size_t *act = malloc(n * sizeof *act);
  signed char *side = calloc(n, 1);
  int rc = GR_OK;
  if (!ta || !act || !side) {
    rc = gr_fail(e, GR_EMEM, "out of memory refining %zu crossings", n);
    goto done;
  }
  double *tb = ta + n, *fa = tb + n, *fb = fa + n, *len = fb + n, *tn = len + n;
  double *qx = tn + n, *qy = qx + n, *qt = qy + n, *qf = qt + n, *gx = qf + n, *gy = gx + n;
  size_t na = 0;
  for (size_t k = 0; k < n; k++) {
    ta[k] = 0; tb[k] = 1; fa[k] = fp[k]; fb[k] = fq[k];
    tn[k] = NAN;
    /* a grid edge runs along x or y: hypot(d, 0) is |d| exactly (C11 F.10.4.3) */
    double dx = Q[2 * k] - P[2 * k], dy = Q[2 * k + 1] - P[2 * k + 1];
    len[k] = dy == 0 ? fabs(dx) : dx == 0 ? fabs(dy) : hypot(dx, dy);
    if (refine && len[k] > tol && fb[k] != 0) act[na++] = k;
  }
  for (int it = 0; it < 200 && na > 0; it++) {
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double t = tn[k];
      if (!(t > ta[k] && t < tb[k])) t = (ta[k] * fb[k] - tb[k] * fa[k]) / (fb[k] - fa[k]);
      if (!(t > ta[k] && t < tb[k]) || !isfinite(t)) t = 0.5 * (ta[k] + tb[k]);
      if (it > 100) t = 0.5 * (ta[k] + tb[k]); /* safety net: plain bisection */
      qt[i] = t;
      qx[i] = P[2 * k] + t * (Q[2 * k] - P[2 * k]);
      qy[i] = P[2 * k + 1] + t * (Q[2 * k + 1] - P[2 * k + 1]);
    }
    if (gfn) {
      for (size_t s = 0; s < na && !rc; s += MS_CHUNK) {
        size_t m = na - s < MS_CHUNK ? na - s : MS_CHUNK;
        rc = gfn(ud, m, qx + s, qy + s, qf + s, gx + s, gy + s, e);
      }
    } else {
      rc = gr_ms_eval(fn, ud, na, qx, qy, qf, e);
    }
    if (rc) goto done;
    size_t keep = 0;
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double f = qf[i], t = qt[i];
      if (f < 0) {
        ta[k] = t; fa[k] = f;
        if (side[k] == -1) fb[k] *= 0.5;
        side[k] = -1;
      } else {
        tb[k] = t; fb[k] = f;
        if (side[k] == 1) fa[k] *= 0.5;
        side[k] = 1;
      }
      if (f == 0) { ta[k] = tb[k] = t; continue; }
      if (gfn) {
        double dt = gx[i] * (Q[2 * k] - P[2 * k]) + gy[i] * (Q[2 * k + 1] - P[2 * k + 1]);
        double step = dt > 0 ? -f / dt : NAN;
        tn[k] = t + step;
        double err = it == 0 ? newton_error(fp[k], fq[k], t, f, dt, step) : fabs(step);
        if (err * len[k] < tol && tn[k] >= ta[k] && tn[k] <= tb[k]) { ta[k] = tb[k] = tn[k]; continue; }
      }
      if ((tb[k] - ta[k]) * len[k] > tol) act[keep++] = k;
    }
    na = keep;
  }
  for (size_t k = 0; k < n; k++) {
    double t;
    if (ta[k] == tb[k]) t = ta[k];
    else if (fb[k] == 0) t = tb[k];
    else {
      /* final linear estimate inside the (tiny) bracket; with the original
       * values this is plain linear interpolation when refine is off */
      double A = refine ? fa[k] : fp[k], B = refine ? fb[k] : fq[k];
      t = ta[k] + (tb[k] - ta[k]) * (A / (A - B));
      if (!(t >= ta[k] && t <= tb[k])) t = 0.5 * (ta[k] + tb[k]);
    }
    out[2 * k] = P[2 * k] + t * (Q[2 * k] - P[2 * k]);
    out[2 * k + 1] = P[2 * k + 1] + t * (Q[2 * k + 1] - P[2 * k + 1]);
  }
done:
  free(ta); free(side); free(act);
  return rc;
}

/* ---- marching squares ---- */


static double node_x(const gr_ms_grid *g, int I) {
  int i = I - 1;
  if (i < 0) i = 0;
  if (i > g->nx - 1) i = g->nx - 1;
  return i == g->nx - 1 ? g->x0 + (g->nx - 1) * g->hx : g->x0 + i * g->hx;
}
static double node_y(const gr_ms_grid *g, int J) {
  int j = J - 1;
  if (j < 0) j = 0;
  if (j > g->ny - 1) j = g->ny - 1;
  return g->y0 + j * g->hy;
}
/* Value at padded node (I, J): pad nodes are outside (+1). */
static double node_v(const gr_ms_grid *g, int I, int J) {
  if (I < 1 || J < 1 || I > g->nx || J > g->ny) return 1.0;
  return g->v[(I - 1) + (size_t)g->nx * (J - 1)];
}

/* Remove consecutive duplicates of the ring being built in `tmp` (xy, n
 * points) and append it to out if it keeps >= 3 points and nonzero area. */
int gr_ms_emit_ring(gr_rings *out, double *xy, size_t n) {
  size_t m = 0;
  for (size_t k = 0; k < n; k++) {
    if (m > 0 && xy[2 * k] == xy[2 * (m - 1)] && xy[2 * k + 1] == xy[2 * (m - 1) + 1]) continue;
    xy[2 * m] = xy[2 * k];
    xy[2 * m + 1] = xy[2 * k + 1];
    m++;
  }
  while (m > 1 && xy[0] == xy[2 * (m - 1)] && xy[1] == xy[2 * (m - 1) + 1]) m--;
  if (m < 3) return GR_OK;
  double a = 0;
  for (size_t k = 0, j = m - 1; k < m; j = k++)
    a += (xy[2 * j] - xy[0]) * (xy[2 * k + 1] - xy[1]) - (xy[2 * k] - xy[0]) * (xy[2 * j + 1] - xy[1]);
  if (a == 0) return GR_OK;
  return gr_rings_add(out, xy, m);
}

/* The scans below read the padded grid's inside flags (one byte a node,
 * in[I + NX J]) eight at a time: a word of nodes equal to the word of
 * their right neighbours and to that of their upper ones (and, for cells,
 * the upper ones' right neighbours) holds no crossing edge and no mixed
 * cell, and most of the grid, away from the boundary, is passed over so.
 * The flags are followed by a row of zeros (the pad row's upper
 * neighbours) and 8 more bytes for words read past the end; a word read
 * past a row's end compares pad nodes (0) with pad nodes. */

/* The crossing edges (sign change) of the padded grid, in the order of the
 * node (I, J) they start from (J, then I) and along x before along y: edge
 * id 2 (I + NX J) + dir, cross[id] its crossing's index (only crossing
 * edges' entries are set: only those are read). P (inside end) and Q
 * (outside end) 2 each, fp, fq their values: the bracket for roots_batch. */
typedef struct ms_cross {
  double *P, *Q, *fp, *fq;
  int *e; /* per crossing: padded I, J of its first node and dir (3 each) */
  size_t n, cap;
} ms_cross;

static int ms_add_cross(const gr_ms_grid *g, int I, int J, int dir, ms_cross *c) {
  int I1 = I + (dir == 0), J1 = J + (dir == 1);
  if (c->n + 1 > c->cap) {
    size_t a = c->cap, b = c->cap, d = c->cap, f = c->cap, h = c->cap;
    if (gr_grow(&c->P, &a, c->n + 1, 2 * sizeof(double)) || gr_grow(&c->Q, &b, c->n + 1, 2 * sizeof(double)) ||
        gr_grow(&c->fp, &d, c->n + 1, sizeof(double)) || gr_grow(&c->fq, &f, c->n + 1, sizeof(double)) ||
        gr_grow(&c->e, &h, c->n + 1, 3 * sizeof(int)))
      return GR_EMEM;
    c->cap = a;
  }
  double v0 = node_v(g, I, J), v1 = node_v(g, I1, J1);
  /* inside end first */
  int inI = v0 < 0 ? I : I1, inJ = v0 < 0 ? J : J1;
  int ouI = v0 < 0 ? I1 : I, ouJ = v0 < 0 ? J1 : J;
  size_t k = c->n++;
  c->e[3 * k] = I; c->e[3 * k + 1] = J; c->e[3 * k + 2] = dir;
  c->P[2 * k] = node_x(g, inI); c->P[2 * k + 1] = node_y(g, inJ);
  c->Q[2 * k] = node_x(g, ouI); c->Q[2 * k + 1] = node_y(g, ouJ);
  c->fp[k] = v0 < 0 ? v0 : v1;
  c->fq[k] = v0 < 0 ? v1 : v0;
  return GR_OK;
}

static int ms_crossings(const gr_ms_grid *g, const unsigned char *in, int *cross, ms_cross *c) {
  int NX = g->nx + 2, NY = g->ny + 2;
  /* room for a few rings across the window first (fewer reallocations) */
  size_t a = 0, b = 0, d = 0, f = 0, h = 0, guess = 4 * ((size_t)NX + NY);
  if (gr_grow(&c->P, &a, guess, 2 * sizeof(double)) || gr_grow(&c->Q, &b, guess, 2 * sizeof(double)) ||
      gr_grow(&c->fp, &d, guess, sizeof(double)) || gr_grow(&c->fq, &f, guess, sizeof(double)) ||
      gr_grow(&c->e, &h, guess, 3 * sizeof(int)))
    return GR_EMEM;
  c->cap = a;
  for (int J = 0; J < NY; J++) {
    const unsigned char *row = in + (size_t)NX * J, *up = row + NX;
    for (int I = 0; I < NX; I++) {
      if (I + 8 <= NX && !((gr_ms_word(row + I) ^ gr_ms_word(row + I + 1)) | (gr_ms_word(row + I) ^ gr_ms_word(up + I)))) {
        I += 7;
        continue;
      }
      for (int dir = 0; dir < 2; dir++) {
        if (dir ? J + 1 >= NY || row[I] == up[I] : I + 1 >= NX || row[I] == row[I + 1]) continue;
        if (ms_add_cross(g, I, J, dir, c)) return GR_EMEM;
        cross[2 * ((size_t)I + (size_t)NX * J) + dir] = (int)(c->n - 1);
      }
    }
  }
  return GR_OK;
}

/* The mixed cells (corners of both signs), in the order of (J, I): cell
 * (I, J) and its corners' flags m (bit k: corner k inside, counter-clockwise
 * from (I, J)); the saddles among them (m 5 or 10) with their centres, to be
 * decided by fn there. */
typedef struct ms_cells {
  int *ij;
  unsigned char *m;
  size_t n, cap;
  double *cx, *cy;
  size_t ns, caps;
} ms_cells;

static int ms_mixed_cells(const gr_ms_grid *g, const unsigned char *in, size_t ncr, ms_cells *c) {
  int NX = g->nx + 2, NY = g->ny + 2;
  /* room for all: a mixed cell has two crossing edges or four, each edge
   * in two cells at most, so there are at most ncr mixed cells and ncr / 2
   * saddles */
  size_t a = 0, b = 0, d = 0, f = 0;
  if (gr_grow(&c->ij, &a, ncr, 2 * sizeof *c->ij) || gr_grow(&c->m, &b, ncr, 1) ||
      gr_grow(&c->cx, &d, ncr / 2 + 1, sizeof *c->cx) || gr_grow(&c->cy, &f, ncr / 2 + 1, sizeof *c->cy))
    return GR_EMEM;
  c->cap = a < b ? a : b;
  c->caps = d < f ? d : f;
  for (int J = 0; J + 1 < NY; J++) {
    const unsigned char *row = in + (size_t)NX * J, *up = row + NX;
    for (int I = 0; I + 1 < NX; I++) {
      if (I + 9 <= NX) {
        uint64_t w = gr_ms_word(row + I);
        if (!((w ^ gr_ms_word(row + I + 1)) | (w ^ gr_ms_word(up + I)) | (w ^ gr_ms_word(up + I + 1)))) {
          I += 7;
          continue;
        }
      }
      int m = row[I] | row[I + 1] << 1 | up[I + 1] << 2 | up[I] << 3;
      if (m == 0 || m == 15) continue;
      if (c->n + 1 > c->cap) {
        size_t ca = c->cap, cb = c->cap;
        if (gr_grow(&c->ij, &ca, c->n + 1, 2 * sizeof *c->ij) || gr_grow(&c->m, &cb, c->n + 1, 1)) return GR_EMEM;
        c->cap = ca;
      }
      c->ij[2 * c->n] = I;
      c->ij[2 * c->n + 1] = J;
      c->m[c->n++] = (unsigned char)m;
      if (m != 5 && m != 10) continue;
      if (c->ns + 1 > c->caps) {
        size_t ca = c->caps, cb = c->caps;
        if (gr_grow(&c->cx, &ca, c->ns + 1, sizeof *c->cx) || gr_grow(&c->cy, &cb, c->ns + 1, sizeof *c->cy)) return GR_EMEM;
        c->caps = ca;
      }
      c->cx[c->ns] = 0.5 * (node_x(g, I) + node_x(g, I + 1));
      c->cy[c->ns++] = 0.5 * (node_y(g, J) + node_y(g, J + 1));
    }
  }
  return GR_OK;
}

/* For a cell of corner flags m (bit k: corner k inside, corners and edges
 * counted counter-clockwise from the bottom: edge k joins corners k and
 * k + 1) and a crossing X at edge k (in->out), the edge y of the out->in
 * crossing joined to it: the next one counter-clockwise when the centre is
 * inside, else the previous one (-1: no X at k). MS_LINK[centre_in][m][k]. */
static const signed char MS_LINK[2][16][4] = {
    {{-1, -1, -1, -1}, {3, -1, -1, -1}, {-1, 0, -1, -1}, {-1, 3, -1, -1}, {-1, -1, 1, -1}, {3, -1, 1, -1},
     {-1, -1, 0, -1}, {-1, -1, 3, -1}, {-1, -1, -1, 2}, {2, -1, -1, -1}, {-1, 0, -1, 2}, {-1, 2, -1, -1},
     {-1, -1, -1, 1}, {1, -1, -1, -1}, {-1, -1, -1, 0}, {-1, -1, -1, -1}},
    {{-1, -1, -1, -1}, {3, -1, -1, -1}, {-1, 0, -1, -1}, {-1, 3, -1, -1}, {-1, -1, 1, -1}, {1, -1, 3, -1},
     {-1, -1, 0, -1}, {-1, -1, 3, -1}, {-1, -1, -1, 2}, {2, -1, -1, -1}, {-1, 2, -1, 0}, {-1, 2, -1, -1},
     {-1, -1, -1, 1}, {1, -1, -1, -1}, {-1, -1, -1, 0}, {-1, -1, -1, -1}}};

/* Contour {fn < 0} from the sampled grid: crossings on grid edges refined on
 * fn, saddles decided by fn at the cell centre, segments oriented with the
 * inside on the left and chained by edge id into closed rings (appended to
 * out, not nested). */
/* A crossing from the nodes along its grid line (g->exact > 0): on the
 * edge from node a (unpadded (i, j)) to its neighbour along dir (0: x,
 * 1: y), the root t (0..1 from a) of the cubic through nodes a-1 .. a+2.
 * Its error is f4 / 24 (t+1) t (t-1) (t-2) h^4 (f4: the fourth derivative
 * along the line), at most 0.5625 / 24 of h^4 f4, which the fourth
 * differences of the six nodes a-2 .. a+3 estimate (the larger of the
 * two); taken as a root error over the cubic's slope, CUBIC_SAFETY to
 * spare. 1 when that is within tol (mm); 0 when not, when a node is not
 * fn's exact value (|v| >= g->exact: a bound) or the line has fewer than
 * three nodes on either side. A kink between the nodes (the medial
 * surface, a voxel face's clamp) or a node whose value came from another
 * patch of H shows in the differences, and the crossing is refined on fn. */
#define CUBIC_SAFETY 4.0
static int cubic_crossing(const gr_ms_grid *g, int i, int j, int dir, double tol, double *t) {
  int n = dir ? g->ny : g->nx, a = dir ? j : i;
  if (a < 2 || a + 3 >= n || i < 0 || j < 0 || i >= g->nx || j >= g->ny) return 0;
  size_t step = dir ? (size_t)g->nx : 1;
  const double *v = g->v + (size_t)i + (size_t)g->nx * j - 2 * step;
  double f[6];
  for (int m = 0; m < 6; m++)
    if (!(fabs(f[m] = v[m * step]) < g->exact)) return 0;
  if (f[2] == 0 || f[3] == 0 || (f[2] < 0) == (f[3] < 0)) return 0;
  double d4a = f[4] - 4 * f[3] + 6 * f[2] - 4 * f[1] + f[0], d4b = f[5] - 4 * f[4] + 6 * f[3] - 4 * f[2] + f[1];
  double h = dir ? g->hy : g->hx, d4 = gr_hi(fabs(d4a), fabs(d4b)) * CUBIC_SAFETY * (0.5625 / 24) * h;
  /* the estimate with twice the chord's slope first: most rejections
   * without the solve */
  if (!(d4 < 2 * tol * fabs(f[3] - f[2]))) return 0;
  /* Newton's form on the nodes -1, 0, 1, 2:
   * p(x) = f1 + (x + 1) (d1 + x (d2 / 2 + (x - 1) d3 / 6)) */
  double d1 = f[2] - f[1], d2 = f[3] - 2 * f[2] + f[1], d3 = f[4] - 3 * f[3] + 3 * f[2] - f[1];
  double lo = 0, hi = 1, x = f[2] / (f[2] - f[3]), dp = d1;
  for (int it = 0; it < 60; it++) { /* Newton kept in the bracket */
    double pv = f[1] + (x + 1) * (d1 + x * (d2 / 2 + (x - 1) * d3 / 6));
    if (pv == 0) break;
    dp = d1 + d2 / 2 * (2 * x + 1) + d3 / 6 * (3 * x * x - 1);
    if ((pv < 0) == (f[2] < 0)) lo = x; else hi = x;
    double xn = x - pv / dp;
    if (!(xn >= lo && xn <= hi)) xn = 0.5 * (lo + hi);
    double dx = fabs(xn - x);
    x = xn;
    if (dx < 1e-4) break; /* quadratic: what is left is of order dx^2, below 1e-8 (0.25 pm at h = 25 um) */
  }
  dp = d1 + d2 / 2 * (2 * x + 1) + d3 / 6 * (3 * x * x - 1);
  if (!(d4 < tol * fabs(dp)) || !(x >= 0 && x <= 1)) return 0;
  *t = x;
  return 1;
}

/* The crossings' points pt (2 each): from the nodes' cubic where
 * cubic_crossing takes them, the others refined on fn (roots_batch). */
static int refine_crossings(const gr_ms_grid *g, gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, int refine,
                            double tol, const ms_cross *cr, double *pt, gr_err *e) {
  size_t n = cr->n;
  if (!(g->exact > 0) || !refine)
    return roots_batch(fn, gfn, ud, n, cr->P, cr->Q, cr->fp, cr->fq, refine, tol, pt, e);
  double *w = malloc(8 * n * sizeof *w);
  size_t *id = malloc(n * sizeof *id), m = 0;
  if (!w || !id) {
    free(w);
    free(id);
    return gr_fail(e, GR_EMEM, "out of memory refining %zu crossings", n);
  }
  double *P = w, *Q = w + 2 * n, *fp = w + 4 * n, *fq = w + 5 * n, *out = w + 6 * n;
  for (size_t k = 0; k < n; k++) {
    const int *c = cr->e + 3 * k;
    double t;
    if (cubic_crossing(g, c[0] - 1, c[1] - 1, c[2], tol, &t)) {
      /* from the line's first node to the next (padded indices) */
      double ax = node_x(g, c[0]), ay = node_y(g, c[1]);
      double bx = node_x(g, c[0] + (c[2] == 0)), by = node_y(g, c[1] + (c[2] == 1));
      pt[2 * k] = ax + t * (bx - ax);
      pt[2 * k + 1] = ay + t * (by - ay);
      continue;
    }
    memcpy(P + 2 * m, cr->P + 2 * k, 2 * sizeof *P);
    memcpy(Q + 2 * m, cr->Q + 2 * k, 2 * sizeof *Q);
    fp[m] = cr->fp[k];
    fq[m] = cr->fq[k];
    id[m++] = k;
  }
  int rc = roots_batch(fn, gfn, ud, m, P, Q, fp, fq, refine, tol, out, e);
  for (size_t r = 0; r < m && !rc; r++) memcpy(pt + 2 * id[r], out + 2 * r, 2 * sizeof *pt);
  free(w);
  free(id);
  return rc;
}

int gr_ms_contour(const gr_ms_grid *g, gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, int refine,
                      double tol, gr_rings *out, gr_err *e) {
  int NX = g->nx + 2, NY = g->ny + 2;
  size_t nn = (size_t)NX * NY;
  int rc = GR_OK;
  int *cross = malloc(2 * nn * sizeof *cross);
  unsigned char *in = calloc(nn + (size_t)NX + 8, 1); /* padded node (I, J) inside: in[I + NX J] */
  ms_cross cr = {0};
  ms_cells cl = {0};
  double *pt = NULL, *cv = NULL, *ring = NULL;
  int *next = NULL;
  if (!cross || !in) {
    free(cross);
    free(in);
    return gr_fail(e, GR_EMEM, "out of memory: marching squares on %dx%d nodes", g->nx, g->ny);
  }
  for (int j = 0; j < g->ny; j++) {
    unsigned char *row = in + (size_t)NX * (j + 1) + 1;
    const double *v = g->v + (size_t)g->nx * j;
    for (int i = 0; i < g->nx; i++) row[i] = v[i] < 0;
  }
  /* 1. crossing edges, refined */
  if (ms_crossings(g, in, cross, &cr)) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", cr.n); goto done; }
  size_t ncr = cr.n;
  if (ncr == 0) goto done;
  pt = malloc(2 * ncr * sizeof *pt);
  next = malloc(ncr * sizeof *next);
  if (!pt || !next) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", ncr); goto done; }
  rc = refine_crossings(g, fn, gfn, ud, refine, tol, &cr, pt, e);
  if (rc) goto done;
  /* 2. mixed cells; saddles: centre value on the true function */
  if (ms_mixed_cells(g, in, ncr, &cl)) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu saddles", cl.ns); goto done; }
  if (cl.ns) {
    if (!(cv = malloc(cl.ns * sizeof *cv))) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu saddles", cl.ns); goto done; }
    rc = gr_ms_eval(fn, ud, cl.ns, cl.cx, cl.cy, cv, e);
    if (rc) goto done;
  }
  /* 3. segments: walk the cell boundary CCW (edges e0 bottom, e1 right,
   * e2 top, e3 left); an in->out crossing X is joined to the out->in
   * crossing Y that follows it (centre inside) or precedes it (outside). */
  for (size_t k = 0; k < ncr; k++) next[k] = -1;
  for (size_t c = 0, s = 0; c < cl.n; c++) {
    size_t I = (size_t)cl.ij[2 * c], J = (size_t)cl.ij[2 * c + 1];
    int m = cl.m[c], centre_in = 0;
    if (m == 5 || m == 10) centre_in = cv[s++] < 0;
    size_t ids[4] = {2 * (I + NX * J), 2 * (I + 1 + NX * J) + 1, 2 * (I + NX * (J + 1)), 2 * (I + NX * J) + 1};
    for (int k = 0; k < 4; k++) {
      int y = MS_LINK[centre_in][m][k];
      if (y >= 0) next[cross[ids[k]]] = cross[ids[y]];
    }
  }
  /* 4. chain */
  ring = malloc(2 * (ncr + 1) * sizeof *ring);
  if (!ring) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", ncr); goto done; }
  for (size_t k = 0; k < ncr; k++) {
    if (next[k] < 0) continue;
    size_t n = 0;
    int c = (int)k;
    while (c >= 0 && next[c] >= 0) {
      ring[2 * n] = pt[2 * c];
      ring[2 * n + 1] = pt[2 * c + 1];
      n++;
      int nc = next[c];
      next[c] = -1;
      c = nc;
    }
    rc = gr_ms_emit_ring(out, ring, n);
    if (rc) { rc = gr_fail(e, GR_EMEM, "out of memory storing rings"); goto done; }
  }
done:
  free(cross); free(in); free(cr.P); free(cr.Q); free(cr.fp); free(cr.fq); free(cr.e); free(pt); free(next);
  free(cl.ij); free(cl.m); free(cl.cx); free(cl.cy); free(cv); free(ring);
  return rc;
}

/* Chords by Newton along the normal from the midpoint (value and gradient):
 * one evaluation settles chords whose zero set is well inside chord_tol; the
 * others converge in one or two more, and a converged root more than
 * chord_tol from the midpoint becomes an insertion (ins[seg] = 1 + index into
 * ipt). Chords Newton cannot settle (flat gradient, a step leaving the
 * bracket) stay in the candidate arrays (compacted, *m updated) for
 * bracketing. */
static int chord_newton(gr_slice_grad_fn gfn, void *ud, double tol, double chord_tol,
                        double *ax, double *ay, double *bx, double *by, size_t *seg, size_t *m,
                        const unsigned char *must, int *ins, double *ipt, size_t *nins, gr_err *e) {
  size_t n = *m;
  double *mx = malloc((9 * n + 1) * sizeof *mx); /* mx, my, t, qx, qy, f, gx, gy, hl */
  size_t *act = malloc(n * sizeof *act + 1);
  unsigned char *left = calloc(n + 1, 1); /* 1: bracket it */
  int rc = GR_OK;
  if (!mx || !act || !left) {
    rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
    goto done;
  }
  double *my = mx + n, *t = my + n, *qx = t + n, *qy = qx + n, *f = qy + n, *gx = f + n, *gy = gx + n, *hl = gy + n;
  memset(t, 0, n * sizeof *t);
  size_t na = n;
  for (size_t k = 0; k < n; k++) {
    mx[k] = 0.5 * (ax[k] + bx[k]);
    my[k] = 0.5 * (ay[k] + by[k]);
    hl[k] = gr_len2d(bx[k] - mx[k], by[k] - my[k]); /* half the bracket */
    act[k] = k;
  }
  for (int it = 0; it < 6 && na > 0; it++) {
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double h = hl[k];
      qx[i] = mx[k] + t[k] * (bx[k] - mx[k]) / h;
      qy[i] = my[k] + t[k] * (by[k] - my[k]) / h;
    }
    for (size_t s = 0; s < na && !rc; s += MS_CHUNK) {
      size_t c = na - s < MS_CHUNK ? na - s : MS_CHUNK;
      rc = gfn(ud, c, qx + s, qy + s, f + s, gx + s, gy + s, e);
    }
    if (rc) goto done;
    size_t keep = 0;
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double h = hl[k];
      double dn = (gx[i] * (bx[k] - mx[k]) + gy[i] * (by[k] - my[k])) / h;
      double step = dn > 0.5 ? -f[i] / dn : NAN;
      if (!isfinite(step) || fabs(t[k] + step) > h) { left[k] = 1; continue; }
      t[k] += step;
      int split = must && must[seg[k]];
      if (!split && it == 0 && fabs(t[k]) < 0.9 * chord_tol) continue; /* the chord is fine */
      if (fabs(step) < tol) {                                           /* converged */
        if (split || fabs(t[k]) > chord_tol) {
          ipt[2 * *nins] = mx[k] + t[k] * (bx[k] - mx[k]) / h;
          ipt[2 * *nins + 1] = my[k] + t[k] * (by[k] - my[k]) / h;
          ins[seg[k]] = (int)++*nins;
        }
        continue;
      }
      act[keep++] = k;
    }
    na = keep;
  }
  for (size_t i = 0; i < na; i++) left[act[i]] = 1; /* not converged */
  size_t q = 0;
  for (size_t k = 0; k < n; k++) {
    if (!left[k]) continue;
    ax[q] = ax[k]; ay[q] = ay[k]; bx[q] = bx[k]; by[q] = by[k]; seg[q] = seg[k];
    q++;
  }
  *m = q;
done:
  free(mx); free(act); free(left);
  return rc;
}

/* a segment along the window border is exact */
static int on_border(const gr_ms_win *w, const double *a, const double *b) {
  if (!w->on) return 0;
  for (int c = 0; c < 2; c++)
    if ((a[c] == w->lo[c] && b[c] == w->lo[c]) || (a[c] == w->hi[c] && b[c] == w->hi[c])) return 1;
  return 0;
}

void gr_ms_chord_corner(const double *p0, const double *a, const double *b, const double *p1, double c[2]) {
  double ux = a[0] - p0[0], uy = a[1] - p0[1], vx = p1[0] - b[0], vy = p1[1] - b[1];
  double den = ux * vy - uy * vx, lu = gr_len2d(ux, uy), lv = gr_len2d(vx, vy);
  double t = (b[0] - a[0]) * vy - (b[1] - a[1]) * vx;
  if (!(fabs(den) > 1e-6 * lu * lv)) { c[0] = c[1] = NAN; return; }
  t /= den;
  c[0] = a[0] + t * ux;
  c[1] = a[1] + t * uy;
}

/* The corner of the chord from point g (global index) of ring i. */
static void chord_corner_of(const gr_rings *r, size_t i, size_t g, double c[2]) {
  size_t len = gr_ring_len(r, i), k = g - r->start[i];
  const double *p = gr_ring_xy(r, i);
  gr_ms_chord_corner(p + 2 * gr_ring_prev(k, len), p + 2 * k, p + 2 * gr_ring_next(k, len), p + 2 * gr_ring_at(k, 2, len), c);
}

/* Chords whose bracket (+-half the chord along the normal) has one sign at
 * both ends cut across a corner sharper than a right angle (the curve runs
 * farther than half the chord from the midpoint: thick graded sheets' pores
 * have such corners and tapering tips, narrower than a grid cell) or have
 * no curve near them. If the midpoint has the other sign, it takes the
 * place of the end on that side; else the end on the wrong side is moved
 * out along the normal, to 2 and 4 times as far, until the signs differ.
 * A tip that leans away from the normal is then looked for towards the
 * corner where the lines of the two neighbouring chords meet
 * (chord_corner_of the chord whose first point is seg, rof its ring; none
 * where they are near parallel or it is farther than reach): a point 1.5
 * or 3 times as far as that corner from the midpoint, bracketed against
 * the midpoint where their signs differ. viac[i] = 1 where a bracket came
 * from the midpoint or the corner (its root is checked by corner_ok).
 * fa, fb updated. */
#define CHORD_REACH 2
static int chord_extend(gr_slice_fn fn, void *ud, size_t m, double *ax, double *ay, double *bx, double *by,
                        double *fa, double *fb, const gr_rings *r, const size_t *rof, const size_t *seg,
                        double reach, unsigned char *viac, gr_err *e) {
  double *px = malloc(4 * m * sizeof *px + 1), *pf = malloc(2 * m * sizeof *pf + 1), *py = px + m;
  double *mx = py + m, *my = mx + m, *mf = pf + m;
  size_t *id = malloc(m * sizeof *id + 1);
  int rc = px && pf && id ? GR_OK : gr_fail(e, GR_EMEM, "out of memory refining chords");
  /* first the midpoint: where it has the other sign (the chord crosses a
   * sliver twice), the boundary lies between it and the end on the chord's
   * own side (a when both are inside, b when both are outside) */
  size_t n0 = 0;
  for (size_t i = 0; i < m && !rc; i++) {
    if ((fa[i] < 0) == (fb[i] >= 0)) continue;
    px[n0] = 0.5 * (ax[i] + bx[i]);
    py[n0] = 0.5 * (ay[i] + by[i]);
    id[n0++] = i;
  }
  if (!rc && n0) rc = gr_ms_eval(fn, ud, n0, px, py, pf, e);
  for (size_t q = 0; q < n0 && !rc; q++) {
    size_t i = id[q];
    if ((pf[q] < 0) == (fa[i] < 0)) continue;
    viac[i] = 1;
    if (fa[i] < 0) { bx[i] = px[q]; by[i] = py[q]; fb[i] = pf[q]; }
    else { ax[i] = px[q]; ay[i] = py[q]; fa[i] = pf[q]; }
  }
  for (int round = 1; round <= CHORD_REACH + 2 && !rc; round++) {
    int corner = round > CHORD_REACH;
    double k = corner ? 1.5 * (round - CHORD_REACH) : (double)(1 << round); /* the moved end's distance */
    size_t n = 0;
    for (size_t i = 0; i < m; i++) {
      int in_a = fa[i] < 0, out_b = fb[i] >= 0;
      if (in_a == out_b) continue; /* bracketed, or reversed (skipped) */
      double cx = 0.5 * (ax[i] + bx[i]), cy = 0.5 * (ay[i] + by[i]);
      double ux = 0.5 * (bx[i] - ax[i]), uy = 0.5 * (by[i] - ay[i]);
      double sgn = in_a ? 1 : -1; /* both inside: move b out; both outside: move a in */
      if (corner) {
        double c[2];
        chord_corner_of(r, rof[seg[i]], seg[i], c);
        double vx = c[0] - cx, vy = c[1] - cy;
        if (!(vx * vx + vy * vy < reach * reach)) continue; /* none, or too far */
        sgn = 1;
        ux = vx;
        uy = vy;
      }
      px[n] = cx + sgn * k * ux;
      py[n] = cy + sgn * k * uy;
      mx[n] = cx;
      my[n] = cy;
      id[n++] = i;
    }
    if (n == 0) continue;
    if ((rc = gr_ms_eval(fn, ud, n, px, py, pf, e))) break;
    if (corner && (rc = gr_ms_eval(fn, ud, n, mx, my, mf, e))) break;
    for (size_t q = 0; q < n; q++) {
      size_t i = id[q];
      if (corner) {
        if ((pf[q] < 0) == (mf[q] < 0)) continue;
        int pin = pf[q] < 0;
        viac[i] = 1;
        ax[i] = pin ? px[q] : mx[q]; ay[i] = pin ? py[q] : my[q]; fa[i] = pin ? pf[q] : mf[q];
        bx[i] = pin ? mx[q] : px[q]; by[i] = pin ? my[q] : py[q]; fb[i] = pin ? mf[q] : pf[q];
      } else if (fa[i] < 0) {
        if (pf[q] >= 0) { bx[i] = px[q]; by[i] = py[q]; fb[i] = pf[q]; }
      } else if (pf[q] < 0) {
        ax[i] = px[q]; ay[i] = py[q]; fa[i] = pf[q];
      }
    }
  }
  free(px);
  free(pf);
  free(id);
  return rc;
}

int gr_ms_seg_cross(const double *a, const double *b, const double *c, const double *d) {
  double d1 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  double d2 = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0]);
  double d3 = (d[0] - c[0]) * (a[1] - c[1]) - (d[1] - c[1]) * (a[0] - c[0]);
  double d4 = (d[0] - c[0]) * (b[1] - c[1]) - (d[1] - c[1]) * (b[0] - c[0]);
  return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}

/* May the root R found towards a corner be put between the chord's ends
 * (point k of ring i and the next)? Not on top of either end, and the two
 * new chords must not cross the ring's nearby chords (a root on another
 * branch of the curve, past a crease, would fold the ring). */
#define CORNER_NEAR 6
static int corner_ok(const gr_rings *r, size_t i, size_t k, const double *R, double chord_tol) {
  size_t len = gr_ring_len(r, i);
  const double *p = gr_ring_xy(r, i), *A = p + 2 * k, *B = p + 2 * gr_ring_next(k, len);
  if (gr_len2d(R[0] - A[0], R[1] - A[1]) <= chord_tol || gr_len2d(R[0] - B[0], R[1] - B[1]) <= chord_tol) return 0;
  long span = (long)len / 2 < CORNER_NEAR ? (long)len / 2 : CORNER_NEAR;
  for (long j = -span; j <= span; j++) {
    if (j == 0) continue;
    size_t a = (k + (size_t)(j + (long)len)) % len, b = (a + 1) % len;
    if (gr_ms_seg_cross(A, R, p + 2 * a, p + 2 * b) || gr_ms_seg_cross(R, B, p + 2 * a, p + 2 * b)) return 0;
  }
  return 1;
}

/* Whether the sagitta of chord a-b on the circle through p, a and b is at
 * most s > 0 (yes when they are collinear; no when two points coincide).
 * The sagitta of a chord of length L on a circle of radius R,
 * R - sqrt(R^2 - L^2 / 4), is at most s exactly when
 * R >= K = (L^2 / 4 + s^2) / (2 s) (K >= L / 2: the chord fits); with the
 * circumradius R = |u| |v| L / (2 |u x v|) (u, v: from p to a and b) that
 * is |u|^2 |v|^2 L^2 >= 4 (u x v)^2 K^2, without a root or a division by
 * the points. */
static int circle_within(const double *p, const double *a, const double *b, double s) {
  double ux = a[0] - p[0], uy = a[1] - p[1], vx = b[0] - p[0], vy = b[1] - p[1];
  double wx = b[0] - a[0], wy = b[1] - a[1], L2 = wx * wx + wy * wy;
  double den2 = (ux * ux + uy * uy) * (vx * vx + vy * vy) * L2, cr = ux * vy - uy * vx;
  if (!(den2 > 0)) return 0;
  if (cr == 0) return 1; /* collinear: no sagitta */
  double K = (0.25 * L2 + s * s) / (2 * s);
  return den2 >= 4 * cr * cr * K * K;
}

/* Whether the chord from point k of ring i lies within chord_tol / 2 of a
 * smooth curve by its neighbours: the circles through its ends and the
 * point before, and through its ends and the point after, both put it
 * there (a smooth curve's curvature changes little over four points a grid
 * cell apart). Not where a neighbouring segment runs along the window border
 * (its far end is no point of the curve) or the ring is too short. */
static int chord_fine_by_circles(const gr_rings *r, size_t i, size_t k, double chord_tol, const gr_ms_win *w) {
  size_t len = gr_ring_len(r, i);
  if (len < 4) return 0;
  const double *P = gr_ring_xy(r, i);
  const double *p = P + 2 * gr_ring_prev(k, len), *a = P + 2 * k;
  size_t kn = gr_ring_next(k, len);
  const double *b = P + 2 * kn, *c = P + 2 * gr_ring_next(kn, len);
  if (on_border(w, p, a) || on_border(w, b, c)) return 0;
  return circle_within(p, a, b, 0.5 * chord_tol) && circle_within(a, b, c, 0.5 * chord_tol);
}

/* Chord accuracy passes: for each ring segment not yet checked (*okp[i] = 0
 * for the chord from point i), find the zero of fn on the normal line
 * through the chord midpoint (bracket +-half the chord); where it lies more
 * than chord_tol from the midpoint, or the chord is marked in must (NULL:
 * none; the first pass only), insert it. Repeats until no insertion (at
 * most 12 passes). Rings in `r` and *okp are rewritten. */
static int chord_passes(gr_rings *r, unsigned char **okp, const unsigned char *must, gr_slice_fn fn,
                        gr_slice_grad_fn gfn, void *ud, double tol, double chord_tol, const gr_ms_win *w, gr_err *e) {
  int rc = GR_OK;
  gr_rings *nr = gr_rings_new();
  unsigned char *ok = *okp;
  if (!nr) return gr_fail(e, GR_EMEM, "out of memory refining chords");
  for (int pass = 0; pass < 12; pass++) {
    size_t n = r->npts;
    /* per candidate chord: bracket ends a, b (+-half the chord along the
     * outward normal through the midpoint) and its first point's index */
    /* the pass's arrays carved from three blocks (ins and viac zeroed) */
    double *blk = malloc((6 * n + 6 * 2 * n + 1) * sizeof *blk);
    size_t *zs = malloc((2 * n + 1) * sizeof *zs);
    int *ins = calloc(n + 1, sizeof *ins);
    unsigned char *viac = calloc(n + 1, 1); /* bracketed towards a corner */
    unsigned char *ok2 = NULL;
    size_t nins = 0;
    if (!blk || !zs || !ins || !viac) {
      rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
      goto pass_done;
    }
    double *ax = blk, *ay = ax + n, *bx = ay + n, *by = bx + n, *fa = by + n, *fb = fa + n;
    double *A = fb + n, *B = A + 2 * n, *root = B + 2 * n, *ipt = root + 2 * n;
    double *cm = ipt + 2 * n; /* chord midpoints, by first point */
    double *cn = cm + 2 * n;  /* chord normals */
    size_t *seg = zs, *rof = zs + n; /* rof: ring of each point */
    size_t m = 0;
    for (size_t i = 0; i < r->nrings; i++) {
      size_t len = gr_ring_len(r, i), st = r->start[i];
      const double *p = gr_ring_xy(r, i);
      for (size_t k = 0; k < len; k++) rof[st + k] = i;
      for (size_t k = 0; k < len; k++) {
        if (ok[st + k]) continue;
        const double *a = p + 2 * k, *b = p + 2 * gr_ring_next(k, len);
        if (on_border(w, a, b)) continue;
        double dx = b[0] - a[0], dy = b[1] - a[1], L = gr_len2d(dx, dy);
        if (L <= 2 * chord_tol) continue;
        /* a smooth stretch whose neighbours show the chord well within the
         * tolerance: not checked on the field (about half the chords of a
         * graded sheet's section; corners marked `must` always are) */
        if (w->smooth && !(pass == 0 && must && must[st + k]) && chord_fine_by_circles(r, i, k, chord_tol, w) &&
            w->smooth(ud, a, b)) {
          ok[st + k] = 1;
          continue;
        }
        double mx = 0.5 * (a[0] + b[0]), my = 0.5 * (a[1] + b[1]);
        double nx = dy / L, ny = -dx / L, h = 0.5 * L; /* right normal: outside */
        ax[m] = mx - h * nx; ay[m] = my - h * ny;
        bx[m] = mx + h * nx; by[m] = my + h * ny;
        cm[2 * (st + k)] = mx; cm[2 * (st + k) + 1] = my;
        cn[2 * (st + k)] = nx; cn[2 * (st + k) + 1] = ny;
        seg[m] = st + k;
        m++;
      }
    }
    if (m == 0) goto pass_done;
    if (pass > 0) must = NULL; /* its indices are those of the rings given */
    if (gfn && (rc = chord_newton(gfn, ud, tol, chord_tol, ax, ay, bx, by, seg, &m, must, ins, ipt, &nins, e)))
      goto pass_done;
    if ((rc = gr_ms_eval(fn, ud, m, ax, ay, fa, e)) || (rc = gr_ms_eval(fn, ud, m, bx, by, fb, e))) goto pass_done;
    if ((rc = chord_extend(fn, ud, m, ax, ay, bx, by, fa, fb, r, rof, seg, w->reach, viac, e))) goto pass_done;
    size_t q = 0;
    for (size_t k = 0; k < m; k++) {
      if (!(fa[k] < 0 && fb[k] >= 0)) continue;
      A[2 * q] = ax[k]; A[2 * q + 1] = ay[k];
      B[2 * q] = bx[k]; B[2 * q + 1] = by[k];
      fa[q] = fa[k]; fb[q] = fb[k]; seg[q] = seg[k]; viac[q] = viac[k];
      q++;
    }
    rc = roots_batch(fn, gfn, ud, q, A, B, fa, fb, 1, tol, root, e);
    if (rc) goto pass_done;
    /* mark insertions: ins[global point index] = 1 + index into ipt */
    for (size_t k = 0; k < q; k++) {
      /* off the chord's line by more than chord_tol (a root found towards a
       * corner that lies on the line itself is no missing curve) */
      const double *c = cm + 2 * seg[k], *nn = cn + 2 * seg[k];
      size_t ri = rof[seg[k]];
      if (viac[k] && !corner_ok(r, ri, seg[k] - r->start[ri], root + 2 * k, chord_tol)) continue;
      if ((must && must[seg[k]]) || fabs((root[2 * k] - c[0]) * nn[0] + (root[2 * k + 1] - c[1]) * nn[1]) > chord_tol) {
        ipt[2 * nins] = root[2 * k];
        ipt[2 * nins + 1] = root[2 * k + 1];
        ins[seg[k]] = (int)++nins;
      }
    }
    /* the section is known inside the window only: a root found beyond it
     * (a curve bulging out between two border nodes) goes onto the border,
     * so that no ring leaves the window and nesting (by boxes) holds */
    for (size_t c = 0; c < nins && w->on; c++)
      for (int a = 0; a < 2; a++) ipt[2 * c + a] = fmin(fmax(ipt[2 * c + a], w->lo[a]), w->hi[a]);
    if (nins) {
      ok2 = calloc(n + nins + 1, 1);
      if (!ok2) { rc = gr_fail(e, GR_EMEM, "out of memory refining chords"); goto pass_done; }
      gr_rings_clear(nr);
      size_t np = 0;
      for (size_t i = 0; i < r->nrings && !rc; i++) {
        size_t len = gr_ring_len(r, i), st = r->start[i];
        const double *p = gr_ring_xy(r, i);
        for (size_t k = 0; k < len && !rc; k++) {
          rc = gr_rings_point(nr, p[2 * k], p[2 * k + 1]);
          ok2[np++] = !ins[st + k];
          if (!rc && ins[st + k]) {
            size_t c = (size_t)ins[st + k] - 1;
            rc = gr_rings_point(nr, ipt[2 * c], ipt[2 * c + 1]);
            ok2[np++] = 0;
          }
        }
        if (!rc) rc = gr_rings_close(nr);
      }
      if (rc) rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
      if (!rc) { /* the new rings become r's; r's arrays are the next pass's to fill */
        gr_rings t = *r;
        *r = *nr;
        *nr = t;
        free(ok);
        ok = ok2;
        ok2 = NULL;
      }
    }
  pass_done:
    free(blk); free(zs); free(ins); free(viac); free(ok2);
    if (rc || nins == 0) {
      /* the last pass checked every chord still unchecked and inserted
       * nothing: all are checked now (a later call checks only new ones) */
      if (!rc) memset(ok, 1, r->npts);
      break;
    }
  }
  gr_rings_free(nr);
  *okp = ok;
  return rc;
}

/* Where the boundary runs along a jump of the field (a graded sheet's
 * closest point changing sides of the medial surface), it turns sharply
 * where the jump meets the zero set of either side; a long chord can cut
 * such a corner with its midpoint on the curve, and the midpoint check
 * passes (on the lidinoid graded 0.06 + 0.03 w a chord of 26 um cut a
 * corner by 1.9 um). Such a chord shows itself at its end: the vertex turns
 * (by more than 15 degrees), and the chord leaves the curve there:
 * fn a little way along it (CORNER_PROBE, at most an eighth of the chord)
 * is off zero by more than CORNER_OFF, where a chord within the tolerance
 * s of a smooth curve, or one from a true corner of the section at the
 * vertex (the sheet's offsets meeting on a mirror plane), stays within
 * 4 s / 8 of it. Those chords, longer than CORNER_LEN and not on the
 * window's border, are marked in must (sized r->npts) and unchecked in ok,
 * to be split at their midpoint's root, round after round until shorter.
 * *nm: how many were marked. */
#define CORNER_LEN 2e-3
#define CORNER_TURN 0.9659 /* cos 15 degrees */
#define CORNER_PROBE 1e-3
#define CORNER_OFF 1.5e-4
#define CORNER_ROUNDS 6
static int corner_marks(const gr_rings *r, unsigned char *ok, unsigned char *must, const gr_ms_win *w,
                        gr_slice_fn fn, void *ud, size_t *nm, gr_err *e) {
  size_t nc = 0, cap = 0, *cg = NULL;
  double *px = NULL, *py = NULL, *pv = NULL;
  int rc = GR_OK;
  *nm = 0;
  for (size_t i = 0; i < r->nrings && !rc; i++) {
    size_t len = gr_ring_len(r, i), st = r->start[i];
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < len && len >= 3 && !rc; k++) {
      size_t kp = gr_ring_prev(k, len), kn = gr_ring_next(k, len);
      const double *P = p + 2 * kp, *T = p + 2 * k, *N = p + 2 * kn;
      double ux = T[0] - P[0], uy = T[1] - P[1], vx = N[0] - T[0], vy = N[1] - T[1], dot = ux * vx + uy * vy;
      /* most vertices turn far less than 15 degrees: seen from the squares
       * (with room for their rounding), the exact test only near the limit */
      if (dot > 0 && dot * dot > (CORNER_TURN * CORNER_TURN + 1e-9) * (ux * ux + uy * uy) * (vx * vx + vy * vy)) continue;
      double lu = gr_len2d(ux, uy), lv = gr_len2d(vx, vy);
      if (!(lu > 0 && lv > 0) || dot >= CORNER_TURN * lu * lv) continue;
      if (w->on && (T[0] == w->lo[0] || T[0] == w->hi[0] || T[1] == w->lo[1] || T[1] == w->hi[1])) continue;
      for (int side = 0; side < 2 && !rc; side++) {
        const double *Q = side ? N : P;
        double L = side ? lv : lu, d = fmin(CORNER_PROBE, L / 8);
        size_t g = side ? st + k : st + kp; /* the chord's first point */
        if (!(L > CORNER_LEN) || (side ? on_border(w, T, N) : on_border(w, P, T)) || must[g]) continue;
        size_t c1 = cap, c2 = cap, c3 = cap;
        if (gr_grow(&cg, &c1, nc + 1, sizeof *cg) || gr_grow(&px, &c2, nc + 1, sizeof *px) ||
            gr_grow(&py, &c3, nc + 1, sizeof *py)) {
          rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
          break;
        }
        cap = c1;
        cg[nc] = g;
        px[nc] = T[0] + d * (Q[0] - T[0]) / L;
        py[nc++] = T[1] + d * (Q[1] - T[1]) / L;
      }
    }
  }
  if (!rc && nc && !(pv = malloc(nc * sizeof *pv))) rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
  if (!rc && nc) rc = gr_ms_eval(fn, ud, nc, px, py, pv, e);
  for (size_t c = 0; c < nc && !rc; c++)
    if (fabs(pv[c]) > CORNER_OFF && !must[cg[c]]) { must[cg[c]] = 1; ok[cg[c]] = 0; ++*nm; }
  free(cg); free(px); free(py); free(pv);
  return rc;
}

/* Chord accuracy pass over the rings of r; then, with w->tips (field
 * sections), tips of slivers narrower than the chords followed to their
 * end (tips.c) and long chords at sharp turns split (corner_marks), the
 * chords that gives checked in turn. */
int gr_ms_chord_refine(gr_rings *r, gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, double tol,
                       double chord_tol, const gr_ms_win *w, gr_err *e) {
  /* ok[i]: the chord from point i was checked (only new chords are checked
   * in later passes) */
  unsigned char *ok = calloc(r->npts + 1, 1);
  if (!ok) return gr_fail(e, GR_EMEM, "out of memory refining chords");
  size_t grown = 0;
  int rc = chord_passes(r, &ok, NULL, fn, gfn, ud, tol, chord_tol, w, e);
  if (!rc && w->tips) rc = gr_ms_follow_tips(r, &ok, fn, ud, tol, w, &grown, e);
  if (!rc && grown) rc = chord_passes(r, &ok, NULL, fn, gfn, ud, tol, chord_tol, w, e);
  for (int round = 0; round < CORNER_ROUNDS && !rc && w->tips; round++) {
    unsigned char *must = calloc(r->npts + 1, 1);
    if (!must) { rc = gr_fail(e, GR_EMEM, "out of memory refining chords"); break; }
    size_t nm = 0;
    rc = corner_marks(r, ok, must, w, fn, ud, &nm, e);
    if (!rc && nm) rc = chord_passes(r, &ok, must, fn, gfn, ud, tol, chord_tol, w, e);
    free(must);
    if (!nm) break;
  }
  free(ok);
  return rc;
}

int gr_ms_check_window(const double lo[2], const double hi[2], double cell,
                        double tol, gr_err *e) {
  for (int c = 0; c < 2; c++) {
    if (!isfinite(lo[c]) || !isfinite(hi[c]) || !(hi[c] > lo[c]))
      return gr_fail(e, GR_EARG, "window must have hi > lo, got %s lo %g, hi %g",
                     c ? "y" : "x", lo[c], hi[c]);
  }
  if (!(cell > 0) || !isfinite(cell)) return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (!(tol > 0) || !isfinite(tol)) return gr_fail(e, GR_EARG, "tol must be > 0, got %g", tol);
  double nx = ceil((hi[0] - lo[0]) / cell) + 1, ny = ceil((hi[1] - lo[1]) / cell) + 1;
  if (nx * ny > (double)MS_MAX_NODES)
    return gr_fail(e, GR_EMEM, "slice grid too large: %.0f x %.0f nodes for cell %g mm (limit %zu nodes)",
                   nx, ny, cell, MS_MAX_NODES);
  return GR_OK;
}
