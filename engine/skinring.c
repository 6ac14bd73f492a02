/* skinring.c: more contours along a domain's skin, see skinring.h. */
#include "skinring.h"
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include "clip.h"
#include "hatch.h"
#include "job.h"
#include "regions.h"
#include "slice.h"

struct gr_skinring {
  gr_job *j;
  const gr_tlayer *tl;
  double o[3], z;     /* the voxel's corner; the layer's middle, mm */
  int n, k;           /* the job's contours, the skin's */
  double hk;          /* the skin's hatch offset b + (k-1) d + gap, mm */
  gr_polydist *pd;    /* in-plane distance to the window section (voxel-local) */
  double m;           /* the window's margin around the voxel square, mm */
};

/* 1 when the section boundary point q (voxel-local) is on the domain's
 * surface: |domain| < 5 um there (a lattice pore's edge lies at -skin or
 * deeper), and not on the window's cut border. */
static int on_surface(gr_skinring *s, const double q[2], gr_err *e) {
  for (int a = 0; a < 2; a++)
    if (q[a] <= -s->m + 1e-6 || q[a] >= s->j->o.cell[a] + s->m - 1e-6) return 0;
  double x = q[0] + s->o[0], y = q[1] + s->o[1], f;
  pthread_mutex_t *mu = gr_regions_mutex(s->j);
  if (mu) pthread_mutex_lock(mu);
  int rc = gr_field_eval(s->j->domain, 1, &x, &y, &s->z, &f, e);
  if (mu) pthread_mutex_unlock(mu);
  if (rc) return -rc;
  return fabs(f) < 5e-3;
}

gr_skinring *gr_skinring_new(gr_job *j, int g, int v, const gr_tlayer *tl, gr_err *e) {
  int k = gr_regions_skin_contours(j);
  if (k <= j->o.contours || !j->domain || !(j->skin > 0) || !j->cls[j->vcls[v]].trimmed || !tl->section ||
      tl->section->nrings == 0)
    return NULL;
  gr_skinring *s = calloc(1, sizeof *s);
  if (!s) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  s->j = j;
  s->tl = tl;
  gr_grid_origin(&j->grid, v, s->o);
  s->z = gr_grid_mid(&j->grid, g);
  s->n = j->o.contours;
  s->k = k;
  s->m = gr_job_window(j);
  s->hk = j->o.beam_offset + (k - 1) * j->o.hatch + gr_hatch_defaults().gap;
  gr_rings *nested = gr_rings_new();
  int rc = (nested && !gr_rings_copy(nested, tl->section)) ? gr_rings_nest(nested, e) : gr_fail(e, GR_EMEM, "out of memory");
  if (rc == GR_OK && !(s->pd = gr_polydist_new(nested, 0, e))) rc = e->code ? e->code : GR_EMEM;
  gr_rings_free(nested);
  if (rc) { gr_skinring_free(s); return NULL; }
  return s;
}

void gr_skinring_free(gr_skinring *s) {
  if (!s) return;
  gr_polydist_free(s->pd);
  free(s);
}

int gr_skinring_drop(gr_skinring *s, double x, double y, gr_err *e) {
  double q[2], d = gr_polydist_at(s->pd, x - s->o[0], y - s->o[1], q);
  if (!(d > -s->hk)) return 0; /* deeper than the skin's hatch offset (or outside) */
  return on_surface(s, q, e);
}

/* The runs of ring r's points (the section's offset by off) whose nearest
 * boundary point is on the domain's surface, clipped to the voxel square,
 * into cont. */
static int keep_runs(gr_skinring *s, const gr_rings *r, size_t ri, double off, gr_layer *cont, double **buf,
                     size_t *cap, double **run, size_t *caprun, gr_err *e) {
  const double *p = gr_ring_xy(r, ri);
  size_t m = gr_ring_len(r, ri);
  if (m < 3) return GR_OK;
  char *keep = malloc(m);
  if (!keep) return gr_fail(e, GR_EMEM, "out of memory");
  size_t nk = 0;
  for (size_t a = 0; a < m; a++) {
    double q[2], d = fabs(gr_polydist_at(s->pd, p[2 * a], p[2 * a + 1], q));
    /* a guard: a point off its distance by 1 um or more is not scanned
     * (none is since polydist's sign follows the even-odd rule) */
    int on = fabs(d - off) < 1e-3 ? on_surface(s, q, e) : 0;
    if (on < 0) { free(keep); return -on; }
    keep[a] = (char)on;
    nk += (size_t)on;
  }
  double lo[2] = {0, 0}, hi[2] = {s->j->o.cell[0], s->j->o.cell[1]};
  int rc = GR_OK, dir = gr_ring_area(r, ri) > 0 ? 1 : 0;
  size_t a0 = 0;
  if (nk == m) { /* the whole ring: closed */
    if (gr_grow(run, caprun, 2 * (m + 1), sizeof **run)) rc = GR_EMEM;
    if (!rc) {
      memcpy(*run, p, 2 * m * sizeof *p);
      (*run)[2 * m] = p[0];
      (*run)[2 * m + 1] = p[1];
      rc = gr_clip_poly(*run, m + 1, 1, GR_CONTOUR, dir, lo, hi, cont, buf, cap);
    }
  } else if (nk > 0) {
    while (keep[a0]) a0++; /* start after a dropped point: runs do not wrap */
    size_t np = 0;
    for (size_t t = 1; t <= m && !rc; t++) {
      size_t a = (a0 + t) % m;
      if (keep[a]) {
        if (gr_grow(run, caprun, 2 * (np + 1), sizeof **run)) { rc = GR_EMEM; break; }
        (*run)[2 * np] = p[2 * a];
        (*run)[2 * np + 1] = p[2 * a + 1];
        np++;
      }
      if ((!keep[a] || t == m) && np >= 2) rc = gr_clip_poly(*run, np, 0, GR_CONTOUR, 2, lo, hi, cont, buf, cap);
      if (!keep[a]) np = 0;
    }
  }
  free(keep);
  return rc ? gr_fail(e, GR_EMEM, "out of memory") : GR_OK;
}

int gr_skinring_contours(gr_skinring *s, int slot, gr_layer *cont, gr_err *e) {
  gr_layer *loc = gr_layer_new(0); /* voxel-local, then translated into cont */
  gr_rings *off = gr_rings_new();
  double *buf = NULL, *run = NULL;
  size_t cap = 0, caprun = 0;
  int rc = (loc && off) ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  for (int i = s->n; i < s->k && rc == GR_OK; i++) {
    /* chords refined (the offsets' tolerance): corners stay corners, as in the templates */
    double b = s->j->o.beam_offset + i * s->j->o.hatch;
    rc = gr_offset_rings_opt(s->tl->section, b, s->j->o.slice_cell, 1e-6, GR_OFFSET_CHORD_TOL, NULL, off, e);
    for (size_t r = 0; rc == GR_OK && r < off->nrings; r++) rc = keep_runs(s, off, r, b, loc, &buf, &cap, &run, &caprun, e);
  }
  size_t b0 = cont->nb;
  if (rc == GR_OK && gr_layer_append(cont, loc, s->o[0], s->o[1])) rc = gr_fail(e, GR_EMEM, "out of memory");
  for (size_t b = b0; rc == GR_OK && b < cont->nb; b++) cont->b[b].laser = slot;
  free(buf);
  free(run);
  gr_rings_free(off);
  gr_layer_free(loc);
  return rc;
}
