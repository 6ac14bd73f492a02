/* place.c: part-scale placement, see place.h.
 *
 * Layer geometry (SPEC.md s.4): N = round(nz*L/t) layers; layer g (1..N) has
 * CLI height z_g = oz + g*t and its geometry is taken at mid(g) = z_g - t/2.
 * Voxel row k spans [oz + k*L, oz + (k+1)*L); its first layer is g0(k), the
 * first g with mid(g) inside the row; local layer index = g - g0(k). The
 * z-phase mid(g0(k)) - (oz + k*L) is part of a class's signature.
 *
 * A template holds, per local layer, in voxel-local coordinates:
 *  - section: the section rings in a window a margin wider than the voxel
 *    (the in-plane offsets near the voxel's border depend on the section just
 *    outside it);
 *  - region: the hatch region (section offset inward, see hatch_offset());
 *  - paths: contour loops clipped to the voxel square: closed loops and open
 *    pieces that end on the square's border and are joined with the pieces of
 *    the neighbouring voxels at placement.
 * Hatches are generated at placement, on the global line family, per voxel,
 * and clipped to the voxel square; in continuous mode collinear touching
 * vectors of neighbouring voxels (same laser) are joined into long vectors. */
#include "place.h"
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include "distance.h"
#include "expr.h"
#include "hatch.h"
#include "kb.h"
#include "slice.h"
#include "verify.h"
#include "version.h"

#define EPS 1e-9

gr_job_opts gr_job_defaults(void) {
  gr_job_opts o;
  memset(&o, 0, sizeof o);
  o.cell = 2.0;
  o.n[0] = o.n[1] = o.n[2] = 1;
  o.layer = 0.04;
  o.hatch = 0.05;
  o.beam_offset = -1; /* d/2 */
  o.track = -1;       /* d */
  o.contours = 1;
  o.contour_first = 1;
  o.angle = 45;
  o.rotation = 67;
  o.pattern = GR_PATTERN_PARALLEL;
  o.slice_cell = -1;  /* d/4 */
  o.res = 40;
  o.exact = 1;
  o.quant = 1e-3;
  o.min_length = 0;
  o.threads = 2;
  o.verify = 0;
  o.max_pore = 0.005;
  o.max_overmelt = 0.01;
  o.max_dev = 0.001;
  o.nlasers = 1;
  o.share = 1;
  o.faces = 1;
  return o;
}

/* ---- templates ---- */
typedef struct tlayer {
  double area;        /* section area inside the voxel square, mm^2 */
  double q[3];        /* verify(): pore, overmelt, max contour deviation (mm); NaN = not verified */
  gr_rings *section;  /* window, voxel-local */
  gr_rings *region;   /* hatch region, voxel-local */
  gr_layer *paths;    /* contours (+ thin-wall scans) clipped to [0,L]^2 */
  gr_layer *faces;    /* contour segments along the voxel's sides at the contour
                         offsets, for voxels on the part's boundary (block.laser
                         = side: 0 x=0, 1 x=L, 2 y=0, 3 y=L) */
} tlayer;

typedef struct tmpl {
  int j0, nl;         /* local layers j0 .. j0+nl-1 */
  tlayer *l;
  double quality[4];  /* worst pore, worst overmelt, max contour deviation (mm), layers verified */
  int qualified;      /* passed the qualification rules */
  int from_kb;
} tmpl;

typedef struct vclass {
  int rep;            /* representative voxel */
  int count;          /* voxels in the class */
  int trimmed;        /* computed directly (domain boundary) */
  char key[65];
  char *sig;
  tmpl *t;
  gr_field *field;    /* while its template is being built */
  int need;           /* template must be computed in this run */
} vclass;

struct gr_job {
  gr_job_opts o;
  gr_spec *specs;
  size_t nspecs, capspecs;
  gr_expr **texpr;    /* compiled thickness per spec (signature sampling) */
  gr_expr **iexpr;    /* inside thickness or NULL */
  int nvox;
  int *vspec, *vlaser, *vcls;
  double *vseq;
  unsigned char *vstate; /* 0 outside, 1 inside, 2 cut */
  gr_field *domain;
  double skin;
  vclass *cls;
  int ncls;
  int nlayers;        /* N */
  /* machine */
  gr_machine m;
  /* results */
  gr_job_stats st;
  char warning[1024];
  gr_layer **keep;    /* layers kept for pictures (by global index) */
  int *keep_idx;
  int nkeep;
  int *roworder;      /* per row: voxels with a class, in sequence order */
  int *rowcount;
  int rowlen;         /* nx*ny */
  long st_dropped;
};

static void tmpl_free(tmpl *t) {
  if (!t) return;
  for (int i = 0; i < t->nl; i++) {
    gr_rings_free(t->l[i].section);
    gr_rings_free(t->l[i].region);
    gr_layer_free(t->l[i].paths);
    gr_layer_free(t->l[i].faces);
  }
  free(t->l);
  free(t);
}

gr_job *gr_job_new(const gr_job_opts *o, gr_err *e) {
  gr_job_opts d = *o;
  if (!(d.cell > 0) || !isfinite(d.cell))
    return gr_fail(e, GR_EARG, "cell must be > 0 mm, got %g", d.cell), NULL;
  for (int a = 0; a < 3; a++)
    if (d.n[a] < 1 || d.n[a] > 100000)
      return gr_fail(e, GR_EARG, "cells must be >= 1 along each axis, got %d,%d,%d", d.n[0], d.n[1], d.n[2]), NULL;
  if (!(d.hatch > 0) || !isfinite(d.hatch))
    return gr_fail(e, GR_EARG, "hatch spacing must be > 0 mm, got %g", d.hatch), NULL;
  if (!(d.layer > 0) || !isfinite(d.layer))
    return gr_fail(e, GR_EARG, "layer thickness must be > 0 mm, got %g", d.layer), NULL;
  if (d.layer > d.cell)
    return gr_fail(e, GR_EARG, "layer thickness %g mm is larger than the cell %g mm", d.layer, d.cell), NULL;
  if (!isfinite(d.angle)) return gr_fail(e, GR_EARG, "angle must be a number, got %g", d.angle), NULL;
  if (!isfinite(d.rotation)) return gr_fail(e, GR_EARG, "rotation must be a number, got %g", d.rotation), NULL;
  if (d.beam_offset < 0) d.beam_offset = d.hatch / 2;
  if (!isfinite(d.beam_offset)) return gr_fail(e, GR_EARG, "beam_offset must be a number >= 0, got %g", d.beam_offset), NULL;
  if (d.track < 0) d.track = d.hatch;
  if (d.slice_cell <= 0) d.slice_cell = d.hatch / 2; /* eq. (7); chords refined to 0.2 um below */
  if (d.slice_cell > gr_slice_max_cell(d.hatch) + 1e-12)
    return gr_fail(e, GR_EARG,
                   "slice resolution too coarse: cell %g mm > hatch/2 = %g mm (eq. 7, L <= n*d/2)",
                   d.slice_cell, gr_slice_max_cell(d.hatch)), NULL;
  /* make the marching-squares grid divide the cell exactly so that the
   * grids of neighbouring voxels line up */
  {
    double n = ceil(d.cell / d.slice_cell - 1e-9);
    d.slice_cell = d.cell / n;
  }
  if (d.contours < 0 || d.contours > 20) return gr_fail(e, GR_EARG, "contours must be 0..20, got %d", d.contours), NULL;
  if (d.res < 2) return gr_fail(e, GR_EARG, "res must be >= 2, got %d", d.res), NULL;
  if (!(d.quant > 0)) return gr_fail(e, GR_EARG, "quantisation must be > 0 mm, got %g", d.quant), NULL;
  if (d.threads < 1) d.threads = 1;
  if (d.nlasers < 1) d.nlasers = 1;
  gr_job *j = calloc(1, sizeof *j);
  if (!j) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  j->o = d;
  j->nvox = d.n[0] * d.n[1] * d.n[2];
  j->vspec = calloc(j->nvox, sizeof *j->vspec);
  j->vlaser = malloc(j->nvox * sizeof *j->vlaser);
  j->vcls = malloc(j->nvox * sizeof *j->vcls);
  j->vseq = malloc(j->nvox * sizeof *j->vseq);
  j->vstate = malloc(j->nvox);
  if (!j->vspec || !j->vlaser || !j->vcls || !j->vseq || !j->vstate) {
    gr_job_free(j);
    return gr_fail(e, GR_EMEM, "out of memory for %d voxels", j->nvox), NULL;
  }
  for (int v = 0; v < j->nvox; v++) {
    j->vlaser[v] = -1;
    j->vcls[v] = -1;
    j->vseq[v] = v; /* raster */
    j->vstate[v] = 1;
  }
  j->nlayers = (int)lround(d.n[2] * d.cell / d.layer);
  j->m = gr_machine_default(d.nlasers);
  return j;
}

void gr_job_free(gr_job *j) {
  if (!j) return;
  for (size_t s = 0; s < j->nspecs; s++) {
    gr_expr_free(j->texpr[s]);
    gr_expr_free(j->iexpr[s]);
  }
  free(j->texpr);
  free(j->iexpr);
  free(j->specs);
  for (int c = 0; c < j->ncls; c++) {
    tmpl_free(j->cls[c].t);
    gr_field_free(j->cls[c].field);
    free(j->cls[c].sig);
  }
  free(j->cls);
  free(j->vspec);
  free(j->vlaser);
  free(j->vcls);
  free(j->vseq);
  free(j->vstate);
  gr_field_free(j->domain);
  for (int i = 0; i < j->nkeep; i++) gr_layer_free(j->keep[i]);
  free(j->keep);
  free(j->keep_idx);
  free(j->roworder);
  free(j->rowcount);
  free(j);
}

int gr_job_layers(const gr_job *j) { return j->nlayers; }
const gr_job_opts *gr_job_options(const gr_job *j) { return &j->o; }

static const char *const TVARS[] = {"x", "y", "z", "u", "v", "w"};

int gr_job_add_spec(gr_job *j, const gr_spec *s, gr_err *e) {
  if (s->surface < 0 || s->surface >= gr_tpms_count())
    return gr_fail(e, GR_EARG, "unknown surface index %d (valid: %s)", s->surface, gr_tpms_names()), -1;
  if (!s->thickness[0]) return gr_fail(e, GR_EARG, "thickness is empty"), -1;
  if (gr_grow(&j->specs, &j->capspecs, j->nspecs + 1, sizeof *j->specs)) return gr_fail(e, GR_EMEM, "out of memory"), -1;
  gr_expr **te = realloc(j->texpr, (j->nspecs + 1) * sizeof *te);
  if (!te) return gr_fail(e, GR_EMEM, "out of memory"), -1;
  j->texpr = te;
  gr_expr **ie = realloc(j->iexpr, (j->nspecs + 1) * sizeof *ie);
  if (!ie) return gr_fail(e, GR_EMEM, "out of memory"), -1;
  j->iexpr = ie;
  const char *cn[] = {"L"};
  double cv[] = {j->o.cell};
  gr_expr *t = gr_expr_compile(s->thickness, 6, TVARS, 1, cn, cv, e);
  if (!t) return -1;
  gr_expr *in = NULL;
  if (s->inside[0]) {
    in = gr_expr_compile(s->inside, 6, TVARS, 1, cn, cv, e);
    if (!in) { gr_expr_free(t); return -1; }
  }
  j->specs[j->nspecs] = *s;
  j->texpr[j->nspecs] = t;
  j->iexpr[j->nspecs] = in;
  return (int)j->nspecs++;
}

int gr_job_set_voxel(gr_job *j, int i, int jj, int k, int spec, int laser,
                     double seq, gr_err *e) {
  if (i < 0 || jj < 0 || k < 0 || i >= j->o.n[0] || jj >= j->o.n[1] || k >= j->o.n[2])
    return gr_fail(e, GR_EARG, "voxel (%d,%d,%d) outside the grid %dx%dx%d", i, jj, k, j->o.n[0], j->o.n[1], j->o.n[2]);
  if (spec >= (int)j->nspecs) return gr_fail(e, GR_EARG, "voxel spec %d does not exist (%zu specs)", spec, j->nspecs);
  if (laser >= j->m.n) return gr_fail(e, GR_EARG, "voxel laser %d does not exist (%d lasers)", laser + 1, j->m.n);
  if (!isfinite(seq)) return gr_fail(e, GR_EARG, "voxel sequence key must be a number");
  int v = i + j->o.n[0] * (jj + j->o.n[1] * k);
  j->vspec[v] = spec;
  j->vlaser[v] = laser;
  j->vseq[v] = seq;
  return GR_OK;
}

int gr_job_set_domain(gr_job *j, gr_field *domain, double skin, gr_err *e) {
  if (!(skin >= 0) || !isfinite(skin)) return gr_fail(e, GR_EARG, "skin must be >= 0 mm, got %g", skin);
  gr_field_free(j->domain);
  j->domain = domain ? gr_field_ref(domain) : NULL;
  j->skin = skin;
  return GR_OK;
}

int gr_job_set_machine(gr_job *j, const gr_machine *m, gr_err *e) {
  if (m->n < 1 || m->n > GR_MAX_LASERS) return gr_fail(e, GR_EARG, "lasers must be 1..%d, got %d", GR_MAX_LASERS, m->n);
  for (int l = 0; l < m->n; l++)
    for (int k = 0; k < GR_NKINDS; k++)
      if (!(m->speed[l][k] > 0)) return gr_fail(e, GR_EARG, "laser %d speed must be > 0 mm/s", l + 1);
  if (!(m->jump_speed > 0)) return gr_fail(e, GR_EARG, "jump speed must be > 0 mm/s, got %g", m->jump_speed);
  j->m = *m;
  j->o.nlasers = m->n;
  return GR_OK;
}

gr_machine gr_machine_default(int n) {
  gr_machine m;
  memset(&m, 0, sizeof m);
  m.n = n < 1 ? 1 : (n > GR_MAX_LASERS ? GR_MAX_LASERS : n);
  for (int l = 0; l < m.n; l++) {
    m.speed[l][GR_CONTOUR] = 600;
    m.speed[l][GR_HATCH] = 1000;
    m.speed[l][GR_EDGE] = 500;
    m.lo[l][0] = m.lo[l][1] = -INFINITY;
    m.hi[l][0] = m.hi[l][1] = INFINITY;
  }
  m.jump_speed = 5000;
  return m;
}

/* ---- layer geometry ---- */
static double layer_mid(const gr_job *j, int g) {
  return j->o.origin[2] + (g - 0.5) * j->o.layer;
}
static int row_first_layer(const gr_job *j, int k) {
  double z0 = k * j->o.cell;
  int g = (int)ceil(z0 / j->o.layer + 0.5 - 1e-9);
  return g < 1 ? 1 : g;
}
static int row_layers(const gr_job *j, int k) {
  int g0 = row_first_layer(j, k);
  int last = (int)ceil(((k + 1) * j->o.cell) / j->o.layer + 0.5 - 1e-9) - 1;
  if (last > j->nlayers) last = j->nlayers;
  return last >= g0 ? last - g0 + 1 : 0;
}
static int layer_row(const gr_job *j, int g) {
  int k = (int)floor((layer_mid(j, g) - j->o.origin[2]) / j->o.cell);
  if (k < 0) k = 0;
  if (k >= j->o.n[2]) k = j->o.n[2] - 1;
  return k;
}
static void voxel_ijk(const gr_job *j, int v, int *i, int *jj, int *k) {
  *i = v % j->o.n[0];
  *jj = (v / j->o.n[0]) % j->o.n[1];
  *k = v / (j->o.n[0] * j->o.n[1]);
}
static void voxel_origin(const gr_job *j, int v, double o[3]) {
  int i, jj, k;
  voxel_ijk(j, v, &i, &jj, &k);
  o[0] = j->o.origin[0] + i * j->o.cell;
  o[1] = j->o.origin[1] + jj * j->o.cell;
  o[2] = j->o.origin[2] + k * j->o.cell;
}

/* ---- classification ---- */
#define NS 4 /* thickness samples per axis for the signature */

/* Classify voxels against the domain: sample the domain field on a 5^3
 * lattice of the voxel grown by the contour margin; all positive -> outside,
 * all negative -> inside, else cut. With a Lipschitz bound the samples also
 * prove emptiness of the gaps between them. */
static int classify_domain(gr_job *j, gr_err *e) {
  if (!j->domain) return GR_OK;
  double K = gr_field_lipschitz(j->domain);
  enum { M = 5 };
  double x[M * M * M], y[M * M * M], z[M * M * M], f[M * M * M];
  double L = j->o.cell, grow = j->o.beam_offset + j->o.contours * j->o.hatch + j->skin;
  double h = (L + 2 * grow) / (M - 1);
  double ilo[3] = {INFINITY, INFINITY, INFINITY}, ihi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int v = 0; v < j->nvox; v++) {
    if (j->vspec[v] < 0) continue;
    double o[3];
    voxel_origin(j, v, o);
    int n = 0;
    for (int a = 0; a < M; a++)
      for (int b = 0; b < M; b++)
        for (int c = 0; c < M; c++, n++) {
          x[n] = o[0] - grow + a * h;
          y[n] = o[1] - grow + b * h;
          z[n] = o[2] - grow + c * h;
        }
    if (gr_field_eval(j->domain, n, x, y, z, f, e)) return e->code;
    int pos = 0, neg = 0;
    double half = h * sqrt(3.0) / 2;
    for (int q = 0; q < n; q++) {
      double margin = isfinite(K) ? K * half : 0;
      if (f[q] > margin) pos++;
      else if (f[q] < -margin) neg++;
    }
    if (neg == n) j->vstate[v] = 1 + (j->skin > 0 ? 0 : 0);
    else if (pos == n) j->vstate[v] = 0;
    else j->vstate[v] = 2;
    if (j->skin > 0 && j->vstate[v] == 1) {
      /* a voxel within the skin's reach of the boundary is cut too */
      for (int q = 0; q < n; q++)
        if (isfinite(K) ? -f[q] / K < j->skin + h : 1) { j->vstate[v] = 2; break; }
    }
    for (int q = 0; q < n; q++)
      if (f[q] < 0) {
        double p[3] = {x[q], y[q], z[q]};
        for (int a = 0; a < 3; a++) { ilo[a] = fmin(ilo[a], p[a]); ihi[a] = fmax(ihi[a], p[a]); }
      }
  }
  /* a domain smaller than one cell along every axis holds no cell: refuse it
   * (extent from the samples inside it, one sample spacing added) */
  int small = isfinite(ilo[0]);
  for (int a = 0; a < 3 && small; a++) small = ihi[a] - ilo[a] + h < L;
  if (small)
    return gr_fail(e, GR_EARG,
                   "cell %g mm is larger than the design domain (about %.2g x %.2g x %.2g mm); choose a smaller cell",
                   L, ihi[0] - ilo[0] + h, ihi[1] - ilo[1] + h, ihi[2] - ilo[2] + h);
  return GR_OK;
}

/* Signature text of voxel v: everything that changes its toolpaths. */
static char *voxel_signature(gr_job *j, int v, gr_err *e) {
  const gr_spec *s = &j->specs[j->vspec[v]];
  double o[3];
  voxel_origin(j, v, o);
  int i, jj, k;
  voxel_ijk(j, v, &i, &jj, &k);
  double L = j->o.cell;
  enum { N = NS * NS * NS };
  double x[N], y[N], z[N], u[N], vv[N], w[N], t[N], ti[N];
  int n = 0;
  for (int a = 0; a < NS; a++)
    for (int b = 0; b < NS; b++)
      for (int c = 0; c < NS; c++, n++) {
        double fa = (a + 0.5) / NS, fb = (b + 0.5) / NS, fc = (c + 0.5) / NS;
        x[n] = o[0] + fa * L;
        y[n] = o[1] + fb * L;
        z[n] = o[2] + fc * L;
        u[n] = 2 * fa - 1;
        vv[n] = 2 * fb - 1;
        w[n] = 2 * fc - 1;
      }
  const double *vars[6] = {x, y, z, u, vv, w};
  if (s->target ? gr_field_eval(s->target, N, x, y, z, t, e) : gr_expr_eval(j->texpr[j->vspec[v]], N, vars, t, e)) return NULL;
  if (j->iexpr[j->vspec[v]] && gr_expr_eval(j->iexpr[j->vspec[v]], N, vars, ti, e)) return NULL;
  size_t cap = 2048 + N * 24 * 2;
  char *sig = malloc(cap);
  if (!sig) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  int g0 = row_first_layer(j, k);
  double phase = layer_mid(j, g0) - o[2];
  size_t len = (size_t)snprintf(
      sig, cap,
      "{gradus_template: 1, surface: %s, L: %.9g, level: %.9g, kind: %s, side: %d, "
      "phase: %.9g, layers: %d, t: %.9g, d: %.9g, b: %.9g, contours: %d, cell: %.9g, res: %d, "
      "mode: %s, quant: %.9g, T: [",
      gr_tpms_name(s->surface), L, s->level, s->network ? "network" : "sheet", s->side,
      round(phase / 1e-9) * 1e-9, row_layers(j, k), j->o.layer, j->o.hatch,
      j->o.beam_offset, j->o.contours, j->o.slice_cell, j->o.res,
      j->o.exact ? "exact" : "mesh", j->o.quant);
  for (int q = 0; q < N; q++)
    len += (size_t)snprintf(sig + len, cap - len, "%s%lld", q ? "," : "", (long long)llround(t[q] / j->o.quant));
  len += (size_t)snprintf(sig + len, cap - len, "]");
  if (s->density || s->target) /* density samples: name the table; a field: its source */
    len += (size_t)snprintf(sig + len, cap - len, ", density: \"%s\", target: \"%s\"", s->density ? gr_dtable_key(s->density) : "",
                            s->target ? gr_field_describe(s->target) : "");
  if (j->iexpr[j->vspec[v]]) {
    len += (size_t)snprintf(sig + len, cap - len, ", Tin: [");
    for (int q = 0; q < N; q++)
      len += (size_t)snprintf(sig + len, cap - len, "%s%lld", q ? "," : "", (long long)llround(ti[q] / j->o.quant));
    len += (size_t)snprintf(sig + len, cap - len, "]");
  }
  snprintf(sig + len, cap - len, "}");
  return sig;
}

/* Group voxels into classes. direct != 0: one class per voxel (kb=off). */
int gr_job_classify(gr_job *j, int direct, gr_err *e) {
  if (j->nspecs == 0) return gr_fail(e, GR_EARG, "job has no cell spec");
  if (classify_domain(j, e)) return e->code;
  for (int c = 0; c < j->ncls; c++) {
    tmpl_free(j->cls[c].t);
    free(j->cls[c].sig);
  }
  free(j->cls);
  j->cls = calloc(j->nvox + 1, sizeof *j->cls);
  if (!j->cls) return gr_fail(e, GR_EMEM, "out of memory");
  j->ncls = 0;
  /* hash of keys -> class */
  size_t nb = 1;
  while (nb < (size_t)j->nvox * 2) nb <<= 1;
  int *head = malloc(nb * sizeof *head), *link = malloc((j->nvox + 1) * sizeof *link);
  if (!head || !link) { free(head); free(link); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (size_t b = 0; b < nb; b++) head[b] = -1;
  memset(&j->st.voxels, 0, sizeof j->st.voxels);
  for (int v = 0; v < j->nvox; v++) {
    j->vcls[v] = -1;
    if (j->vspec[v] < 0 || j->vstate[v] == 0) continue;
    char *sig = voxel_signature(j, v, e);
    if (!sig) { free(head); free(link); return e->code; }
    char key[65];
    if (j->vstate[v] == 2 || direct) {
      char buf[64];
      snprintf(buf, sizeof buf, ", voxel: %d, trimmed: %d", v, j->vstate[v] == 2);
      size_t sl = strlen(sig);
      char *s2 = realloc(sig, sl + strlen(buf) + 1);
      if (!s2) { free(sig); free(head); free(link); return gr_fail(e, GR_EMEM, "out of memory"); }
      sig = s2;
      memmove(sig + sl - 1, buf, strlen(buf) + 1);
      strcat(sig, "}");
    }
    gr_sha256_hex(sig, strlen(sig), key);
    size_t b = strtoull(key + 48, NULL, 16) & (nb - 1);
    int c = head[b];
    while (c >= 0 && strcmp(j->cls[c].key, key) != 0) c = link[c];
    if (c < 0) {
      c = j->ncls++;
      memset(&j->cls[c], 0, sizeof j->cls[c]);
      j->cls[c].rep = v;
      j->cls[c].sig = sig;
      j->cls[c].trimmed = j->vstate[v] == 2;
      memcpy(j->cls[c].key, key, 65);
      link[c] = head[b];
      head[b] = c;
    } else {
      free(sig);
    }
    j->cls[c].count++;
    j->vcls[v] = c;
    j->st.voxels++;
    if (j->vstate[v] == 2) j->st.trimmed++;
  }
  free(head);
  free(link);
  j->st.classes = j->ncls;
  return GR_OK;
}

/* ---- template build ---- */

/* -domain - skin, negative inside the skin band's inner side. */
typedef struct skin_ud { gr_field *d; double s; } skin_ud;
static int skin_eval(void *ud, size_t n, const double *x, const double *y,
                     const double *z, double *out, gr_err *e) {
  skin_ud *k = ud;
  if (gr_field_eval(k->d, n, x, y, z, out, e)) return e->code;
  for (size_t i = 0; i < n; i++) out[i] = -out[i] - k->s;
  return GR_OK;
}
static void skin_free(void *ud) {
  skin_ud *k = ud;
  gr_field_free(k->d);
  free(k);
}
static gr_field *skin_field(gr_field *d, double s) {
  skin_ud *k = malloc(sizeof *k);
  if (!k) return NULL;
  k->d = gr_field_ref(d);
  k->s = s;
  gr_field *f = gr_field_callback(skin_eval, NULL, k, skin_free, gr_field_threadsafe(d), "skin");
  if (!f) skin_free(k);
  return f;
}

/* The graded field of voxel v (offset field of its spec, with H meshed over
 * the voxel grown by a margin), intersected with the domain when trimmed. */
static gr_field *voxel_field(gr_job *j, int v, int trimmed, gr_field *like, const double shift[3],
                             double extra, gr_err *e) {
  const gr_spec *s = &j->specs[j->vspec[v]];
  double o[3];
  voxel_origin(j, v, o);
  gr_field *phi = gr_field_tpms(gr_tpms_name(s->surface), j->o.cell, j->o.origin, s->level, e);
  if (!phi) return NULL;
  gr_offset_opts oo = gr_offset_defaults();
  oo.surface = phi;
  oo.cell = j->o.cell;
  oo.like = like;
  for (int a = 0; a < 3 && like; a++) oo.like_shift[a] = shift[a];
  for (int a = 0; a < 3; a++) oo.origin[a] = j->o.origin[a];
  for (int a = 0; a < 3; a++) oo.box_lo[a] = o[a];
  for (int a = 0; a < 3; a++) oo.box_hi[a] = o[a] + j->o.cell;
  oo.margin = j->o.beam_offset + (j->o.contours + 2) * j->o.hatch + 4 * j->o.slice_cell + extra;
  oo.res = j->o.res;
  oo.thickness_expr = j->specs[j->vspec[v]].thickness;
  oo.inside_expr = s->inside[0] ? s->inside : NULL;
  oo.density = s->density;
  if (s->target) oo.thickness_expr = NULL, oo.thickness_field = s->target;
  oo.kind = s->network ? GR_OFFSET_NETWORK : GR_OFFSET_SHEET;
  oo.side = s->side;
  oo.mode = j->o.exact ? GR_DIST_EXACT : GR_DIST_MESH;
  gr_field *g = gr_offset_field_new(&oo, e);
  gr_field_free(phi);
  if (!g) return NULL;
  if (trimmed && j->domain) {
    gr_field *f = g;
    if (j->skin > 0) {
      /* solid skin {-skin <= domain <= 0}: part = max(domain, min(g, -domain - skin)) */
      gr_field *sk = skin_field(j->domain, j->skin);
      gr_field *inner = sk ? gr_field_min(g, sk) : NULL;
      gr_field_free(sk);
      f = inner ? gr_field_max(j->domain, inner) : NULL;
      gr_field_free(inner);
    } else {
      f = gr_field_max(g, j->domain);
    }
    gr_field_free(g);
    g = f;
    if (!g) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  return g;
}

/* Liang-Barsky: clip segment p->q to the box; returns 0 if nothing is left,
 * else the parameters t0 <= t1 in [0,1]. */
static int clip_seg(double px, double py, double qx, double qy, const double lo[2],
                    const double hi[2], double *t0, double *t1) {
  double a = 0, b = 1;
  double dx = qx - px, dy = qy - py;
  double pp[4] = {-dx, dx, -dy, dy};
  double qq[4] = {px - lo[0], hi[0] - px, py - lo[1], hi[1] - py};
  for (int i = 0; i < 4; i++) {
    if (pp[i] == 0) {
      if (qq[i] < 0) return 0;
    } else {
      double r = qq[i] / pp[i];
      if (pp[i] < 0) { if (r > b) return 0; if (r > a) a = r; }
      else { if (r < a) return 0; if (r < b) b = r; }
    }
  }
  *t0 = a;
  *t1 = b;
  return a <= b;
}

/* Clip one polyline (closed: the last point joins the first; the first point
 * may or may not be repeated) to the box and append the pieces to `out`: a
 * closed polyline wholly inside stays GR_CLOSED (first point repeated), the
 * rest become GR_OPEN pieces that start and end on the box border. */
/* CLI direction of an open piece cut from a block of direction dir:
 * thin-wall lines keep their tag, everything else becomes "open" (2). */
static int open_dir(int dir) { return dir == GR_DIR_THIN ? GR_DIR_THIN : 2; }

static int clip_poly(const double *p, size_t n, int closed, int kind, int dir,
                     const double lo[2], const double hi[2], gr_layer *out,
                     double **buf, size_t *cap) {
  if (closed && n > 1 && p[0] == p[2 * (n - 1)] && p[1] == p[2 * (n - 1) + 1]) n--;
  int odir = open_dir(dir);
  if (n < 2) return GR_OK;
  if (gr_grow(buf, cap, n + 2, 2 * sizeof(double))) return GR_EMEM;
  double *bf = *buf;
  size_t s0 = n;
  for (size_t k = 0; k < n; k++)
    if (p[2 * k] < lo[0] || p[2 * k] > hi[0] || p[2 * k + 1] < lo[1] || p[2 * k + 1] > hi[1]) { s0 = k; break; }
  if (s0 == n) { /* wholly inside */
    memcpy(bf, p, n * 2 * sizeof(double));
    size_t m = n;
    if (closed) { bf[2 * n] = p[0]; bf[2 * n + 1] = p[1]; m++; }
    return gr_layer_add(out, closed ? GR_CLOSED : GR_OPEN, kind, 0, closed ? dir : odir, bf, m);
  }
  if (!closed) s0 = 0;
  size_t nedges = closed ? n : n - 1, m = 0;
  for (size_t e = 0; e < nedges; e++) {
    size_t a = (s0 + e) % n, b = (s0 + e + 1) % n;
    double ax = p[2 * a], ay = p[2 * a + 1], bx = p[2 * b], by = p[2 * b + 1];
    double t0, t1;
    if (!clip_seg(ax, ay, bx, by, lo, hi, &t0, &t1)) continue;
    if (t0 > 0 || m == 0) {
      if (m >= 2 && gr_layer_add(out, GR_OPEN, kind, 0, odir, bf, m)) return GR_EMEM;
      bf[0] = ax + t0 * (bx - ax);
      bf[1] = ay + t0 * (by - ay);
      m = 1;
    }
    bf[2 * m] = t1 < 1 ? ax + t1 * (bx - ax) : bx;
    bf[2 * m + 1] = t1 < 1 ? ay + t1 * (by - ay) : by;
    m++;
    if (t1 < 1) {
      if (m >= 2 && gr_layer_add(out, GR_OPEN, kind, 0, odir, bf, m)) return GR_EMEM;
      m = 0;
    }
  }
  if (m >= 2 && gr_layer_add(out, GR_OPEN, kind, 0, odir, bf, m)) return GR_EMEM;
  return GR_OK;
}

/* Area of the region bounded by `r` (signed ring areas) inside the box:
 * each ring clipped by Sutherland-Hodgman against the four box edges; the
 * degenerate edges this leaves along the border have no area. */
static double area_in_box(const gr_rings *r, const double lo[2], const double hi[2]) {
  double total = 0;
  size_t cap = 0;
  double *a = NULL, *b = NULL;
  size_t capb = 0;
  for (size_t i = 0; i < r->nrings; i++) {
    size_t n = gr_ring_len(r, i);
    if (gr_grow(&a, &cap, 2 * n + 8, 2 * sizeof(double)) || gr_grow(&b, &capb, 2 * n + 8, 2 * sizeof(double))) break;
    memcpy(a, gr_ring_xy(r, i), n * 2 * sizeof(double));
    for (int edge = 0; edge < 4 && n > 0; edge++) {
      int ax = edge & 1;          /* 0: x, 1: y */
      int upper = edge >= 2;      /* 0: keep >= lo, 1: keep <= hi */
      double c = upper ? hi[ax] : lo[ax];
      size_t m = 0;
      if (gr_grow(&b, &capb, 2 * n + 8, 2 * sizeof(double))) break;
      for (size_t k = 0; k < n; k++) {
        const double *P = a + 2 * ((k + n - 1) % n), *Q = a + 2 * k;
        int pin = upper ? P[ax] <= c : P[ax] >= c, qin = upper ? Q[ax] <= c : Q[ax] >= c;
        if (qin != pin) {
          double t = (c - P[ax]) / (Q[ax] - P[ax]);
          b[2 * m] = P[0] + t * (Q[0] - P[0]);
          b[2 * m + 1] = P[1] + t * (Q[1] - P[1]);
          b[2 * m + ax] = c;
          m++;
        }
        if (qin) { b[2 * m] = Q[0]; b[2 * m + 1] = Q[1]; m++; }
      }
      double *t = a; a = b; b = t;
      size_t tc = cap; cap = capb; capb = tc;
      n = m;
      if (gr_grow(&a, &cap, 2 * n + 8, 2 * sizeof(double))) { n = 0; break; }
    }
    double ar = 0;
    for (size_t k = 0, q = n ? n - 1 : 0; k < n; q = k++) ar += a[2 * q] * a[2 * k + 1] - a[2 * k] * a[2 * q + 1];
    total += 0.5 * ar;
  }
  free(a);
  free(b);
  return total;
}

/* Chords of sections and contours deviate from the true curve by at most
 * this (mm): refined midpoints are inserted where they would not. */
#define CHORD_TOL 2e-4
/* Hatch regions are simplified to this (mm): hatch ends move by at most this. */
#define REGION_TOL 1e-4

static int offset_fine(const gr_rings *in, double b, double cell, gr_rings *out, gr_err *e) {
  return gr_offset_rings_opt(in, b, cell, 1e-6, 0, out, e);
}

/* Allocate class c's template for local layers [ja, jb). */
static int template_alloc(gr_job *j, int c, int ja, int jb, gr_err *e) {
  tmpl *t = calloc(1, sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory");
  t->j0 = ja;
  t->nl = jb - ja;
  t->l = calloc(t->nl > 0 ? t->nl : 1, sizeof *t->l);
  if (!t->l) { free(t); return gr_fail(e, GR_EMEM, "out of memory"); }
  tmpl_free(j->cls[c].t);
  j->cls[c].t = t;
  return GR_OK;
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
 * line can be nearer than R; inside/outside from the crossings cr (sorted). */
typedef struct fline {
  double x0, y0, ux, uy, R;
  const double *ed;  /* candidate edges (4 per edge) */
  size_t ne;
  const double *cr;  /* crossing parameters, sorted */
  size_t nc;
} fline;

static double fline_value(const fline *f, double t) {
  double px = f->x0 + t * f->ux, py = f->y0 + t * f->uy, best = f->R * f->R;
  for (size_t k = 0; k < f->ne; k++) {
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

/* The side segment [ta, tb] of the line, oriented like the contours (the
 * part on the left): down along x = c, up along x = L - c, and so on. */
static int face_seg(gr_layer *l, const fline *f, int side, double ta, double tb) {
  int rev = side == 0 || side == 3;
  double a = rev ? tb : ta, b = rev ? ta : tb;
  double seg[4] = {f->x0 + a * f->ux, f->y0 + a * f->uy, f->x0 + b * f->ux, f->y0 + b * f->uy};
  return gr_layer_add(l, GR_OPEN, GR_CONTOUR, side, 2, seg, 2);
}

static int face_lines(const gr_job *j, tlayer *tl) {
  if (!tl->faces && !(tl->faces = gr_layer_new(0))) return GR_EMEM;
  gr_layer_clear(tl->faces, 0);
  const gr_rings *r = tl->section;
  double L = j->o.cell, b = j->o.beam_offset, d = j->o.hatch, step = j->o.slice_cell / 4;
  int nc = j->o.contours;
  if (nc <= 0 || r->npts == 0) return GR_OK;
  double R = b + (nc - 1) * d + 2 * step;
  double *ed = malloc(4 * r->npts * sizeof *ed), *cr = malloc((r->npts + 1) * sizeof *cr);
  if (!ed || !cr) { free(ed); free(cr); return GR_EMEM; }
  int rc = GR_OK;
  for (int side = 0; side < 4 && rc == GR_OK; side++) {
    int vert = side < 2; /* x = const */
    for (int k = 0; k < nc && rc == GR_OK; k++) {
      double c = b + k * d, pos = (side & 1) ? L - c : c;
      fline f = {vert ? pos : 0, vert ? 0 : pos, vert ? 0 : 1, vert ? 1 : 0, R, ed, 0, cr, 0};
      for (size_t i = 0; i < r->nrings; i++) {
        const double *p = gr_ring_xy(r, i);
        size_t n = gr_ring_len(r, i);
        for (size_t a = 0; a < n; a++) {
          const double *P = p + 2 * a, *Q = p + 2 * ((a + 1) % n);
          double pa = vert ? P[0] : P[1], qa = vert ? Q[0] : Q[1];   /* across the line */
          double pl = vert ? P[1] : P[0], ql = vert ? Q[1] : Q[0];   /* along it */
          if ((pa > pos) != (qa > pos)) cr[f.nc++] = pl + (pos - pa) * (ql - pl) / (qa - pa);
          if (fmin(pa, qa) <= pos + R && fmax(pa, qa) >= pos - R) {
            double *e4 = ed + 4 * f.ne++;
            e4[0] = P[0]; e4[1] = P[1]; e4[2] = Q[0]; e4[3] = Q[1];
          }
        }
      }
      qsort(cr, f.nc, sizeof *cr, dbl_cmp);
      /* intervals of [0, L] where the value is <= -c: sample, then bisect the ends */
      int ns = (int)ceil(L / step);
      double t0 = 0, v0 = fline_value(&f, 0) + c, start = v0 <= 0 ? 0 : NAN;
      for (int q = 1; q <= ns && rc == GR_OK; q++) {
        double t1 = q == ns ? L : q * step, v1 = fline_value(&f, t1) + c;
        if ((v0 <= 0) != (v1 <= 0)) {
          double lo = t0, hi = t1, vlo = v0;
          for (int it = 0; it < 40 && hi - lo > 1e-7; it++) {
            double m = 0.5 * (lo + hi), vm = fline_value(&f, m) + c;
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
static int verify_template_layer(const gr_job *j, tlayer *tl, double angle, gr_err *e) {
  gr_layer *l = gr_layer_new(0);
  if (!l) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = gr_layer_append(l, tl->paths, 0, 0) ? gr_fail(e, GR_EMEM, "out of memory") : GR_OK;
  gr_hatch_opts ho = gr_hatch_defaults();
  ho.spacing = j->o.hatch;
  ho.angle = angle;
  ho.contours = 0;
  if (rc == GR_OK) rc = gr_hatch_region(tl->region, &ho, l, NULL, e);
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = j->o.track;
  vo.pixel = j->o.track / 10;
  vo.offset = j->o.beam_offset;
  vo.spacing = j->o.hatch;
  vo.contours = j->o.contours > 0 ? j->o.contours : 1;
  vo.clip = 1;
  vo.clip_lo[0] = vo.clip_lo[1] = 0;
  vo.clip_hi[0] = vo.clip_hi[1] = j->o.cell;
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
 * wide enough for the contours and hatch region of the voxel's edge. */
static double window_margin(const gr_job *j) {
  double h = j->o.slice_cell;
  return ceil((j->o.beam_offset + (j->o.contours + 1) * j->o.hatch + 2 * h) / h) * h;
}

/* ---- shared closest points ----
 * Classes that differ only in thickness (same surface, level, kind, z-phase
 * and layers: the rows of a part graded along its height, say) share H. The
 * closest point of every slice-grid node is computed once for the group,
 * over one period of the grid (L = P h), and each class only evaluates its
 * own T there; crossings are refined from the nearest node's closest point
 * instead of searching the mesh. Exact mode only (mesh mode's H depends on
 * the voxel's box). */
typedef struct cptab {
  int P;          /* nodes per period */
  int ref;        /* reference class */
  double lo[2];   /* slice window corner of the reference voxel, mm */
  double oref[3]; /* reference voxel origin, mm */
  double dmax;    /* closest points are exact within this distance of H, mm */
  double *q, *sd; /* per template layer, P*P nodes: closest point, signed distance */
} cptab;

static void cptab_free(cptab *t) {
  if (!t) return;
  free(t->q);
  free(t->sd);
  free(t);
}

/* Nodes per period, or 0 when the slice grid is not periodic with the cell. */
static int grid_period(const gr_job *j) {
  double P = j->o.cell / j->o.slice_cell;
  return fabs(P - round(P)) < 1e-9 * P && round(P) >= 2 ? (int)round(P) : 0;
}

/* Closest points of table layer q (thread-safe for distinct q). */
static int cptab_layer(gr_job *j, const cptab *t, int q, gr_err *e) {
  const vclass *cl = &j->cls[t->ref];
  int i, jj, k;
  voxel_ijk(j, cl->rep, &i, &jj, &k);
  size_t n = (size_t)t->P * t->P;
  double *x = malloc(3 * n * sizeof *x);
  if (!x) return gr_fail(e, GR_EMEM, "out of memory");
  double *y = x + n, *z = x + 2 * n, zq = layer_mid(j, row_first_layer(j, k) + cl->t->j0 + q);
  for (int b = 0; b < t->P; b++)
    for (int a = 0; a < t->P; a++) {
      x[a + (size_t)t->P * b] = t->lo[0] + a * j->o.slice_cell;
      y[a + (size_t)t->P * b] = t->lo[1] + b * j->o.slice_cell;
      z[a + (size_t)t->P * b] = zq;
    }
  int rc = gr_offset_closest(cl->field, n, x, y, z, t->dmax, t->q + 3 * n * q, t->sd + n * q, e);
  free(x);
  return rc;
}

/* Refinement on the true field from the closest points of the nearest nodes. */
typedef struct near_ud {
  const gr_field *f;
  double z, lo[2], h;
  int nx, ny;
  const double *q; /* 3 per window node */
} near_ud;


/* Value (and in-plane gradient when gx != NULL) at n points. */
static int near_eval(void *ud_, size_t n, const double *x, const double *y, double *out,
                     double *gx, double *gy, gr_err *e) {
  const near_ud *u = ud_;
  enum { B = 256 };
  double hint[3 * B], zb[B], g[3 * B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B;
    for (size_t i = 0; i < m; i++) {
      double fx = (x[s + i] - u->lo[0]) / u->h, fy = (y[s + i] - u->lo[1]) / u->h;
      int a = (int)floor(fx), b = (int)floor(fy);
      double best = INFINITY;
      hint[3 * i] = hint[3 * i + 1] = hint[3 * i + 2] = NAN;
      for (int c = 0; c < 4; c++) {
        int ia = a + (c & 1), ib = b + (c >> 1);
        if (ia < 0 || ib < 0 || ia >= u->nx || ib >= u->ny) continue;
        const double *q = u->q + 3 * (ia + (size_t)u->nx * ib);
        double d2 = (fx - ia) * (fx - ia) + (fy - ib) * (fy - ib);
        if (!isnan(q[0]) && d2 < best) {
          /* the node's closest point moved along the tangent plane there
           * by the point's offset from the node */
          double c[3] = {u->lo[0] + ia * u->h, u->lo[1] + ib * u->h, u->z};
          double nv[3] = {c[0] - q[0], c[1] - q[1], c[2] - q[2]}, dp[3] = {x[s + i] - c[0], y[s + i] - c[1], 0};
          double nn = sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
          double dn = nn > 1e-9 ? (dp[0] * nv[0] + dp[1] * nv[1]) / (nn * nn) : 0;
          best = d2;
          for (int k = 0; k < 3; k++) hint[3 * i + k] = q[k] + dp[k] - dn * nv[k];
        }
      }
      zb[i] = u->z;
    }
    int rc = gr_offset_eval_near(u->f, m, x + s, y + s, zb, hint, out + s, gx ? g : NULL, e);
    if (rc) return rc;
    if (gx)
      for (size_t i = 0; i < m; i++) {
        gx[s + i] = g[3 * i];
        gy[s + i] = g[3 * i + 1];
      }
  }
  return GR_OK;
}
static int near_fn(void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  return near_eval(ud, n, x, y, out, NULL, NULL, e);
}

/* Section of class c's layer at z (template layer q) through the table. */
static int slice_shared(gr_job *j, const cptab *t, const gr_field *f, const double o[3], int q,
                        double z, const gr_slice_opts *so, gr_rings *out, gr_err *e) {
  int nx, ny;
  double hx, hy, L = j->o.cell;
  gr_slice_grid_size(so, &nx, &ny, &hx, &hy);
  size_t nn = (size_t)nx * ny, np = (size_t)t->P * t->P;
  double *Q = malloc(5 * nn * sizeof *Q);
  if (!Q) return gr_fail(e, GR_EMEM, "out of memory");
  double *sd = Q + 3 * nn, *v = Q + 4 * nn;
  double sh[3] = {o[0] - t->oref[0], o[1] - t->oref[1], o[2] - t->oref[2]};
  const double *tq = t->q + 3 * np * q, *tsd = t->sd + np * q;
  for (int b = 0; b < ny; b++)
    for (int a = 0; a < nx; a++) {
      size_t n = a + (size_t)nx * b, k = a % t->P + (size_t)t->P * (b % t->P);
      Q[3 * n] = tq[3 * k] + sh[0] + (a / t->P) * L;
      Q[3 * n + 1] = tq[3 * k + 1] + sh[1] + (b / t->P) * L;
      Q[3 * n + 2] = tq[3 * k + 2] + sh[2];
      sd[n] = tsd[k];
    }
  int rc = gr_offset_values(f, nn, Q, sd, v, e);
  near_ud u = {f, z, {so->lo[0], so->lo[1]}, hx, nx, ny, Q};
  if (!rc) rc = gr_slice_grid(v, so, near_fn, near_eval, &u, out, e);
  free(Q);
  return rc;
}

/* Compute local layers [qa, qb) (indices into the template) of class c
 * with its field f, through the shared closest points tab if not NULL.
 * Thread-safe for disjoint layer ranges. */
static int build_layers(gr_job *j, int c, const gr_field *f, const cptab *tab, int qa, int qb, gr_err *e) {
  vclass *cl = &j->cls[c];
  tmpl *t = cl->t;
  int v = cl->rep;
  double o[3];
  voxel_origin(j, v, o);
  int i, jj, k;
  voxel_ijk(j, v, &i, &jj, &k);
  int g0 = row_first_layer(j, k);
  double L = j->o.cell, h = j->o.slice_cell;
  double m = window_margin(j);
  gr_slice_opts so = gr_slice_defaults();
  so.lo[0] = o[0] - m;
  so.lo[1] = o[1] - m;
  so.hi[0] = o[0] + L + m;
  so.hi[1] = o[1] + L + m;
  so.cell = h;
  so.refine = 1;
  so.chord_tol = CHORD_TOL;
  double box_lo[2] = {0, 0}, box_hi[2] = {L, L};
  gr_hatch_opts ho = gr_hatch_defaults();
  ho.spacing = j->o.hatch;
  ho.beam_offset = j->o.beam_offset;
  ho.contours = j->o.contours;
  ho.cell = h;
  ho.pattern = GR_PARALLEL;
  ho.offset = offset_fine;
  /* the window's cut edges are not walls: thin walls only where they reach the voxel */
  ho.thin_box[0] = ho.thin_box[1] = -j->o.beam_offset;
  ho.thin_box[2] = ho.thin_box[3] = L + j->o.beam_offset;
  gr_layer *tmp = gr_layer_new(0);
  double *buf = NULL;
  size_t cap = 0;
  int rc = tmp ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  for (int q = qa; q < qb && rc == GR_OK; q++) {
    tlayer *tl = &t->l[q];
    tl->section = gr_rings_new();
    tl->region = gr_rings_new();
    tl->paths = gr_layer_new(0);
    if (!tl->section || !tl->region || !tl->paths) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    double z = layer_mid(j, g0 + t->j0 + q);
    if ((rc = tab ? slice_shared(j, tab, f, o, q, z, &so, tl->section, e) : gr_slice_field(f, z, &so, tl->section, e))) break;
    gr_rings_translate(tl->section, -o[0], -o[1]);
    tl->area = area_in_box(tl->section, box_lo, box_hi);
    /* contours and thin-wall scans of the window, clipped to the voxel */
    gr_layer_clear(tmp, 0);
    gr_hatch_report rep;
    memset(&rep, 0, sizeof rep);
    if ((rc = gr_hatch_layer(tl->section, &ho, tmp, &rep, e))) break;
    for (size_t b = 0; b < tmp->nb && rc == GR_OK; b++) {
      const gr_block *bk = &tmp->b[b];
      if (bk->kind == GR_HATCH) continue;
      if (clip_poly(tmp->xy + 2 * bk->start, bk->n, bk->shape == GR_CLOSED, bk->kind, bk->dir, box_lo, box_hi,
                    tl->paths, &buf, &cap))
        rc = gr_fail(e, GR_EMEM, "out of memory");
    }
    tl->paths->thin_walls = rep.thin_walls;
    if (rc == GR_OK) rc = offset_fine(tl->section, rep.hatch_offset, h, tl->region, e);
    /* hatch ends need no sub-micrometre region: fewer edges to scan per instance */
    if (rc == GR_OK && gr_rings_simplify(tl->region, REGION_TOL)) rc = gr_fail(e, GR_EMEM, "out of memory");
    if (rc == GR_OK && face_lines(j, tl)) rc = gr_fail(e, GR_EMEM, "out of memory");
    tl->q[0] = tl->q[1] = tl->q[2] = NAN;
    if (rc == GR_OK && j->o.verify) rc = verify_template_layer(j, tl, gr_job_angle(j, g0 + t->j0 + q), e);
  }
  free(buf);
  gr_layer_free(tmp);
  return rc;
}

/* ---- placement of one layer ---- */
typedef struct seg {
  double x0, y0, x1, y1; /* global, mm */
  long line;             /* index on the global line family */
  double s0, s1;         /* positions along the line direction (s0 < s1) */
  int laser;
  int voxel;             /* position in the row order */
} seg;

typedef struct scratch {
  gr_rings *rg;          /* region translated to global coordinates */
  gr_layer *hl;          /* hatch output of one voxel */
  gr_layer *cont;        /* contour pieces of the layer, block.laser = voxel slot */
  seg *segs, *segs2;     /* the layer's hatch segments; segs2: sorting space */
  size_t nseg, capseg, capseg2;
  size_t *bucket;        /* sorting: counts per (laser, line) */
  size_t capbucket;
  double *vtime;         /* per voxel slot: estimated scan time */
  int *vlas;             /* per voxel slot: laser */
  size_t *vseg0, *vseg1; /* per voxel slot: its segments */
  size_t *vcont0, *vcont1; /* per voxel slot: its contour blocks */
  double *pts;
  size_t cappts;
  long *link;
  size_t caplink;
  gr_layer *fl;          /* contours of a boundary voxel, voxel-local */
  double *cbuf;
  size_t capcbuf;
} scratch;

static void scratch_free(scratch *s) {
  gr_rings_free(s->rg);
  gr_layer_free(s->fl);
  free(s->cbuf);
  gr_layer_free(s->hl);
  gr_layer_free(s->cont);
  free(s->segs);
  free(s->segs2);
  free(s->bucket);
  free(s->vtime);
  free(s->vlas);
  free(s->vseg0);
  free(s->vseg1);
  free(s->vcont0);
  free(s->vcont1);
  free(s->pts);
  free(s->link);
}

static int scratch_init(scratch *s, int nrow) {
  memset(s, 0, sizeof *s);
  s->rg = gr_rings_new();
  s->hl = gr_layer_new(0);
  s->cont = gr_layer_new(0);
  s->fl = gr_layer_new(0);
  s->vtime = calloc(nrow, sizeof *s->vtime);
  s->vlas = calloc(nrow, sizeof *s->vlas);
  s->vseg0 = calloc(nrow, sizeof(size_t));
  s->vseg1 = calloc(nrow, sizeof(size_t));
  s->vcont0 = calloc(nrow, sizeof(size_t));
  s->vcont1 = calloc(nrow, sizeof(size_t));
  if (!s->rg || !s->hl || !s->cont || !s->fl || !s->vtime || !s->vlas || !s->vseg0 || !s->vseg1 ||
      !s->vcont0 || !s->vcont1)
    return GR_EMEM;
  return GR_OK;
}

static int seg_cmp(const void *a, const void *b) {
  const seg *p = a, *q = b;
  if (p->laser != q->laser) return p->laser < q->laser ? -1 : 1;
  if (p->line != q->line) return p->line < q->line ? -1 : 1;
  return (p->s0 > q->s0) - (p->s0 < q->s0);
}

/* Order the layer's segments as seg_cmp does, stably: a counting sort on
 * (laser, line), then insertion sort by s0 within a line (a line crosses
 * one row of voxels, so few segments share it). qsort when the lines are
 * too sparse for buckets. */
static int sort_segs(scratch *s, gr_err *e) {
  size_t n = s->nseg;
  if (n < 2) return GR_OK;
  long lo = LONG_MAX, hi = LONG_MIN;
  int lmax = 0;
  for (size_t r = 0; r < n; r++) {
    if (s->segs[r].line < lo) lo = s->segs[r].line;
    if (s->segs[r].line > hi) hi = s->segs[r].line;
    if (s->segs[r].laser > lmax) lmax = s->segs[r].laser;
  }
  size_t nl = (size_t)(hi - lo) + 1, nb = nl * (size_t)(lmax + 1);
  if (hi - lo > 4 * (long)n + 4096 || nb > 8 * n + 65536) {
    qsort(s->segs, n, sizeof *s->segs, seg_cmp);
    return GR_OK;
  }
  if (gr_grow(&s->bucket, &s->capbucket, nb + 1, sizeof *s->bucket) ||
      gr_grow(&s->segs2, &s->capseg2, n, sizeof *s->segs2))
    return gr_fail(e, GR_EMEM, "out of memory");
  size_t *c = s->bucket;
  memset(c, 0, (nb + 1) * sizeof *c);
  for (size_t r = 0; r < n; r++) c[(size_t)s->segs[r].laser * nl + (size_t)(s->segs[r].line - lo) + 1]++;
  for (size_t b = 0; b < nb; b++) c[b + 1] += c[b];
  for (size_t r = 0; r < n; r++) s->segs2[c[(size_t)s->segs[r].laser * nl + (size_t)(s->segs[r].line - lo)]++] = s->segs[r];
  /* c[b] is now the end of bucket b */
  for (size_t b = 0, a = 0; b < nb; a = c[b++])
    for (size_t r = a + 1; r < c[b]; r++) {
      seg x = s->segs2[r];
      size_t q = r;
      while (q > a && s->segs2[q - 1].s0 > x.s0) { s->segs2[q] = s->segs2[q - 1]; q--; }
      s->segs2[q] = x;
    }
  seg *t = s->segs;
  size_t tc = s->capseg;
  s->segs = s->segs2;
  s->capseg = s->capseg2;
  s->segs2 = t;
  s->capseg2 = tc;
  return GR_OK;
}

/* The hatch angle of global layer g (1-based), degrees in [0, 360). */
double gr_job_angle(const gr_job *j, int g) {
  double a = fmod(j->o.angle + (g - 1) * j->o.rotation, 360.0);
  return a < 0 ? a + 360 : a;
}

/* Hatch one voxel: its template region translated to global coordinates,
 * lines of the global family at angle a, clipped to the voxel square. */
/* Sides of voxel v on the part's boundary (no lattice beyond): bits 1 x=0,
 * 2 x=L, 4 y=0, 8 y=L; 0 when the job leaves cut sides open. */
static int voxel_sides(const gr_job *j, int v) {
  if (!j->o.faces) return 0;
  int i, jj, k, nx = j->o.n[0], ny = j->o.n[1], m = 0;
  voxel_ijk(j, v, &i, &jj, &k);
  if (i == 0 || j->vcls[v - 1] < 0) m |= 1;
  if (i == nx - 1 || j->vcls[v + 1] < 0) m |= 2;
  if (jj == 0 || j->vcls[v - nx] < 0) m |= 4;
  if (jj == ny - 1 || j->vcls[v + nx] < 0) m |= 8;
  (void)ny;
  return m;
}

/* The voxel square [0, L]^2 with the sides in mask moved in by c (mm). */
static void side_box(const gr_job *j, int mask, double c, double lo[2], double hi[2]) {
  double L = j->o.cell;
  lo[0] = (mask & 1) ? c : 0;
  hi[0] = (mask & 2) ? L - c : L;
  lo[1] = (mask & 4) ? c : 0;
  hi[1] = (mask & 8) ? L - c : L;
}

/* Offset of the hatch region from the section boundary (hatch.h), mm. */
static double hatch_offset(const gr_job *j) {
  double gap = gr_hatch_defaults().gap;
  int n = j->o.contours;
  return n == 0 ? j->o.beam_offset + gap : j->o.beam_offset + (n - 1) * j->o.hatch + gap;
}

/* Contours of boundary voxel tl (sides in mask): the template's cut by the
 * sides moved in by b, plus the side segments; voxel-local, into s->fl. */
static int boundary_contours(const gr_job *j, scratch *s, const tlayer *tl, int mask) {
  double lo[2], hi[2];
  side_box(j, mask, j->o.beam_offset, lo, hi);
  gr_layer_clear(s->fl, 0);
  for (size_t b = 0; b < tl->paths->nb; b++) {
    const gr_block *bk = &tl->paths->b[b];
    if (clip_poly(tl->paths->xy + 2 * bk->start, bk->n, bk->shape == GR_CLOSED, bk->kind, bk->dir, lo, hi, s->fl,
                  &s->cbuf, &s->capcbuf))
      return GR_EMEM;
  }
  for (size_t b = 0; tl->faces && b < tl->faces->nb; b++) {
    const gr_block *bk = &tl->faces->b[b];
    if (!((mask >> bk->laser) & 1)) continue;
    if (clip_poly(tl->faces->xy + 2 * bk->start, bk->n, 0, bk->kind, 2, lo, hi, s->fl, &s->cbuf, &s->capcbuf))
      return GR_EMEM;
  }
  s->fl->thin_walls = tl->paths->thin_walls;
  return GR_OK;
}

static int hatch_voxel(gr_job *j, scratch *s, const tlayer *tl, const double o[3],
                       double a, int slot, int mask, gr_err *e) {
  if (tl->region->nrings == 0) return GR_OK;
  if (gr_rings_copy(s->rg, tl->region)) return gr_fail(e, GR_EMEM, "out of memory");
  gr_rings_translate(s->rg, o[0], o[1]);
  gr_layer_clear(s->hl, 0);
  gr_hatch_opts ho = gr_hatch_defaults();
  ho.spacing = j->o.hatch;
  ho.angle = a;
  ho.pattern = GR_PARALLEL;
  ho.alternate = 0;
  ho.contours = 0;
  if (gr_hatch_region(s->rg, &ho, s->hl, NULL, e)) return e->code;
  double ca = cos(a * M_PI / 180), sa = sin(a * M_PI / 180);
  double lo[2], hi[2];
  side_box(j, mask, hatch_offset(j), lo, hi);
  for (int k = 0; k < 2; k++) { lo[k] += o[k]; hi[k] += o[k]; }
  for (size_t b = 0; b < s->hl->nb; b++) {
    const gr_block *bk = &s->hl->b[b];
    const double *p = s->hl->xy + 2 * bk->start;
    for (size_t q = 0; q + 1 < bk->n; q += 2) {
      double t0, t1, px = p[2 * q], py = p[2 * q + 1], qx = p[2 * q + 2], qy = p[2 * q + 3];
      if (!clip_seg(px, py, qx, qy, lo, hi, &t0, &t1)) continue;
      double ax = px + t0 * (qx - px), ay = py + t0 * (qy - py);
      double bx = px + t1 * (qx - px), by = py + t1 * (qy - py);
      double sa0 = ax * ca + ay * sa, sb0 = bx * ca + by * sa;
      if (fabs(sb0 - sa0) < 1e-9) continue;
      if (gr_grow(&s->segs, &s->capseg, s->nseg + 1, sizeof *s->segs)) return gr_fail(e, GR_EMEM, "out of memory");
      seg *sg = &s->segs[s->nseg++];
      if (sb0 < sa0) { double tx = ax, ty = ay; ax = bx; ay = by; bx = tx; by = ty; double ts = sa0; sa0 = sb0; sb0 = ts; }
      sg->x0 = ax; sg->y0 = ay; sg->x1 = bx; sg->y1 = by;
      sg->s0 = sa0; sg->s1 = sb0;
      sg->line = lround((-ax * sa + ay * ca) / j->o.hatch);
      sg->laser = 0;
      sg->voxel = slot;
    }
  }
  return GR_OK;
}

static int triple_cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Join open contour pieces whose end meets another's start (within tol, same
 * laser) into chains; closed chains become GR_CLOSED loops. Pieces come from
 * s->cont blocks [b0, b1); output appended to `out`. */
static int join_contours(scratch *s, size_t b0, size_t b1, double tol, gr_layer *out,
                         const int *slot_laser, gr_err *e) {
  gr_layer *c = s->cont;
  size_t n = b1 - b0;
  if (n == 0) return GR_OK;
  if (gr_grow(&s->link, &s->caplink, 3 * n, sizeof *s->link)) return gr_fail(e, GR_EMEM, "out of memory");
  long *next = s->link, *prev = s->link + n, *used = s->link + 2 * n;
  for (size_t i = 0; i < n; i++) next[i] = prev[i] = -1, used[i] = 0;
  /* sort open pieces by start x to find matches in O(n log n) */
  size_t nopen = 0;
  long *idx = malloc((n ? n : 1) * sizeof *idx);
  if (!idx) return gr_fail(e, GR_EMEM, "out of memory");
  for (size_t i = 0; i < n; i++)
    if (c->b[b0 + i].shape == GR_OPEN) idx[nopen++] = (long)i;
  /* insertion into a sorted array by start x (qsort with a context-free
   * comparator needs the coordinates: copy them) */
  double *sx = malloc((nopen ? nopen : 1) * 3 * sizeof *sx);
  if (!sx) { free(idx); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (size_t q = 0; q < nopen; q++) {
    const gr_block *bk = &c->b[b0 + idx[q]];
    sx[3 * q] = c->xy[2 * bk->start];
    sx[3 * q + 1] = c->xy[2 * bk->start + 1];
    sx[3 * q + 2] = (double)idx[q];
  }
  qsort(sx, nopen, 3 * sizeof *sx, triple_cmp);
  for (size_t q = 0; q < nopen; q++) {
    long i = idx[q];
    const gr_block *bk = &c->b[b0 + i];
    double ex = c->xy[2 * (bk->start + bk->n - 1)], ey = c->xy[2 * (bk->start + bk->n - 1) + 1];
    /* binary search the first start with x >= ex - tol */
    size_t lo = 0, hi = nopen;
    while (lo < hi) {
      size_t mid = (lo + hi) / 2;
      if (sx[3 * mid] < ex - tol) lo = mid + 1; else hi = mid;
    }
    long best = -1;
    double bd = tol * tol;
    for (size_t r = lo; r < nopen && sx[3 * r] <= ex + tol; r++) {
      long cand = (long)sx[3 * r + 2];
      if (cand == i || prev[cand] >= 0) continue;
      if (slot_laser[c->b[b0 + cand].laser] != slot_laser[bk->laser]) continue;
      if ((c->b[b0 + cand].dir == GR_DIR_THIN) != (bk->dir == GR_DIR_THIN)) continue;
      double dx = sx[3 * r] - ex, dy = sx[3 * r + 1] - ey, d2 = dx * dx + dy * dy;
      if (d2 <= bd) { bd = d2; best = cand; }
    }
    if (best >= 0) { next[i] = best; prev[best] = i; }
  }
  free(sx);
  free(idx);
  /* emit: closed blocks as they are; chains from heads, then cycles */
  for (int pass = 0; pass < 2; pass++) {
    for (size_t i = 0; i < n; i++) {
      const gr_block *bk = &c->b[b0 + i];
      if (used[i]) continue;
      if (bk->shape != GR_OPEN) {
        if (pass == 0) {
          used[i] = 1;
          if (gr_layer_add(out, bk->shape, bk->kind, slot_laser[bk->laser], bk->dir, c->xy + 2 * bk->start, bk->n))
            return gr_fail(e, GR_EMEM, "out of memory");
        }
        continue;
      }
      if (pass == 0 && prev[i] >= 0) continue; /* not a head */
      /* walk the chain */
      size_t m = 0;
      long q = (long)i;
      int closed = 0;
      while (q >= 0 && !used[q]) {
        used[q] = 1;
        const gr_block *pb = &c->b[b0 + q];
        size_t skip = m > 0 ? 1 : 0; /* drop the shared joint point */
        if (gr_grow(&s->pts, &s->cappts, m + pb->n, 2 * sizeof(double))) return gr_fail(e, GR_EMEM, "out of memory");
        if (skip) { /* average the joint: both ends are within tol */
          s->pts[2 * (m - 1)] = 0.5 * (s->pts[2 * (m - 1)] + c->xy[2 * pb->start]);
          s->pts[2 * (m - 1) + 1] = 0.5 * (s->pts[2 * (m - 1) + 1] + c->xy[2 * pb->start + 1]);
        }
        memcpy(s->pts + 2 * m, c->xy + 2 * (pb->start + skip), (pb->n - skip) * 2 * sizeof(double));
        m += pb->n - skip;
        q = next[q];
        if (q == (long)i) closed = 1;
      }
      if (closed && bk->dir == GR_DIR_THIN) { /* a thin-wall loop stays an open, tagged line */
        if (gr_layer_add(out, GR_OPEN, bk->kind, slot_laser[bk->laser], GR_DIR_THIN, s->pts, m))
          return gr_fail(e, GR_EMEM, "out of memory");
      } else if (closed) {
        s->pts[0] = 0.5 * (s->pts[0] + s->pts[2 * (m - 1)]);
        s->pts[1] = 0.5 * (s->pts[1] + s->pts[2 * (m - 1) + 1]);
        s->pts[2 * (m - 1)] = s->pts[0];
        s->pts[2 * (m - 1) + 1] = s->pts[1];
        double a = 0;
        for (size_t k = 0; k + 1 < m; k++)
          a += s->pts[2 * k] * s->pts[2 * k + 3] - s->pts[2 * k + 2] * s->pts[2 * k + 1];
        if (gr_layer_add(out, GR_CLOSED, bk->kind, slot_laser[bk->laser], a > 0 ? 1 : 0, s->pts, m))
          return gr_fail(e, GR_EMEM, "out of memory");
      } else if (m >= 2) {
        if (gr_layer_add(out, GR_OPEN, bk->kind, slot_laser[bk->laser], open_dir(bk->dir), s->pts, m))
          return gr_fail(e, GR_EMEM, "out of memory");
      }
    }
  }
  return GR_OK;
}

/* Estimated scan time of a voxel slot on laser l (s). */
static double est_time(const gr_machine *m, int l, double lc, double lh) {
  return lc / m->speed[l][GR_CONTOUR] + lh / m->speed[l][GR_HATCH];
}

/* Can laser l scan the whole voxel with min corner o? */
static int laser_reaches(const gr_machine *m, int l, const double o[3], double cell) {
  return !(o[0] < m->lo[l][0] - EPS || o[1] < m->lo[l][1] - EPS || o[0] + cell > m->hi[l][0] + EPS ||
           o[1] + cell > m->hi[l][1] + EPS);
}

/* Assign lasers to the voxel slots of a layer: fixed ones as given; the
 * others by longest-processing-time-first onto the laser that would finish
 * first among those that reach the voxel. */
static int assign_lasers(gr_job *j, scratch *s, const int *vox, int nslot,
                         const double *lc, const double *lh, gr_err *e) {
  const gr_machine *m = &j->m;
  double load[GR_MAX_LASERS] = {0};
  int *ord = malloc((size_t)(nslot > 0 ? nslot : 1) * sizeof *ord);
  if (!ord) return gr_fail(e, GR_EMEM, "out of memory");
  int nfree = 0;
  for (int q = 0; q < nslot; q++) {
    int v = vox[q];
    if (j->vlaser[v] >= 0 || m->n == 1) {
      s->vlas[q] = j->vlaser[v] >= 0 ? j->vlaser[v] : 0;
      double o[3];
      voxel_origin(j, v, o);
      if (!laser_reaches(m, s->vlas[q], o, j->o.cell)) {
        free(ord);
        return gr_fail(e, GR_EARG, "laser %d does not reach voxel [%g, %g] x [%g, %g] mm: the machine's laser fields do not cover the part",
                       s->vlas[q] + 1, o[0], o[0] + j->o.cell, o[1], o[1] + j->o.cell);
      }
      load[s->vlas[q]] += est_time(m, s->vlas[q], lc[q], lh[q]);
    } else {
      ord[nfree++] = q;
    }
  }
  /* sort free slots by decreasing time (insertion sort: rows are small) */
  for (int a = 1; a < nfree; a++) {
    int x = ord[a], b = a;
    double tx = lc[x] + lh[x];
    while (b > 0 && lc[ord[b - 1]] + lh[ord[b - 1]] < tx) { ord[b] = ord[b - 1]; b--; }
    ord[b] = x;
  }
  for (int a = 0; a < nfree; a++) {
    int q = ord[a], v = vox[q];
    double o[3];
    voxel_origin(j, v, o);
    int best = -1;
    double bt = INFINITY;
    for (int l = 0; l < m->n; l++) {
      if (!laser_reaches(m, l, o, j->o.cell)) continue;
      double t = load[l] + est_time(m, l, lc[q], lh[q]);
      if (t < bt) { bt = t; best = l; }
    }
    if (best < 0) {
      free(ord);
      return gr_fail(e, GR_EARG, "no laser reaches voxel [%g, %g] x [%g, %g] mm: the machine's laser fields do not cover the part",
                     o[0], o[0] + j->o.cell, o[1], o[1] + j->o.cell);
    }
    s->vlas[q] = best;
    load[best] = bt;
  }
  free(ord);
  return GR_OK;
}

/* Per-layer output statistics, per laser (blocks of one laser in order). */
static void layer_account(gr_job *j, const gr_layer *l, gr_job_stats *st) {
  const gr_machine *m = &j->m;
  double len[GR_MAX_LASERS][GR_NKINDS];
  double jl[GR_MAX_LASERS];
  size_t nj[GR_MAX_LASERS], nb[GR_MAX_LASERS];
  double px[GR_MAX_LASERS], py[GR_MAX_LASERS];
  int have[GR_MAX_LASERS];
  memset(len, 0, sizeof len);
  memset(jl, 0, sizeof jl);
  memset(nj, 0, sizeof nj);
  memset(nb, 0, sizeof nb);
  memset(have, 0, sizeof have);
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    int la = bk->laser, k = bk->kind;
    if (la < 0 || la >= m->n || bk->n < 2) continue;
    const double *p = l->xy + 2 * bk->start;
    nb[la]++;
    size_t step = bk->shape == GR_SEGMENTS ? 2 : bk->n;
    for (size_t q = 0; q + 1 < bk->n; q += step) {
      double d = gr_len2d(p[2 * q] - px[la], p[2 * q + 1] - py[la]);
      if (have[la] && d > 1e-9) { nj[la]++; jl[la] += d; }
      have[la] = 1;
      size_t last = bk->shape == GR_SEGMENTS ? q + 1 : bk->n - 1;
      px[la] = p[2 * last];
      py[la] = p[2 * last + 1];
      if (bk->shape == GR_SEGMENTS) {
        st->vectors[k]++;
        len[la][k] += gr_len2d(p[2 * q + 2] - p[2 * q], p[2 * q + 3] - p[2 * q + 1]);
      } else {
        st->vectors[k] += bk->n - 1;
        for (size_t r = 0; r + 1 < bk->n; r++) len[la][k] += gr_len2d(p[2 * r + 2] - p[2 * r], p[2 * r + 3] - p[2 * r + 1]);
      }
    }
  }
  double makespan = 0, total = 0;
  for (int la = 0; la < m->n; la++) {
    double t = jl[la] / m->jump_speed + nj[la] * m->jump_delay + nb[la] * m->polygon_delay;
    for (int k = 0; k < GR_NKINDS; k++) {
      t += len[la][k] / m->speed[la][k];
      st->length[k] += len[la][k];
      st->laser_length[la] += len[la][k];
    }
    st->laser_time[la] += t;
    st->jumps += nj[la];
    st->jump_length += jl[la];
    if (t > makespan) makespan = t;
    total += t;
  }
  st->build_time += makespan + m->recoat_time;
  st->balanced_time += total / m->n + m->recoat_time;
  st->thin_walls += l->thin_walls;
  st->solid_area += l->area;
}

/* Add one layer's figures (layer_account into a zeroed struct, done by the
 * worker that placed it) to the job's, in layer order. */
static void layer_stats_add(gr_job_stats *st, const gr_job_stats *l) {
  for (int k = 0; k < GR_NKINDS; k++) {
    st->vectors[k] += l->vectors[k];
    st->length[k] += l->length[k];
  }
  for (int la = 0; la < GR_MAX_LASERS; la++) {
    st->laser_time[la] += l->laser_time[la];
    st->laser_length[la] += l->laser_length[la];
  }
  st->jumps += l->jumps;
  st->jump_length += l->jump_length;
  st->build_time += l->build_time;
  st->balanced_time += l->balanced_time;
  st->thin_walls += l->thin_walls;
  st->solid_area += l->solid_area;
}

/* Place global layer g (1..N) into `out`. */
static int place_layer(gr_job *j, int g, scratch *s, gr_layer *out, gr_err *e) {
  int k = layer_row(j, g);
  int jl = g - row_first_layer(j, k);
  gr_layer_clear(out, j->o.origin[2] + g * j->o.layer);
  const int *vox = j->roworder + (size_t)k * j->rowlen;
  int nslot = j->rowcount[k];
  double a = gr_job_angle(j, g);
  s->nseg = 0;
  gr_layer_clear(s->cont, 0);
  double *lc = s->vtime; /* reuse: contour length per slot, hatch length below */
  double *lh = malloc((size_t)(nslot > 0 ? nslot : 1) * sizeof *lh);
  if (!lh) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = GR_OK;
  for (int q = 0; q < nslot && rc == GR_OK; q++) {
    int v = vox[q];
    const tmpl *t = j->cls[j->vcls[v]].t;
    lc[q] = lh[q] = 0;
    s->vcont0[q] = s->cont->nb;
    s->vseg0[q] = s->nseg;
    if (!t || jl < t->j0 || jl >= t->j0 + t->nl) {
      rc = gr_fail(e, GR_EARG, "internal: no template layer %d for voxel %d", jl, v);
      break;
    }
    const tlayer *tl = &t->l[jl - t->j0];
    double o[3];
    voxel_origin(j, v, o);
    out->area += tl->area;
    size_t nb0 = s->cont->nb;
    int mask = voxel_sides(j, v);
    if (mask && boundary_contours(j, s, tl, mask)) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    if (gr_layer_append(s->cont, mask ? s->fl : tl->paths, o[0], o[1])) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    for (size_t b = nb0; b < s->cont->nb; b++) {
      s->cont->b[b].laser = q; /* slot, mapped to the laser later */
      lc[q] += gr_block_length(s->cont, &s->cont->b[b]);
    }
    int i, jj, kk;
    voxel_ijk(j, v, &i, &jj, &kk);
    double av = a;
    if (j->o.pattern == GR_PATTERN_ISLAND && ((i + jj) & 1)) av = fmod(a + 90, 360);
    rc = hatch_voxel(j, s, tl, o, av, q, mask, e);
    s->vcont1[q] = s->cont->nb;
    s->vseg1[q] = s->nseg;
    for (size_t r = s->vseg0[q]; r < s->nseg; r++) lh[q] += s->segs[r].s1 - s->segs[r].s0;
  }
  if (rc == GR_OK) rc = assign_lasers(j, s, vox, nslot, lc, lh, e);
  free(lh);
  if (rc) return rc;
  out->thin_walls = s->cont->thin_walls;
  for (size_t r = 0; r < s->nseg; r++) s->segs[r].laser = s->vlas[s->segs[r].voxel];
  int cf = j->o.contour_first;
  if (j->o.pattern == GR_PATTERN_ISLAND) {
    /* per island (voxel) in sequence order: contours and hatches unjoined */
    for (int q = 0; q < nslot; q++) {
      for (int pass = 0; pass < 2; pass++) {
        int contours = (pass == 0) == (cf != 0);
        if (contours) {
          for (size_t b = s->vcont0[q]; b < s->vcont1[q]; b++) {
            const gr_block *bk = &s->cont->b[b];
            if (gr_layer_add(out, bk->shape, bk->kind, s->vlas[q], bk->dir, s->cont->xy + 2 * bk->start, bk->n))
              return gr_fail(e, GR_EMEM, "out of memory");
          }
        } else {
          long lastline = LONG_MIN;
          int flip = 0;
          for (size_t r = s->vseg0[q]; r < s->vseg1[q]; r++) {
            const seg *sg = &s->segs[r];
            if (sg->line != lastline) { flip = !flip; lastline = sg->line; }
            int rev = j->o.alternate && flip;
            if (gr_layer_add_segment(out, GR_HATCH, s->vlas[q], rev ? sg->x1 : sg->x0, rev ? sg->y1 : sg->y0,
                                     rev ? sg->x0 : sg->x1, rev ? sg->y0 : sg->y1))
              return gr_fail(e, GR_EMEM, "out of memory");
          }
        }
      }
    }
    return GR_OK;
  }
  /* continuous: join hatches along lines across voxels, contours across voxels */
  if (sort_segs(s, e)) return e->code;
  size_t w = 0;
  double tol = 1e-7;
  for (size_t r = 0; r < s->nseg; r++) {
    if (w > 0 && s->segs[w - 1].laser == s->segs[r].laser && s->segs[w - 1].line == s->segs[r].line &&
        s->segs[r].s0 <= s->segs[w - 1].s1 + tol) {
      if (s->segs[r].s1 > s->segs[w - 1].s1) {
        s->segs[w - 1].s1 = s->segs[r].s1;
        s->segs[w - 1].x1 = s->segs[r].x1;
        s->segs[w - 1].y1 = s->segs[r].y1;
      }
    } else {
      s->segs[w++] = s->segs[r];
    }
  }
  s->nseg = w;
  gr_layer *hat = gr_layer_new(0);
  if (!hat) return gr_fail(e, GR_EMEM, "out of memory");
  long lastline = LONG_MIN;
  int flip = 0, lastlaser = -1;
  for (size_t r = 0; r < s->nseg; r++) {
    const seg *sg = &s->segs[r];
    if (sg->s1 - sg->s0 < j->o.min_length) { __atomic_fetch_add(&j->st_dropped, 1, __ATOMIC_RELAXED); continue; }
    if (sg->laser != lastlaser) { flip = 0; lastline = LONG_MIN; lastlaser = sg->laser; }
    if (sg->line != lastline) { flip = !flip; lastline = sg->line; }
    int rev = j->o.alternate && !flip;
    if (gr_layer_add_segment(hat, GR_HATCH, sg->laser, rev ? sg->x1 : sg->x0, rev ? sg->y1 : sg->y0,
                             rev ? sg->x0 : sg->x1, rev ? sg->y0 : sg->y1)) {
      gr_layer_free(hat);
      return gr_fail(e, GR_EMEM, "out of memory");
    }
  }
  gr_layer *con = gr_layer_new(0);
  if (!con) { gr_layer_free(hat); return gr_fail(e, GR_EMEM, "out of memory"); }
  rc = join_contours(s, 0, s->cont->nb, j->o.hatch / 4, con, s->vlas, e);
  /* per laser: contours then hatches (or the reverse) */
  for (int la = 0; la < j->m.n && rc == GR_OK; la++) {
    for (int pass = 0; pass < 2 && rc == GR_OK; pass++) {
      const gr_layer *src = ((pass == 0) == (cf != 0)) ? con : hat;
      for (size_t b = 0; b < src->nb; b++) {
        const gr_block *bk = &src->b[b];
        if (bk->laser != la) continue;
        if (gr_layer_add(out, bk->shape, bk->kind, la, bk->dir, src->xy + 2 * bk->start, bk->n)) {
          rc = gr_fail(e, GR_EMEM, "out of memory");
          break;
        }
      }
    }
  }
  gr_layer_free(hat);
  gr_layer_free(con);
  return rc;
}

/* ---- running a job ---- */

/* Rows: the voxels of each z-row that have a class, in sequence order. */
static int seq_cmp_job; /* unused marker to keep qsort_r out */
typedef struct vkey { double key; int v; } vkey;
static int vkey_cmp(const void *a, const void *b) {
  const vkey *p = a, *q = b;
  if (p->key != q->key) return p->key < q->key ? -1 : 1;
  return p->v - q->v;
}

static int build_rows(gr_job *j, gr_err *e) {
  (void)seq_cmp_job;
  int nx = j->o.n[0], ny = j->o.n[1], nz = j->o.n[2];
  free(j->roworder);
  free(j->rowcount);
  j->rowlen = nx * ny;
  j->roworder = malloc((size_t)j->nvox * sizeof *j->roworder);
  j->rowcount = calloc(nz, sizeof *j->rowcount);
  vkey *tmp = malloc((size_t)j->rowlen * sizeof *tmp);
  if (!j->roworder || !j->rowcount || !tmp) { free(tmp); return gr_fail(e, GR_EMEM, "out of memory"); }
  for (int k = 0; k < nz; k++) {
    int n = 0;
    for (int q = 0; q < nx * ny; q++) {
      int v = q + nx * ny * k;
      if (j->vcls[v] >= 0) tmp[n++] = (vkey){j->vseq[v], v};
    }
    qsort(tmp, n, sizeof *tmp, vkey_cmp);
    for (int q = 0; q < n; q++) j->roworder[(size_t)k * j->rowlen + q] = tmp[q].v;
    j->rowcount[k] = n;
  }
  free(tmp);
  return GR_OK;
}

/* A minimal parallel-for: threads pull item indices from a shared counter;
 * the first error stops the others. */
typedef struct pfor {
  gr_job *j;
  int n, next, failed;
  int (*fn)(gr_job *j, int item, void *arg, gr_err *e);
  void *arg;
  pthread_mutex_t mu;
  gr_err err;
  gr_progress_fn progress;
  void *pud;
  const char *stage;
  int done;
} pfor;

static void *pfor_main(void *p_) {
  pfor *p = p_;
  gr_err e;
  gr_err_clear(&e);
  for (;;) {
    pthread_mutex_lock(&p->mu);
    int it = p->failed ? p->n : p->next++;
    pthread_mutex_unlock(&p->mu);
    if (it >= p->n) break;
    int rc = p->fn(p->j, it, p->arg, &e);
    pthread_mutex_lock(&p->mu);
    if (rc && !p->failed) { p->failed = 1; p->err = e; }
    p->done++;
    pthread_mutex_unlock(&p->mu);
  }
  return NULL;
}

static int parallel_for(gr_job *j, int n, int (*fn)(gr_job *, int, void *, gr_err *), void *arg,
                        int threads, gr_progress_fn progress, void *pud, const char *stage, gr_err *e) {
  pfor p;
  memset(&p, 0, sizeof p);
  p.j = j;
  p.n = n;
  p.fn = fn;
  p.arg = arg;
  pthread_mutex_init(&p.mu, NULL);
  pthread_t th[64];
  int nt = threads > 64 ? 64 : threads;
  if (nt > n) nt = n;
  int started = 0;
  for (int t = 1; t < nt; t++)
    if (pthread_create(&th[started], NULL, pfor_main, &p) == 0) started++;
  /* the calling thread works too, and reports progress between items */
  for (;;) {
    pthread_mutex_lock(&p.mu);
    int it = p.failed ? p.n : p.next++;
    pthread_mutex_unlock(&p.mu);
    if (it >= p.n) break;
    gr_err le;
    gr_err_clear(&le);
    int rc = fn(j, it, arg, &le);
    pthread_mutex_lock(&p.mu);
    if (rc && !p.failed) { p.failed = 1; p.err = le; }
    p.done++;
    int d = p.done;
    pthread_mutex_unlock(&p.mu);
    if (progress) progress(pud, stage, d, n);
  }
  for (int t = 0; t < started; t++) pthread_join(th[t], NULL);
  pthread_mutex_destroy(&p.mu);
  if (progress) progress(pud, stage, n, n);
  if (p.failed) {
    if (e) *e = p.err;
    return p.err.code ? p.err.code : GR_EARG;
  }
  return GR_OK;
}

/* Template <-> knowledge-base record: slot 0 section, slot 1 region; the
 * extra layer holds the clipped contour paths. */
static gr_template *tmpl_to_record(const gr_job *j, const vclass *cl, gr_err *e) {
  const tmpl *t = cl->t;
  gr_template *r = gr_template_new(cl->sig, t->nl, 2, 1, e);
  if (!r) return NULL;
  char meta[256];
  snprintf(meta, sizeof meta, "{gradus: %s, voxels_at_build: %d, cell: %g}", GRADUS_VERSION, cl->count, j->o.cell);
  if (gr_template_set_meta(r, meta, e)) { gr_template_free(r); return NULL; }
  for (int q = 0; q < t->nl; q++) {
    r->z[q] = q * j->o.layer; /* local layer offsets from the first layer */
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

static tmpl *tmpl_from_record(const gr_job *j, const gr_template *r, int nl, double L) {
  if (r->nlayers != nl || r->nslots != 2 || !r->extra) return NULL;
  for (int q = 0; q < nl; q++)
    if (!r->rings[q * 2] || !r->rings[q * 2 + 1] || !r->extra[q]) return NULL;
  tmpl *t = calloc(1, sizeof *t);
  if (!t) return NULL;
  t->j0 = 0;
  t->nl = nl;
  t->l = calloc(nl > 0 ? nl : 1, sizeof *t->l);
  if (!t->l) { free(t); return NULL; }
  for (int q = 0; q < nl; q++) {
    t->l[q].section = gr_rings_new();
    t->l[q].region = gr_rings_new();
    t->l[q].paths = gr_layer_new(0);
    if (!t->l[q].section || !t->l[q].region || !t->l[q].paths ||
        gr_rings_copy(t->l[q].section, r->rings[q * 2]) || gr_rings_copy(t->l[q].region, r->rings[q * 2 + 1]) ||
        gr_layer_append(t->l[q].paths, r->extra[q], 0, 0)) {
      tmpl_free(t);
      return NULL;
    }
  }
  for (int q = 0; q < nl; q++) {
    double lo[2] = {0, 0}, hi[2] = {L, L};
    t->l[q].area = area_in_box(t->l[q].section, lo, hi);
    if (face_lines(j, &t->l[q])) { tmpl_free(t); return NULL; }
  }
  for (int i = 0; i < 4; i++) t->quality[i] = r->quality[i];
  t->qualified = r->qualified;
  t->from_kb = 1;
  return t;
}

typedef struct build_arg {
  gr_kb *kb;
  pthread_mutex_t *kbmu;
  int *items;        /* classes */
  int nitems;
  int ja, jb;        /* local layer range, jb < 0: all */
  int *wc, *wa, *wb; /* work items: class, template layers [wa, wb) */
  int nwork;
  cptab *tab;        /* shared closest points of the classes in work, or NULL */
  gr_qualify_fn qualify;
  void *qualify_ud;
  int *fc, *fref;    /* field items: class, reference class or -1 */
  double *fextra;    /* field items: extra margin of H, mm */
} build_arg;

/* Phase 1, per class: take the template from the knowledge base, or make the
 * class's field and allocate its template. */
static int prepare_item(gr_job *j, int item, void *arg_, gr_err *e) {
  build_arg *a = arg_;
  int c = a->items[item];
  vclass *cl = &j->cls[c];
  cl->need = 0;
  int i, jj, k;
  voxel_ijk(j, cl->rep, &i, &jj, &k);
  int nl = row_layers(j, k);
  int use_kb = a->kb && !cl->trimmed && a->jb < 0;
  if (use_kb) {
    gr_template *r = NULL;
    char warn[512] = "";
    pthread_mutex_lock(a->kbmu);
    int rc = gr_kb_get(a->kb, cl->key, &r, warn, sizeof warn, e);
    if (warn[0]) {
      snprintf(j->warning, sizeof j->warning, "%s", warn);
      j->st.kb_corrupt++;
    }
    pthread_mutex_unlock(a->kbmu);
    if (rc) return rc;
    if (r) {
      tmpl *t = tmpl_from_record(j, r, nl, j->o.cell);
      gr_template_free(r);
      if (t) {
        tmpl_free(cl->t);
        cl->t = t;
        pthread_mutex_lock(a->kbmu);
        j->st.reused++;
        if (!t->qualified) {
          j->st.unqualified++;
          snprintf(j->st.unqualified_why, sizeof j->st.unqualified_why, "%.16s: stored as not qualified", cl->key);
        }
        pthread_mutex_unlock(a->kbmu);
        return GR_OK;
      }
    }
  }
  int ja = a->jb < 0 ? 0 : a->ja, jb = a->jb < 0 ? nl : a->jb;
  if (ja < 0) ja = 0;
  if (jb > nl) jb = nl;
  int rc = template_alloc(j, c, ja, jb, e);
  if (rc) return rc;
  cl->need = 1;
  return GR_OK;
}

/* Phase 1b, per class to build: its field, sharing H with its group's
 * reference class (fref >= 0, whose field exists) or its own. */
static int field_item(gr_job *j, int item, void *arg_, gr_err *e) {
  build_arg *a = arg_;
  int c = a->fc[item], ref = a->fref[item];
  vclass *cl = &j->cls[c];
  double o[3], oref[3], sh[3] = {0, 0, 0};
  if (ref >= 0) {
    voxel_origin(j, cl->rep, o);
    voxel_origin(j, j->cls[ref].rep, oref);
    for (int k = 0; k < 3; k++) sh[k] = o[k] - oref[k];
  }
  /* a reference's H reaches a quarter cell further, for thicker members */
  cl->field = voxel_field(j, cl->rep, cl->trimmed, ref >= 0 ? j->cls[ref].field : NULL, sh,
                          a->fextra[item], e);
  if (!cl->field) return e->code ? e->code : GR_EMEM;
  const char *w = gr_offset_warning(cl->field);
  if (w[0]) {
    pthread_mutex_lock(a->kbmu);
    snprintf(j->warning, sizeof j->warning, "%s", w);
    pthread_mutex_unlock(a->kbmu);
  }
  return GR_OK;
}

/* Phase 2, per (class, layer chunk). */
static int layers_item(gr_job *j, int item, void *arg_, gr_err *e) {
  build_arg *a = arg_;
  int c = a->wc[item];
  return build_layers(j, c, j->cls[c].field, a->tab, a->wa[item], a->wb[item], e);
}

/* Phase 2a, per table layer: the shared closest points. */
static int table_item(gr_job *j, int item, void *arg_, gr_err *e) {
  build_arg *a = arg_;
  return cptab_layer(j, a->tab, item, e);
}

/* Phase 3, per class: drop the field, store the template. */
/* A built template's quality (worst verified layer; NaN when the job does
 * not verify) and qualification: the SPEC targets when verified, then the
 * recipe's rule; counted in the stats. */
static void qualify_template(gr_job *j, const build_arg *a, const vclass *cl) {
  tmpl *t = cl->t;
  long thin = 0;
  char why[200] = "";
  for (int q = 0; q < t->nl; q++) thin += t->l[q].paths->thin_walls;
  t->quality[0] = t->quality[1] = t->quality[2] = t->quality[3] = NAN;
  if (j->o.verify) {
    t->quality[0] = t->quality[1] = t->quality[2] = t->quality[3] = 0;
    for (int q = 0; q < t->nl; q++) {
      for (int k = 0; k < 3; k++)
        if (!isnan(t->l[q].q[k])) t->quality[k] = fmax(t->quality[k], t->l[q].q[k]);
      t->quality[3] += !isnan(t->l[q].q[0]);
    }
    j->st.verified++;
    if (t->quality[0] > j->o.max_pore)
      snprintf(why, sizeof why, "pore %.3g %% > %.3g %%", 100 * t->quality[0], 100 * j->o.max_pore);
    else if (t->quality[1] > j->o.max_overmelt)
      snprintf(why, sizeof why, "overmelt %.3g %% > %.3g %%", 100 * t->quality[1], 100 * j->o.max_overmelt);
    else if (t->quality[2] > j->o.max_dev)
      snprintf(why, sizeof why, "contour deviation %.3g um > %.3g um", 1e3 * t->quality[2], 1e3 * j->o.max_dev);
  }
  t->qualified = !why[0];
  if (t->qualified && a->qualify && !a->qualify(a->qualify_ud, cl->key, t->quality, thin, why, sizeof why)) {
    t->qualified = 0;
    if (!why[0]) snprintf(why, sizeof why, "refused by the recipe's rule");
  }
  if (!t->qualified) {
    j->st.unqualified++;
    snprintf(j->st.unqualified_why, sizeof j->st.unqualified_why, "%.16s: %s", cl->key, why);
  }
}

static int store_item(gr_job *j, int item, void *arg_, gr_err *e) {
  build_arg *a = arg_;
  int c = a->items[item];
  vclass *cl = &j->cls[c];
  if (!cl->need) return GR_OK;
  gr_field_free(cl->field);
  cl->field = NULL;
  cl->need = 0;
  pthread_mutex_lock(a->kbmu);
  j->st.built++;
  pthread_mutex_unlock(a->kbmu);
  qualify_template(j, a, cl);
  if (a->kb && !cl->trimmed && a->jb < 0) {
    gr_template *r = tmpl_to_record(j, cl, e);
    if (!r) return e->code ? e->code : GR_EMEM;
    pthread_mutex_lock(a->kbmu);
    int rc = gr_kb_put(a->kb, r, e);
    pthread_mutex_unlock(a->kbmu);
    gr_template_free(r);
    if (rc) return rc;
  }
  return GR_OK;
}

/* Group key of a class for shared closest points ("" = not shareable). */
static void share_key(const gr_job *j, int c, char *key, size_t n) {
  const vclass *cl = &j->cls[c];
  key[0] = 0;
  if (!cl->need || cl->trimmed || !j->o.exact || !j->o.share || !grid_period(j)) return;
  const gr_spec *sp = &j->specs[j->vspec[cl->rep]];
  int i, jj, k;
  voxel_ijk(j, cl->rep, &i, &jj, &k);
  double o[3];
  voxel_origin(j, cl->rep, o);
  double phase = layer_mid(j, row_first_layer(j, k)) - o[2];
  snprintf(key, n, "%d %.9g %d %d %.9g %d %d", sp->surface, sp->level, sp->network, sp->side,
           round(phase / 1e-9) * 1e-9, cl->t->nl, cl->t->j0);
}

/* Work items for the classes cs[0..nc): chunks of 5 layers, enough for every core. */
static int make_work(build_arg *a, const gr_job *j, const int *cs, int nc, gr_err *e) {
  size_t cap = 0;
  free(a->wc); free(a->wa); free(a->wb);
  a->wc = a->wa = a->wb = NULL;
  a->nwork = 0;
  for (int q = 0; q < nc; q++) {
    const vclass *cl = &j->cls[cs[q]];
    for (int s = 0; s < cl->t->nl; s += 5) {
      if ((size_t)a->nwork + 1 > cap) {
        cap = cap ? 2 * cap : 64;
        int *wc = realloc(a->wc, cap * sizeof *wc), *wa = realloc(a->wa, cap * sizeof *wa), *wb = realloc(a->wb, cap * sizeof *wb);
        if (wc) a->wc = wc;
        if (wa) a->wa = wa;
        if (wb) a->wb = wb;
        if (!wc || !wa || !wb) return gr_fail(e, GR_EMEM, "out of memory");
      }
      a->wc[a->nwork] = cs[q];
      a->wa[a->nwork] = s;
      a->wb[a->nwork] = s + 5 < cl->t->nl ? s + 5 : cl->t->nl;
      a->nwork++;
    }
  }
  return GR_OK;
}

/* The shared closest points of a group whose first class is ref. */
static cptab *cptab_new(gr_job *j, const int *cs, int nc, build_arg *a, gr_err *e) {
  cptab *t = calloc(1, sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  t->P = grid_period(j);
  t->ref = cs[0];
  const vclass *cl = &j->cls[t->ref];
  voxel_origin(j, cl->rep, t->oref);
  double m = window_margin(j);
  t->lo[0] = t->oref[0] - m;
  t->lo[1] = t->oref[1] - m;
  double tmax = 0;
  for (int q = 0; q < nc; q++) tmax = fmax(tmax, gr_offset_max_thickness(j->cls[cs[q]].field));
  /* nodes of crossing edges lie within T + h of H; beyond, only signs matter */
  t->dmax = 1.2 * tmax + 2 * j->o.slice_cell;
  size_t np = (size_t)t->P * t->P * cl->t->nl;
  t->q = malloc(3 * np * sizeof *t->q);
  t->sd = malloc(np * sizeof *t->sd);
  if (!t->q || !t->sd) { cptab_free(t); return gr_fail(e, GR_EMEM, "out of memory"), NULL; }
  a->tab = t;
  if (parallel_for(j, cl->t->nl, table_item, a, j->o.threads, NULL, NULL, "closest points", e)) {
    a->tab = NULL;
    cptab_free(t);
    return NULL;
  }
  return t;
}

/* Progress of a part of the work, reported as a share of the whole. */
typedef struct prog_part { const gr_job_run_opts *r; long base, span, total; } prog_part;
static void prog_part_fn(void *ud, const char *stage, long d, long n) {
  const prog_part *p = ud;
  p->r->progress(p->r->progress_ud, stage, p->base + (n > 0 ? d * p->span / n : p->span), p->total);
}

/* Build (or load) the templates of the classes in a->items: classes that
 * share closest points group by group, the others each on its own. */
static int build_classes(gr_job *j, build_arg *a, const gr_job_run_opts *r, const char *stage, gr_err *e) {
  int rc = parallel_for(j, a->nitems, prepare_item, a, j->o.threads, NULL, NULL, stage, e);
  int n = a->nitems;
  /* groups: gid[q] = index (into items) of the group's first class, -1 = none */
  int *cs = malloc((n + 1) * sizeof *cs), *gid = malloc((n + 1) * sizeof *gid);
  a->fc = malloc((n + 1) * sizeof *a->fc);
  a->fref = malloc((n + 1) * sizeof *a->fref);
  a->fextra = malloc((n + 1) * sizeof *a->fextra);
  char (*keys)[128] = malloc((n + 1) * sizeof *keys);
  if (!cs || !gid || !a->fc || !a->fref || !a->fextra || !keys) rc = rc ? rc : gr_fail(e, GR_EMEM, "out of memory");
  long total = 0, base = 0;
  for (int q = 0; q < n && rc == GR_OK; q++) {
    gid[q] = -1;
    if (!j->cls[a->items[q]].need) continue;
    total += j->cls[a->items[q]].t->nl;
    share_key(j, a->items[q], keys[q], sizeof keys[q]);
    if (!keys[q][0]) continue;
    for (int p = 0; p < q && gid[q] < 0; p++)
      if (gid[p] == p && strcmp(keys[p], keys[q]) == 0) gid[q] = p;
    if (gid[q] < 0) gid[q] = q;
  }
  /* fields: group references and unshared classes, then the members */
  for (int pass = 0; pass < 2 && rc == GR_OK; pass++) {
    int nf = 0;
    for (int q = 0; q < n; q++) {
      if (!j->cls[a->items[q]].need) continue;
      int member = gid[q] >= 0 && gid[q] != q;
      if (member != pass) continue;
      a->fc[nf] = a->items[q];
      a->fref[nf] = member ? a->items[gid[q]] : -1;
      a->fextra[nf] = gid[q] == q ? 0.25 * j->o.cell : 0;
      nf++;
    }
    rc = parallel_for(j, nf, field_item, a, j->o.threads, NULL, NULL, stage, e);
  }
  for (int q = 0; q < n && rc == GR_OK; q++) {
    if (!j->cls[a->items[q]].need || (gid[q] >= 0 && gid[q] != q)) continue;
    int nc = 0;
    if (gid[q] < 0) cs[nc++] = a->items[q];
    else
      for (int p = q; p < n; p++)
        if (gid[p] == q) cs[nc++] = a->items[p];
    cptab *t = NULL;
    if (gid[q] >= 0 && !(t = cptab_new(j, cs, nc, a, e))) { rc = e->code ? e->code : GR_EMEM; break; }
    a->tab = t;
    long nl = 0;
    for (int p = 0; p < nc; p++) nl += j->cls[cs[p]].t->nl;
    prog_part pp = {r, base, nl, total};
    int prog = r && r->progress;
    if ((rc = make_work(a, j, cs, nc, e)) == GR_OK)
      rc = parallel_for(j, a->nwork, layers_item, a, j->o.threads, prog ? prog_part_fn : NULL, prog ? &pp : NULL, stage, e);
    a->tab = NULL;
    cptab_free(t);
    base += nl;
  }
  free(keys);
  free(gid);
  free(a->fc); free(a->fref); free(a->fextra);
  a->fc = a->fref = NULL;
  a->fextra = NULL;
  free(cs);
  gr_err e2;
  gr_err_clear(&e2);
  /* store (and qualify) only complete templates: after a failure some layers were never built */
  int rc2 = rc == GR_OK ? parallel_for(j, a->nitems, store_item, a, 1, NULL, NULL, stage, &e2) : GR_OK;
  if (rc == GR_OK && rc2) { rc = rc2; *e = e2; }
  /* on failure, drop any fields left */
  for (int q = 0; q < a->nitems; q++) {
    vclass *cl = &j->cls[a->items[q]];
    gr_field_free(cl->field);
    cl->field = NULL;
  }
  return rc;
}

/* Layer pipeline: workers place layers ga..gb; the calling thread hands
 * them to the sink in order. At most S layers are in flight. */
typedef struct lpipe {
  gr_job *j;
  int ga, gb, next, written, S, failed;
  gr_layer **slot;
  gr_job_stats *acct; /* per slot: the layer's figures (layer_account) */
  int *ready;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  gr_err err;
} lpipe;

static void *lpipe_worker(void *p_) {
  lpipe *p = p_;
  scratch s;
  gr_err e;
  gr_err_clear(&e);
  int ok = scratch_init(&s, p->j->rowlen) == GR_OK;
  for (;;) {
    pthread_mutex_lock(&p->mu);
    while (!p->failed && p->next <= p->gb && p->next - (p->ga + p->written) >= p->S)
      pthread_cond_wait(&p->cv, &p->mu);
    if (p->failed || p->next > p->gb) { pthread_mutex_unlock(&p->mu); break; }
    int g = p->next++;
    pthread_mutex_unlock(&p->mu);
    int rc = ok ? place_layer(p->j, g, &s, p->slot[g % p->S], &e) : gr_fail(&e, GR_EMEM, "out of memory");
    if (rc == GR_OK) {
      memset(&p->acct[g % p->S], 0, sizeof *p->acct);
      layer_account(p->j, p->slot[g % p->S], &p->acct[g % p->S]);
    }
    pthread_mutex_lock(&p->mu);
    if (rc) {
      if (!p->failed) { p->failed = 1; p->err = e; }
    } else {
      p->ready[g % p->S] = 1;
    }
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
  }
  scratch_free(&s);
  return NULL;
}

static int run_layers(gr_job *j, int ga, int gb, const gr_job_run_opts *r, long *done, long total, gr_err *e) {
  if (gb < ga) return GR_OK;
  lpipe p;
  memset(&p, 0, sizeof p);
  p.j = j;
  p.ga = ga;
  p.gb = gb;
  p.next = ga;
  p.S = 4 * j->o.threads + 2;
  p.slot = calloc(p.S, sizeof *p.slot);
  p.ready = calloc(p.S, sizeof *p.ready);
  p.acct = calloc(p.S, sizeof *p.acct);
  if (!p.slot || !p.ready || !p.acct) {
    free(p.slot); free(p.ready); free(p.acct);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  int no_slots = 0;
  for (int i = 0; i < p.S; i++)
    if (!(p.slot[i] = gr_layer_new(0))) no_slots = 1;
  pthread_mutex_init(&p.mu, NULL);
  pthread_cond_init(&p.cv, NULL);
  int nt = j->o.threads > 64 ? 64 : j->o.threads;
  pthread_t th[64];
  int started = 0;
  if (!no_slots)
    for (int t = 0; t < nt; t++)
      if (pthread_create(&th[started], NULL, lpipe_worker, &p) == 0) started++;
  /* A worker may already have failed (with its own error, taken below)
   * before this point: only a job that could start no worker at all is
   * reported as such. Fewer threads than asked is fine. */
  int rc = GR_OK;
  if (no_slots) rc = gr_fail(e, GR_EMEM, "out of memory for the layer pipeline");
  else if (started == 0) rc = gr_fail(e, GR_EMEM, "cannot start any worker thread (the system refused all %d)", nt);
  for (int g = ga; g <= gb && rc == GR_OK; g++) {
    pthread_mutex_lock(&p.mu);
    while (!p.ready[g % p.S] && !p.failed) pthread_cond_wait(&p.cv, &p.mu);
    int failed = p.failed && !p.ready[g % p.S];
    pthread_mutex_unlock(&p.mu);
    if (failed) break;
    gr_layer *l = p.slot[g % p.S];
    layer_stats_add(&j->st, &p.acct[g % p.S]);
    if (r->sink) rc = r->sink(r->sink_ud, g, l, e);
    pthread_mutex_lock(&p.mu);
    p.ready[g % p.S] = 0;
    p.written++;
    if (rc && !p.failed) { p.failed = 1; p.err = *e; }
    pthread_cond_broadcast(&p.cv);
    pthread_mutex_unlock(&p.mu);
    (*done)++;
    if (r->progress) r->progress(r->progress_ud, "layers", *done, total);
  }
  pthread_mutex_lock(&p.mu);
  if (rc) p.failed = 1;
  pthread_cond_broadcast(&p.cv);
  pthread_mutex_unlock(&p.mu);
  for (int t = 0; t < started; t++) pthread_join(th[t], NULL);
  if (p.failed && rc == GR_OK) { *e = p.err; rc = p.err.code ? p.err.code : GR_EARG; }
  for (int i = 0; i < p.S; i++) gr_layer_free(p.slot[i]);
  free(p.slot);
  free(p.ready);
  free(p.acct);
  pthread_mutex_destroy(&p.mu);
  pthread_cond_destroy(&p.cv);
  return rc;
}

int gr_job_run(gr_job *j, const gr_job_run_opts *r, gr_err *e) {
  double t0 = gr_now();
  memset(&j->st, 0, sizeof j->st);
  j->st_dropped = 0;
  j->warning[0] = 0;
  int rc = gr_job_classify(j, r->direct, e);
  if (rc) return rc;
  if ((rc = build_rows(j, e))) return rc;
  int ga = r->first > 0 ? r->first : 1, gb = r->last > 0 ? r->last : j->nlayers;
  if (gb > j->nlayers) gb = j->nlayers;
  if (ga > gb && j->nlayers > 0) return gr_fail(e, GR_EARG, "layer range %d:%d is empty (the job has %d layers)", ga, gb, j->nlayers);
  double t1 = gr_now();
  j->st.seconds[0] = t1 - t0;
  pthread_mutex_t kbmu;
  pthread_mutex_init(&kbmu, NULL);
  long done = 0, total = gb - ga + 1;
  int *items = malloc((j->ncls ? j->ncls : 1) * sizeof *items);
  if (!items) { pthread_mutex_destroy(&kbmu); return gr_fail(e, GR_EMEM, "out of memory"); }
  build_arg ba;
  memset(&ba, 0, sizeof ba);
  ba.kb = r->kb;
  ba.kbmu = &kbmu;
  ba.qualify = r->qualify;
  ba.qualify_ud = r->qualify_ud;
  ba.items = items;
  ba.jb = -1;
  if (!r->direct) {
    /* every class's template, once (from the knowledge base when there) */
    int n = 0;
    for (int c = 0; c < j->ncls; c++) {
      int i, jj, k;
      voxel_ijk(j, j->cls[c].rep, &i, &jj, &k);
      int g0 = row_first_layer(j, k), g1 = g0 + row_layers(j, k) - 1;
      if (g1 >= ga && g0 <= gb) items[n++] = c;
    }
    ba.nitems = n;
    rc = build_classes(j, &ba, r, "templates", e);
    j->st.seconds[1] = gr_now() - t1;
    if (rc == GR_OK) rc = run_layers(j, ga, gb, r, &done, total, e);
  } else {
    /* direct: per row, build every voxel for the needed layers, then place */
    for (int k = 0; k < j->o.n[2] && rc == GR_OK; k++) {
      int g0 = row_first_layer(j, k), g1 = g0 + row_layers(j, k) - 1;
      int a = g0 > ga ? g0 : ga, b = g1 < gb ? g1 : gb;
      if (a > b) continue;
      int n = 0;
      for (int q = 0; q < j->rowcount[k]; q++) items[n++] = j->vcls[j->roworder[(size_t)k * j->rowlen + q]];
      ba.ja = a - g0;
      ba.jb = b - g0 + 1;
      double tb = gr_now();
      ba.nitems = n;
      rc = build_classes(j, &ba, NULL, "voxels", e);
      j->st.seconds[1] += gr_now() - tb;
      if (rc == GR_OK) rc = run_layers(j, a, b, r, &done, total, e);
      for (int q = 0; q < n; q++) { tmpl_free(j->cls[items[q]].t); j->cls[items[q]].t = NULL; }
    }
  }
  free(items);
  free(ba.wc);
  free(ba.wa);
  free(ba.wb);
  pthread_mutex_destroy(&kbmu);
  j->st.layers = (int)done;
  j->st.dropped = j->st_dropped;
  j->st.seconds[2] = gr_now() - t1 - j->st.seconds[1];
  j->st.seconds[3] = gr_now() - t0;
  return rc;
}

const gr_job_stats *gr_job_get_stats(const gr_job *j) { return &j->st; }
const char *gr_job_warning(const gr_job *j) { return j->warning; }
int gr_job_classes(const gr_job *j) { return j->ncls; }
const char *gr_job_class_key(const gr_job *j, int c) { return c >= 0 && c < j->ncls ? j->cls[c].key : NULL; }
