/* domain.c: a design domain's field made a signed distance, see domain.h. */
#include "domain.h"
#include "bvh.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DOM_ITERS 60     /* projection rounds (most points stop after 2-5) */
#define DOM_FAR 1e6      /* mm: the value where the gradient vanishes */

typedef struct dom {
  gr_field *f;
  double band; /* mm: exact distances below this */
  double tol;  /* mm: convergence of the closest point */
} dom;

/* An error of the domain's own field, said to come from the domain. */
static int dom_fail(gr_err *e) {
  if (e && strncmp(e->msg, "domain", 6) != 0) {
    char m[sizeof e->msg];
    memcpy(m, e->msg, sizeof m);
    m[sizeof m - 9] = 0;
    snprintf(e->msg, sizeof e->msg, "domain: %.500s", m);
  }
  return e ? e->code : GR_ENUM;
}

/* Scratch of n points: value, gradient and the moving foot points. */
typedef struct dom_work {
  double *v, *gx, *gy, *gz, *qx, *qy, *qz;
  size_t *act;
} dom_work;

static int work_new(dom_work *w, size_t n) {
  double *b = malloc((n ? n : 1) * 7 * sizeof *b);
  w->act = malloc((n ? n : 1) * sizeof *w->act);
  if (!b || !w->act) { free(b); free(w->act); return GR_EMEM; }
  w->v = b, w->gx = b + n, w->gy = b + 2 * n, w->gz = b + 3 * n;
  w->qx = b + 4 * n, w->qy = b + 5 * n, w->qz = b + 6 * n;
  return GR_OK;
}
static void work_free(dom_work *w) {
  free(w->v);
  free(w->act);
}

/* Project the m points act[] (p given, q started at p) onto f = 0 together:
 * q <- p - ((f(q) + grad f(q).(p - q)) / |grad f(q)|^2) grad f(q). Writes
 * |p - q| into out[] for those that converge; the others keep out[] (the
 * first-order estimate). Uses w's value/gradient arrays as scratch, packed
 * in the order of the active points. */
static int project(const dom *d, const double *x, const double *y, const double *z, dom_work *w, size_t m,
                   double *out, gr_err *e) {
  for (int it = 0; it < DOM_ITERS && m > 0; it++) {
    /* the active feet are packed at the front of qx, qy, qz */
    if (gr_field_eval_grad(d->f, m, w->qx, w->qy, w->qz, w->v, w->gx, w->gy, w->gz, e)) return dom_fail(e);
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
        out[i] = dist;
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

static int dom_eval(void *ud, size_t n, const double *x, const double *y, const double *z, double *out,
                    gr_err *e) {
  const dom *d = ud;
  dom_work w;
  if (work_new(&w, n)) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = gr_field_eval_grad(d->f, n, x, y, z, w.v, w.gx, w.gy, w.gz, e);
  if (rc) {
    work_free(&w);
    return dom_fail(e);
  }
  double *sg = malloc((n ? n : 1) * sizeof *sg);
  if (!sg) {
    work_free(&w);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    double v = w.v[i], g = sqrt(w.gx[i] * w.gx[i] + w.gy[i] * w.gy[i] + w.gz[i] * w.gz[i]);
    sg[i] = v < 0 ? -1 : 1;
    double est = g > 0 ? fabs(v) / g : DOM_FAR;
    out[i] = fmin(est, DOM_FAR);
    if (v == 0) { out[i] = 0; continue; }
    if (est >= d->band) { out[i] = fmax(out[i], d->band); continue; }
    w.act[m] = i;
    w.qx[m] = x[i], w.qy[m] = y[i], w.qz[m] = z[i];
    m++;
  }
  rc = project(d, x, y, z, &w, m, out, e);
  for (size_t i = 0; i < n; i++) out[i] *= sg[i];
  free(sg);
  work_free(&w);
  return rc;
}

/* The unit normal grad f / |grad f| (the gradient of the distance where it
 * is one), 0 at critical points. */
static int dom_grad(void *ud, size_t n, const double *x, const double *y, const double *z, double *gx, double *gy,
                    double *gz, gr_err *e) {
  const dom *d = ud;
  if (gr_field_grad(d->f, n, x, y, z, gx, gy, gz, e)) return dom_fail(e);
  for (size_t i = 0; i < n; i++) {
    double g = sqrt(gx[i] * gx[i] + gy[i] * gy[i] + gz[i] * gz[i]);
    if (g > 0) gx[i] /= g, gy[i] /= g, gz[i] /= g;
  }
  return GR_OK;
}

static void dom_free(void *ud) {
  dom *d = ud;
  gr_field_free(d->f);
  free(d);
}

gr_field *gr_domain_distance(gr_field *f, double band, double L, gr_err *e) {
  if (!f) return NULL;
  if (gr_field_lipschitz(f) <= 1 || gr_domain_is_distance(f)) return gr_field_ref(f);
  if (!(band > 0) || !(L > 0) || !isfinite(band) || !isfinite(L))
    return gr_fail(e, GR_EARG, "domain distance: band %g mm and cell %g mm must be > 0", band, L), NULL;
  dom *d = malloc(sizeof *d);
  if (!d) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  d->f = gr_field_ref(f);
  d->band = band;
  d->tol = 1e-9 * fmax(L, 1);
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
