/* build.h: building the templates of a set of classes (paper s.3.2-3.4 and
 * the knowledge base of s.3.6), the step between classification and layer
 * assembly.
 *
 * Takes: the classified job and a set of classes (every class of the job, or
 * with kb=off the voxels of one row and a layer range), the knowledge base.
 * Gives: each class's template (gr_tmpl), from the knowledge base when it is
 * there, else built: (1) each class's graded field - the offset of H by its
 * thickness T (distance.h), trimmed by the part's domain and skin where the
 * voxel is cut - with classes that differ only in T sharing H and its
 * closest points (cptab.h); (2) its layers (template.h) in chunks on the
 * worker pool (pool.h); (3) its quality and qualification, stored into the
 * knowledge base. Counts built, reused, verified and unqualified templates in
 * the job's statistics. */
#ifndef GR_BUILD_H
#define GR_BUILD_H
#include <pthread.h>
#include "job.h"
#include "kbwriter.h"

/* A group's canonical field and closest-point table, kept across calls of
 * gr_build_classes (the part is built band by band: a group met again in a
 * later band is not recomputed). Both depend on the group's key only. */
#define GR_BUILD_CACHE 4
typedef struct gr_build_group {
  char key[128];           /* share key, "" = empty entry */
  gr_field *field;         /* canonical field (a reference) */
  gr_cptab *tab;           /* its closest points */
  long used;               /* call number of the last use (least recently used goes) */
} gr_build_group;

typedef struct gr_build {
  gr_job *j;
  gr_kb *kb;               /* knowledge base or NULL */
  int kb_store;            /* enum gr_kb_store (place.h) */
  pthread_mutex_t *kbmu;   /* guards kb, the job's warning and counts */
  int *items;              /* classes */
  int nitems;
  int ja, jb;              /* local layer range, jb < 0: all */
  gr_qualify_fn qualify;   /* the recipe's rule or NULL */
  void *qualify_ud;
  /* work space */
  int *wc, *wa, *wb;       /* work items: class, template layers [wa, wb) */
  int nwork;
  gr_cptab *tab;           /* shared closest points of the classes in work, or NULL */
  int *fc, *fref, *fkind;  /* field items: class, its group (index into items) or -1, kind */
  gr_field **gfield;       /* per group head (index into items): the canonical field */
  gr_build_group **ghit;   /* per group head: its cache entry when found there, else NULL */
  gr_build_group cache[GR_BUILD_CACHE];
  long calls;              /* gr_build_classes calls so far */
  gr_kbw *kbw;             /* the knowledge base's writer, started at the first record stored */
  /* layer bands: lb <= 0 builds the templates whole in one call; else the
   * call builds their layers [la, lb) only, the call with la = 0 prepares
   * them and their fields, the one with band_last set qualifies and stores
   * them (a template's layers are independent of each other) */
  int la, lb, band_last;
} gr_build;

/* Build (or load) the templates of the classes in a->items; progress via r
 * (may be NULL) under the name `stage`. */
int gr_build_classes(gr_build *a, const gr_job_run_opts *r, const char *stage, gr_err *e);
/* 1 if class c's template, once built, is stored (then it is built whole). */
int gr_build_stores(const gr_build *a, int c);
/* Wait for the templates handed to the knowledge base's writer to be
 * stored (counted in the job's statistics); the writer's first failure. */
int gr_build_finish(gr_build *a, gr_err *e);
/* Free the work space and the cache (finishing the writer if still running). */
void gr_build_done(gr_build *a);

#endif
