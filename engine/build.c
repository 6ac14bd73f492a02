/* build.c: building the templates of a set of classes, see build.h. */
#include "build.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "distance.h"
#include "domain.h"
#include "pool.h"
#include "regions.h"

/* Offset options of spec s for the voxel with min corner o (u, v, w
 * relative to that voxel), H meshed over it grown by a margin (+ extra, mm). */
static gr_offset_opts offset_opts(const gr_job *j, const gr_spec *s, gr_field *phi, const double o[3], double extra) {
  gr_offset_opts oo = gr_offset_defaults();
  oo.surface = phi;
  for (int a = 0; a < 3; a++) oo.cell[a] = j->o.cell[a];
  for (int a = 0; a < 3; a++) oo.origin[a] = j->o.origin[a];
  for (int a = 0; a < 3; a++) oo.box_lo[a] = o[a];
  for (int a = 0; a < 3; a++) oo.box_hi[a] = o[a] + j->o.cell[a];
  oo.voxel = 1;
  oo.margin = j->o.beam_offset + (j->o.contours + 2) * j->o.hatch + 4 * j->o.slice_cell + extra;
  oo.res = j->o.res;
  oo.kind = s->network ? GR_OFFSET_NETWORK : GR_OFFSET_SHEET;
  oo.side = s->side;
  oo.mode = j->o.exact ? GR_DIST_EXACT : GR_DIST_MESH;
  return oo;
}

/* The canonical field of a group of classes sharing closest points: H of
 * class c's surface over the grid's first voxel (the origin), grown by three
 * quarters of a cell so that it serves every member's window (T <= L/2);
 * thickness 0. It depends on the group's key only, never on which classes
 * are built with it: templates stay pure functions of their keys. */
static gr_field *canon_field(gr_job *j, int c, gr_err *e) {
  const gr_spec *s = &j->specs[j->vspec[j->cls[c].rep]];
  gr_field *phi = gr_field_tpms3(gr_tpms_name(s->surface), j->o.cell, j->o.origin, s->level, e);
  if (!phi) return NULL;
  gr_offset_opts oo = offset_opts(j, s, phi, j->o.origin, 0.75 * gr_cell_min(j->o.cell));
  oo.thickness = 0;
  oo.threads = j->o.threads; /* H meshed and checked on all threads: nothing else runs meanwhile */
  oo.periodic = 1; /* a TPMS of period cell: H's local reach over one period, shared by the group */
  gr_field *g = gr_offset_field_new(&oo, e);
  gr_field_free(phi);
  return g;
}

/* The graded field of voxel v (offset field of its spec, u, v, w relative to
 * v, H meshed over the voxel grown by a margin or shared with `like` shifted
 * by `shift`), intersected with the domain when trimmed. */
static gr_field *voxel_field(gr_job *j, int v, int trimmed, gr_field *like, const double shift[3], gr_err *e) {
  const gr_spec *s = &j->specs[j->vspec[v]];
  double o[3];
  gr_grid_origin(&j->grid, v, o);
  gr_field *phi = gr_field_tpms3(gr_tpms_name(s->surface), j->o.cell, j->o.origin, s->level, e);
  if (!phi) return NULL;
  gr_offset_opts oo = offset_opts(j, s, phi, o, 0);
  oo.like = like;
  for (int a = 0; a < 3 && like; a++) oo.like_shift[a] = shift[a];
  oo.thickness_expr = s->thickness;
  oo.inside_expr = s->inside[0] ? s->inside : NULL;
  oo.density = s->density;
  if (s->target) oo.thickness_expr = NULL, oo.thickness_field = s->target;
  gr_field *g = gr_offset_field_new(&oo, e);
  gr_field_free(phi);
  if (!g) return NULL;
  if (trimmed && j->domain) {
    /* cut by the domain, with the solid skin along its boundary (domain.h) */
    gr_field *f = gr_domain_trim(g, j->domain, j->skin, e);
    gr_field_free(g);
    g = f;
    if (!g) return NULL;
  }
  return g;
}

/* Phase 1, per class: take the template from the knowledge base, or make the
 * class's field and allocate its template. */
static int prepare_item(void *arg_, int item, gr_err *e) {
  gr_build *a = arg_;
  gr_job *j = a->j;
  int c = a->items[item];
  gr_vclass *cl = &j->cls[c];
  cl->need = 0;
  int i, jj, k;
  gr_grid_ijk(&j->grid, cl->rep, &i, &jj, &k);
  int nl = gr_grid_row_layers(&j->grid, k);
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
      gr_tmpl *t = gr_tmpl_from_record(&j->o, r, nl, cl->edge);
      gr_template_free(r);
      if (t) {
        gr_tmpl_free(cl->t);
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
  gr_tmpl *t = gr_tmpl_new(ja, jb);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory");
  gr_tmpl_free(cl->t);
  cl->t = t;
  cl->need = 1;
  return GR_OK;
}

/* Phase 1b, per field item: a group's canonical field (fkind 1), a class's
 * own field (0), or a group member's field sharing the canonical H (2). */
static int field_item(void *arg_, int item, gr_err *e) {
  gr_build *a = arg_;
  gr_job *j = a->j;
  int c = a->fc[item], g = a->fref[item];
  if (a->fkind[item] == 1) {
    a->gfield[g] = canon_field(j, c, e);
    return a->gfield[g] ? GR_OK : (e->code ? e->code : GR_EMEM);
  }
  gr_vclass *cl = &j->cls[c];
  double o[3], sh[3] = {0, 0, 0};
  if (a->fkind[item] == 2) {
    gr_grid_origin(&j->grid, cl->rep, o);
    for (int k = 0; k < 3; k++) sh[k] = o[k] - j->o.origin[k];
  }
  cl->field = voxel_field(j, cl->rep, cl->trimmed, a->fkind[item] == 2 ? a->gfield[g] : NULL, sh, e);
  if (!cl->field) return e->code ? e->code : GR_EMEM;
  const char *w = gr_offset_warning(cl->field);
  if (w[0]) {
    pthread_mutex_lock(a->kbmu);
    snprintf(j->warning, sizeof j->warning, "%s", w);
    pthread_mutex_unlock(a->kbmu);
  }
  return GR_OK;
}

/* 1 if a built template of a class of `count` voxels goes to the knowledge
 * base under policy kb_store (enum gr_kb_store): all, none, or reused = only
 * when the class occurs more than once in the part. */
static int should_store(int kb_store, int count) {
  return kb_store == GR_KB_STORE_ALL || (kb_store == GR_KB_STORE_REUSED && count > 1);
}

/* 1 if class cl's template, once built, goes to the knowledge base. */
static int will_store(const gr_build *a, const gr_vclass *cl) {
  return a->kb && !cl->trimmed && a->jb < 0 && should_store(a->kb_store, cl->count);
}

int gr_build_stores(const gr_build *a, int c) { return will_store(a, &a->j->cls[c]); }

/* Phase 2, per (class, layer chunk). The sections stay: layer assembly
 * reads them where a neighbour is graded otherwise (facestep.h). */
static int layers_item(void *arg_, int item, gr_err *e) {
  gr_build *a = arg_;
  gr_job *j = a->j;
  int c = a->wc[item];
  const gr_vclass *cl = &j->cls[c];
  gr_tmpl_in in = {&j->o, &j->grid, {0, 0, 0}, 0, cl->edge, gr_job_window(j)};
  int i, jj, k;
  gr_grid_origin(&j->grid, cl->rep, in.vo);
  gr_grid_ijk(&j->grid, cl->rep, &i, &jj, &k);
  in.g0 = gr_grid_row_first(&j->grid, k);
  return gr_tmpl_layers(&in, cl->t, cl->field, a->tab, a->wa[item], a->wb[item], e);
}

/* Phase 2a, per table layer: the shared closest points. */
static int table_item(void *arg_, int item, gr_err *e) {
  gr_build *a = arg_;
  gr_job *j = a->j;
  (void)j;
  return gr_cptab_layer(a->tab, item, e);
}

static int store_item(void *arg_, int item, gr_err *e) {
  gr_build *a = arg_;
  gr_job *j = a->j;
  int c = a->items[item];
  gr_vclass *cl = &j->cls[c];
  if (!cl->need) return GR_OK;
  gr_field_free(cl->field);
  cl->field = NULL;
  cl->need = 0;
  pthread_mutex_lock(a->kbmu);
  j->st.built++;
  pthread_mutex_unlock(a->kbmu);
  char why[200];
  gr_tmpl_qualify(&j->o, cl->t, cl->key, a->qualify, a->qualify_ud, why, sizeof why);
  if (j->o.verify) j->st.verified++;
  if (!cl->t->qualified) {
    j->st.unqualified++;
    snprintf(j->st.unqualified_why, sizeof j->st.unqualified_why, "%.16s: %s", cl->key, why);
  }
  if (a->kb && !cl->trimmed && a->jb < 0 && !will_store(a, cl)) {
    pthread_mutex_lock(a->kbmu);
    j->st.kb_not_stored++;
    pthread_mutex_unlock(a->kbmu);
  } else if (a->kb && !cl->trimmed && a->jb < 0) {
    gr_template *r = gr_tmpl_to_record(&j->o, cl->t, cl->sig, cl->count, e);
    if (!r) return e->code ? e->code : GR_EMEM;
    /* written on the writer's thread while the layers go on (stored ones
     * are counted at gr_build_finish) */
    if (!a->kbw && !(a->kbw = gr_kbw_start(a->kb, e))) {
      gr_template_free(r);
      return e->code ? e->code : GR_EMEM;
    }
    return gr_kbw_push(a->kbw, r, e);
  }
  return GR_OK;
}

/* Group key of a class for shared closest points ("" = not shareable).
 * Trimmed classes join too: their section cuts the table's values by the
 * domain (gr_cptab_slice). */
static void share_key(const gr_job *j, int c, char *key, size_t n) {
  const gr_vclass *cl = &j->cls[c];
  key[0] = 0;
  if (!cl->need || !j->o.exact || !j->o.share || !gr_cptab_periodic(j->o.cell, j->o.slice_cell)) return;
  const gr_spec *sp = &j->specs[j->vspec[cl->rep]];
  int i, jj, k;
  gr_grid_ijk(&j->grid, cl->rep, &i, &jj, &k);
  double o[3];
  gr_grid_origin(&j->grid, cl->rep, o);
  double phase = gr_grid_mid(&j->grid, gr_grid_row_first(&j->grid, k)) - o[2];
  snprintf(key, n, "%d %.9g %d %d %.9g %d %d", sp->surface, sp->level, sp->network, sp->side,
           round(phase / 1e-9) * 1e-9, cl->t->nl, cl->t->j0);
}

/* Work items for the classes cs[0..nc): chunks of WORK_LAYERS layers (enough
 * items for every core), in the order of the chunks, then of the classes:
 * items one after another read the same layers of the shared closest-point
 * table (cptab.h, 0.2 MB a layer), which stay in the core's cache. (Class
 * by class, each class read every layer from memory again: 2 % of a
 * continuous job's time.) */
#define WORK_LAYERS 5
static int make_work(gr_build *a, const int *cs, int nc, gr_err *e) {
  const gr_job *j = a->j;
  size_t cap = 0;
  free(a->wc); free(a->wa); free(a->wb);
  a->wc = a->wa = a->wb = NULL;
  a->nwork = 0;
  int sa = a->lb > 0 ? a->la : 0, top = 0;
  for (int q = 0; q < nc; q++) top = j->cls[cs[q]].t->nl > top ? j->cls[cs[q]].t->nl : top;
  for (int s = sa; s < top; s += WORK_LAYERS)
    for (int q = 0; q < nc; q++) {
      const gr_vclass *cl = &j->cls[cs[q]];
      int sb = a->lb > 0 && a->lb < cl->t->nl ? a->lb : cl->t->nl;
      if (s >= sb) continue;
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
      a->wb[a->nwork] = s + WORK_LAYERS < sb ? s + WORK_LAYERS : sb;
      a->nwork++;
    }
  return GR_OK;
}

/* Table t's layers filled to dmax (those filled to less before gain the
 * nodes between). */
static int fill_table(gr_build *a, gr_cptab *t, double dmax, gr_err *e) {
  double was = t->dmax;
  t->dmax = dmax;
  a->tab = t;
  int rc = gr_pool_for(t->nl, table_item, a, a->j->o.threads, NULL, NULL, "closest points", e);
  a->tab = NULL;
  if (rc) t->dmax = was; /* layers not grown: a later call tries again */
  return rc;
}

/* The shared closest points of the group of class c (canonical field g):
 * over one period of the slice grid at the grid's first voxel, layers at the
 * group's z-phase, every node within dmax of H (group_dmax). Depends on the
 * group's key and on dmax only. */
static gr_cptab *make_table(gr_build *a, int c, gr_field *g, double dmax, gr_err *e) {
  gr_job *j = a->j;
  const gr_vclass *cl = &j->cls[c];
  double o[3];
  int i, jj, k;
  gr_grid_origin(&j->grid, cl->rep, o);
  gr_grid_ijk(&j->grid, cl->rep, &i, &jj, &k);
  double phase = gr_grid_mid(&j->grid, gr_grid_row_first(&j->grid, k)) - o[2];
  double z0 = j->o.origin[2] + round(phase / 1e-9) * 1e-9 + cl->t->j0 * j->o.layer;
  gr_cptab *t = gr_cptab_new(j->o.cell, j->o.slice_cell, gr_job_window(j), g, j->o.origin, z0, j->o.layer,
                             cl->t->nl, dmax, e);
  if (t && fill_table(a, t, dmax, e)) {
    gr_cptab_free(t);
    return NULL;
  }
  return t;
}

/* The farthest a node of a cell can be from H (any T up to L/2). */
static double full_dmax(const gr_job *j) { return 0.6 * gr_cell_min(j->o.cell) + 2 * j->o.slice_cell; }

/* How far from H the table of the group cs[0..nc) (canonical field ref)
 * finds closest points: as far as its members' sections read them
 * (gr_cptab_reach: their thickness and a few grid cells; beyond, the nodes'
 * values are bounds with the right sign), at most full_dmax. */
static double group_dmax(const gr_job *j, const int *cs, int nc, const gr_field *ref) {
  /* the members of later calls (rows of voxels, thickness graded along z)
   * estimated from the signatures' largest thickness and a fifth more (the
   * whole reach where a class is trimmed: its values are exact everywhere):
   * T over H near a voxel exceeds T sampled inside it by its slope times
   * the window's margin (growing the table later searches the mesh again
   * from every node beyond its reach) */
  double d = j->st.trimmed_classes ? INFINITY : gr_cptab_reach_est(ref, 1.2 * j->tsig, j->o.slice_cell);
  for (int p = 0; p < nc; p++)
    d = fmax(d, j->cls[cs[p]].field ? gr_cptab_reach(j->cls[cs[p]].field, j->o.slice_cell) : INFINITY);
  return fmin(d, full_dmax(j));
}

/* The cache entry of group key `key`, or NULL. */
static gr_build_group *cache_find(gr_build *a, const char *key) {
  for (int i = 0; i < GR_BUILD_CACHE; i++)
    if (a->cache[i].key[0] && strcmp(a->cache[i].key, key) == 0) return &a->cache[i];
  return NULL;
}

/* Keep group key's canonical field g and table t (the cache takes t and a
 * reference to g) in place of the least recently used entry not used in
 * this call; 0 when every entry is in use (the caller keeps t). */
static int cache_put(gr_build *a, const char *key, gr_field *g, gr_cptab *t) {
  gr_build_group *v = NULL;
  for (int i = 0; i < GR_BUILD_CACHE; i++) {
    gr_build_group *c = &a->cache[i];
    if (c->key[0] && c->used == a->calls) continue;
    if (!v || !c->key[0] || (v->key[0] && c->used < v->used)) v = c;
  }
  if (!v) return 0;
  gr_cptab_free(v->tab);
  gr_field_free(v->field);
  snprintf(v->key, sizeof v->key, "%s", key);
  v->field = gr_field_ref(g);
  v->tab = t;
  v->used = a->calls;
  return 1;
}

/* Progress of a part of the work, reported as a share of the whole. */
typedef struct prog_part { const gr_job_run_opts *r; long base, span, total; } prog_part;
static void prog_part_fn(void *ud, const char *stage, long d, long n) {
  const prog_part *p = ud;
  p->r->progress(p->r->progress_ud, stage, p->base + (n > 0 ? d * p->span / n : p->span), p->total);
}

/* Build (or load) the templates of the classes in a->items: classes that
 * share closest points group by group, the others each on its own. */
int gr_build_classes(gr_build *a, const gr_job_run_opts *r, const char *stage, gr_err *e) {
  gr_job *j = a->j;
  /* layer bands (a->lb > 0): the first prepares and makes the fields, the last stores */
  int first = a->lb <= 0 || a->la == 0, last = a->lb <= 0 || a->band_last;
  int rc = first ? gr_pool_for(a->nitems, prepare_item, a, j->o.threads, NULL, NULL, stage, e) : GR_OK;
  int n = a->nitems;
  /* groups: gid[q] = index (into items) of the group's first class, -1 = none */
  int *cs = malloc((n + 1) * sizeof *cs), *gid = malloc((n + 1) * sizeof *gid);
  a->fc = malloc(2 * (n + 1) * sizeof *a->fc);
  a->fref = malloc(2 * (n + 1) * sizeof *a->fref);
  a->fkind = malloc(2 * (n + 1) * sizeof *a->fkind);
  a->gfield = calloc(n + 1, sizeof *a->gfield);
  a->ghit = calloc(n + 1, sizeof *a->ghit);
  char (*keys)[128] = malloc((n + 1) * sizeof *keys);
  a->calls++;
  if (!cs || !gid || !a->fc || !a->fref || !a->fkind || !a->gfield || !a->ghit || !keys)
    rc = rc ? rc : gr_fail(e, GR_EMEM, "out of memory");
  long total = 0, base = 0;
  for (int q = 0; q < n && rc == GR_OK; q++) {
    gid[q] = -1;
    if (!j->cls[a->items[q]].need) continue;
    total += j->cls[a->items[q]].t->nl;
    share_key(j, a->items[q], keys[q], sizeof keys[q]);
    if (!keys[q][0]) continue;
    for (int p = 0; p < q && gid[q] < 0; p++)
      if (gid[p] == p && strcmp(keys[p], keys[q]) == 0) gid[q] = p;
    if (gid[q] < 0 && (a->ghit[q] = cache_find(a, keys[q]))) {
      a->ghit[q]->used = a->calls;
      a->gfield[q] = gr_field_ref(a->ghit[q]->field);
    }
    if (gid[q] < 0) gid[q] = q;
  }
  /* fields: the groups' canonical fields and unshared classes, then the members */
  for (int pass = 0; pass < 2 && rc == GR_OK; pass++) {
    int nf = 0;
    for (int q = 0; q < n; q++) {
      if (!j->cls[a->items[q]].need) continue;
      if (pass == 0 && gid[q] == q && !a->ghit[q]) { a->fc[nf] = a->items[q]; a->fref[nf] = q; a->fkind[nf++] = 1; }
      if ((gid[q] >= 0) != pass || !first) continue; /* a later band keeps the class fields */
      a->fc[nf] = a->items[q];
      a->fref[nf] = gid[q];
      a->fkind[nf++] = pass ? 2 : 0;
    }
    rc = gr_pool_for(nf, field_item, a, j->o.threads, NULL, NULL, stage, e);
  }
  for (int q = 0; q < n && rc == GR_OK; q++) {
    if (!j->cls[a->items[q]].need || (gid[q] >= 0 && gid[q] != q)) continue;
    int nc = 0;
    if (gid[q] < 0) cs[nc++] = a->items[q];
    else
      for (int p = q; p < n; p++)
        if (gid[p] == q) cs[nc++] = a->items[p];
    gr_cptab *t = a->ghit[q] ? a->ghit[q]->tab : NULL;
    double dmax = gid[q] >= 0 ? group_dmax(j, cs, nc, a->gfield[q]) : 0;
    /* a cached table grows where these members read farther from H: by
     * half at least (each growth searches the mesh again from every node
     * beyond the table's reach; thickness graded along z grows a little
     * with every row of voxels) */
    if (t && t->dmax < dmax && (rc = fill_table(a, t, fmin(fmax(dmax, 1.5 * t->dmax), full_dmax(j)), e))) break;
    if (gid[q] >= 0 && !t && !(t = make_table(a, a->items[q], a->gfield[q], dmax, e))) { rc = e->code ? e->code : GR_EMEM; break; }
    if (gid[q] >= 0 && !a->ghit[q] && cache_put(a, keys[q], a->gfield[q], t)) a->ghit[q] = cache_find(a, keys[q]);
    a->tab = t;
    long nl = 0;
    for (int p = 0; p < nc; p++) nl += j->cls[cs[p]].t->nl;
    prog_part pp = {r, base, nl, total};
    int prog = r && r->progress;
    if ((rc = make_work(a, cs, nc, e)) == GR_OK)
      rc = gr_pool_for(a->nwork, layers_item, a, j->o.threads, prog ? prog_part_fn : NULL, prog ? &pp : NULL, stage, e);
    a->tab = NULL;
    if (!a->ghit[q]) gr_cptab_free(t);
    base += nl;
  }
  free(keys);
  free(gid);
  for (int q = 0; q < n && a->gfield; q++) gr_field_free(a->gfield[q]);
  free(a->gfield);
  free(a->ghit);
  free(a->fc); free(a->fref); free(a->fkind);
  a->fc = a->fref = a->fkind = NULL;
  a->gfield = NULL;
  a->ghit = NULL;
  free(cs);
  gr_err e2;
  gr_err_clear(&e2);
  /* store (and qualify) only complete templates: after a failure some layers were never built */
  int rc2 = rc == GR_OK && last ? gr_pool_for(a->nitems, store_item, a, 1, NULL, NULL, stage, &e2) : GR_OK;
  if (rc == GR_OK && rc2) { rc = rc2; *e = e2; }
  /* on failure, drop any fields left */
  for (int q = 0; q < a->nitems && (last || rc); q++) {
    gr_vclass *cl = &j->cls[a->items[q]];
    gr_field_free(cl->field);
    cl->field = NULL;
  }
  return rc;
}

int gr_build_finish(gr_build *a, gr_err *e) {
  long stored = 0;
  int rc = gr_kbw_finish(a->kbw, &stored, e);
  a->kbw = NULL;
  a->j->st.kb_stored += stored;
  return rc;
}

void gr_build_done(gr_build *a) {
  gr_err e;
  gr_build_finish(a, &e); /* only if the caller has not */
  free(a->wc);
  free(a->wa);
  free(a->wb);
  a->wc = a->wa = a->wb = NULL;
  for (int i = 0; i < GR_BUILD_CACHE; i++) {
    gr_cptab_free(a->cache[i].tab);
    gr_field_free(a->cache[i].field);
    memset(&a->cache[i], 0, sizeof a->cache[i]);
  }
}
