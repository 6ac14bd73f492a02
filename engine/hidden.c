/* hidden.c: parts of a zero set narrower than the grid it is sampled on,
 * found before marching squares (see march.h, gr_ms_unhide). Used by field
 * sections (slice.c) and in-plane offsets (polydist.c).
 *
 * Two nodes of one sign can have a part of the boundary between them
 * narrower than the grid: a sliver of void along a jump of f (a graded
 * thickness T(q) that differs on the two sides of the medial surface, where
 * the foot point changes sides), or the tip of a narrowing void. The
 * marching squares then lose it. Such an edge shows itself by its ends: one
 * of them is near zero (within HID_GUARD cell diagonals), and the straight
 * continuation of the edge before it (f's slope there) reaches the other
 * sign within the edge, from either end, or the ends jump (differ by more
 * than HID_JUMP times the edge). Those edges are probed at HID_PROBE - 1
 * points between their ends; if a probe has the other sign, the window is
 * sampled again twice as fine, and again (up to HID_LEVELS times) while
 * probes of the finer grid still find one; it is contoured on the last grid
 * (the chord pass then follows the feature to its end). Where f is straight
 * or bends away from zero no edge is probed. In an in-plane offset by b the
 * same shows where a wall is just over 2b wide: the distance's ridge along
 * the wall's middle rises above b between nodes, and the offset's strip
 * there (the inner contour) is narrower than the grid. */
#include "march.h"
#include <math.h>
#include <stdlib.h>

#define HID_JUMP 1.5
#define HID_GUARD 2.0
#define HID_PROBE 8
#define HID_LEVELS 2
#define HID_DEPTH 1e-3

/* Value of g at node (i, j), NAN outside. */
static double grid_at(const gr_ms_grid *g, int i, int j) {
  return i < 0 || j < 0 || i >= g->nx || j >= g->ny ? NAN : g->v[i + (size_t)g->nx * j];
}

/* Does the grid edge from node a = (i, j) to b = a + (di, dj) need probing?
 * Its values va, vb; the nodes before a and after b (vp, vn) are read only
 * when va, vb pass the first tests (most edges do not). lip > 0: f's slope
 * is at most lip (a distance: 1), so f can reach zero between the nodes only
 * if |va| + |vb| <= lip h. */
static int edge_suspect(const gr_ms_grid *g, int i, int j, int di, int dj, double guard, double lip) {
  double va = g->v[i + (size_t)g->nx * j], vb = g->v[i + di + (size_t)g->nx * (j + dj)], h = dj ? g->hy : g->hx;
  if ((va < 0) != (vb < 0) || !(fmin(fabs(va), fabs(vb)) <= guard)) return 0;
  if (lip > 0 && fabs(va) + fabs(vb) > lip * h) return 0;
  double vp = grid_at(g, i - di, j - dj), vn = grid_at(g, i + 2 * di, j + 2 * dj);
  double s = va < 0 ? 1 : -1; /* s * f rises towards zero */
  if (s * (2 * va - vp) >= 0 || s * (2 * vb - vn) >= 0) return 1; /* NaN compares false */
  return fabs(va - vb) > HID_JUMP * h;
}

/* *hidden = 1 if a probe between two nodes of one sign has the other sign. */
static int hidden_boundary(const gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, int *hidden,
                           gr_err *e) {
  const int S = HID_PROBE;
  double guard = HID_GUARD * hypot(g->hx, g->hy);
  if (lip > 0) guard = fmin(guard, lip * fmax(g->hx, g->hy));
  double *px = NULL, *py = NULL, *pv = NULL;
  int *sign = NULL;
  size_t n = 0, cap = 0, ne = 0, cape = 0;
  int rc = GR_OK;
  *hidden = 0;
  for (int j = 0; j < g->ny && !rc; j++)
    for (int i = 0; i < g->nx && !rc; i++) {
      if (box) {
        double x = g->x0 + i * g->hx, y = g->y0 + j * g->hy;
        if (x < box[0] - 2 * g->hx || x > box[2] + g->hx || y < box[1] - 2 * g->hy || y > box[3] + g->hy) continue;
      }
      for (int dir = 0; dir < 2; dir++) {
        int di = dir == 0, dj = dir == 1;
        if (i + di >= g->nx || j + dj >= g->ny) continue;
        if (!edge_suspect(g, i, j, di, dj, guard, lip)) continue;
        size_t c1 = cape, c2 = cap, c3 = cap, c4 = cap;
        if (gr_grow(&sign, &c1, ne + 1, sizeof *sign) || gr_grow(&px, &c2, n + S, sizeof *px) ||
            gr_grow(&py, &c3, n + S, sizeof *py) || gr_grow(&pv, &c4, n + S, sizeof *pv)) {
          rc = gr_fail(e, GR_EMEM, "out of memory probing %zu grid edges", ne);
          break;
        }
        cape = c1;
        cap = c2;
        sign[ne++] = g->v[i + (size_t)g->nx * j] < 0;
        for (int a = 1; a < S; a++) {
          px[n] = g->x0 + (i + di * (double)a / S) * g->hx;
          py[n++] = g->y0 + (j + dj * (double)a / S) * g->hy;
        }
      }
    }
  if (!rc && n) rc = gr_ms_eval(fn, ud, n, px, py, pv, e);
  /* the other sign by more than HID_DEPTH (1 um): a void (or solid) that
   * shallow is under about 2 um wide, and fields that differ in the last
   * digits (shared closest points or not) must not decide differently on
   * it (the finer grid moves contours elsewhere within the chord tolerance) */
  for (size_t k = 0; !rc && k < n && !*hidden; k++)
    *hidden = sign[k / (size_t)(S - 1)] ? pv[k] > HID_DEPTH : pv[k] < -HID_DEPTH;
  free(px); free(py); free(pv); free(sign);
  return rc;
}

/* g sampled again r times finer (fine takes the grid, *v its values; the
 * caller frees). The coarse nodes keep their values. fn is evaluated only in
 * the cells where the boundary may run: a sign change, or a corner within a
 * cell diagonal of zero; elsewhere all four corners have one sign and are
 * farther from zero than any point of the cell from its nearest corner (f
 * keeps its sign there, with slope about 1), and the fine nodes take the
 * bilinear blend of the corners, of that sign. */
static int refine_grid(const gr_ms_grid *g, int r, gr_slice_fn fn, void *ud, gr_ms_grid *fine, double **v,
                       gr_err *e) {
  *fine = *g;
  fine->nx = (g->nx - 1) * r + 1;
  fine->ny = (g->ny - 1) * r + 1;
  fine->hx = g->hx / r;
  fine->hy = g->hy / r;
  size_t nn = (size_t)fine->nx * fine->ny, ne = 0;
  if (nn > MS_MAX_NODES) return gr_fail(e, GR_EMEM, "a slice grid refined to %d x %d nodes is too large", fine->nx, fine->ny);
  double *w = malloc(nn * sizeof *w), *px = malloc(nn * sizeof *px), *py = malloc(nn * sizeof *py);
  size_t *id = malloc(nn * sizeof *id);
  unsigned char *ex = calloc(nn, 1); /* 1: evaluate fn at this fine node */
  int rc = w && px && py && id && ex ? GR_OK : gr_fail(e, GR_EMEM, "out of memory: slice grid %d x %d", fine->nx, fine->ny);
  double guard = hypot(g->hx, g->hy);
  for (int j = 0; !rc && j + 1 < g->ny; j++)
    for (int i = 0; i + 1 < g->nx; i++) {
      const double *v0 = g->v + i + (size_t)g->nx * j, *v1 = v0 + g->nx;
      double c[4] = {v0[0], v0[1], v1[0], v1[1]}; /* (i,j) (i+1,j) (i,j+1) (i+1,j+1) */
      int neg = (c[0] < 0) + (c[1] < 0) + (c[2] < 0) + (c[3] < 0);
      int near = neg != 0 && neg != 4;
      for (int k = 0; k < 4; k++) near |= fabs(c[k]) <= guard;
      for (int b = 0; b <= r; b++)
        for (int a = 0; a <= r; a++) {
          size_t n = (size_t)(i * r + a) + (size_t)fine->nx * (size_t)(j * r + b);
          if (near) { ex[n] = 1; continue; }
          if (ex[n]) continue;
          double s = (double)a / r, t = (double)b / r;
          w[n] = (1 - t) * ((1 - s) * c[0] + s * c[1]) + t * ((1 - s) * c[2] + s * c[3]);
        }
    }
  for (int J = 0; !rc && J < fine->ny; J++)
    for (int I = 0; I < fine->nx; I++) {
      size_t n = (size_t)I + (size_t)fine->nx * J;
      if (I % r == 0 && J % r == 0) { w[n] = g->v[I / r + (size_t)g->nx * (J / r)]; continue; }
      if (!ex[n]) continue;
      px[ne] = g->x0 + (double)I / r * g->hx;
      py[ne] = g->y0 + (double)J / r * g->hy;
      id[ne++] = n;
    }
  double *val = rc || !ne ? NULL : malloc(ne * sizeof *val);
  if (!rc && ne && !val) rc = gr_fail(e, GR_EMEM, "out of memory: slice grid %d x %d", fine->nx, fine->ny);
  if (!rc && ne) rc = gr_ms_eval(fn, ud, ne, px, py, val, e);
  for (size_t k = 0; !rc && k < ne; k++) w[id[k]] = val[k];
  free(val); free(px); free(py); free(id); free(ex);
  if (rc) { free(w); return rc; }
  fine->v = *v = w;
  return GR_OK;
}

int gr_ms_unhide(gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, double **owned, gr_err *e) {
  *owned = NULL;
  int rc = GR_OK;
  for (int level = 0, hidden = 1; level < HID_LEVELS && hidden && !rc; level++) {
    double *w = NULL;
    gr_ms_grid fine;
    rc = hidden_boundary(g, lip, box, fn, ud, &hidden, e);
    if (!rc && hidden && !(rc = refine_grid(g, 2, fn, ud, &fine, &w, e))) {
      free(*owned);
      *owned = w;
      *g = fine;
    }
  }
  if (rc) {
    free(*owned);
    *owned = NULL;
  }
  return rc;
}
