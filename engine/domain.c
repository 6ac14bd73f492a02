/* domain.c: a design domain's field made a signed distance, see domain.h. */
#include "domain.h"
#include "bvh.h"
#include "mc.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DOM_ITERS 60     /* projection rounds (most points stop after 2-5) */
#define DOM_FAR 1e6      /* mm: the value where the gradient vanishes */
#define DOM_SAG 0.05     /* of the mesh spacing: how much farther a re-projected foot may be */

typedef struct dom {
  gr_field *f;
  double band;  /* mm: exact distances below this */
  double tol;   /* mm: convergence of the closest point */
  gr_mesh *zm;  /* f = 0 near the part's box (marching cubes), or NULL */
  double zh;    /* its sample spacing, mm */
  gr_bvh *zb;   /* its closest points */
} dom;

/* An error of the domain's own field, said to come from the domain. */
static int dom_fail(gr_err *e) { return gr_err_prefix(e, "domain"); }

/* Value and gradient of f at n points, the gradient by forward differences
 * (3 evaluations more, where central differences take 6; step
 * 1e-7 of the coordinates' size: a relative error near 1e-8, which moves the
 * closest point by less than 1e-7 of the distance). s: 3n scratch. */
static int value_grad(const gr_field *f, size_t n, const double *x, const double *y, const double *z, double *v,
                      double *gx, double *gy, double *gz, double *s, gr_err *e) {
  if (gr_field_eval(f, n, x, y, z, v, e)) return e->code;
  double *h = s, *c = s + n, *fv = s + 2 * n;
  for (int a = 0; a < 3; a++) {
    const double *src = a == 0 ? x : a == 1 ? y : z;
    double *g = a == 0 ? gx : a == 1 ? gy : gz;
    for (size_t i = 0; i < n; i++) {
      double st = 1e-7 * fmax(1.0, fabs(src[i]));
      c[i] = src[i] + st;
      h[i] = c[i] - src[i]; /* the step actually taken */
    }
    if (gr_field_eval(f, n, a == 0 ? c : x, a == 1 ? c : y, a == 2 ? c : z, fv, e)) return e->code;
    for (size_t i = 0; i < n; i++) g[i] = (fv[i] - v[i]) / h[i];
  }
  return GR_OK;
}

/* Scratch of n points: value, gradient and the moving foot points. */
typedef struct dom_work {
  double *v, *gx, *gy, *gz, *qx, *qy, *qz, *s;
  size_t *act;
} dom_work;

static int work_new(dom_work *w, size_t n) {
  double *b = malloc((n ? n : 1) * 10 * sizeof *b);
  w->act = malloc((n ? n : 1) * sizeof *w->act);
  if (!b || !w->act) { free(b); free(w->act); return GR_EMEM; }
  w->v = b, w->gx = b + n, w->gy = b + 2 * n, w->gz = b + 3 * n;
  w->qx = b + 4 * n, w->qy = b + 5 * n, w->qz = b + 6 * n, w->s = b + 7 * n;
  return GR_OK;
}
static void work_free(dom_work *w) {
  free(w->v);
  free(w->act);
}

/* Project the m points act[] (p given, q started at p, the value and gradient
 * there packed in w's arrays) onto f = 0 together:
 * q <- p - ((f(q) + grad f(q).(p - q)) / |grad f(q)|^2) grad f(q). Writes
 * |p - q| into out[] for those that converge; the others keep out[] (the
 * first-order estimate). Uses w's value/gradient arrays as scratch, packed
 * in the order of the active points. */
/* Converged feet waiting for the sign check (crossing). */
typedef struct dom_feet {
  size_t n, *i;
  double *d, *q; /* distance; foot xyz */
} dom_feet;

/* A foot counts only where the domain's sign changes across it: a zero of f
 * that is not a boundary (f <= 0 on both sides, as on the shared face of two
 * boxes joined by min) is not a closest point of the domain; those points keep
 * the first-order estimate. Probes each foot a small step beyond it, away
 * from p. */
static int check_feet(const dom *d, const double *x, const double *y, const double *z, const dom_feet *c,
                      dom_work *w, const double *sg, double *out, gr_err *e) {
  double step = 1e4 * d->tol;
  for (size_t k = 0; k < c->n; k++) {
    size_t i = c->i[k];
    const double *q = c->q + 3 * k;
    double r = c->d[k];
    w->qx[k] = q[0] + step * (q[0] - x[i]) / r;
    w->qy[k] = q[1] + step * (q[1] - y[i]) / r;
    w->qz[k] = q[2] + step * (q[2] - z[i]) / r;
  }
  if (c->n && gr_field_eval(d->f, c->n, w->qx, w->qy, w->qz, w->v, e)) return dom_fail(e);
  for (size_t k = 0; k < c->n; k++) {
    size_t i = c->i[k];
    if (sg[i] < 0 ? w->v[k] > 0 : w->v[k] < 0) out[i] = c->d[k]; /* sg: the sign of f(p) */
  }
  return GR_OK;
}

static int project(const dom *d, const double *x, const double *y, const double *z, dom_work *w, size_t m,
                   double *out, dom_feet *c, gr_err *e) {
  for (int it = 0; it < DOM_ITERS && m > 0; it++) {
    /* the active feet are packed at the front of qx, qy, qz */
    /* round 0 starts at q = p, whose value and gradient the caller packed */
    if (it > 0 && value_grad(d->f, m, w->qx, w->qy, w->qz, w->v, w->gx, w->gy, w->gz, w->s, e)) return dom_fail(e);
    size_t keep = 0;
    for (size_t k = 0; k < m; k++) {
      size_t i = w->act[k];
      double g[3] = {w->gx[k], w->gy[k], w->gz[k]}, g2 = gr_dot3(g, g);
      if (!(g2 > 1e-300)) continue; /* a critical point: keep the estimate */
      double r[3] = {x[i] - w->qx[k], y[i] - w->qy[k], z[i] - w->qz[k]};
      double lam = (w->v[k] + gr_dot3(g, r)) / g2;
      double q[3] = {x[i] - lam * g[0], y[i] - lam * g[1], z[i] - lam * g[2]};
      double step = sqrt((q[0] - w->qx[k]) * (q[0] - w->qx[k]) + (q[1] - w->qy[k]) * (q[1] - w->qy[k]) +
                         (q[2] - w->qz[k]) * (q[2] - w->qz[k]));
      double dist = fabs(lam) * sqrt(g2);
      if (!isfinite(step) || dist > 4 * d->band) continue; /* ran off: the estimate stands */
      if (step < d->tol && fabs(w->v[k]) < d->tol * sqrt(g2)) {
        if (dist > 0) { /* checked below: a foot where f changes sign */
          c->i[c->n] = i, c->d[c->n] = dist;
          c->q[3 * c->n] = q[0], c->q[3 * c->n + 1] = q[1], c->q[3 * c->n + 2] = q[2];
          c->n++;
        } else {
          out[i] = 0;
        }
        continue;
      }
      w->act[keep] = i;
      w->qx[keep] = q[0], w->qy[keep] = q[1], w->qz[keep] = q[2];
      keep++;
    }
    m = keep;
  }
  return GR_OK;
}

/* Point i as the m-th projection to run, started at p itself (its value and
 * gradient already in w at i): packed in place, m <= i, so the entries below
 * i have been read already. */
static void pack_start(dom_work *w, size_t m, size_t i, const double *x, const double *y, const double *z) {
  w->act[m] = i;
  w->qx[m] = x[i], w->qy[m] = y[i], w->qz[m] = z[i];
  w->v[m] = w->v[i], w->gx[m] = w->gx[i], w->gy[m] = w->gy[i], w->gz[m] = w->gz[i];
}

/* With the zero set's mesh (f is not a distance): the mesh's closest point
 * within the band says how far the boundary is (nothing within the band: at
 * least the band away); the exact distance is the nearer of two projections,
 * one from p and one from the mesh's closest point (which starts on the
 * nearest branch where f is the max or min of terms of different scales, so
 * that f's own gradient at p points to a farther one), each kept only where f
 * changes sign across its foot, and taken when it is no farther than the
 * mesh distance plus DOM_SAG x the spacing (the chords' sag, for radii above
 * about 0.06 mm at the 0.05 mm spacing). Otherwise the mesh distance stands
 * (at edges and corners of the domain, which the mesh cuts and no projection
 * reaches). mq: 3n scratch. */
static int mesh_eval(const dom *d, size_t n, const double *x, const double *y, const double *z, dom_work *w,
                     dom_feet *c, const double *sg, double *out, double *dm, double *ra, double *rb, double *mq,
                     gr_err *e) {
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    double v = w->v[i], g = sqrt(w->gx[i] * w->gx[i] + w->gy[i] * w->gy[i] + w->gz[i] * w->gz[i]);
    double p[3] = {x[i], y[i], z[i]};
    ra[i] = rb[i] = dm[i] = NAN;
    if (v == 0) { out[i] = 0; continue; }
    gr_hit h;
    gr_bvh_closest(d->zb, p, d->band, &h);
    if (h.tri < 0) {
      out[i] = fmax(g > 0 ? fmin(fabs(v) / g, DOM_FAR) : DOM_FAR, d->band);
      continue;
    }
    dm[i] = out[i] = h.dist;
    memcpy(mq + 3 * i, h.q, sizeof h.q);
    if (!(g > 0)) continue;
    pack_start(w, m++, i, x, y, z);
  }
  c->n = 0;
  int rc = project(d, x, y, z, w, m, ra, c, e);
  if (rc == GR_OK) rc = check_feet(d, x, y, z, c, w, sg, ra, e);
  m = 0;
  for (size_t i = 0; i < n; i++)
    if (!isnan(dm[i])) {
      w->act[m] = i;
      w->qx[m] = mq[3 * i], w->qy[m] = mq[3 * i + 1], w->qz[m] = mq[3 * i + 2];
      m++;
    }
  if (rc == GR_OK && m && value_grad(d->f, m, w->qx, w->qy, w->qz, w->v, w->gx, w->gy, w->gz, w->s, e))
    rc = dom_fail(e);
  c->n = 0;
  if (rc == GR_OK) rc = project(d, x, y, z, w, m, rb, c, e);
  if (rc == GR_OK) rc = check_feet(d, x, y, z, c, w, sg, rb, e);
  for (size_t i = 0; i < n; i++) {
    double best = fmin(ra[i], rb[i]); /* fmin ignores a NaN: no foot */
    if (!isnan(dm[i]) && best <= dm[i] + DOM_SAG * d->zh) out[i] = best;
  }
  return rc;
}

/* Without a mesh: the first-order estimate, f itself where |grad f| = 1,
 * and the projection from p below the band. */
static int plain_eval(const dom *d, size_t n, const double *x, const double *y, const double *z, dom_work *w,
                      dom_feet *c, const double *sg, double *out, gr_err *e) {
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    double v = w->v[i], g = sqrt(w->gx[i] * w->gx[i] + w->gy[i] * w->gy[i] + w->gz[i] * w->gz[i]);
    double est = g > 0 ? fabs(v) / g : DOM_FAR;
    out[i] = fmin(est, DOM_FAR);
    if (v == 0) { out[i] = 0; continue; }
    /* no gradient: a crease of min/max (two planes tie and the one-sided
     * differences cancel) or a critical point: |f| (a distance on creases) */
    if (!(g > 0)) { out[i] = fabs(v); continue; }
    /* |grad f| = 1: f is already a distance near p (planes joined by min and
     * max, a sphere written with sqrt): kept as it is. Projecting along such a
     * field's gradient would land on box corners and inner faces. */
    if (fabs(g - 1) < 1e-6) { out[i] = fabs(v); continue; }
    if (est >= d->band) { out[i] = fmax(out[i], d->band); continue; }
    pack_start(w, m++, i, x, y, z);
  }
  int rc = project(d, x, y, z, w, m, out, c, e);
  return rc ? rc : check_feet(d, x, y, z, c, w, sg, out, e);
}

static int dom_eval(void *ud, size_t n, const double *x, const double *y, const double *z, double *out,
                    gr_err *e) {
  const dom *d = ud;
  dom_work w;
  if (work_new(&w, n)) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = value_grad(d->f, n, x, y, z, w.v, w.gx, w.gy, w.gz, w.s, e);
  if (rc) {
    work_free(&w);
    return dom_fail(e);
  }
  size_t nn = n ? n : 1;
  double *sg = malloc(nn * (d->zb ? 7 : 1) * sizeof *sg);
  dom_feet c = {0, malloc(nn * sizeof *c.i), malloc(nn * 4 * sizeof *c.d), NULL};
  if (!sg || !c.i || !c.d) rc = gr_fail(e, GR_EMEM, "out of memory");
  c.q = c.d ? c.d + n : NULL;
  for (size_t i = 0; rc == GR_OK && i < n; i++) sg[i] = w.v[i] < 0 ? -1 : 1;
  if (rc == GR_OK)
    rc = d->zb ? mesh_eval(d, n, x, y, z, &w, &c, sg, out, sg + n, sg + 2 * n, sg + 3 * n, sg + 4 * n, e)
               : plain_eval(d, n, x, y, z, &w, &c, sg, out, e);
  for (size_t i = 0; rc == GR_OK && i < n; i++) out[i] *= sg[i];
  free(c.i);
  free(c.d);
  free(sg);
  work_free(&w);
  return rc;
}

/* With a zero-set mesh the distance may come from another branch than f's
 * gradient points to (max of terms of different scales): central
 * differences of the distance itself, step 1e-6 mm x max(cell, 1). */
static int dist_diff(void *ud, size_t n, const double *x, const double *y, const double *z, double *gx, double *gy,
                     double *gz, gr_err *e) {
  const dom *d = ud;
  double *b = calloc((n ? n : 1) * 3, sizeof *b), st = 1e3 * d->tol;
  if (!b) return gr_fail(e, GR_EMEM, "out of memory");
  double *c = b, *lo = b + n, *hi = b + 2 * n;
  int rc = GR_OK;
  for (int a = 0; a < 3 && rc == GR_OK; a++) {
    const double *src = a == 0 ? x : a == 1 ? y : z;
    double *g = a == 0 ? gx : a == 1 ? gy : gz;
    for (size_t i = 0; i < n; i++) c[i] = src[i] - st;
    rc = dom_eval(ud, n, a == 0 ? c : x, a == 1 ? c : y, a == 2 ? c : z, lo, e);
    for (size_t i = 0; i < n; i++) c[i] = src[i] + st;
    if (rc == GR_OK) rc = dom_eval(ud, n, a == 0 ? c : x, a == 1 ? c : y, a == 2 ? c : z, hi, e);
    for (size_t i = 0; rc == GR_OK && i < n; i++) g[i] = (hi[i] - lo[i]) / (2 * st);
  }
  free(b);
  return rc;
}

/* The unit normal grad f / |grad f| (the gradient of the distance where it
 * is one), 0 at critical points. */
static int dom_grad(void *ud, size_t n, const double *x, const double *y, const double *z, double *gx, double *gy,
                    double *gz, gr_err *e) {
  const dom *d = ud;
  if (d->zb) return dist_diff(ud, n, x, y, z, gx, gy, gz, e);
  if (gr_field_grad(d->f, n, x, y, z, gx, gy, gz, e)) return dom_fail(e);
  for (size_t i = 0; i < n; i++) {
    double g = sqrt(gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]);
    if (g > 0) gx[i] /= g, gy[i] /= g, gz[i] /= g;
  }
  return GR_OK;
}

static void dom_free(void *ud) {
  dom *d = ud;
  gr_bvh_free(d->zb);
  gr_mesh_free(d->zm);
  gr_field_free(d->f);
  free(d);
}

/* f's zero set over the box grown by the band (marching cubes with the
 * crossings refined onto f = 0), spacing min(L/40, band/8) mm, coarser only
 * to stay within DOM_MESH_NODES samples. An empty zero set leaves no mesh. */
#define DOM_MESH_NODES 2e7
static int zero_mesh(dom *d, const double box[6], double L, gr_err *e) {
  double lo[3], hi[3], vol = 1, h = fmin(L / 40, d->band / 8);
  for (int k = 0; k < 3; k++) {
    lo[k] = box[k] - d->band - h, hi[k] = box[3 + k] + d->band + h;
    vol *= hi[k] - lo[k];
  }
  if (vol / (h * h * h) > DOM_MESH_NODES) h = cbrt(vol / DOM_MESH_NODES);
  int n[3];
  for (int k = 0; k < 3; k++) n[k] = (int)ceil((hi[k] - lo[k]) / h) + 1;
  d->zh = h;
  d->zm = gr_mc_field(d->f, lo, hi, n, 1, e);
  if (!d->zm) return dom_fail(e);
  if (d->zm->nf == 0) {
    gr_mesh_free(d->zm);
    d->zm = NULL;
    return GR_OK;
  }
  d->zb = gr_bvh_new(d->zm, e);
  return d->zb ? GR_OK : dom_fail(e);
}

/* Whether f is a distance already over the box: its gradient has length 1
 * (within 1e-4) at DOM_PROBES points of a Kronecker sequence (irrational
 * steps: no point lies on a symmetry plane such as x = 5 of abs(x-5), where
 * min/max and abs have creases). Planes and spheres joined by min, max and
 * abs pass; a squared form, a scaled distance or a mixture does not. A
 * handful of points may sit on creases, where the differences mix two
 * branches: 99 % must pass. 1 yes, 0 no, -1 an error (in e). */
#define DOM_PROBES 1000
static int unit_gradient_on(const gr_field *f, const double box[6], gr_err *e) {
  static const double a[3] = {0.8191725133961645, 0.6710436067037893, 0.5497004779019703};
  double *b = malloc(DOM_PROBES * 6 * sizeof *b);
  if (!b) return gr_fail(e, GR_EMEM, "out of memory"), -1;
  double *x = b, *y = b + DOM_PROBES, *z = b + 2 * DOM_PROBES, *g = b + 3 * DOM_PROBES;
  for (int i = 0; i < DOM_PROBES; i++) {
    double *c[3] = {x, y, z};
    for (int k = 0; k < 3; k++) {
      double t = 0.1234567 + (i + 1) * a[k];
      c[k][i] = box[k] + (box[3 + k] - box[k]) * (t - floor(t));
    }
  }
  int rc = gr_field_grad(f, DOM_PROBES, x, y, z, g, g + DOM_PROBES, g + 2 * DOM_PROBES, e);
  int unit = 0;
  for (int i = 0; rc == GR_OK && i < DOM_PROBES; i++) {
    double n = sqrt(g[i] * g[i] + g[DOM_PROBES + i] * g[DOM_PROBES + i] + g[2 * DOM_PROBES + i] * g[2 * DOM_PROBES + i]);
    unit += fabs(n - 1) <= 1e-4;
  }
  free(b);
  return rc != GR_OK ? -1 : unit >= DOM_PROBES * 99 / 100;
}

gr_field *gr_domain_distance(gr_field *f, double band, double L, const double *box, gr_err *e) {
  if (!f) return NULL;
  if (gr_field_lipschitz(f) <= 1 || gr_domain_is_distance(f)) return gr_field_ref(f);
  if (!(band > 0) || !(L > 0) || !isfinite(band) || !isfinite(L))
    return gr_fail(e, GR_EARG, "domain distance: band %g mm and cell %g mm must be > 0", band, L), NULL;
  if (box) {
    for (int k = 0; k < 3; k++)
      if (!isfinite(box[k]) || !isfinite(box[3 + k]) || !(box[3 + k] > box[k]))
        return gr_fail(e, GR_EARG, "domain distance: box %g..%g mm along %c is empty", box[k], box[3 + k], "xyz"[k]), NULL;
    int u = unit_gradient_on(f, box, e);
    if (u < 0) return dom_fail(e), NULL;
    if (u) return gr_field_ref(f);
  }
  dom *d = calloc(1, sizeof *d);
  if (!d) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  d->f = gr_field_ref(f);
  d->band = band;
  d->tol = 1e-9 * fmax(L, 1);
  if (box && zero_mesh(d, box, L, e)) {
    dom_free(d);
    return NULL;
  }
  char desc[256];
  snprintf(desc, sizeof desc, "%s", gr_field_describe(f));
  gr_field *r = gr_field_callback(dom_eval, dom_grad, d, dom_free, gr_field_threadsafe(f), desc);
  if (!r) {
    dom_free(d);
    return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  return r;
}

int gr_domain_is_distance(const gr_field *d) { return gr_field_callback_data(d, dom_eval) != NULL; }

/* ---- the trimmed part field ---- */

typedef struct trim {
  gr_field *g, *d;
  double skin;
} trim;

/* max(d, min(g, -d - skin)) (skin > 0) or max(g, d), from one evaluation of
 * each; sel (may be NULL) gets 1 where d decides, 2 where -d - skin does. */
void gr_domain_trim_apply(size_t n, double *v, const double *dv, double skin, unsigned char *sel) {
  for (size_t i = 0; i < n; i++) {
    int s = 0;
    if (skin > 0 && -dv[i] - skin < v[i]) v[i] = -dv[i] - skin, s = 2;
    if (dv[i] > v[i]) v[i] = dv[i], s = 1;
    if (sel) sel[i] = (unsigned char)s;
  }
}

static int trim_values(const trim *t, size_t n, const double *x, const double *y, const double *z, double *out,
                       double *dv, unsigned char *sel, gr_err *e) {
  if (gr_field_eval(t->g, n, x, y, z, out, e) || gr_field_eval(t->d, n, x, y, z, dv, e)) return e->code;
  gr_domain_trim_apply(n, out, dv, t->skin, sel);
  return GR_OK;
}

static int trim_eval(void *ud, size_t n, const double *x, const double *y, const double *z, double *out,
                     gr_err *e) {
  double *dv = malloc((n ? n : 1) * sizeof *dv);
  if (!dv) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = trim_values(ud, n, x, y, z, out, dv, NULL, e);
  free(dv);
  return rc;
}

/* The gradient of the branch that decides (g on ties, like min and max). */
static int trim_grad(void *ud, size_t n, const double *x, const double *y, const double *z, double *gx, double *gy,
                     double *gz, gr_err *e) {
  const trim *t = ud;
  double *b = malloc((n ? n : 1) * 5 * sizeof *b);
  unsigned char *sel = malloc(n ? n : 1);
  int rc = b && sel ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  if (rc == GR_OK) rc = trim_values(t, n, x, y, z, b, b + n, sel, e);
  if (rc == GR_OK) rc = gr_field_grad(t->g, n, x, y, z, gx, gy, gz, e);
  if (rc == GR_OK) rc = gr_field_grad(t->d, n, x, y, z, b, b + n, b + 2 * n, e);
  for (size_t i = 0; rc == GR_OK && i < n; i++) {
    double s = sel[i] == 1 ? 1 : sel[i] == 2 ? -1 : 0;
    if (s != 0) gx[i] = s * b[i], gy[i] = s * b[n + i], gz[i] = s * b[2 * n + i];
  }
  free(b);
  free(sel);
  return rc;
}

static void trim_free(void *ud) {
  trim *t = ud;
  gr_field_free(t->g);
  gr_field_free(t->d);
  free(t);
}

gr_field *gr_domain_trim(gr_field *g, gr_field *d, double skin, gr_err *e) {
  trim *t = malloc(sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  t->g = gr_field_ref(g);
  t->d = gr_field_ref(d);
  t->skin = skin > 0 ? skin : 0;
  char desc[256];
  snprintf(desc, sizeof desc, "trim(%.100s, %.100s, skin=%g)", gr_field_describe(g), gr_field_describe(d), t->skin);
  gr_field *f = gr_field_callback(trim_eval, trim_grad, t, trim_free,
                                  gr_field_threadsafe(g) && gr_field_threadsafe(d), desc);
  if (!f) {
    trim_free(t);
    return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  return f;
}

int gr_domain_trim_parts(const gr_field *f, const gr_field **g, const gr_field **d, double *skin) {
  const trim *t = gr_field_callback_data(f, trim_eval);
  if (!t) return 0;
  *g = t->g, *d = t->d, *skin = t->skin;
  return 1;
}

/* ---- the domain on a plane grid, exact only near its boundary ---- */

#define GRID_BLOCK 4      /* nodes per block side: one sample decides a block */
#define GRID_LIP_SAFETY 1.5 /* on a bound estimated from gradients (as classify.c does) */

/* d's Lipschitz bound over the samples (x, y, z): known, 1 for the distance
 * wrapper (whose values beyond its band are only clamped to it: *clamp),
 * else the largest gradient there times a safety factor (INFINITY if none
 * can be had: every node is then evaluated). */
static double grid_lipschitz(const gr_field *d, size_t n, const double *x, const double *y, const double *z,
                             double *s, double *clamp) {
  const dom *w = gr_field_callback_data(d, dom_eval);
  *clamp = INFINITY;
  if (w) {
    *clamp = w->zb ? w->band : 0; /* without the zero-set mesh the far values bound nothing */
    return 1;
  }
  double K = gr_field_lipschitz(d), g = 0;
  if (isfinite(K)) return K;
  gr_err e2;
  gr_err_clear(&e2);
  if (gr_field_grad(d, n, x, y, z, s, s + n, s + 2 * n, &e2)) return INFINITY;
  for (size_t i = 0; i < n; i++) g = fmax(g, sqrt(s[i] * s[i] + s[n + i] * s[n + i] + s[2 * n + i] * s[2 * n + i]));
  return isfinite(g) && g > 0 ? GRID_LIP_SAFETY * g : INFINITY;
}

/* d at the bx x by block centres (x, y, z) into v, row by row: a centre
 * whose distance is bounded from the last one evaluated in its row (|v| -
 * K x their distance, beyond `reach`) gets that bound with its sign instead
 * (a far region costs one evaluation in a few); without a bound (K
 * infinite) all in one batch. */
static int grid_samples(const gr_field *d, int bx, int by, const double *x, const double *y, const double *z,
                        double K, double clamp, double reach, double *v, gr_err *e) {
  size_t nb = (size_t)bx * by;
  if (!isfinite(K)) return gr_field_eval(d, nb, x, y, z, v, e) ? e->code : GR_OK;
  for (int j = 0; j < by; j++) {
    size_t last = SIZE_MAX;
    for (int i = 0; i < bx; i++) {
      size_t k = i + (size_t)bx * j;
      double a = last == SIZE_MAX ? 0 : fmin(fabs(v[last]), clamp) - K * hypot(x[k] - x[last], y[k] - y[last]);
      if (a > reach) { v[k] = v[last] < 0 ? -a : a; continue; }
      if (gr_field_eval(d, 1, x + k, y + k, z + k, v + k, e)) return e->code;
      last = k;
    }
  }
  return GR_OK;
}

/* Evaluate d at the m nodes idx[] of the grid into dv (batches of 256). */
static int grid_exact(const gr_field *d, const size_t *idx, size_t m, int nx, double z, double x0, double y0,
                      double hx, double hy, double *dv, gr_err *e) {
  enum { B = 256 };
  double x[B], y[B], zb[B], v[B];
  for (size_t s = 0; s < m; s += B) {
    size_t k = m - s < B ? m - s : B;
    for (size_t i = 0; i < k; i++) {
      size_t n = idx[s + i];
      x[i] = x0 + (double)(n % (size_t)nx) * hx, y[i] = y0 + (double)(n / (size_t)nx) * hy, zb[i] = z;
    }
    if (gr_field_eval(d, k, x, y, zb, v, e)) return e->code;
    for (size_t i = 0; i < k; i++) dv[idx[s + i]] = v[i];
  }
  return GR_OK;
}

int gr_domain_grid(const gr_field *d, double skin, double z, double x0, double y0, double hx, double hy, int nx,
                   int ny, double *dv, unsigned char *far_out, gr_err *e) {
  int bx = (nx + GRID_BLOCK - 1) / GRID_BLOCK, by = (ny + GRID_BLOCK - 1) / GRID_BLOCK;
  size_t nb = (size_t)bx * by, nn = (size_t)nx * ny;
  double *b = malloc(7 * nb * sizeof *b);
  size_t *idx = malloc(nn * sizeof *idx);
  if (!b || !idx) { free(b); free(idx); return gr_fail(e, GR_EMEM, "out of memory"); }
  double *cx = b, *cy = b + nb, *cz = b + 2 * nb, *cv = b + 3 * nb, clamp = INFINITY;
  /* one sample at the centre of each block of GRID_BLOCK^2 nodes */
  for (int j = 0; j < by; j++)
    for (int i = 0; i < bx; i++) {
      size_t k = i + (size_t)bx * j;
      cx[k] = x0 + (i * GRID_BLOCK + 0.5 * (GRID_BLOCK - 1)) * hx;
      cy[k] = y0 + (j * GRID_BLOCK + 0.5 * (GRID_BLOCK - 1)) * hy;
      cz[k] = z;
    }
  double K = grid_lipschitz(d, nb, cx, cy, cz, b + 4 * nb, &clamp);
  /* a block's nodes lie within r of its centre; the trimmed value needs d
   * exactly where |d| <= skin + 3 K h (the skin, and the crossings of the
   * lattice part next to it) */
  double r = 0.5 * (GRID_BLOCK - 1) * sqrt(hx * hx + hy * hy), h = fmax(hx, hy);
  double near = skin + 3 * fmax(K, 1) * h;
  /* a centre beyond the window (a partial block) that d refuses: every node exactly */
  gr_err e2;
  gr_err_clear(&e2);
  if (grid_samples(d, bx, by, cx, cy, cz, K, clamp, near + K * r, cv, &e2)) K = INFINITY;
  size_t m = 0;
  for (int j = 0; j < by; j++)
    for (int i = 0; i < bx; i++) {
      double c = cv[i + (size_t)bx * j], a = isfinite(K) ? fmin(fabs(c), clamp) - K * r : 0;
      int far = a > near;
      for (int q = j * GRID_BLOCK; q < ny && q < (j + 1) * GRID_BLOCK; q++)
        for (int p = i * GRID_BLOCK; p < nx && p < (i + 1) * GRID_BLOCK; p++) {
          size_t n = p + (size_t)nx * q;
          if (far) dv[n] = c < 0 ? -a : a; /* d's sign, nearer the boundary than d */
          else idx[m++] = n;
          if (far_out) far_out[n] = (unsigned char)far;
        }
    }
  int rc = grid_exact(d, idx, m, nx, z, x0, y0, hx, hy, dv, e);
  free(b);
  free(idx);
  return rc;
}
