/* regions.c: regions with their own build styles, see regions.h. */
#include "regions.h"
#include "job.h"
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#define MAXN 64 /* layers looked at below / above */

struct gr_regions {
  gr_regions_opts o;
  pthread_mutex_t mu; /* domain evaluation when the field is not thread-safe */
};

int gr_job_set_regions(gr_job *j, const gr_regions_opts *o, gr_err *e) {
  if (o->mask & ~((1 << GR_NREGIONS) - 2))
    return gr_fail(e, GR_EARG, "regions: unknown region in mask 0x%x (skin, thin, downskin, upskin)", o->mask);
  if ((o->mask & (1 << GR_DOWNSKIN)) && !(o->down >= 1 && o->down <= MAXN))
    return gr_fail(e, GR_EARG, "regions: down-skin layers must be 1..%d, got %d", MAXN, o->down);
  if ((o->mask & (1 << GR_UPSKIN)) && !(o->up >= 1 && o->up <= MAXN))
    return gr_fail(e, GR_EARG, "regions: up-skin layers must be 1..%d, got %d", MAXN, o->up);
  for (int r = 1; r < GR_NREGIONS; r++)
    if ((o->mask >> r & 1) && !(isfinite(o->speed[r]) && o->speed[r] > 0))
      return gr_fail(e, GR_EARG, "regions: the speed of region %s must be > 0 mm/s, got %g", gr_region_name(r),
                     o->speed[r]);
  gr_regions_free(j->regions);
  j->regions = NULL;
  for (int r = 1; r < GR_NREGIONS; r++) j->m.rspeed[r] = 0;
  if (!o->mask) return GR_OK;
  struct gr_regions *g = calloc(1, sizeof *g);
  if (!g) return gr_fail(e, GR_EMEM, "out of memory");
  g->o = *o;
  if (!(o->mask & (1 << GR_DOWNSKIN))) g->o.down = 0;
  if (!(o->mask & (1 << GR_UPSKIN))) g->o.up = 0;
  pthread_mutex_init(&g->mu, NULL);
  for (int r = 1; r < GR_NREGIONS; r++) j->m.rspeed[r] = (o->mask >> r & 1) ? o->speed[r] : 0;
  j->regions = g;
  return GR_OK;
}

int gr_regions_mask(const gr_job *j) { return j->regions ? j->regions->o.mask : 0; }

void gr_regions_margin(const gr_job *j, int *below, int *above) {
  *below = j->regions ? j->regions->o.down : 0;
  *above = j->regions ? j->regions->o.up : 0;
}

void gr_regions_free(struct gr_regions *r) {
  if (!r) return;
  pthread_mutex_destroy(&r->mu);
  free(r);
}

void gr_regions_tag_thin(const gr_job *j, gr_layer *l) {
  if (!(gr_regions_mask(j) & (1 << GR_THIN))) return;
  for (size_t b = 0; b < l->nb; b++)
    if (l->b[b].dir == GR_DIR_THIN) l->b[b].region = GR_THIN;
}

/* ---- the solid of a neighbouring layer in one voxel column ---- */
enum { SOLID = 0, VOID = 1, RINGS = 2 };
typedef struct nbr { int state; const gr_rings *r; } nbr;

/* Layer g2's solid in the column of voxel v (rings voxel-local). */
static int neighbour(const gr_job *j, int v, int g2, nbr *out, gr_err *e) {
  out->r = NULL;
  if (g2 < 1) { out->state = SOLID; return GR_OK; } /* the build plate */
  if (g2 > j->nlayers) { out->state = VOID; return GR_OK; }
  int i, jj, k, kk = gr_grid_layer_row(&j->grid, g2);
  gr_grid_ijk(&j->grid, v, &i, &jj, &k);
  int v2 = i + j->grid.n[0] * (jj + j->grid.n[1] * kk);
  out->state = VOID;
  if (j->vcls[v2] < 0) return GR_OK;
  const gr_tmpl *t = j->cls[j->vcls[v2]].t;
  int jl = g2 - gr_grid_row_first(&j->grid, kk);
  if (!t || jl < t->j0 || jl >= t->j0 + t->nl)
    return gr_fail(e, GR_EARG, "internal: regions need layer %d's template (voxel %d)", g2, v2);
  const gr_rings *r = t->l[jl - t->j0].region;
  if (r && r->nrings > 0) { out->state = RINGS; out->r = r; }
  return GR_OK;
}

static int inside(const nbr *n, double x, double y) {
  return n->state == SOLID || (n->state == RINGS && gr_rings_contains(n->r, x, y));
}

/* ---- cutting one segment ---- */
typedef struct cutbuf { double *t; size_t n, cap; } cutbuf;

static int add_cut(cutbuf *c, double t) {
  if (!(t > 1e-12 && t < 1 - 1e-12)) return GR_OK;
  if (gr_grow(&c->t, &c->cap, c->n + 1, sizeof *c->t)) return GR_EMEM;
  c->t[c->n++] = t;
  return GR_OK;
}

/* Parameters where p0 + t (p1 - p0) crosses an edge of rings r (local). */
static int ring_cuts(const gr_rings *r, const double p0[2], const double p1[2], cutbuf *c) {
  double dx = p1[0] - p0[0], dy = p1[1] - p0[1];
  for (size_t q = 0; q < r->nrings; q++) {
    const double *p = gr_ring_xy(r, q);
    size_t m = gr_ring_len(r, q);
    for (size_t a = 0; a < m; a++) {
      const double *A = p + 2 * a, *B = p + 2 * ((a + 1) % m);
      double ex = B[0] - A[0], ey = B[1] - A[1], den = dx * ey - dy * ex;
      if (fabs(den) < 1e-300) continue;
      double wx = A[0] - p0[0], wy = A[1] - p0[1];
      double t = (wx * ey - wy * ex) / den, u = (wx * dy - wy * dx) / den;
      if (u >= -1e-12 && u <= 1 + 1e-12 && add_cut(c, t)) return GR_EMEM;
    }
  }
  return GR_OK;
}

typedef struct vctx {
  gr_job *j;
  nbr nb[2 * MAXN];
  int nbelow, nabove;
  double o[2];        /* voxel min corner x, y (rings are local) */
  double z;           /* layer middle, mm (domain) */
  int skin;           /* the skin test applies */
  int mask;
} vctx;

static int dom_eval(vctx *c, size_t n, const double *x, const double *y, double *f, gr_err *e) {
  double zz[16];
  for (size_t q = 0; q < n; q++) zz[q] = c->z;
  int lock = !gr_field_threadsafe(c->j->domain);
  if (lock) pthread_mutex_lock(&c->j->regions->mu);
  int rc = gr_field_eval(c->j->domain, n, x, y, zz, f, e);
  if (lock) pthread_mutex_unlock(&c->j->regions->mu);
  for (size_t q = 0; q < n; q++) f[q] += c->j->skin; /* >= 0: in the skin band */
  return rc;
}

/* Where the segment crosses the skin band's inner side domain = -skin:
 * samples every h, each sign change bisected. */
static int skin_cuts(vctx *c, const double p0[2], const double p1[2], cutbuf *cb, gr_err *e) {
  double len = hypot(p1[0] - p0[0], p1[1] - p0[1]);
  double h = 0.5 * fmin(c->j->o.hatch, c->j->skin);
  int m = (int)ceil(len / h);
  if (m < 1) m = 1;
  double prev = 0, pt = 0;
  for (int a = 0; a <= m; a += 16) {
    double x[16], y[16], f[16];
    int n = m - a + 1 < 16 ? m - a + 1 : 16;
    for (int q = 0; q < n; q++) {
      double t = (double)(a + q) / m;
      x[q] = p0[0] + t * (p1[0] - p0[0]);
      y[q] = p0[1] + t * (p1[1] - p0[1]);
    }
    if (dom_eval(c, (size_t)n, x, y, f, e)) return e->code;
    for (int q = 0; q < n; q++) {
      double t = (double)(a + q) / m;
      if (a + q > 0 && (f[q] >= 0) != (prev >= 0)) {
        double lo = pt, hi = t, flo = prev;
        for (int it = 0; it < 40; it++) {
          double mid = 0.5 * (lo + hi), xm = p0[0] + mid * (p1[0] - p0[0]), ym = p0[1] + mid * (p1[1] - p0[1]), fm;
          if (dom_eval(c, 1, &xm, &ym, &fm, e)) return e->code;
          if ((fm >= 0) == (flo >= 0)) { lo = mid; flo = fm; } else hi = mid;
        }
        if (add_cut(cb, 0.5 * (lo + hi))) return gr_fail(e, GR_EMEM, "out of memory");
      }
      prev = f[q];
      pt = t;
    }
  }
  return GR_OK;
}

/* The region of global point (x, y) of the layer. */
static int region_at(vctx *c, double x, double y, int *reg, gr_err *e) {
  double lx = x - c->o[0], ly = y - c->o[1];
  int down = 0, up = 0;
  for (int i = 0; i < c->nbelow && !down; i++) down = !inside(&c->nb[i], lx, ly);
  for (int i = 0; i < c->nabove && !up; i++) up = !inside(&c->nb[c->nbelow + i], lx, ly);
  if (down && (c->mask >> GR_DOWNSKIN & 1)) { *reg = GR_DOWNSKIN; return GR_OK; }
  if (up && (c->mask >> GR_UPSKIN & 1)) { *reg = GR_UPSKIN; return GR_OK; }
  *reg = GR_CORE;
  if (c->skin) {
    double f;
    if (dom_eval(c, 1, &x, &y, &f, e)) return e->code;
    if (f >= 0) *reg = GR_SKIN;
  }
  return GR_OK;
}

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Append the pieces of segment s (cut by region) to out[*n]. */
static int split_one(vctx *c, const gr_hseg *s, cutbuf *cb, gr_hseg **out, size_t *n, size_t *cap, gr_err *e) {
  double p0[2] = {s->x0, s->y0}, p1[2] = {s->x1, s->y1};
  double l0[2] = {p0[0] - c->o[0], p0[1] - c->o[1]}, l1[2] = {p1[0] - c->o[0], p1[1] - c->o[1]};
  cb->n = 0;
  for (int i = 0; i < c->nbelow + c->nabove; i++)
    if (c->nb[i].state == RINGS && ring_cuts(c->nb[i].r, l0, l1, cb)) return gr_fail(e, GR_EMEM, "out of memory");
  if (c->skin && skin_cuts(c, p0, p1, cb, e)) return e->code;
  if (gr_grow(&cb->t, &cb->cap, cb->n + 2, sizeof *cb->t)) return gr_fail(e, GR_EMEM, "out of memory");
  qsort(cb->t, cb->n, sizeof *cb->t, cmp_dbl);
  memmove(cb->t + 1, cb->t, cb->n * sizeof *cb->t);
  cb->t[0] = 0;
  cb->t[cb->n + 1] = 1;
  size_t nt = cb->n + 2;
  double ta = 0;
  int cur = -1;
  for (size_t q = 0; q + 1 < nt; q++) {
    double t0 = cb->t[q], t1 = cb->t[q + 1];
    if (t1 - t0 < 1e-9) continue;
    double tm = 0.5 * (t0 + t1);
    int reg;
    if (region_at(c, p0[0] + tm * (p1[0] - p0[0]), p0[1] + tm * (p1[1] - p0[1]), &reg, e)) return e->code;
    if (cur >= 0 && reg != cur) {
      if (gr_grow(out, cap, *n + 1, sizeof **out)) return gr_fail(e, GR_EMEM, "out of memory");
      gr_hseg *p = &(*out)[(*n)++];
      *p = *s;
      p->x0 = p0[0] + ta * (p1[0] - p0[0]); p->y0 = p0[1] + ta * (p1[1] - p0[1]);
      p->x1 = p0[0] + t0 * (p1[0] - p0[0]); p->y1 = p0[1] + t0 * (p1[1] - p0[1]);
      p->s0 = s->s0 + ta * (s->s1 - s->s0); p->s1 = s->s0 + t0 * (s->s1 - s->s0);
      p->region = cur;
      ta = t0;
    }
    cur = reg;
  }
  if (gr_grow(out, cap, *n + 1, sizeof **out)) return gr_fail(e, GR_EMEM, "out of memory");
  gr_hseg *p = &(*out)[(*n)++];
  *p = *s;
  p->x0 = p0[0] + ta * (p1[0] - p0[0]); p->y0 = p0[1] + ta * (p1[1] - p0[1]);
  p->s0 = s->s0 + ta * (s->s1 - s->s0);
  p->region = cur < 0 ? GR_CORE : cur;
  return GR_OK;
}

int gr_regions_split(gr_job *j, int g, int v, gr_hseg **segs, size_t *n, size_t *cap, size_t a, gr_err *e) {
  int mask = gr_regions_mask(j);
  if (!(mask & ((1 << GR_SKIN) | (1 << GR_DOWNSKIN) | (1 << GR_UPSKIN))) || *n <= a) return GR_OK;
  vctx c;
  memset(&c, 0, sizeof c);
  c.j = j;
  c.mask = mask;
  c.nbelow = j->regions->o.down;
  c.nabove = j->regions->o.up;
  for (int i = 0; i < c.nbelow; i++)
    if (neighbour(j, v, g - 1 - i, &c.nb[i], e)) return e->code;
  for (int i = 0; i < c.nabove; i++)
    if (neighbour(j, v, g + 1 + i, &c.nb[c.nbelow + i], e)) return e->code;
  double o[3];
  gr_grid_origin(&j->grid, v, o);
  c.o[0] = o[0];
  c.o[1] = o[1];
  c.z = gr_grid_mid(&j->grid, g);
  c.skin = (mask >> GR_SKIN & 1) && j->skin > 0 && j->domain && j->cls[j->vcls[v]].trimmed;
  size_t m = *n - a;
  gr_hseg *orig = malloc(m * sizeof *orig);
  if (!orig) return gr_fail(e, GR_EMEM, "out of memory");
  memcpy(orig, *segs + a, m * sizeof *orig);
  *n = a;
  cutbuf cb = {NULL, 0, 0};
  int rc = GR_OK;
  for (size_t q = 0; q < m && rc == GR_OK; q++) rc = split_one(&c, &orig[q], &cb, segs, n, cap, e);
  free(cb.t);
  free(orig);
  return rc;
}
