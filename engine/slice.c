/* slice.c: sections of fields (marching squares, march.h) and of meshes
 * (mesh/plane intersection). See slice.h; 2-D offsets are in polydist.c. */
#include "slice.h"
#include "march.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

gr_slice_opts gr_slice_defaults(void) {
  gr_slice_opts o;
  memset(&o, 0, sizeof o);
  o.lo[0] = o.lo[1] = 0;
  o.hi[0] = o.hi[1] = 1;
  o.cell = 0.0125;
  o.refine = 1;
  o.tol = 1e-6;
  o.chord_tol = 0;
  return o;
}

double gr_slice_max_cell(double hatch) { return hatch / 2; }

int gr_slice_check_res(double cell, double hatch, gr_err *e) {
  if (!(hatch > 0) || !isfinite(hatch))
    return gr_fail(e, GR_EARG, "hatch spacing must be > 0, got %g", hatch);
  if (!(cell > 0) || !isfinite(cell))
    return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (cell > hatch / 2 * (1 + 1e-12))
    return gr_fail(e, GR_EARG,
                   "resolution too coarse: cell %g mm > hatch/2 = %g mm (eq. 7, L <= n*d/2)",
                   cell, hatch / 2);
  return GR_OK;
}


/* ---- field sections ---- */

typedef struct field_ud {
  const gr_field *f;
  double z;
  double *zb; /* MS_CHUNK copies of z */
} field_ud;

static int field_fn(void *ud, size_t n, const double *x, const double *y,
                    double *out, gr_err *e) {
  field_ud *u = ud;
  return gr_field_eval(u->f, n, x, y, u->zb, out, e);
}

/* The grid over the window: nodes at most `cell` apart. A width that is a
 * whole number of cells up to rounding (a window [o - m, o + L + m] far from
 * the origin, say) keeps exactly that number: one node more would shrink
 * every spacing and misalign the grid with grids of equal windows elsewhere
 * (the shared closest-point tables rely on that alignment). */
static gr_ms_grid window_grid(const gr_slice_opts *o) {
  int nx = (int)ceil((o->hi[0] - o->lo[0]) / o->cell - 1e-9) + 1;
  int ny = (int)ceil((o->hi[1] - o->lo[1]) / o->cell - 1e-9) + 1;
  gr_ms_grid g = {nx, ny, o->lo[0], o->lo[1], (o->hi[0] - o->lo[0]) / (nx - 1),
               (o->hi[1] - o->lo[1]) / (ny - 1), NULL};
  return g;
}

static int check_opts(const gr_slice_opts *o, gr_err *e) {
  int rc = gr_ms_check_window(o->lo, o->hi, o->cell, o->tol, e);
  if (rc) return rc;
  if (o->chord_tol < 0 || !isfinite(o->chord_tol))
    return gr_fail(e, GR_EARG, "chord_tol must be >= 0, got %g", o->chord_tol);
  return GR_OK;
}

void gr_slice_grid_size(const gr_slice_opts *o, int *nx, int *ny, double *hx, double *hy) {
  gr_ms_grid g = window_grid(o);
  *nx = g.nx;
  *ny = g.ny;
  *hx = g.hx;
  *hy = g.hy;
}

/* ---- boundary hidden between grid nodes ----
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
 * or bends away from zero no edge is probed. */
#define HID_JUMP 1.5
#define HID_GUARD 2.0
#define HID_PROBE 8
#define HID_LEVELS 2
#define HID_DEPTH 1e-3

/* Value of g at node (i, j), NAN outside. */
static double grid_at(const gr_ms_grid *g, int i, int j) {
  return i < 0 || j < 0 || i >= g->nx || j >= g->ny ? NAN : g->v[i + (size_t)g->nx * j];
}

/* Does the edge from node a (value va, the node before it vp) to b (vb,
 * the node after it vn), h long, need probing? */
static int edge_suspect(double vp, double va, double vb, double vn, double h, double guard) {
  if ((va < 0) != (vb < 0) || !(fmin(fabs(va), fabs(vb)) <= guard)) return 0;
  double s = va < 0 ? 1 : -1; /* s * f rises towards zero */
  if (s * (2 * va - vp) >= 0 || s * (2 * vb - vn) >= 0) return 1; /* NaN compares false */
  return fabs(va - vb) > HID_JUMP * h;
}

/* *hidden = 1 if a probe between two nodes of one sign has the other sign. */
static int hidden_boundary(const gr_ms_grid *g, gr_slice_fn fn, void *ud, int *hidden, gr_err *e) {
  const int S = HID_PROBE;
  double guard = HID_GUARD * hypot(g->hx, g->hy);
  double *px = NULL, *py = NULL, *pv = NULL;
  int *sign = NULL;
  size_t n = 0, cap = 0, ne = 0, cape = 0;
  int rc = GR_OK;
  *hidden = 0;
  for (int j = 0; j < g->ny && !rc; j++)
    for (int i = 0; i < g->nx && !rc; i++)
      for (int dir = 0; dir < 2; dir++) {
        int di = dir == 0, dj = dir == 1;
        if (i + di >= g->nx || j + dj >= g->ny) continue;
        double va = grid_at(g, i, j), vb = grid_at(g, i + di, j + dj);
        if (!edge_suspect(grid_at(g, i - di, j - dj), va, vb, grid_at(g, i + 2 * di, j + 2 * dj), dir ? g->hy : g->hx, guard))
          continue;
        size_t c1 = cape, c2 = cap, c3 = cap, c4 = cap;
        if (gr_grow(&sign, &c1, ne + 1, sizeof *sign) || gr_grow(&px, &c2, n + S, sizeof *px) ||
            gr_grow(&py, &c3, n + S, sizeof *py) || gr_grow(&pv, &c4, n + S, sizeof *pv)) {
          rc = gr_fail(e, GR_EMEM, "out of memory probing %zu grid edges", ne);
          break;
        }
        cape = c1;
        cap = c2;
        sign[ne++] = va < 0;
        for (int a = 1; a < S; a++) {
          px[n] = g->x0 + (i + di * (double)a / S) * g->hx;
          py[n++] = g->y0 + (j + dj * (double)a / S) * g->hy;
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

/* Contour the sampled grid g (values set) with fn for refinement, chords and
 * nesting; on a finer grid where a cell hides a part of the boundary. */
static int slice_sampled(gr_ms_grid *g, const gr_slice_opts *o, gr_slice_fn fn, gr_slice_grad_fn gfn,
                         void *ud, gr_rings *out, gr_err *e) {
  gr_rings_clear(out);
  double *fv = NULL;
  gr_ms_grid fine[2];
  double reach = 4 * fmax(g->hx, g->hy); /* four cells of the grid given, refined or not */
  int rc = GR_OK;
  for (int level = 0, hidden = 1; level < HID_LEVELS && hidden && !rc; level++) {
    double *w = NULL;
    rc = hidden_boundary(g, fn, ud, &hidden, e);
    if (!rc && hidden && !(rc = refine_grid(g, 2, fn, ud, &fine[level & 1], &w, e))) {
      free(fv);
      fv = w;
      g = &fine[level & 1];
    }
  }
  if (!rc) rc = gr_ms_contour(g, fn, gfn, ud, o->refine, o->tol, out, e);
  if (!rc && o->chord_tol > 0) {
    gr_ms_win w = {1, {o->lo[0], o->lo[1]}, {o->hi[0], o->hi[1]}, reach};
    rc = gr_ms_chord_refine(out, fn, gfn, ud, o->tol, o->chord_tol, &w, e);
  }
  if (!rc) rc = gr_rings_nest(out, e);
  free(fv);
  return rc;
}

int gr_slice_grid(const double *v, const gr_slice_opts *o, gr_slice_fn fn,
                  gr_slice_grad_fn gfn, void *ud, gr_rings *out, gr_err *e) {
  if (!o || !v || !fn) return gr_fail(e, GR_EARG, "slice grid: options, values and function are needed");
  int rc = check_opts(o, e);
  if (rc) return rc;
  gr_ms_grid g = window_grid(o);
  g.v = v;
  return slice_sampled(&g, o, fn, gfn, ud, out, e);
}

int gr_slice_field(const gr_field *f, double z, const gr_slice_opts *o,
                   gr_rings *out, gr_err *e) {
  gr_slice_opts d = gr_slice_defaults();
  if (!o) o = &d;
  if (!f) return gr_fail(e, GR_EARG, "field must not be NULL");
  if (!isfinite(z)) return gr_fail(e, GR_EARG, "z must be finite, got %g", z);
  int rc = check_opts(o, e);
  if (rc) return rc;
  gr_ms_grid g = window_grid(o);
  int nx = g.nx, ny = g.ny;
  size_t nn = (size_t)nx * ny;
  field_ud u = {f, z, malloc(MS_CHUNK * sizeof(double))};
  double *v = malloc(nn * sizeof *v);
  double *xs = malloc((size_t)nx * sizeof *xs), *ys = malloc((size_t)nx * sizeof *ys);
  if (!u.zb || !v || !xs || !ys) {
    rc = gr_fail(e, GR_EMEM, "out of memory: slice grid %d x %d", nx, ny);
    goto done;
  }
  for (size_t k = 0; k < MS_CHUNK; k++) u.zb[k] = z;
  for (int i = 0; i < nx; i++) xs[i] = i == nx - 1 ? o->hi[0] : o->lo[0] + i * g.hx;
  for (int j = 0; j < ny && !rc; j++) {
    double y = j == ny - 1 ? o->hi[1] : o->lo[1] + j * g.hy;
    for (int i = 0; i < nx; i++) ys[i] = y;
    rc = gr_ms_eval(field_fn, &u, (size_t)nx, xs, ys, v + (size_t)nx * j, e);
  }
  if (rc) goto done;
  g.v = v;
  rc = slice_sampled(&g, o, field_fn, NULL, &u, out, e);
done:
  free(u.zb); free(v); free(xs); free(ys);
  return rc;
}

/* ---- mesh / plane ---- */

typedef struct mkey { uint64_t key; size_t idx; } mkey;
static int cmp_key(const void *a, const void *b) {
  uint64_t x = ((const mkey *)a)->key, y = ((const mkey *)b)->key;
  return x < y ? -1 : x > y;
}
static long find_key(const uint64_t *keys, size_t n, uint64_t k) {
  size_t lo = 0, hi = n;
  while (lo < hi) {
    size_t m = (lo + hi) / 2;
    if (keys[m] < k) lo = m + 1;
    else hi = m;
  }
  return lo < n && keys[lo] == k ? (long)lo : -1;
}

int gr_slice_mesh(const gr_mesh *m, double z, gr_rings *closed,
                  gr_layer *open, gr_err *e) {
  if (!m) return gr_fail(e, GR_EARG, "mesh must not be NULL");
  if (!isfinite(z)) return gr_fail(e, GR_EARG, "z must be finite, got %g", z);
  if (closed) gr_rings_clear(closed);
  if (open) gr_layer_clear(open, z);
  /* segments: two crossing-edge keys each, oriented so that the inside is
   * on the left: direction along z x n */
  size_t nseg = 0, cap = 0;
  uint64_t *seg = NULL;
  int rc = GR_OK;
  uint64_t nv = m->nv;
  for (size_t f = 0; f < m->nf; f++) {
    const uint32_t *t = m->f + 3 * f;
    if (t[0] >= nv || t[1] >= nv || t[2] >= nv)
      { rc = gr_fail(e, GR_EGEOM, "face %zu has a vertex index out of range", f); goto fail; }
    const double *p[3] = {m->v + 3 * t[0], m->v + 3 * t[1], m->v + 3 * t[2]};
    int above[3] = {p[0][2] >= z, p[1][2] >= z, p[2][2] >= z};
    int na = above[0] + above[1] + above[2];
    if (na == 0 || na == 3) continue;
    uint64_t k[2];
    double q[2][2];
    int c = 0;
    for (int a = 0; a < 3; a++) {
      int b = (a + 1) % 3;
      if (above[a] == above[b]) continue;
      uint32_t u = t[a] < t[b] ? t[a] : t[b], w = t[a] < t[b] ? t[b] : t[a];
      k[c] = (uint64_t)u * nv + w;
      const double *pu = m->v + 3 * (size_t)u, *pw = m->v + 3 * (size_t)w;
      double s = (z - pu[2]) / (pw[2] - pu[2]);
      q[c][0] = pu[0] + s * (pw[0] - pu[0]);
      q[c][1] = pu[1] + s * (pw[1] - pu[1]);
      c++;
    }
    double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    double e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    double nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2];
    /* z x n = (-ny, nx) */
    if ((q[1][0] - q[0][0]) * -ny + (q[1][1] - q[0][1]) * nx < 0) { uint64_t tk = k[0]; k[0] = k[1]; k[1] = tk; }
    if (k[0] == k[1]) continue;
    if (gr_grow(&seg, &cap, nseg + 1, 2 * sizeof *seg)) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    seg[2 * nseg] = k[0];
    seg[2 * nseg + 1] = k[1];
    nseg++;
  }
  {
    size_t nk = 2 * nseg;
    uint64_t *keys = malloc(nk * sizeof *keys + 1);
    long *nxt = NULL;
    int *hasin = NULL, *used = NULL;
    double *pt = NULL, *buf = NULL;
    if (!keys) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    memcpy(keys, seg, nk * sizeof *keys);
    mkey *tmp = malloc(nk * sizeof *tmp + 1);
    if (!tmp) { free(keys); rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    for (size_t i = 0; i < nk; i++) { tmp[i].key = keys[i]; tmp[i].idx = i; }
    qsort(tmp, nk, sizeof *tmp, cmp_key);
    size_t nu = 0;
    for (size_t i = 0; i < nk; i++) if (nu == 0 || keys[nu - 1] != tmp[i].key) keys[nu++] = tmp[i].key;
    free(tmp);
    nxt = malloc(nu * sizeof *nxt + 1);
    hasin = calloc(nu + 1, sizeof *hasin);
    used = calloc(nu + 1, sizeof *used);
    pt = malloc(2 * nu * sizeof *pt + 1);
    buf = malloc(2 * (nu + 1) * sizeof *buf);
    if (!nxt || !hasin || !used || !pt || !buf) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin; }
    for (size_t i = 0; i < nu; i++) {
      nxt[i] = -1;
      uint64_t u = keys[i] / nv, w = keys[i] % nv;
      const double *pu = m->v + 3 * u, *pw = m->v + 3 * w;
      double s = (z - pu[2]) / (pw[2] - pu[2]);
      pt[2 * i] = pu[0] + s * (pw[0] - pu[0]);
      pt[2 * i + 1] = pu[1] + s * (pw[1] - pu[1]);
    }
    for (size_t s = 0; s < nseg; s++) {
      long a = find_key(keys, nu, seg[2 * s]), b = find_key(keys, nu, seg[2 * s + 1]);
      nxt[a] = b; /* non-manifold input: last one wins */
      hasin[b] = 1;
    }
    /* open chains first (start where nothing comes in), then loops */
    for (int pass = 0; pass < 2; pass++)
      for (size_t i = 0; i < nu; i++) {
        if (used[i] || nxt[i] < 0 || (pass == 0 && hasin[i])) continue;
        size_t n = 0;
        long c = (long)i;
        int loop = 0;
        while (c >= 0 && !used[c]) {
          used[c] = 1;
          buf[2 * n] = pt[2 * c]; buf[2 * n + 1] = pt[2 * c + 1]; n++;
          c = nxt[c];
          if (c == (long)i) { loop = 1; break; }
        }
        if (pass == 0 || !loop) {
          if (c >= 0 && !loop) { buf[2 * n] = pt[2 * c]; buf[2 * n + 1] = pt[2 * c + 1]; n++; }
          if (open && n >= 2 && gr_layer_add(open, GR_OPEN, GR_CONTOUR, 0, 2, buf, n)) {
            rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin;
          }
        } else if (closed && gr_ms_emit_ring(closed, buf, n)) {
          rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin;
        }
      }
    if (closed) {
      /* keep the orientation found from the normals; nest for parents only */
      gr_rings *tmpr = gr_rings_new();
      if (!tmpr || gr_rings_copy(tmpr, closed)) { gr_rings_free(tmpr); rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin; }
      rc = gr_rings_nest(tmpr, e);
      if (!rc) {
        free(closed->parent);
        closed->parent = tmpr->parent;
        tmpr->parent = NULL;
      }
      gr_rings_free(tmpr);
    }
  fin:
    free(keys); free(nxt); free(hasin); free(used); free(pt); free(buf);
  }
fail:
  free(seg);
  return rc;
}
