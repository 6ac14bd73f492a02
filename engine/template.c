/* template.c: one unique voxel to its layers of scan paths, see template.h. */
#include "template.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "clip.h"
#include "distance.h"
#include "hatch.h"
#include "verify.h"
#include "version.h"

/* Free a template layer's rings, scans and face data (NULL after). */
static void tlayer_drop(gr_tlayer *l) {
  gr_rings_free(l->section);
  gr_rings_free(l->region);
  gr_layer_free(l->paths);
  gr_layer_free(l->faces);
  free(atomic_exchange(&l->fx, NULL));
  l->section = l->region = NULL;
  l->paths = l->faces = NULL;
}

void gr_tmpl_free(gr_tmpl *t) {
  if (!t) return;
  for (int i = 0; i < t->nl; i++) tlayer_drop(&t->l[i]);
  free(t->l);
  free(t);
}

void gr_tmpl_release(gr_tmpl *t, int qa, int qb) {
  for (int q = qa < 0 ? 0 : qa; q < qb && q < t->nl; q++) {
    gr_tlayer *l = &t->l[q];
    gr_layer *p = gr_layer_new(0); /* keeps the thin-wall count for qualification */
    if (!p) continue;                /* out of memory: the layer stays */
    if (l->paths) p->thin_walls = l->paths->thin_walls;
    tlayer_drop(l);
    l->paths = p;
  }
}

gr_tmpl *gr_tmpl_new(int ja, int jb) {
  gr_tmpl *t = calloc(1, sizeof *t);
  if (!t) return NULL;
  t->j0 = ja;
  t->nl = jb - ja;
  t->l = calloc(t->nl > 0 ? t->nl : 1, sizeof *t->l);
  if (!t->l) { free(t); return NULL; }
  for (int q = 0; q < t->nl; q++) t->l[q].cut[0] = t->l[q].cut[1] = t->l[q].cut[2] = t->l[q].cut[3] = NAN;
  return t;
}

/* ---- voxels on the part's boundary ----
 * The part's section in a boundary voxel is the lattice section A cut by the
 * voxel's outer sides. Eroding an intersection erodes each part, so its
 * contour at offset c is (the contour of A at c, cut by the sides moved in by
 * c) plus (the sides moved in by c, where they lie inside A's offset by c):
 * the first from the template's contours, the second computed here once per
 * template layer for the four sides, c = b, b + d, ... */

/* Signed in-plane distance to the section boundary at t along the line
 * (x0 + t ux, y0 + t uy), negative inside, clamped to +-R. Only edges near the
 * line can be nearer than R; inside/outside from the crossings cr (sorted).
 * The candidate edges are sorted by where they start along the line (lo),
 * each spanning at most span along it: only those within R of t along the
 * line are measured (the others are farther than R). */
typedef struct fline {
  double x0, y0, ux, uy, R;
  double *ed;        /* candidate edges (4 per edge) */
  size_t ne;
  const double *cr;  /* crossing parameters, sorted */
  size_t nc;
  double *lo, span;  /* per candidate edge: its smaller coordinate along the line */
} fline;

static double fline_value(const fline *f, double t) {
  double px = f->x0 + t * f->ux, py = f->y0 + t * f->uy, best = f->R * f->R;
  /* the first edge with lo >= t - R - span (lo sorted) */
  size_t k0 = 0, k1 = f->ne;
  while (k0 < k1) {
    size_t m = (k0 + k1) / 2;
    if (f->lo[m] < t - f->R - f->span) k0 = m + 1;
    else k1 = m;
  }
  for (size_t k = k0; k < f->ne && f->lo[k] <= t + f->R; k++) {
    const double *a = f->ed + 4 * k;
    double ex = a[2] - a[0], ey = a[3] - a[1], L2 = ex * ex + ey * ey;
    double s = L2 > 0 ? ((px - a[0]) * ex + (py - a[1]) * ey) / L2 : 0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    double dx = a[0] + s * ex - px, dy = a[1] + s * ey - py, d2 = dx * dx + dy * dy;
    if (d2 < best) best = d2;
  }
  size_t below = 0;
  while (below < f->nc && f->cr[below] < t) below++;
  return (below & 1) ? -sqrt(best) : sqrt(best);
}

static int dbl_cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Sort f's candidate edges by their start along the line (ties by the
 * coordinates, so that the order is the same on every machine), filling
 * f->lo and f->span; tmp holds ne * 5 doubles. */
static int fline_edge_cmp(const void *a, const void *b) {
  const double *x = a, *y = b;
  for (int k = 0; k < 5; k++)
    if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
  return 0;
}

static void fline_sort(fline *f, int vert, double *tmp) {
  f->span = 0;
  for (size_t k = 0; k < f->ne; k++) {
    const double *a = f->ed + 4 * k;
    double p = vert ? a[1] : a[0], q = vert ? a[3] : a[2];
    tmp[5 * k] = fmin(p, q);
    memcpy(tmp + 5 * k + 1, a, 4 * sizeof *a);
    f->span = fmax(f->span, fabs(q - p));
  }
  qsort(tmp, f->ne, 5 * sizeof *tmp, fline_edge_cmp);
  for (size_t k = 0; k < f->ne; k++) {
    f->lo[k] = tmp[5 * k];
    memcpy(f->ed + 4 * k, tmp + 5 * k + 1, 4 * sizeof *tmp);
  }
}

/* The side segment [ta, tb] of the line, oriented like the contours (the
 * part on the left): down along x = c, up along x = L - c, and so on. */
static int face_seg(gr_layer *l, const fline *f, int side, double ta, double tb) {
  int rev = side == 0 || side == 3;
  double a = rev ? tb : ta, b = rev ? ta : tb;
  double seg[4] = {f->x0 + a * f->ux, f->y0 + a * f->uy, f->x0 + b * f->ux, f->y0 + b * f->uy};
  return gr_layer_add(l, GR_OPEN, GR_CONTOUR, side, 2, seg, 2);
}

#define FACE_SKIP 1e-9 /* mm: room for rounding in the Lipschitz skip below */
static int face_lines(const gr_job_opts *o, gr_tlayer *tl) {
  if (!tl->faces && !(tl->faces = gr_layer_new(0))) return GR_EMEM;
  gr_layer_clear(tl->faces, 0);
  const gr_rings *r = tl->section;
  double b = o->beam_offset, d = o->hatch, step = o->slice_cell / 4;
  int nc = o->contours;
  if (nc <= 0 || r->npts == 0) return GR_OK;
  double R = b + (nc - 1) * d + 2 * step;
  double *ed = malloc(10 * r->npts * sizeof *ed + 1), *cr = malloc((r->npts + 1) * sizeof *cr);
  if (!ed || !cr) { free(ed); free(cr); return GR_EMEM; }
  double *elo = ed + 4 * r->npts, *tmp = elo + r->npts;
  int rc = GR_OK;
  for (int side = 0; side < 4 && rc == GR_OK; side++) {
    int vert = side < 2; /* x = const */
    double Lc = vert ? o->cell[0] : o->cell[1], L = vert ? o->cell[1] : o->cell[0]; /* across, along */
    for (int k = 0; k < nc && rc == GR_OK; k++) {
      double c = b + k * d, pos = (side & 1) ? Lc - c : c;
      fline f = {vert ? pos : 0, vert ? 0 : pos, vert ? 0 : 1, vert ? 1 : 0, R, ed, 0, cr, 0, elo, 0};
      for (size_t i = 0; i < r->nrings; i++) {
        const double *p = gr_ring_xy(r, i);
        size_t n = gr_ring_len(r, i);
        for (size_t a = 0; a < n; a++) {
          const double *P = p + 2 * a, *Q = p + 2 * gr_ring_next(a, n);
          double pa = vert ? P[0] : P[1], qa = vert ? Q[0] : Q[1];   /* across the line */
          double pl = vert ? P[1] : P[0], ql = vert ? Q[1] : Q[0];   /* along it */
          if ((pa > pos) != (qa > pos)) cr[f.nc++] = pl + (pos - pa) * (ql - pl) / (qa - pa);
          if (gr_lo(pa, qa) <= pos + R && gr_hi(pa, qa) >= pos - R) {
            double *e4 = ed + 4 * f.ne++;
            e4[0] = P[0]; e4[1] = P[1]; e4[2] = Q[0]; e4[3] = Q[1];
          }
        }
      }
      qsort(cr, f.nc, sizeof *cr, dbl_cmp);
      fline_sort(&f, vert, tmp);
      /* intervals of [0, L] where the value is <= -c - GR_FACE_EPS: sample, then bisect the ends.
       * The value is 1-Lipschitz along the line (a distance, clamped): a sample nearer to the
       * last one evaluated (te) than that one's |value| has its sign and is not evaluated (the
       * brackets and bisections are those of evaluating every sample) */
      int ns = (int)ceil(L / step);
      double ce = c + GR_FACE_EPS;
      double t0 = 0, v0 = fline_value(&f, 0) + ce, start = v0 <= 0 ? 0 : NAN, te = 0;
      for (int q = 1; q <= ns && rc == GR_OK; q++) {
        double t1 = q == ns ? L : q * step;
        if (t1 - te < fabs(v0) - FACE_SKIP) {
          t0 = t1;
          continue;
        }
        double v1 = fline_value(&f, t1) + ce;
        te = t1;
        if ((v0 <= 0) != (v1 <= 0)) {
          double lo = t0, hi = t1, vlo = v0;
          for (int it = 0; it < 40 && hi - lo > 1e-7; it++) {
            double m = 0.5 * (lo + hi), vm = fline_value(&f, m) + ce;
            if ((vm <= 0) == (vlo <= 0)) { lo = m; vlo = vm; } else hi = m;
          }
          double tc = 0.5 * (lo + hi);
          if (v1 <= 0) start = tc;
          else {
            if (tc > start && face_seg(tl->faces, &f, side, start, tc)) rc = GR_EMEM;
            start = NAN;
          }
        }
        t0 = t1;
        v0 = v1;
      }
      if (rc == GR_OK && !isnan(start) && L > start && face_seg(tl->faces, &f, side, start, L)) rc = GR_EMEM;
    }
  }
  free(ed);
  free(cr);
  return rc;
}

/* verify() one template layer: its contours and the hatches of its region
 * (at the layer's angle) against its section, inside the voxel square. */
static int verify_template_layer(const gr_job_opts *o, gr_tlayer *tl, double angle, gr_err *e) {
  gr_layer *l = gr_layer_new(0);
  if (!l) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = gr_layer_append(l, tl->paths, 0, 0) ? gr_fail(e, GR_EMEM, "out of memory") : GR_OK;
  gr_hatch_opts ho = gr_hatch_defaults();
  ho.spacing = o->hatch;
  ho.angle = angle;
  ho.contours = 0;
  if (rc == GR_OK) rc = gr_hatch_region(tl->region, &ho, l, NULL, e);
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = o->track;
  vo.pixel = o->track / 10;
  vo.offset = o->beam_offset;
  vo.spacing = o->hatch;
  vo.contours = o->contours > 0 ? o->contours : 1;
  vo.clip = 1;
  vo.clip_lo[0] = vo.clip_lo[1] = 0;
  vo.clip_hi[0] = o->cell[0];
  vo.clip_hi[1] = o->cell[1];
  gr_verify_result vr;
  if (rc == GR_OK && (rc = gr_verify_layer(tl->section, l, &vo, &vr, e)) == GR_OK) {
    tl->q[0] = vr.pore;
    tl->q[1] = vr.overmelt;
    tl->q[2] = vr.max_dev;
  }
  gr_layer_free(l);
  return rc;
}

/* Margin of a template's slice window around the voxel: whole grid cells,
 * wide enough for what the voxel's layer takes from the section beyond its
 * sides: the deepest offset (the last contour or the hatch region, b + (n -
 * 1) d, n the most contours scanned along a boundary: the job's, or a
 * skin's) and a thin wall's far side (its centre line is scanned within b
 * of the voxel, its sides within 2b), and two cells for the grid's
 * crossings and chords by the window's border. */
double gr_tmpl_window(const gr_job_opts *o, int deep) {
  double h = o->slice_cell, b = o->beam_offset;
  int n = deep > o->contours ? deep : o->contours;
  double far = b + (n > 1 ? n - 1 : 0) * o->hatch;
  return ceil((fmax(far, 2 * b) + 2 * h) / h - 1e-9) * h;
}

/* Contour, thin-wall and hatch-region options of the templates. */
static gr_hatch_opts tmpl_hatch_opts(const gr_job_opts *opt) {
  gr_hatch_opts ho = gr_hatch_defaults();
  ho.spacing = opt->hatch;
  ho.beam_offset = opt->beam_offset;
  ho.contours = opt->contours;
  ho.cell = opt->slice_cell;
  ho.pattern = GR_PARALLEL;
  /* the window's cut edges are not walls: thin walls only where they reach the voxel */
  ho.thin_box[0] = ho.thin_box[1] = -opt->beam_offset;
  ho.thin_box[2] = opt->cell[0] + opt->beam_offset;
  ho.thin_box[3] = opt->cell[1] + opt->beam_offset;
  return ho;
}

int gr_tmpl_paths(const gr_job_opts *opt, gr_tlayer *tl, int faces, gr_err *e) {
  double box_lo[2] = {0, 0}, box_hi[2] = {opt->cell[0], opt->cell[1]};
  gr_hatch_opts ho = tmpl_hatch_opts(opt);
  memcpy(ho.cut, tl->cut, sizeof ho.cut); /* the window's sides are no walls */
  if (!tl->region && !(tl->region = gr_rings_new())) return gr_fail(e, GR_EMEM, "out of memory");
  if (!tl->paths && !(tl->paths = gr_layer_new(0))) return gr_fail(e, GR_EMEM, "out of memory");
  gr_rings_clear(tl->region);
  gr_layer_clear(tl->paths, 0);
  gr_layer *tmp = gr_layer_new(0);
  double *buf = NULL;
  size_t cap = 0;
  if (!tmp) return gr_fail(e, GR_EMEM, "out of memory");
  gr_hatch_report rep;
  memset(&rep, 0, sizeof rep);
  /* contours, thin walls and the hatch region from one set of offsets */
  int rc = gr_hatch_contours(tl->section, &ho, tmp, tl->region, &rep, e);
  /* contours and thin-wall scans of the window, clipped to the voxel */
  for (size_t b = 0; rc == GR_OK && b < tmp->nb; b++) {
    const gr_block *bk = &tmp->b[b];
    if (bk->kind == GR_HATCH) continue;
    const double *xy = tmp->xy + 2 * bk->start;
    /* closed contours are oriented (inside on the left): one voxel scans a piece on a shared face */
    int owned = bk->shape == GR_CLOSED && bk->kind == GR_CONTOUR;
    if (owned ? gr_clip_ring_owned(xy, bk->n, bk->kind, bk->dir, box_lo, box_hi, tl->paths, &buf, &cap)
              : gr_clip_poly(xy, bk->n, bk->shape == GR_CLOSED, bk->kind, bk->dir, box_lo, box_hi, tl->paths, &buf, &cap))
      rc = gr_fail(e, GR_EMEM, "out of memory");
  }
  tl->paths->thin_walls = rep.thin_walls;
  /* (the hatch region is not simplified again here: the direct offset gave
   * it simplified to 0.3 um, and simplifying it to 0.1 um, as was done, took
   * 2 % of a template layer's instructions to remove 0.6 % of its points,
   * all in the few layers whose offset came from the grid) */
  if (rc == GR_OK && faces && face_lines(opt, tl)) rc = gr_fail(e, GR_EMEM, "out of memory");
  free(buf);
  gr_layer_free(tmp);
  return rc;
}

/* Compute template layers [qa, qb) from the voxel's field f, through the
 * shared closest points tab if not NULL (template.h). */
int gr_tmpl_layers(const gr_tmpl_in *in, gr_tmpl *t, const gr_field *f, const gr_cptab *tab, int qa, int qb,
                   gr_err *e) {
  const gr_job_opts *opt = in->o;
  const double *o = in->vo;
  int g0 = in->g0;
  const double *L = opt->cell;
  double h = opt->slice_cell;
  double m = in->win;
  gr_slice_opts so = gr_slice_defaults();
  so.lo[0] = o[0] - m;
  so.lo[1] = o[1] - m;
  so.hi[0] = o[0] + L[0] + m;
  so.hi[1] = o[1] + L[1] + m;
  so.cell = h;
  so.refine = 1;
  so.tol = GR_CROSS_TOL;
  so.chord_tol = GR_CHORD_TOL;
  double box_lo[2] = {0, 0}, box_hi[2] = {L[0], L[1]};
  int rc = GR_OK;
  for (int q = qa; q < qb && rc == GR_OK; q++) {
    gr_tlayer *tl = &t->l[q];
    tl->section = gr_rings_new();
    tl->region = gr_rings_new();
    tl->paths = gr_layer_new(0);
    if (!tl->section || !tl->region || !tl->paths) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    double z = gr_grid_mid(in->grid, g0 + t->j0 + q);
    if ((rc = tab ? gr_cptab_slice(tab, f, o, q, z, &so, tl->section, e) : gr_slice_field(f, z, &so, tl->section, e))) break;
    gr_rings_translate(tl->section, -o[0], -o[1]);
    /* the window's sides where the translation put them (offsetdirect.c allows for rounding) */
    tl->cut[0] = so.lo[0] + -o[0];
    tl->cut[1] = so.lo[1] + -o[1];
    tl->cut[2] = so.hi[0] + -o[0];
    tl->cut[3] = so.hi[1] + -o[1];
    tl->area = gr_clip_area(tl->section, box_lo, box_hi);
    if ((rc = gr_tmpl_paths(opt, tl, in->faces, e))) break;
    tl->q[0] = tl->q[1] = tl->q[2] = NAN;
    if (rc == GR_OK && opt->verify) rc = verify_template_layer(opt, tl, gr_layer_angle(opt, g0 + t->j0 + q), e);
  }
  return rc;
}

void gr_tmpl_qualify(const gr_job_opts *o, gr_tmpl *t, const char *key, gr_qualify_fn fn, void *ud,
                     char *why, size_t n) {
  long thin = 0;
  why[0] = 0;
  for (int q = 0; q < t->nl; q++) thin += t->l[q].paths->thin_walls;
  t->quality[0] = t->quality[1] = t->quality[2] = t->quality[3] = NAN;
  if (o->verify) {
    t->quality[0] = t->quality[1] = t->quality[2] = t->quality[3] = 0;
    for (int q = 0; q < t->nl; q++) {
      for (int k = 0; k < 3; k++)
        if (!isnan(t->l[q].q[k])) t->quality[k] = fmax(t->quality[k], t->l[q].q[k]);
      t->quality[3] += !isnan(t->l[q].q[0]);
    }
    if (t->quality[0] > o->max_pore)
      snprintf(why, n, "pore %.3g %% > %.3g %%", 100 * t->quality[0], 100 * o->max_pore);
    else if (t->quality[1] > o->max_overmelt)
      snprintf(why, n, "overmelt %.3g %% > %.3g %%", 100 * t->quality[1], 100 * o->max_overmelt);
    else if (t->quality[2] > o->max_dev)
      snprintf(why, n, "contour deviation %.3g um > %.3g um", 1e3 * t->quality[2], 1e3 * o->max_dev);
  }
  t->qualified = !why[0];
  if (t->qualified && fn && !fn(ud, key, t->quality, thin, why, n)) {
    t->qualified = 0;
    if (!why[0]) snprintf(why, n, "refused by the recipe's rule");
  }
}

/* Template <-> knowledge-base record: slot 0 section, slot 1 region; the
 * extra layer holds the clipped contour paths. */
gr_template *gr_tmpl_to_record(const gr_job_opts *o, const gr_tmpl *t, const char *sig, int count, gr_err *e) {
  gr_template *r = gr_template_new(sig, t->nl, 2, 1, e);
  if (!r) return NULL;
  char meta[256];
  if (gr_cell_cube(o->cell))
    snprintf(meta, sizeof meta, "{gradus: %s, voxels_at_build: %d, cell: %g}", GRADUS_VERSION, count, o->cell[0]);
  else
    snprintf(meta, sizeof meta, "{gradus: %s, voxels_at_build: %d, cell: [%g, %g, %g]}", GRADUS_VERSION, count,
             o->cell[0], o->cell[1], o->cell[2]);
  if (gr_template_set_meta(r, meta, e)) { gr_template_free(r); return NULL; }
  for (int q = 0; q < t->nl; q++) {
    r->z[q] = q * o->layer; /* local layer offsets from the first layer */
    if (gr_rings_copy(r->rings[q * 2], t->l[q].section) || gr_rings_copy(r->rings[q * 2 + 1], t->l[q].region) ||
        gr_layer_append(r->extra[q], t->l[q].paths, 0, 0)) {
      gr_template_free(r);
      gr_fail(e, GR_EMEM, "out of memory");
      return NULL;
    }
    r->extra[q]->thin_walls = t->l[q].paths->thin_walls;
  }
  for (int i = 0; i < GR_TEMPLATE_NQ; i++) r->quality[i] = i < 4 ? t->quality[i] : NAN;
  r->qualified = t->qualified;
  return r;
}

gr_tmpl *gr_tmpl_from_record(const gr_job_opts *o, const gr_template *r, int nl, int faces) {
  if (r->nlayers != nl || r->nslots != 2 || !r->extra) return NULL;
  for (int q = 0; q < nl; q++)
    if (!r->rings[q * 2] || !r->rings[q * 2 + 1] || !r->extra[q]) return NULL;
  gr_tmpl *t = gr_tmpl_new(0, nl);
  if (!t) return NULL;
  for (int q = 0; q < nl; q++) {
    t->l[q].section = gr_rings_new();
    t->l[q].region = gr_rings_new();
    t->l[q].paths = gr_layer_new(0);
    if (!t->l[q].section || !t->l[q].region || !t->l[q].paths ||
        gr_rings_copy(t->l[q].section, r->rings[q * 2]) || gr_rings_copy(t->l[q].region, r->rings[q * 2 + 1]) ||
        gr_layer_append(t->l[q].paths, r->extra[q], 0, 0)) {
      gr_tmpl_free(t);
      return NULL;
    }
  }
  for (int q = 0; q < nl; q++) {
    double lo[2] = {0, 0}, hi[2] = {o->cell[0], o->cell[1]};
    t->l[q].area = gr_clip_area(t->l[q].section, lo, hi);
    if (faces && face_lines(o, &t->l[q])) { gr_tmpl_free(t); return NULL; }
  }
  for (int i = 0; i < 4; i++) t->quality[i] = r->quality[i];
  t->qualified = r->qualified;
  t->from_kb = 1;
  return t;
}
