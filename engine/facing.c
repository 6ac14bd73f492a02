/* facing.c: down- and up-facing contour pieces, see facing.h. */
#include "facing.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "job.h"
#include "regions.h"

#define MAXL 128 /* layers looked at: at most 64 below and 64 above */


/* A section's edges by horizontal strips: an edge is listed in every strip
 * its height range meets (CSR: strip k's edges e[4 start[k] .. 4 start[k+1]),
 * ax ay bx by, voxel-local). */
typedef struct strips {
  double y0, h;
  int ns;
  size_t *start;
  double *e;
} strips;

/* The neighbour layers' sections in one voxel column (filled on first use). */
typedef struct column {
  int ready;
  double ox, oy;           /* the voxel's corner, mm (sections are voxel-local) */
  int st[MAXL];            /* GR_SOLID_*: layers g-1 .. g-nb, then g+1 .. g+na */
  strips s[MAXL];          /* the sections' edges where st is GR_SOLID_RINGS */
} column;

static void strip_range(const strips *s, double ya, double yb, int *k0, int *k1) {
  double lo = (gr_lo(ya, yb) - s->y0) / s->h, hi = (gr_hi(ya, yb) - s->y0) / s->h;
  *k0 = lo < 0 ? 0 : lo >= s->ns ? s->ns : (int)floor(lo);
  *k1 = hi < 0 ? -1 : hi >= s->ns ? s->ns - 1 : (int)floor(hi);
}

/* The strips of rings r (strip height about h, mm). */
static int strips_build(strips *s, const gr_rings *r, double h) {
  double lo = INFINITY, hi = -INFINITY;
  for (size_t k = 0; k < r->npts; k++) { lo = gr_lo(lo, r->xy[2 * k + 1]); hi = gr_hi(hi, r->xy[2 * k + 1]); }
  s->ns = (int)gr_lo(4096, gr_hi(1, ceil((hi - lo) / h)));
  s->y0 = lo;
  s->h = gr_hi(hi - lo, 1e-9) / s->ns * (1 + 1e-9);
  s->start = calloc((size_t)s->ns + 1, sizeof *s->start);
  if (!s->start) return GR_EMEM;
  for (int pass = 0; pass < 2; pass++) {
    for (size_t q = 0; q < r->nrings; q++) {
      const double *p = gr_ring_xy(r, q);
      size_t m = gr_ring_len(r, q);
      for (size_t a = 0; a < m; a++) {
        const double *P = p + 2 * a, *Q = p + 2 * ((a + 1) % m);
        int k0, k1;
        strip_range(s, P[1], Q[1], &k0, &k1);
        for (int k = k0; k <= k1; k++) {
          if (pass == 0) { s->start[k + 1]++; continue; }
          double *d = s->e + 4 * s->start[k]++;
          d[0] = P[0]; d[1] = P[1]; d[2] = Q[0]; d[3] = Q[1];
        }
      }
    }
    if (pass == 0) {
      for (int k = 0; k < s->ns; k++) s->start[k + 1] += s->start[k];
      if (!(s->e = malloc((4 * s->start[s->ns] + 1) * sizeof *s->e))) return GR_EMEM;
    } else {
      for (int k = s->ns; k > 0; k--) s->start[k] = s->start[k - 1];
      s->start[0] = 0;
    }
  }
  return GR_OK;
}

/* Even-odd: (x, y) (voxel-local) inside the strips' rings. */
static int strips_contain(const strips *s, double x, double y) {
  int k0, k1, in = 0;
  strip_range(s, y, y, &k0, &k1);
  if (k0 > k1) return 0;
  for (size_t q = s->start[k0]; q < s->start[k0 + 1]; q++) {
    const double *d = s->e + 4 * q;
    double xc;
    if (gr_edge_at_y(d[0], d[1], d[2], d[3], y, &xc) && x < xc) in = !in;
  }
  return in;
}

typedef struct fctx {
  gr_job *j;
  int g, nb, na, mask, row;
  column *col;             /* n[0] x n[1] columns of layer g's voxel row */
  double *t;               /* cut parameters of the current segment */
  size_t nt, capt;
} fctx;

static column *column_at(fctx *c, double x, double y, gr_err *e) {
  const gr_job_opts *o = &c->j->o;
  int i = (int)floor((x - o->origin[0]) / o->cell[0]), jj = (int)floor((y - o->origin[1]) / o->cell[1]);
  i = i < 0 ? 0 : i >= o->n[0] ? o->n[0] - 1 : i;
  jj = jj < 0 ? 0 : jj >= o->n[1] ? o->n[1] - 1 : jj;
  column *cl = &c->col[i + o->n[0] * jj];
  if (cl->ready) return cl;
  int v = i + o->n[0] * (jj + o->n[1] * c->row);
  double vo[3];
  gr_grid_origin(&c->j->grid, v, vo);
  cl->ox = vo[0];
  cl->oy = vo[1];
  for (int q = 0; q < c->nb + c->na; q++) {
    int g2 = q < c->nb ? c->g - 1 - q : c->g + 1 + (q - c->nb);
    const gr_rings *r;
    if (gr_regions_solid(c->j, v, g2, 1, &cl->st[q], &r, e)) return NULL;
    if (cl->st[q] == GR_SOLID_RINGS && strips_build(&cl->s[q], r, c->j->o.slice_cell))
      return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  cl->ready = 1;
  return cl;
}

/* The region of the point (x, y) of a block of region r0. */
static int region_at(const fctx *c, const column *cl, double x, double y, int r0) {
  int down = 0, up = 0;
  for (int q = 0; q < c->nb + c->na; q++) {
    int in = cl->st[q] == GR_SOLID_PLATE ||
             (cl->st[q] == GR_SOLID_RINGS && strips_contain(&cl->s[q], x - cl->ox, y - cl->oy));
    if (!in) *(q < c->nb ? &down : &up) = 1;
  }
  if (down && (c->mask >> GR_DOWNSKIN & 1)) return GR_DOWNSKIN;
  if (up && (c->mask >> GR_UPSKIN & 1)) return GR_UPSKIN;
  return r0;
}

static int add_t(fctx *c, double t) {
  if (!(t > 1e-12 && t < 1 - 1e-12)) return GR_OK;
  if (gr_grow(&c->t, &c->capt, c->nt + 1, sizeof *c->t)) return GR_EMEM;
  c->t[c->nt++] = t;
  return GR_OK;
}

/* Where segment A-B crosses the edges of the sections of column cl. */
static int column_cuts(fctx *c, const column *cl, const double *A, const double *B) {
  double ex = B[0] - A[0], ey = B[1] - A[1];
  double lo = gr_lo(A[0], B[0]) - cl->ox, hi = gr_hi(A[0], B[0]) - cl->ox;
  for (int q = 0; q < c->nb + c->na; q++) {
    if (cl->st[q] != GR_SOLID_RINGS) continue;
    const strips *s = &cl->s[q];
    int k0, k1;
    strip_range(s, A[1] - cl->oy, B[1] - cl->oy, &k0, &k1);
    for (int k = k0; k <= k1; k++)
      for (size_t m = s->start[k]; m < s->start[k + 1]; m++) {
        const double *d = s->e + 4 * m;
        if (gr_hi(d[0], d[2]) < lo || gr_lo(d[0], d[2]) > hi) continue;
        double fx = d[2] - d[0], fy = d[3] - d[1], den = ex * fy - ey * fx;
        if (den == 0) continue;
        double wx = d[0] + cl->ox - A[0], wy = d[1] + cl->oy - A[1];
        double t = (wx * fy - wy * fx) / den, u = (wx * ey - wy * ex) / den;
        if (u >= 0 && u <= 1 && add_t(c, t)) return GR_EMEM;
      }
  }
  return GR_OK;
}

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* The sub-pieces of a block: each starts at (x, y) with region reg (x, y,
 * reg per triple) and ends where the next starts (the last at the block's end). */
typedef gr_trip subs;

/* Sub-pieces of block bk (points p[0..n)): every segment cut where it
 * crosses a neighbour section's edge, each part's region at its middle. */
static int block_subs(fctx *c, const double *p, size_t n, int r0, subs *sb, gr_err *e) {
  sb->n = 0;
  for (size_t a = 0; a + 1 < n; a++) {
    const double *A = p + 2 * a, *B = p + 2 * (a + 1);
    column *ca = column_at(c, A[0], A[1], e), *cb = column_at(c, B[0], B[1], e);
    if (!ca || !cb) return e->code;
    c->nt = 0;
    if (column_cuts(c, ca, A, B) || (cb != ca && column_cuts(c, cb, A, B))) return gr_fail(e, GR_EMEM, "out of memory");
    if (c->nt > 1) qsort(c->t, c->nt, sizeof *c->t, cmp_dbl);
    double t0 = 0;
    for (size_t q = 0; q <= c->nt; q++) {
      double t1 = q < c->nt ? c->t[q] : 1;
      if (t1 - t0 < 1e-12) continue;
      double tm = 0.5 * (t0 + t1), x = A[0] + tm * (B[0] - A[0]), y = A[1] + tm * (B[1] - A[1]);
      column *cm = column_at(c, x, y, e);
      if (!cm) return e->code;
      if (gr_trip_push(sb, A[0] + t0 * (B[0] - A[0]), A[1] + t0 * (B[1] - A[1]), region_at(c, cm, x, y, r0)))
        return gr_fail(e, GR_EMEM, "out of memory");
      t0 = t1;
    }
  }
  return GR_OK;
}

/* Cut block bk of l into out: as it is when it has one region; else runs of
 * one region as open polylines (a closed block's runs start at a change). */
static int cut_block(fctx *c, const gr_layer *l, const gr_block *bk, gr_layer *out, subs *sb, double **pts,
                     size_t *cap, gr_err *e) {
  const double *p = l->xy + 2 * bk->start;
  size_t n = bk->n;
  if (block_subs(c, p, n, bk->region, sb, e)) return e->code;
  size_t m = sb->n, k0 = 0;
  const double *S = sb->p;
  while (k0 < m && S[3 * k0 + 2] == S[2]) k0++;
  if (m == 0 || k0 == m) { /* one region */
    if (gr_layer_add(out, bk->shape, bk->kind, bk->laser, bk->dir, p, n)) return gr_fail(e, GR_EMEM, "out of memory");
    out->b[out->nb - 1].region = m ? (int)S[2] : bk->region;
    return GR_OK;
  }
  int closed = bk->shape == GR_CLOSED;
  if (!closed) k0 = 0;
  for (size_t a = 0; a < m;) { /* a run of one region from sub-piece k0 + a */
    size_t k = (k0 + a) % m, np = 0;
    int reg = (int)S[3 * k + 2];
    for (; a < m && (int)S[3 * ((k0 + a) % m) + 2] == reg; a++) {
      if (gr_grow(pts, cap, np + 2, 2 * sizeof **pts)) return gr_fail(e, GR_EMEM, "out of memory");
      (*pts)[2 * np] = S[3 * ((k0 + a) % m)];
      (*pts)[2 * np + 1] = S[3 * ((k0 + a) % m) + 1];
      np++;
    }
    /* the run ends where the next sub-piece starts, or at the block's end */
    const double *end = (a < m || closed) ? S + 3 * ((k0 + a) % m) : p + 2 * (n - 1);
    (*pts)[2 * np] = end[0];
    (*pts)[2 * np + 1] = end[1];
    np++;
    if (gr_layer_add(out, GR_OPEN, bk->kind, bk->laser, 2, *pts, np)) return gr_fail(e, GR_EMEM, "out of memory");
    out->b[out->nb - 1].region = reg;
  }
  return GR_OK;
}

int gr_facing_contours(gr_job *j, int g, gr_layer *l, gr_err *e) {
  int mask = gr_regions_mask(j) & ((1 << GR_DOWNSKIN) | (1 << GR_UPSKIN));
  if (!mask || l->nb == 0) return GR_OK;
  fctx c;
  memset(&c, 0, sizeof c);
  c.j = j;
  c.g = g;
  c.mask = mask;
  gr_regions_margin(j, &c.nb, &c.na);
  if (c.nb + c.na > MAXL) return gr_fail(e, GR_EARG, "internal: %d layers looked at (at most %d)", c.nb + c.na, MAXL);
  c.row = gr_grid_layer_row(&j->grid, g);
  c.col = calloc((size_t)j->o.n[0] * j->o.n[1], sizeof *c.col);
  gr_layer *out = gr_layer_new(l->z);
  subs sb = {NULL, 0, 0};
  double *pts = NULL;
  size_t cappts = 0;
  int rc = (c.col && out) ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  for (size_t b = 0; b < l->nb && rc == GR_OK; b++) {
    const gr_block *bk = &l->b[b];
    if (bk->kind == GR_HATCH || bk->shape == GR_SEGMENTS || bk->dir == GR_DIR_THIN || bk->n < 2) {
      if (gr_layer_add(out, bk->shape, bk->kind, bk->laser, bk->dir, l->xy + 2 * bk->start, bk->n))
        rc = gr_fail(e, GR_EMEM, "out of memory");
      else
        out->b[out->nb - 1].region = bk->region;
      continue;
    }
    rc = cut_block(&c, l, bk, out, &sb, &pts, &cappts, e);
  }
  if (rc == GR_OK) { /* out's vectors replace l's; the rest of l stays */
    gr_layer tmp = *l;
    l->xy = out->xy; l->npts = out->npts; l->cappts = out->cappts;
    l->b = out->b; l->nb = out->nb; l->capb = out->capb;
    out->xy = tmp.xy; out->npts = tmp.npts; out->cappts = tmp.cappts;
    out->b = tmp.b; out->nb = tmp.nb; out->capb = tmp.capb;
  }
  gr_layer_free(out);
  free(sb.p);
  free(pts);
  for (int k = 0; c.col && k < j->o.n[0] * j->o.n[1]; k++)
    for (int q = 0; q < MAXL; q++) {
      free(c.col[k].s[q].start);
      free(c.col[k].s[q].e);
    }
  free(c.col);
  free(c.t);
  return rc;
}
