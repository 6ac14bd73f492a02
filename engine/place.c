/* place.c: the job (see place.h) and its run, the spine of the part
 * pipeline:
 *
 *   classify (classify.h)  voxels -> classes (signatures, domain, skin) and rows
 *   build    (build.h)     classes -> templates (template.h, cptab.h; from and
 *                          to the knowledge base, kb.h), on the worker pool
 *   stream   (stream.h)    templates -> part layers in order (assemble.h:
 *                          placement, joining, boundary contours; lasers.h:
 *                          assignment, time estimates, statistics) -> sink
 *
 * build and stream alternate band by band (one row of voxels): a template is
 * built when its first row comes and released after its last (run_templates).
 *
 * The job's state is job.h; doc/architecture.md draws the map. */
#include "place.h"
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include "build.h"
#include "classify.h"
#include "distance.h"
#include "job.h"
#include "lasers.h"
#include "regions.h"
#include "stream.h"

gr_job_opts gr_job_defaults(void) {
  gr_job_opts o;
  memset(&o, 0, sizeof o);
  o.cell[0] = o.cell[1] = o.cell[2] = 2.0;
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

/* The largest step <= h that divides Lx, and Ly too when one of the next
 * few divisions of Lx does (a stretched cell with commensurate lengths, say
 * 3 x 2 mm); else Lx's (the grids line up along x only). A cube: Lx / n. */
static double grid_step(const double cell[3], double h) {
  double n0 = ceil(cell[0] / h - 1e-9);
  for (double n = n0; n <= 4 * n0; n++) {
    double m = cell[1] / (cell[0] / n);
    if (fabs(m - round(m)) < 1e-9 * m) return cell[0] / n;
  }
  return cell[0] / n0;
}

int gr_job_check_size(const int n[3], const double cell[3], gr_err *e) {
  double nvox = (double)n[0] * n[1] * n[2];
  if (nvox > GR_MAX_VOXELS)
    return gr_fail(e, GR_EARG,
                   "cells %d x %d x %d are %.3g voxels, more than a job holds (%.0e): a part of %g x %g x %g mm; "
                   "give fewer or larger cells",
                   n[0], n[1], n[2], nvox, GR_MAX_VOXELS, n[0] * cell[0], n[1] * cell[1], n[2] * cell[2]);
  return GR_OK;
}

gr_job *gr_job_new(const gr_job_opts *o, gr_err *e) {
  gr_job_opts d = *o;
  for (int a = 0; a < 3; a++)
    if (!(d.cell[a] > 0) || !isfinite(d.cell[a]))
      return gr_fail(e, GR_EARG, "cell must be > 0 mm, got %g", d.cell[a]), NULL;
  for (int a = 0; a < 3; a++)
    if (d.n[a] < 1 || d.n[a] > 100000)
      return gr_fail(e, GR_EARG, "cells must be >= 1 along each axis, got %d,%d,%d", d.n[0], d.n[1], d.n[2]), NULL;
  if (gr_job_check_size(d.n, d.cell, e)) return NULL;
  if (!(d.hatch > 0) || !isfinite(d.hatch))
    return gr_fail(e, GR_EARG, "hatch spacing must be > 0 mm, got %g", d.hatch), NULL;
  if (!(d.layer > 0) || !isfinite(d.layer))
    return gr_fail(e, GR_EARG, "layer thickness must be > 0 mm, got %g", d.layer), NULL;
  if (d.layer > d.cell[2])
    return gr_fail(e, GR_EARG, "layer thickness %g mm is larger than the cell %g mm", d.layer, d.cell[2]), NULL;
  if (d.n[2] * d.cell[2] / d.layer > 1e8) /* (the layer count is an int) */
    return gr_fail(e, GR_EARG, "%g mm in layers of %g mm are %.3g layers, more than a job holds (1e8)",
                   d.n[2] * d.cell[2], d.layer, d.n[2] * d.cell[2] / d.layer), NULL;
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
  d.slice_cell = grid_step(d.cell, d.slice_cell);
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
  j->grid = gr_grid_make(d.cell, d.origin, d.n, d.layer);
  j->nlayers = j->grid.nlayers;
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
    gr_tmpl_free(j->cls[c].t);
    gr_field_free(j->cls[c].field);
    free(j->cls[c].sig);
  }
  free(j->cls);
  gr_regions_free(j->regions);
  free(j->vspec);
  free(j->vlaser);
  free(j->vcls);
  free(j->vseq);
  free(j->vstate);
  gr_field_free(j->domain);
  free(j->roworder);
  free(j->rowcount);
  free(j);
}

int gr_job_layers(const gr_job *j) { return j->nlayers; }
const gr_job_opts *gr_job_options(const gr_job *j) { return &j->o; }


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
  gr_expr *t = gr_offset_thickness_expr(s->thickness, j->o.cell, e);
  if (!t) return -1;
  gr_expr *in = NULL;
  if (s->inside[0]) {
    in = gr_offset_thickness_expr(s->inside, j->o.cell, e);
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
  /* used as given: a skin in mm needs a distance (an STL domain, or
   * gradus.field.distance of a smooth expression, domain.h) */
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
  if (!(m->stitch >= 0 && m->stitch <= 10)) return gr_fail(e, GR_EARG, "stitch must be in [0, 10] mm, got %g", m->stitch);
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
  m.stitch = GR_STITCH_DEFAULT;
  return m;
}

/* The hatch angle of global layer g (1-based), degrees in [0, 360). */
double gr_layer_angle(const gr_job_opts *o, int g) {
  double a = fmod(o->angle + (g - 1) * o->rotation, 360.0);
  return a < 0 ? a + 360 : a;
}
double gr_job_angle(const gr_job *j, int g) { return gr_layer_angle(&j->o, g); }

int gr_job_classify(gr_job *j, int direct, gr_err *e) { return gr_classify_run(j, direct, e); }

/* Band of row k: the layers [*a, *b] of the row to stream (within [ga, gb];
 * 0 when none) and the rows [*k0, *k1] whose templates they read: the row
 * itself, and the rows holding the `below` layers under *a and the `above`
 * layers over *b when assembly reads layers around (0, 0: none). */
static int band_rows(const gr_job *j, int k, int ga, int gb, int below, int above, int *a, int *b, int *k0, int *k1) {
  int g0 = gr_grid_row_first(&j->grid, k), g1 = g0 + gr_grid_row_layers(&j->grid, k) - 1;
  *a = g0 > ga ? g0 : ga;
  *b = g1 < gb ? g1 : gb;
  if (*a > *b) return 0;
  int la = *a - below < 1 ? 1 : *a - below, lb = *b + above > j->nlayers ? j->nlayers : *b + above;
  *k0 = gr_grid_layer_row(&j->grid, la);
  *k1 = gr_grid_layer_row(&j->grid, lb);
  if (*k0 > k) *k0 = k;
  if (*k1 < k) *k1 = k;
  return 1;
}

/* gr_build_classes, its time counted in the templates stage. */
static int build_timed(gr_job *j, gr_build *ba, const gr_job_run_opts *r, const char *stage, gr_err *e) {
  double t0 = gr_now();
  int rc = gr_build_classes(ba, r, stage, e);
  j->st.seconds[1] += gr_now() - t0;
  return rc;
}

/* Whether row k's new classes (ba->items) may be built a few layers at a
 * time (run_bands): assembly reads no layers around (down- and up-skin
 * regions: below = above = 0), and no class is stored or used by a later
 * row (last[c] = k), so no template is needed whole. A part graded all over
 * (every voxel its own class) is. */
static int banded(const gr_build *ba, int k, const int *last, int below, int above) {
  if (below || above || ba->nitems == 0) return 0;
  for (int q = 0; q < ba->nitems; q++) {
    int c = ba->items[q];
    if (last[c] != k || gr_build_stores(ba, c)) return 0;
  }
  return 1;
}

/* Row k's new classes built GR_BAND_LAYERS template layers at a time: each
 * band's layers are built, those in [a, b] streamed, and released, so that
 * the row's templates are never all held whole. The output is the same:
 * a template layer depends on its class alone. */
#define GR_BAND_LAYERS 10
static int run_bands(gr_job *j, gr_build *ba, int k, int a, int b, const gr_job_run_opts *r, long *done, long total,
                     gr_err *e) {
  int g0 = gr_grid_row_first(&j->grid, k), nl = gr_grid_row_layers(&j->grid, k), rc = GR_OK;
  j->st.banded_rows++;
  for (int s = 0; s < nl && rc == GR_OK; s += GR_BAND_LAYERS) {
    int t = s + GR_BAND_LAYERS < nl ? s + GR_BAND_LAYERS : nl;
    ba->la = s;
    ba->lb = t;
    ba->band_last = t == nl;
    rc = build_timed(j, ba, r, "templates", e);
    int sa = g0 + s > a ? g0 + s : a, sb = g0 + t - 1 < b ? g0 + t - 1 : b;
    if (rc == GR_OK && sa <= sb) rc = gr_stream_layers(j, sa, sb, r, done, total, e);
    for (int q = 0; q < ba->nitems; q++)
      if (j->cls[ba->items[q]].t) gr_tmpl_release(j->cls[ba->items[q]].t, s, t);
  }
  ba->la = ba->lb = ba->band_last = 0;
  return rc;
}

/* Templates (from the knowledge base or built), streamed band by band: per
 * row of voxels (a band one cell high), the classes the row's layers read
 * (its own, and those of the rows around when assembly reads layers around:
 * below, above) that have no template yet are loaded or built (on all
 * cores), the row's layers in [ga, gb] are streamed, and the templates no
 * later band reads are released. Peak memory thus follows the classes of a
 * band, not of the part; a class recurring in later rows keeps its template
 * until its last band, and groups sharing closest points keep them across
 * rows (build.h). Each template is a function of its key alone: the output
 * is the one of building them all first. */
static int run_templates(gr_job *j, gr_build *ba, int ga, int gb, const gr_job_run_opts *r, long *done, long total,
                         gr_err *e) {
  int below, above; /* regions.h: down-/up-skin read the layers around */
  gr_regions_margin(j, &below, &above);
  int nc = j->ncls ? j->ncls : 1, a, b, k0, k1;
  int *last = malloc(2 * (size_t)nc * sizeof *last), *seen = last + nc;
  if (!last) return gr_fail(e, GR_EMEM, "out of memory");
  for (int c = 0; c < j->ncls; c++) last[c] = seen[c] = -1;
  for (int k = 0; k < j->grid.n[2]; k++)
    if (band_rows(j, k, ga, gb, below, above, &a, &b, &k0, &k1))
      for (int kk = k0; kk <= k1; kk++)
        for (int q = 0; q < j->rowcount[kk]; q++) last[j->vcls[j->roworder[(size_t)kk * j->rowlen + q]]] = k;
  int rc = GR_OK, held = 0;
  for (int k = 0; k < j->grid.n[2] && rc == GR_OK; k++) {
    if (!band_rows(j, k, ga, gb, below, above, &a, &b, &k0, &k1)) continue;
    int n = 0;
    for (int kk = k0; kk <= k1; kk++)
      for (int q = 0; q < j->rowcount[kk]; q++) {
        int c = j->vcls[j->roworder[(size_t)kk * j->rowlen + q]];
        if (!j->cls[c].t && seen[c] < 0) { seen[c] = k; ba->items[n++] = c; }
      }
    ba->nitems = n;
    held += n;
    if (held > j->st.held_max) j->st.held_max = held;
    if (banded(ba, k, last, below, above)) {
      rc = run_bands(j, ba, k, a, b, r, done, total, e);
    } else {
      rc = build_timed(j, ba, r, "templates", e); /* progress per band */
      if (rc == GR_OK) rc = gr_stream_layers(j, a, b, r, done, total, e);
    }
    for (int kk = k0; kk <= k1; kk++)
      for (int q = 0; q < j->rowcount[kk]; q++) {
        int c = j->vcls[j->roworder[(size_t)kk * j->rowlen + q]];
        if (last[c] == k && j->cls[c].t) { gr_tmpl_free(j->cls[c].t); j->cls[c].t = NULL; held--; }
      }
  }
  free(last);
  return rc;
}

/* Direct (kb=off): per row, build every voxel for the needed layers, then
 * stream them; the row's templates are dropped after. */
static int run_direct(gr_job *j, gr_build *ba, int ga, int gb, const gr_job_run_opts *r, long *done, long total,
                      gr_err *e) {
  int rc = GR_OK;
  for (int k = 0; k < j->o.n[2] && rc == GR_OK; k++) {
    int g0 = gr_grid_row_first(&j->grid, k), g1 = g0 + gr_grid_row_layers(&j->grid, k) - 1;
    int a = g0 > ga ? g0 : ga, b = g1 < gb ? g1 : gb;
    if (a > b) continue;
    int n = 0;
    for (int q = 0; q < j->rowcount[k]; q++) ba->items[n++] = j->vcls[j->roworder[(size_t)k * j->rowlen + q]];
    ba->ja = a - g0;
    ba->jb = b - g0 + 1;
    ba->nitems = n;
    if (n > j->st.held_max) j->st.held_max = n;
    rc = build_timed(j, ba, NULL, "voxels", e);
    if (rc == GR_OK) rc = gr_stream_layers(j, a, b, r, done, total, e);
    for (int q = 0; q < n; q++) { gr_tmpl_free(j->cls[ba->items[q]].t); j->cls[ba->items[q]].t = NULL; }
  }
  return rc;
}

/* The pipeline: classify, then templates and layers. */
int gr_job_run(gr_job *j, const gr_job_run_opts *r, gr_err *e) {
  double t0 = gr_now();
  memset(&j->st, 0, sizeof j->st);
  j->st_dropped = 0;
  j->st_split = 0;
  j->warning[0] = 0;
  int below, above;
  gr_regions_margin(j, &below, &above);
  if (r->direct && below + above > 0)
    return gr_fail(e, GR_EARG, "down-skin and up-skin regions need every layer's template: not with kb=off (direct)");
  int rc = gr_classify_run(j, r->direct, e);
  if (rc) return rc;
  if ((rc = gr_classify_rows(j, e))) return rc;
  int ga = r->first > 0 ? r->first : 1, gb = r->last > 0 ? r->last : j->nlayers;
  if (gb > j->nlayers) gb = j->nlayers;
  if (ga > gb && j->nlayers > 0) return gr_fail(e, GR_EARG, "layer range %d:%d is empty (the job has %d layers)", ga, gb, j->nlayers);
  /* every voxel of the rows to build within a laser's reach, before any work */
  for (int k = 0; k < j->grid.n[2]; k++) {
    int g0 = gr_grid_row_first(&j->grid, k), g1 = g0 + gr_grid_row_layers(&j->grid, k) - 1;
    if (g1 < ga || g0 > gb) continue;
    if ((rc = gr_lasers_check(&j->m, &j->grid, j->vlaser, j->roworder + (size_t)k * j->rowlen, j->rowcount[k], e)))
      return rc;
  }
  double t1 = gr_now();
  j->st.seconds[0] = t1 - t0;
  pthread_mutex_t kbmu;
  pthread_mutex_init(&kbmu, NULL);
  long done = 0, total = gb - ga + 1;
  int *items = malloc((j->ncls ? j->ncls : 1) * sizeof *items);
  if (!items) { pthread_mutex_destroy(&kbmu); return gr_fail(e, GR_EMEM, "out of memory"); }
  gr_build ba;
  memset(&ba, 0, sizeof ba);
  ba.j = j;
  ba.kb = r->kb;
  ba.kb_store = r->kb_store;
  ba.kbmu = &kbmu;
  ba.qualify = r->qualify;
  ba.qualify_ud = r->qualify_ud;
  ba.items = items;
  ba.jb = -1;
  rc = r->direct ? run_direct(j, &ba, ga, gb, r, &done, total, e) : run_templates(j, &ba, ga, gb, r, &done, total, e);
  gr_err e2;
  int rc2 = gr_build_finish(&ba, rc ? &e2 : e); /* the templates still being stored */
  if (rc == GR_OK) rc = rc2;
  free(items);
  gr_build_done(&ba);
  pthread_mutex_destroy(&kbmu);
  j->st.layers = (int)done;
  j->st.dropped = j->st_dropped;
  j->st.split_loops = j->st_split;
  j->st.seconds[2] = gr_now() - t1 - j->st.seconds[1];
  j->st.seconds[3] = gr_now() - t0;
  return rc;
}

const gr_job_stats *gr_job_get_stats(const gr_job *j) { return &j->st; }
const char *gr_job_warning(const gr_job *j) { return j->warning; }
int gr_job_classes(const gr_job *j) { return j->ncls; }
const char *gr_job_class_key(const gr_job *j, int c) { return c >= 0 && c < j->ncls ? j->cls[c].key : NULL; }
