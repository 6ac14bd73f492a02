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
               (o->hi[1] - o->lo[1]) / (ny - 1), NULL, 0};
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

/* Contour the sampled grid g (values set) with fn for refinement, chords and
 * nesting; on a finer grid where a cell hides a part of the boundary. */
static int slice_sampled(gr_ms_grid *g, const gr_slice_opts *o, gr_slice_fn fn, gr_slice_grad_fn gfn,
                         void *ud, gr_rings *out, gr_err *e) {
  gr_rings_clear(out);
  double *fv = NULL;
  double reach = 4 * fmax(g->hx, g->hy); /* four cells of the grid given, refined or not */
  int rc = gr_ms_unhide(g, 0, NULL, fn, ud, &fv, e);
  if (!rc) rc = gr_ms_contour(g, fn, gfn, ud, o->refine, o->tol, out, e);
  if (!rc && o->chord_tol > 0) {
    gr_ms_win w = {1, {o->lo[0], o->lo[1]}, {o->hi[0], o->hi[1]}, reach, 1, o->smooth};
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
  g.exact = o->exact;
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
    uint64_t k[2] = {0, 0}; /* set by the two edges that cross z */
    double q[2][2] = {{0, 0}, {0, 0}};
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
