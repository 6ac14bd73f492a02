/* reach.c: the local reach of a periodic surface, see reach.h. */
#include "reach.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include "pool.h"

/* Cells per period along the shortest axis, at most: a cell is never
 * smaller than the spacing of the points, so that the nearest point to any
 * point of H lies in its cell or a neighbour. The finer the cells, the
 * nearer each cell's value to t* there (a cell takes the smallest t* of its
 * 27); 64 keeps the table under 1 MB (res 40 cells are about 36 a period,
 * the points' spacing). */
#define REACH_CELLS 64

struct gr_reach {
  double lo[3], g[3]; /* period box origin, cell size (mm) */
  int n[3];           /* cells per axis */
  float *v;           /* n[0] n[1] n[2] values, mm */
};


/* 1 when s is (within eps) the closest point of s + sg r n, 0 when not, -1
 * when no closest point was found; x: the closest point. */
static int keeps(gr_reach_foot foot, void *ud, const double s[3], const double n[3], int sg, double r, double eps,
                 double x[3]) {
  double c[3] = {s[0] + sg * r * n[0], s[1] + sg * r * n[1], s[2] + sg * r * n[2]};
  if (!foot(ud, c, x)) return -1;
  return gr_dist3(x, s) < eps;
}

/* Bisection for the cut distance (reach.h). */
double gr_reach_bisect(gr_reach_foot foot, void *ud, const double s[3], const double n[3], int sg, double top,
                       double tol, int steps, double eps) {
  double lo = 0, hi = top, x[3];
  for (int it = 0; it < steps && hi - lo > tol; it++) {
    double mid = 0.5 * (lo + hi);
    if (keeps(foot, ud, s, n, sg, mid, eps, x) > 0) lo = mid;
    else hi = mid;
  }
  if (hi < top) return lo;
  return keeps(foot, ud, s, n, sg, top, eps, x) > 0 ? top : lo;
}


/* A shrinking ball: the ball tangent at s of radius r (its centre along
 * sg n) is empty when s is the closest point of its centre; otherwise the
 * closest point x found lies inside it, and the ball tangent at s through x
 * is the next, a little smaller (1 %) so that x is outside it. Where t* is
 * set by another patch this ends in two or three steps; where it is set by
 * the curvature (a focal point), the ball through a nearby x is the
 * osculating one. Unsettled after 8 steps: bisection below the last. */
double gr_reach_cut(gr_reach_foot foot, void *ud, const double s[3], const double n[3], int sg, double cap,
                    double eps) {
  double r = cap, x[3];
  for (int it = 0; it < 8; it++) {
    int k = keeps(foot, ud, s, n, sg, r, eps, x);
    if (k < 0) return 0;
    if (k) return r;
    double dx[3] = {x[0] - s[0], x[1] - s[1], x[2] - s[2]};
    double h = sg * (dx[0] * n[0] + dx[1] * n[1] + dx[2] * n[2]);
    double r2 = h > 0 ? (dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]) / (2 * h) : 0;
    r = fmin(0.99 * r2, 0.99 * r);
    if (!(r > eps)) return 0;
  }
  return gr_reach_bisect(foot, ud, s, n, sg, r, 0, 8, eps);
}

typedef struct cut_job {
  const double *s, *nrm;
  size_t nv;
  double cap, eps;
  gr_reach_foot foot;
  void *ud;
  double *t; /* per point: the smaller t* of its two sides */
} cut_job;

enum { CUT_CHUNK = 64 };

static int cut_item(void *ctx, int item, gr_err *e) {
  (void)e;
  cut_job *j = ctx;
  size_t a = (size_t)item * CUT_CHUNK, b = a + CUT_CHUNK < j->nv ? a + CUT_CHUNK : j->nv;
  for (size_t i = a; i < b; i++) {
    const double *s = j->s + 3 * i, *n = j->nrm + 3 * i;
    double t = gr_reach_cut(j->foot, j->ud, s, n, 1, j->cap, j->eps);
    j->t[i] = t > 0 ? fmin(t, gr_reach_cut(j->foot, j->ud, s, n, -1, t, j->eps)) : 0;
  }
  return GR_OK;
}

/* The index of cell (i, j, k), each wrapped into the period. */
static size_t cell_index(const int n[3], long i, long j, long k) {
  long c[3] = {i, j, k};
  size_t id = 0;
  for (int a = 2; a >= 0; a--) {
    long w = c[a] % n[a];
    id = id * (size_t)n[a] + (size_t)(w < 0 ? w + n[a] : w);
  }
  return id;
}

/* The cell (i, j, k) holding q, unwrapped. */
static void cell_ijk(const gr_reach *r, const double q[3], long c[3]) {
  for (int a = 0; a < 3; a++) c[a] = (long)floor((q[a] - r->lo[a]) / r->g[a]);
}

static size_t cell_of(const gr_reach *r, const double q[3]) {
  long c[3];
  cell_ijk(r, q, c);
  return cell_index(r->n, c[0], c[1], c[2]);
}

/* The steepest slope of t* at each of the nv points s, against the points
 * dmin to dmax from it (both known and below the cap; nearer pairs show only
 * the cut distances' 1 % rounding), found via the cells within dmax (points
 * sorted by cell: order, start): sl[i], -1 where no pair is; returns the
 * steepest of all (0 when none). */
static double slopes(const gr_reach *r, const double *s, const double *t, size_t nv, double cap, double dmin,
                     double dmax, const size_t *order, const size_t *start, double *sl) {
  double worst = 0;
  const int *n = r->n;
  /* cells within dmax of the point's own, whatever the cells' size */
  int w = (int)ceil(dmax / fmin(r->g[0], fmin(r->g[1], r->g[2])));
  for (size_t i = 0; i < nv; i++) {
    sl[i] = -1;
    if (!(t[i] < cap) || !(t[i] > 0)) continue;
    const double *si = s + 3 * i;
    long ci[3];
    cell_ijk(r, si, ci);
    for (int dk = -w; dk <= w; dk++)
      for (int dj = -w; dj <= w; dj++)
        for (int di = -w; di <= w; di++) {
          size_t cell = cell_index(n, ci[0] + di, ci[1] + dj, ci[2] + dk);
          for (size_t k = start[cell]; k < start[cell + 1]; k++) {
            size_t jx = order[k];
            double d = gr_dist3(si, s + 3 * jx);
            if (jx == i || !(d <= dmax) || !(d >= dmin) || !(t[jx] < cap) || !(t[jx] > 0)) continue;
            sl[i] = fmax(sl[i], fabs(t[i] - t[jx]) / d);
          }
        }
    worst = fmax(worst, sl[i]);
  }
  return worst;
}

/* v[cell] = the smallest of cmin over the cell and its 26 neighbours (the
 * period wraps) less the steepest of cslope over them times spacing; 0
 * where all are empty (cmin INFINITY). */
static void dilate(gr_reach *r, const double *cmin, const double *cslope, double spacing, float *v) {
  const int *n = r->n;
  for (int k = 0; k < n[2]; k++)
    for (int j = 0; j < n[1]; j++)
      for (int i = 0; i < n[0]; i++) {
        double m = INFINITY, sl = 0;
        for (int dk = -1; dk <= 1; dk++)
          for (int dj = -1; dj <= 1; dj++)
            for (int di = -1; di <= 1; di++) {
              size_t c = cell_index(n, i + di, j + dj, k + dk);
              m = fmin(m, cmin[c]);
              sl = fmax(sl, cslope[c]);
            }
        v[cell_index(n, i, j, k)] = isfinite(m) ? (float)fmax(0, m - sl * spacing) : 0.f;
      }
}

/* The smallest t* near each cell, less the margin for what t*
 * may lose between a point of H and its nearest sample (within `spacing`).
 * Each sample's t* is a lower bound (an empty ball was found); between
 * samples t* may dip below them by at most its slope times that distance,
 * the slope measured between samples 0.5 to 2 spacings apart, near the cell
 * (its 27 cells; a sample without such a pair counts with the steepest
 * slope of all). Out of memory: no table (all 0). */
static void fill(gr_reach *r, const double *s, const double *t, size_t nv, double cap, double spacing) {
  size_t nc = (size_t)r->n[0] * r->n[1] * r->n[2];
  size_t *start = calloc(nc + 2, sizeof *start), *order = malloc(2 * (nv + 1) * sizeof *order);
  size_t *cell = order ? order + nv + 1 : NULL; /* each point's cell */
  double *sl = malloc((nv + 1) * sizeof *sl), *cmin = malloc(2 * nc * sizeof *cmin);
  double *cslope = cmin ? cmin + nc : NULL;
  int ok = start && order && sl && cmin;
  for (size_t i = 0; ok && i < nv; i++) start[(cell[i] = cell_of(r, s + 3 * i)) + 2]++;
  for (size_t c = 0; ok && c < nc; c++) start[c + 2] += start[c + 1];
  for (size_t i = 0; ok && i < nv; i++) order[start[cell[i] + 1]++] = i;
  if (ok) {
    double steep = slopes(r, s, t, nv, cap, 0.5 * spacing, 2 * spacing, order, start, sl);
    if (getenv("GRADUS_DEBUG")) fprintf(stderr, "local reach: steepest slope %.3f\n", steep);
    for (size_t c = 0; c < nc; c++) cmin[c] = INFINITY, cslope[c] = 0;
    for (size_t i = 0; i < nv; i++) {
      size_t c = cell[i];
      cmin[c] = fmin(cmin[c], t[i]);
      cslope[c] = fmax(cslope[c], sl[i] >= 0 ? sl[i] : steep);
    }
    dilate(r, cmin, cslope, spacing, r->v);
  } else {
    memset(r->v, 0, nc * sizeof *r->v);
  }
  free(start);
  free(order);
  free(sl);
  free(cmin);
}

gr_reach *gr_reach_new(const double lo[3], const double period[3], double cap, double eps, double spacing, size_t nv,
                       const double *s, const double *nrm, gr_reach_foot foot, void *ud, int threads, gr_err *e) {
  double pmin = fmin(period[0], fmin(period[1], period[2]));
  if (!(pmin > 0) || !(cap > 0) || !(spacing > 0))
    return gr_fail(e, GR_EARG, "local reach: the period, cap and spacing must be > 0"), NULL;
  gr_reach *r = calloc(1, sizeof *r);
  double *t = malloc((nv + 1) * sizeof *t);
  size_t nc = 1;
  if (r) {
    for (int a = 0; a < 3; a++) {
      r->lo[a] = lo[a];
      r->n[a] = (int)fmax(3, fmin(round(REACH_CELLS * period[a] / pmin), floor(period[a] / spacing)));
      r->g[a] = period[a] / r->n[a];
      nc *= (size_t)r->n[a];
    }
    r->v = malloc(nc * sizeof *r->v);
  }
  if (!r || !t || !r->v) {
    free(t);
    gr_reach_free(r);
    return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  cut_job j = {.s = s, .nrm = nrm, .nv = nv, .cap = cap, .eps = eps, .foot = foot, .ud = ud, .t = t};
  int rc = gr_pool_for((int)((nv + CUT_CHUNK - 1) / CUT_CHUNK), cut_item, &j, threads, NULL, NULL, "local reach", e);
  if (rc == GR_OK) fill(r, s, t, nv, cap, spacing);
  free(t);
  if (rc) {
    gr_reach_free(r);
    return NULL;
  }
  return r;
}

double gr_reach_at(const gr_reach *r, const double q[3]) {
  return r ? r->v[cell_of(r, q)] : 0;
}

void gr_reach_free(gr_reach *r) {
  if (!r) return;
  free(r->v);
  free(r);
}
