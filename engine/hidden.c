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
 * points between their ends, and the cells beside them once inside (a pore
 * can lie wholly inside a cell: see struct probes); if a probe has the
 * other sign, the window is
 * sampled again twice as fine, and again (up to HID_LEVELS times) while
 * probes of the finer grid still find one; it is contoured on the last grid
 * (the chord pass then follows the feature to its end). Where f is straight
 * or bends away from zero no edge is probed. In an in-plane offset by b the
 * same shows where a wall is just over 2b wide: the distance's ridge along
 * the wall's middle rises above b between nodes, and the offset's strip
 * there (the inner contour) is narrower than the grid. */
#include "march.h"
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define HID_JUMP 1.5
#define HID_GUARD 2.0
#define HID_PROBE 8
#define HID_LEVELS 2
#define HID_DEPTH 1e-3
#define HID_ZERO 1e-9

/* Inside, for the probes: f < 0, or zero (within HID_ZERO). A node on the
 * boundary takes the solid's side: where a skin's straight side lies on a
 * grid line and meets the sheet's section, the void between them can have
 * its corner on a node and lie wholly inside the cell beyond it; marching
 * squares put both the node's crossings on it and lose the void, and only
 * probes that take the node as solid find it. */
static inline int hid_in(double v) { return v <= HID_ZERO; }

/* Does a grid edge of length h need probing? Its ends' values va, vb must
 * have one sign (hid_in) and one of them lie within the guard of zero (|v|
 * <= guard; NaN is neither); vp, vn: the values at the nodes before a and
 * after b (NaN past the grid's border). lip > 0: f's slope is at most lip (a
 * distance: 1), so f can reach zero between the nodes only if |va| + |vb|
 * <= lim = lip h (lim = INFINITY without lip). Then it is suspect where the
 * straight continuation of the edge before either end (f's slope there)
 * reaches the other sign within the edge, or the ends jump (differ by more
 * than HID_JUMP h). Without branches: the scan evaluates it at every node
 * of a row at once (the compiler's vector loop; most of the grid has no
 * suspect edge). */
static inline int edge_suspect(double va, double vb, double vp, double vn, double h, double lim, double guard) {
  int ia = hid_in(va), ib = hid_in(vb);
  int cand = (ia == ib) & ((fabs(va) <= guard) | (fabs(vb) <= guard)) & !(fabs(va) + fabs(vb) > lim);
  double ta = 2 * va - vp, tb = 2 * vb - vn; /* NaN compares false */
  int ext = (ia & ((ta >= 0) | (tb >= 0))) | ((!ia) & ((ta <= 0) | (tb <= 0)));
  return cand & (ext | (fabs(va - vb) > HID_JUMP * h));
}

/* The suspect edges from the nodes c0 .. c1 of row j (all of them inside
 * the grid) into fl[i]: bit 0 the edge along x from node i, bit 1 the one
 * along y. nan: a row of NaN, standing for the rows past the grid. */
static void row_suspects(const gr_ms_grid *g, int j, int c0, int c1, double lip, double guard, const double *nan,
                         unsigned char *fl) {
  int nx = g->nx, ny = g->ny;
  const double *v = g->v + (size_t)nx * j, *vd = j > 0 ? v - nx : nan;
  const double *vu = j + 1 < ny ? v + nx : nan, *vuu = j + 2 < ny ? v + 2 * (size_t)nx : nan;
  int up = j + 1 < ny, i0 = c0 > 1 ? c0 : 1, i1 = c1 < nx - 3 ? c1 : nx - 3;
  double hx = g->hx, hy = g->hy, lx = lip > 0 ? lip * hx : INFINITY, ly = lip > 0 ? lip * hy : INFINITY;
  for (int i = i0; i <= i1; i++) /* the row's inside: both neighbours along x on the grid */
    fl[i] = (unsigned char)(edge_suspect(v[i], v[i + 1], v[i - 1], v[i + 2], hx, lx, guard) |
                            (up & edge_suspect(v[i], vu[i], vd[i], vuu[i], hy, ly, guard)) << 1);
  /* the row's ends, before and after its inside (a neighbour along x past
   * the grid: NaN) */
  int after = i1 + 1 > i0 ? i1 + 1 : i0;
  int ends[2][2] = {{c0, c1 < i0 - 1 ? c1 : i0 - 1}, {after > c0 ? after : c0, c1}};
  for (int r = 0; r < 2; r++)
    for (int i = ends[r][0]; i <= ends[r][1]; i++) {
      double vp = i > 0 ? v[i - 1] : NAN, vn = i + 2 < nx ? v[i + 2] : NAN;
      int x = i + 1 < nx && edge_suspect(v[i], v[i + 1], vp, vn, hx, lx, guard);
      fl[i] = (unsigned char)(x | (up & edge_suspect(v[i], vu[i], vd[i], vuu[i], hy, ly, guard)) << 1);
    }
}

/* Probes of the suspect edges, appended in the order of j, i, then the
 * edge along x before the one along y (the points evaluated, and their
 * order, are those of a scan of every node): S - 1 probes along each edge,
 * then one inside each grid cell beside it not probed yet whose four
 * corners have the edge's sign, where the nodes' quadratic model of f peaks
 * (cell_peak). A pore narrower than the grid can lie wholly inside a cell,
 * and where a sheet's section is nearly level it is shallow: one 20 um
 * across and a few um deep was missed between the edges' probes, and found
 * only where something else in the window had the grid refined.
 * sign[k]: the sign of probe k's nodes. */
typedef struct probes {
  double *px, *py;
  unsigned char *sign, *cell; /* cell: one mark per grid cell, probed */
  size_t n, cap;
} probes;

static int grow_probes(probes *p, size_t more) {
  size_t c1 = p->cap, c2 = p->cap, c3 = p->cap;
  if (gr_grow(&p->sign, &c1, p->n + more, 1) || gr_grow(&p->px, &c2, p->n + more, sizeof *p->px) ||
      gr_grow(&p->py, &c3, p->n + more, sizeof *p->py))
    return GR_EMEM;
  p->cap = c1 < c2 ? c1 : c2;
  return GR_OK;
}

static void add_point(const gr_ms_grid *g, double i, double j, int sign, probes *p) {
  p->px[p->n] = g->x0 + i * g->hx;
  p->py[p->n] = g->y0 + j * g->hy;
  p->sign[p->n++] = (unsigned char)sign;
}

/* Where in cell (i, j) (its corner's offsets s, t in cells, within
 * [0, 1]) f's local quadratic model from the 4 x 4 nodes around it peaks
 * towards the other sign (sg = 1: a maximum, -1: a minimum): a smooth cap
 * of a pore between the nodes (a sheet's section near its horizontal
 * tangent) has its deepest point there; the cell's centre where the model
 * has no such peak or the cell is by the grid's border. */
static void cell_peak(const gr_ms_grid *g, int i, int j, double sg, double *s, double *t) {
  *s = *t = 0.5;
  if (i < 1 || j < 1 || i + 2 >= g->nx || j + 2 >= g->ny) return;
  size_t nx = (size_t)g->nx;
  const double *v = g->v + i + nx * j, *u = v + nx, *d = v - nx, *w = u + nx;
  /* derivatives at the cell's centre, in units of the cell (times sg) */
  double fx = sg * (v[1] - v[0] + u[1] - u[0]) / 2, fy = sg * (u[0] - v[0] + u[1] - v[1]) / 2;
  double fxx = sg * (v[-1] - v[0] - v[1] + v[2] + u[-1] - u[0] - u[1] + u[2]) / 4;
  double fyy = sg * (d[0] - v[0] - u[0] + w[0] + d[1] - v[1] - u[1] + w[1]) / 4;
  double fxy = sg * (u[1] - u[0] - v[1] + v[0]), det = fxx * fyy - fxy * fxy;
  if (!(fxx < 0 && det > 0)) return; /* no peak: the cell's sides hold its highest points */
  double ds = (-fyy * fx + fxy * fy) / det, dt = (fxy * fx - fxx * fy) / det;
  *s = fmin(fmax(0.5 + ds, 0), 1);
  *t = fmin(fmax(0.5 + dt, 0), 1);
}

/* A probe where cell (i, j) may hide a pore (cell_peak) if the cell is on
 * the grid, not probed yet, and its corners all have the sign (hid_in). */
static int add_cell(const gr_ms_grid *g, int i, int j, int sign, probes *p) {
  if (i < 0 || j < 0 || i + 1 >= g->nx || j + 1 >= g->ny || p->cell[i + (size_t)g->nx * j]) return GR_OK;
  p->cell[i + (size_t)g->nx * j] = 1;
  const double *v = g->v + i + (size_t)g->nx * j, *u = v + g->nx, c[4] = {v[0], v[1], u[0], u[1]};
  for (int k = 0; k < 4; k++)
    if (hid_in(c[k]) != sign) return GR_OK;
  if (grow_probes(p, 1)) return GR_EMEM;
  double s, t;
  cell_peak(g, i, j, sign ? 1 : -1, &s, &t);
  add_point(g, i + s, j + t, sign, p);
  return GR_OK;
}

static int add_probes(const gr_ms_grid *g, int i, int j, int dir, probes *p) {
  const int S = HID_PROBE, di = dir == 0, dj = dir == 1;
  double va = g->v[i + (size_t)g->nx * j], vb = g->v[i + di + (size_t)g->nx * (j + dj)];
  int sign = hid_in(va);
  /* an edge from a node on the boundary: only the cells beside it (a void
   * with its corner on the node lies inside one; along a grid line of such
   * nodes the edges' probes would be many and find nothing the cells'
   * do not) */
  if (fabs(va) > HID_ZERO && fabs(vb) > HID_ZERO) {
    if (grow_probes(p, S)) return GR_EMEM;
    for (int a = 1; a < S; a++) add_point(g, i + di * (double)a / S, j + dj * (double)a / S, sign, p);
  }
  int rc = add_cell(g, i, j, sign, p);
  return rc ? rc : add_cell(g, i - dj, j - di, sign, p);
}

/* The nodes within the box (NULL: all): xin[i], yin[j] mark the columns
 * and rows it keeps (the tests made at every node before, now once per
 * column and row), r the first and last of each (x0 + i hx grows with i,
 * so the marks form runs; the scan still reads them). */
static void box_range(const gr_ms_grid *g, const double *box, unsigned char *xin, unsigned char *yin, int r[4]) {
  r[0] = g->nx;
  r[1] = -1;
  r[2] = g->ny;
  r[3] = -1;
  for (int i = 0; i < g->nx; i++) {
    double x = g->x0 + i * g->hx;
    xin[i] = !box || !(x < box[0] - 2 * g->hx || x > box[2] + g->hx);
    if (xin[i]) { r[0] = r[0] < i ? r[0] : i; r[1] = i; }
  }
  for (int j = 0; j < g->ny; j++) {
    double y = g->y0 + j * g->hy;
    yin[j] = !box || !(y < box[1] - 2 * g->hy || y > box[3] + g->hy);
    if (yin[j]) { r[2] = r[2] < j ? r[2] : j; r[3] = j; }
  }
}

/* The suspect edges of g (edge_suspect) from the nodes in the box, their
 * probes appended to p in the order of j, i, x before y. */
static int scan_edges(const gr_ms_grid *g, double lip, const double *box, double guard, probes *p) {
  int nx = g->nx, ny = g->ny, r[4];
  size_t nn = (size_t)nx * ny;
  unsigned char *fl = malloc((size_t)nx + 8 + (size_t)nx + (size_t)ny), *xin = fl + nx + 8, *yin = xin + nx;
  double *nan = malloc((size_t)nx * sizeof *nan);
  if (!fl || !nan || !(p->cell = calloc(nn, 1))) {
    free(fl);
    free(nan);
    return GR_EMEM;
  }
  for (int i = 0; i < nx; i++) nan[i] = NAN;
  box_range(g, box, xin, yin, r); /* the box's columns are the run r[0] .. r[1] */
  int rc = GR_OK;
  for (int j = r[2]; j <= r[3] && !rc; j++) {
    if (!yin[j]) continue;
    row_suspects(g, j, r[0], r[1], lip, guard, nan, fl);
    memset(fl + r[1] + 1, 0, 8);
    for (int i = r[0]; i <= r[1] && !rc; i++) {
      if (!gr_ms_word(fl + i)) { /* most of the row: eight nodes at a time */
        i += 7;
        continue;
      }
      if (fl[i] & 1) rc = add_probes(g, i, j, 0, p);
      if (!rc && fl[i] & 2) rc = add_probes(g, i, j, 1, p);
    }
  }
  free(fl);
  free(nan);
  free(p->cell);
  p->cell = NULL;
  return rc;
}

/* *hidden = 1 if a probe between two nodes of one sign has the other sign. */
static int hidden_boundary(const gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, int *hidden,
                           gr_err *e) {
  double guard = HID_GUARD * hypot(g->hx, g->hy);
  if (lip > 0) guard = fmin(guard, lip * fmax(g->hx, g->hy));
  probes p = {0};
  double *pv = NULL;
  *hidden = 0;
  int rc = scan_edges(g, lip, box, guard, &p);
  if (rc) rc = gr_fail(e, GR_EMEM, "out of memory probing %zu points between grid nodes", p.n);
  if (!rc && p.n && !(pv = malloc(p.n * sizeof *pv)))
    rc = gr_fail(e, GR_EMEM, "out of memory probing %zu points between grid nodes", p.n);
  if (!rc && p.n) rc = gr_ms_eval(fn, ud, p.n, p.px, p.py, pv, e);
  /* the other sign by more than HID_DEPTH (1 um): a void (or solid) that
   * shallow is under about 2 um wide, and fields that differ in the last
   * digits (shared closest points or not) must not decide differently on
   * it (the finer grid moves contours elsewhere within the chord tolerance) */
  for (size_t k = 0; !rc && k < p.n && !*hidden; k++)
    *hidden = p.sign[k] ? pv[k] > HID_DEPTH : pv[k] < -HID_DEPTH;
  free(p.px); free(p.py); free(pv); free(p.sign);
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
  fine->exact = 0; /* the blended nodes are not fn's values */
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

int gr_ms_hidden(const gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, int *hidden, gr_err *e) {
  return hidden_boundary(g, lip, box, fn, ud, hidden, e);
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
