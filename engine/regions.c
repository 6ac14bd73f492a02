/* regions.c: regions with their own build styles, see regions.h. */
#include "regions.h"
#include "job.h"
#include "skinring.h"
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#define MAXN 64 /* layers looked at below / above */
#define MAXDIV 16 /* the line family's spacing: the job's hatch / 1 .. MAXDIV */
#define MAXSTEP 64 /* a region's spacing: at most MAXSTEP lines of the family */
#define HATCHED ((1 << GR_SKIN) | (1 << GR_DOWNSKIN) | (1 << GR_UPSKIN))
#define DROP GR_NREGIONS /* a hatch piece within the skin's contour band */

struct gr_regions {
  gr_regions_opts o;
  double line;            /* the family's spacing d0, mm */
  int step[GR_NREGIONS];  /* region r keeps lines k with k mod step[r] = 0 */
  pthread_mutex_t mu; /* domain evaluation when the field is not thread-safe */
};

/* The largest d0 = hatch / n (n <= MAXDIV) of which every spacing in s[] is a
 * whole multiple (to 1e-6 relative) of at most MAXSTEP; its steps into step[]. */
static int line_family(double hatch, const double *s, int mask, double *d0, int *step, gr_err *e) {
  for (int n = 1; n <= MAXDIV; n++) {
    double d = hatch / n;
    int ok = 1;
    for (int r = 0; r < GR_NREGIONS && ok; r++) {
      double sr = (r && (mask >> r & 1) && s[r] > 0) ? s[r] : hatch, m = sr / d;
      step[r] = (int)fmin(round(m), MAXSTEP + 1);
      ok = step[r] >= 1 && step[r] <= MAXSTEP && fabs(m - step[r]) <= 1e-6 * m;
    }
    if (ok) { *d0 = d; return GR_OK; }
  }
  char list[256];
  int len = snprintf(list, sizeof list, "%g (the job's)", hatch);
  for (int r = 1; r < GR_NREGIONS; r++)
    if ((mask >> r & 1) && s[r] > 0 && len < (int)sizeof list)
      len += snprintf(list + len, sizeof list - (size_t)len, ", %g (%s)", s[r], gr_region_name(r));
  return gr_fail(e, GR_EARG,
                 "regions: the hatch spacings %s mm have no common line spacing: each must be a whole multiple "
                 "(at most %d) of the job's hatch / n, n = 1..%d (e.g. 0.05 with 0.025, 0.1 or 0.075)",
                 list, MAXSTEP, MAXDIV);
}

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
  if (o->hatch[GR_CORE] != 0 && fabs(o->hatch[GR_CORE] - j->o.hatch) > 1e-9 * j->o.hatch)
    return gr_fail(e, GR_EARG, "regions: the core hatches at the job's spacing %g mm, got %g", j->o.hatch,
                   o->hatch[GR_CORE]);
  for (int r = 1; r < GR_NREGIONS; r++) {
    if (o->hatch[r] == 0) continue;
    if (!((o->mask >> r & 1) && (HATCHED >> r & 1)))
      return gr_fail(e, GR_EARG, "regions: a hatch spacing for region %s, which %s", gr_region_name(r),
                     (HATCHED >> r & 1) ? "is not asked for" : "has no hatches");
    if (!(isfinite(o->hatch[r]) && o->hatch[r] > 0))
      return gr_fail(e, GR_EARG, "regions: the hatch spacing of region %s must be > 0 mm, got %g", gr_region_name(r),
                     o->hatch[r]);
  }
  if (o->skin_contours != 0 && !((o->mask >> GR_SKIN & 1) && o->skin_contours >= j->o.contours && o->skin_contours <= 20))
    return gr_fail(e, GR_EARG, "regions: the skin's contours must be the job's %d .. 20 and need the skin region, got %d",
                   j->o.contours, o->skin_contours);
  double d0 = 0;
  int step[GR_NREGIONS];
  if (line_family(j->o.hatch, o->hatch, o->mask, &d0, step, e)) return e->code;
  gr_regions_free(j->regions);
  j->regions = NULL;
  for (int r = 1; r < GR_NREGIONS; r++) j->m.rspeed[r] = 0;
  if (!o->mask) return GR_OK;
  struct gr_regions *g = calloc(1, sizeof *g);
  if (!g) return gr_fail(e, GR_EMEM, "out of memory");
  g->o = *o;
  g->line = d0;
  memcpy(g->step, step, sizeof step);
  if (!(o->mask & (1 << GR_DOWNSKIN))) g->o.down = 0;
  if (!(o->mask & (1 << GR_UPSKIN))) g->o.up = 0;
  pthread_mutex_init(&g->mu, NULL);
  for (int r = 1; r < GR_NREGIONS; r++) j->m.rspeed[r] = (o->mask >> r & 1) ? o->speed[r] : 0;
  j->regions = g;
  return GR_OK;
}

int gr_regions_mask(const gr_job *j) { return j->regions ? j->regions->o.mask : 0; }

int gr_regions_skin_contours(const gr_job *j) {
  return j->regions && j->regions->o.skin_contours > 0 ? j->regions->o.skin_contours : j->o.contours;
}

double gr_job_window(const gr_job *j) { return gr_tmpl_window(&j->o, gr_regions_skin_contours(j)); }

pthread_mutex_t *gr_regions_mutex(gr_job *j) {
  return j->regions && !gr_field_threadsafe(j->domain) ? &j->regions->mu : NULL;
}

double gr_regions_line(const gr_job *j) { return j->regions ? j->regions->line : j->o.hatch; }

double gr_regions_hatch(const gr_job *j, int r) {
  return j->regions && r >= 0 && r < GR_NREGIONS ? j->regions->line * j->regions->step[r] : j->o.hatch;
}

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
/* Where the hatch lines lmin..lmin+nl-1 of the voxel cross the rings of a
 * neighbouring layer: per line, the crossings' positions s along the line
 * (sorted, s[off[k]] .. s[off[k+1]]). Even-odd: a point of a line is inside
 * when an odd number of crossings lie before it. */
typedef struct nbr {
  int state;
  const gr_rings *r;
  size_t *off;
  double *s;
} nbr;

int gr_regions_solid(const gr_job *j, int v, int g2, int section, int *state, const gr_rings **r, gr_err *e) {
  *r = NULL;
  *state = GR_SOLID_NONE;
  if (g2 < 1) { *state = GR_SOLID_PLATE; return GR_OK; } /* the build plate */
  if (g2 > j->nlayers) return GR_OK;
  int i, jj, k, kk = gr_grid_layer_row(&j->grid, g2);
  gr_grid_ijk(&j->grid, v, &i, &jj, &k);
  int v2 = i + j->grid.n[0] * (jj + j->grid.n[1] * kk);
  if (j->vcls[v2] < 0) return GR_OK;
  const gr_tmpl *t = j->cls[j->vcls[v2]].t;
  int jl = g2 - gr_grid_row_first(&j->grid, kk);
  if (!t || jl < t->j0 || jl >= t->j0 + t->nl)
    return gr_fail(e, GR_EARG, "internal: regions need layer %d's template (voxel %d)", g2, v2);
  const gr_rings *rr = section ? t->l[jl - t->j0].section : t->l[jl - t->j0].region;
  if (rr && rr->nrings > 0) { *state = GR_SOLID_RINGS; *r = rr; }
  return GR_OK;
}

/* Layer g2's solid (hatch region) in the column of voxel v (rings voxel-local). */
static int neighbour(const gr_job *j, int v, int g2, nbr *out, gr_err *e) {
  int st;
  if (gr_regions_solid(j, v, g2, 0, &st, &out->r, e)) return e->code;
  out->state = st == GR_SOLID_PLATE ? SOLID : st == GR_SOLID_NONE ? VOID : RINGS;
  return GR_OK;
}

/* The line family: direction (ca, sa), spacing d, lines lmin .. lmin+nl-1;
 * the rings are offset by (ox, oy) to global coordinates. */
typedef struct fam { double ca, sa, d, ox, oy; long lmin, nl; } fam;

/* Lines k of the edge from A to B (global): lo <= k d < hi, clamped. */
static void edge_lines(const fam *f, double na, double nb, long *k0, long *k1) {
  double lo = fmin(na, nb), hi = fmax(na, nb);
  long a = (long)ceil(lo / f->d), b = (long)floor(hi / f->d);
  if (b * f->d >= hi) b--;
  *k0 = a > f->lmin ? a : f->lmin;
  *k1 = b < f->lmin + f->nl - 1 ? b : f->lmin + f->nl - 1;
}

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Fill n->off and n->s for the family f (two passes: count, then place). */
static int crossings(nbr *n, const fam *f) {
  n->off = calloc((size_t)f->nl + 1, sizeof *n->off);
  if (!n->off) return GR_EMEM;
  for (int pass = 0; pass < 2; pass++) {
    for (size_t q = 0; q < n->r->nrings; q++) {
      const double *p = gr_ring_xy(n->r, q);
      size_t m = gr_ring_len(n->r, q);
      for (size_t a = 0; a < m; a++) {
        const double *A = p + 2 * a, *B = p + 2 * ((a + 1) % m);
        double ax = A[0] + f->ox, ay = A[1] + f->oy, bx = B[0] + f->ox, by = B[1] + f->oy;
        double na = -ax * f->sa + ay * f->ca, nb = -bx * f->sa + by * f->ca;
        if (na == nb) continue;
        double sa = ax * f->ca + ay * f->sa, sb = bx * f->ca + by * f->sa;
        long k0, k1;
        edge_lines(f, na, nb, &k0, &k1);
        for (long k = k0; k <= k1; k++) {
          size_t slot = (size_t)(k - f->lmin);
          if (pass == 0) { n->off[slot + 1]++; continue; }
          double t = (k * f->d - na) / (nb - na);
          n->s[n->off[slot]++] = sa + t * (sb - sa);
        }
      }
    }
    if (pass == 0) {
      for (long k = 0; k < f->nl; k++) n->off[k + 1] += n->off[k];
      n->s = malloc((n->off[f->nl] + 1) * sizeof *n->s);
      if (!n->s) return GR_EMEM;
    } else { /* off[k] advanced to the end of line k: shift back */
      for (long k = f->nl; k > 0; k--) n->off[k] = n->off[k - 1];
      n->off[0] = 0;
    }
  }
  for (long k = 0; k < f->nl; k++) qsort(n->s + n->off[k], n->off[k + 1] - n->off[k], sizeof *n->s, cmp_dbl);
  return GR_OK;
}

/* Crossings of line slot k before position s. */
static size_t before(const nbr *n, long k, double s) {
  size_t lo = n->off[k], hi = n->off[k + 1];
  while (lo < hi) {
    size_t mid = (lo + hi) / 2;
    if (n->s[mid] < s) lo = mid + 1; else hi = mid;
  }
  return lo - n->off[k];
}

static int inside(const nbr *n, long k, double s) {
  return n->state == SOLID || (n->state == RINGS && (before(n, k, s) & 1));
}

/* ---- cutting one segment ---- */
typedef struct cutbuf { double *t; size_t n, cap; } cutbuf;

static int add_cut(cutbuf *c, double t) {
  if (!(t > 1e-12 && t < 1 - 1e-12)) return GR_OK;
  if (gr_grow(&c->t, &c->cap, c->n + 1, sizeof *c->t)) return GR_EMEM;
  c->t[c->n++] = t;
  return GR_OK;
}

typedef struct vctx {
  gr_job *j;
  nbr nb[2 * MAXN];
  int nbelow, nabove;
  fam f;
  double z;           /* layer middle, mm (domain) */
  int skin;           /* the skin test applies */
  int mask;
  gr_skinring *sr;    /* the skin's contour band (NULL: none) */
} vctx;

static int dom_eval(vctx *c, size_t n, const double *x, const double *y, double *f, gr_err *e) {
  double zz[16];
  for (size_t q = 0; q < n; q++) zz[q] = c->z;
  pthread_mutex_t *mu = gr_regions_mutex(c->j);
  if (mu) pthread_mutex_lock(mu);
  int rc = gr_field_eval(c->j->domain, n, x, y, zz, f, e);
  if (mu) pthread_mutex_unlock(mu);
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

/* Where the segment enters or leaves the skin's contour band (skinring.h):
 * samples every hatch / 2, each change bisected. */
static int drop_cuts(vctx *c, const double p0[2], const double p1[2], cutbuf *cb, gr_err *e) {
  double len = hypot(p1[0] - p0[0], p1[1] - p0[1]);
  int m = (int)ceil(len / (0.5 * c->j->o.hatch));
  if (m < 1) m = 1;
  int prev = 0;
  for (int a = 0; a <= m; a++) {
    double t = (double)a / m;
    int d = gr_skinring_drop(c->sr, p0[0] + t * (p1[0] - p0[0]), p0[1] + t * (p1[1] - p0[1]), e);
    if (d < 0) return -d;
    if (a > 0 && d != prev) {
      double lo = (double)(a - 1) / m, hi = t;
      for (int it = 0; it < 40; it++) {
        double mid = 0.5 * (lo + hi);
        int dm = gr_skinring_drop(c->sr, p0[0] + mid * (p1[0] - p0[0]), p0[1] + mid * (p1[1] - p0[1]), e);
        if (dm < 0) return -dm;
        if (dm == prev) lo = mid; else hi = mid;
      }
      if (add_cut(cb, 0.5 * (lo + hi))) return gr_fail(e, GR_EMEM, "out of memory");
    }
    prev = d;
  }
  return GR_OK;
}

/* The region of the point at position s of line k (global (x, y)). */
static int region_at(vctx *c, long k, double s, double x, double y, int *reg, gr_err *e) {
  long slot = k - c->f.lmin;
  if (c->sr) { /* within the skin's contour band: not hatched */
    int d = gr_skinring_drop(c->sr, x, y, e);
    if (d < 0) return -d;
    if (d) { *reg = DROP; return GR_OK; }
  }
  int down = 0, up = 0;
  for (int i = 0; i < c->nbelow && !down; i++) down = !inside(&c->nb[i], slot, s);
  for (int i = 0; i < c->nabove && !up; i++) up = !inside(&c->nb[c->nbelow + i], slot, s);
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

/* Append piece [ta, tb] of segment s (parameters along it) with region reg,
 * unless s's line is not one of reg's (step[reg]). */
static int put_piece(const vctx *c, const gr_hseg *s, double ta, double tb, int reg, gr_hseg **out, size_t *n,
                     size_t *cap, gr_err *e) {
  if (reg == DROP) return GR_OK;
  long m = c->j->regions->step[reg];
  if (m > 1 && ((s->line % m) + m) % m != 0) return GR_OK;
  if (gr_grow(out, cap, *n + 1, sizeof **out)) return gr_fail(e, GR_EMEM, "out of memory");
  gr_hseg *p = &(*out)[(*n)++];
  *p = *s;
  p->x0 = s->x0 + ta * (s->x1 - s->x0); p->y0 = s->y0 + ta * (s->y1 - s->y0);
  p->s0 = s->s0 + ta * (s->s1 - s->s0);
  if (tb < 1) {
    p->x1 = s->x0 + tb * (s->x1 - s->x0); p->y1 = s->y0 + tb * (s->y1 - s->y0);
    p->s1 = s->s0 + tb * (s->s1 - s->s0);
  }
  p->region = reg;
  return GR_OK;
}

/* Append the pieces of segment s (cut by region) to out[*n]. */
static int split_one(vctx *c, const gr_hseg *s, cutbuf *cb, gr_hseg **out, size_t *n, size_t *cap, gr_err *e) {
  double p0[2] = {s->x0, s->y0}, p1[2] = {s->x1, s->y1}, len = s->s1 - s->s0;
  long slot = s->line - c->f.lmin;
  cb->n = 0;
  for (int i = 0; i < c->nbelow + c->nabove && len > 0; i++) {
    const nbr *nb = &c->nb[i];
    if (nb->state != RINGS) continue;
    for (size_t q = nb->off[slot] + before(nb, slot, s->s0); q < nb->off[slot + 1] && nb->s[q] < s->s1; q++)
      if (add_cut(cb, (nb->s[q] - s->s0) / len)) return gr_fail(e, GR_EMEM, "out of memory");
  }
  if (c->skin && skin_cuts(c, p0, p1, cb, e)) return e->code;
  if (c->sr && drop_cuts(c, p0, p1, cb, e)) return e->code;
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
    if (region_at(c, s->line, s->s0 + tm * len, p0[0] + tm * (p1[0] - p0[0]), p0[1] + tm * (p1[1] - p0[1]), &reg, e))
      return e->code;
    if (cur >= 0 && reg != cur) {
      if (put_piece(c, s, ta, t0, cur, out, n, cap, e)) return e->code;
      ta = t0;
    }
    cur = reg;
  }
  return put_piece(c, s, ta, 1, cur < 0 ? GR_CORE : cur, out, n, cap, e);
}

static void free_nbrs(vctx *c) {
  for (int i = 0; i < c->nbelow + c->nabove; i++) {
    free(c->nb[i].off);
    free(c->nb[i].s);
  }
}

/* The voxel's line family (from its first segment: s0 < s1 gives the
 * direction) and the neighbours' crossings on it. */
static int prepare(vctx *c, int g, int v, const gr_hseg *sg, size_t m, gr_err *e) {
  gr_job *j = c->j;
  for (int i = 0; i < c->nbelow; i++)
    if (neighbour(j, v, g - 1 - i, &c->nb[i], e)) return e->code;
  for (int i = 0; i < c->nabove; i++)
    if (neighbour(j, v, g + 1 + i, &c->nb[c->nbelow + i], e)) return e->code;
  double o[3];
  gr_grid_origin(&j->grid, v, o);
  double dx = sg[0].x1 - sg[0].x0, dy = sg[0].y1 - sg[0].y0, l = hypot(dx, dy);
  long lo = sg[0].line, hi = sg[0].line;
  for (size_t q = 1; q < m; q++) {
    if (sg[q].line < lo) lo = sg[q].line;
    if (sg[q].line > hi) hi = sg[q].line;
  }
  c->f = (fam){dx / l, dy / l, j->regions->line, o[0], o[1], lo, hi - lo + 1};
  c->z = gr_grid_mid(&j->grid, g);
  for (int i = 0; i < c->nbelow + c->nabove; i++)
    if (c->nb[i].state == RINGS && crossings(&c->nb[i], &c->f)) return gr_fail(e, GR_EMEM, "out of memory");
  return GR_OK;
}

int gr_regions_split(gr_job *j, int g, int v, gr_skinring *sr, gr_hseg **segs, size_t *n, size_t *cap, size_t a,
                     gr_err *e) {
  int mask = gr_regions_mask(j);
  if (!(mask & HATCHED) || *n <= a) return GR_OK;
  vctx c;
  memset(&c, 0, sizeof c);
  c.j = j;
  c.mask = mask;
  c.nbelow = j->regions->o.down;
  c.nabove = j->regions->o.up;
  c.skin = (mask >> GR_SKIN & 1) && j->skin > 0 && j->domain && j->cls[j->vcls[v]].trimmed;
  c.sr = sr;
  size_t m = *n - a;
  gr_hseg *orig = malloc(m * sizeof *orig);
  int rc = orig ? prepare(&c, g, v, *segs + a, m, e) : gr_fail(e, GR_EMEM, "out of memory");
  if (rc == GR_OK) {
    memcpy(orig, *segs + a, m * sizeof *orig);
    *n = a;
  }
  cutbuf cb = {NULL, 0, 0};
  for (size_t q = 0; q < m && rc == GR_OK; q++) rc = split_one(&c, &orig[q], &cb, segs, n, cap, e);
  free(cb.t);
  free(orig);
  free_nbrs(&c);
  return rc;
}
