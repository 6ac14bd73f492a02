/* job.h: the state of one job (place.h's gr_job), shared by the stages that
 * fill it in turn: classification (classify.h) writes the voxel classes and
 * rows, the template builder (build.h) writes each class's template, layer
 * assembly (assemble.h, stream.h) reads both and adds to the statistics. The
 * primitives underneath (grid.h, clip.h, cptab.h, template.h, lasers.h,
 * pool.h) take small structs, not the job. Internal to the engine. */
#ifndef GR_JOB_H
#define GR_JOB_H
#include "expr.h"
#include "grid.h"
#include "place.h"
#include "template.h"

/* A voxel class: voxels with equal signatures share one template. */
typedef struct gr_vclass {
  int rep;            /* representative voxel */
  int count;          /* voxels in the class */
  int trimmed;        /* computed directly (domain boundary) */
  int edge;           /* a voxel of the class lies on the part's boundary
                         (gr_voxel_sides): its template needs side segments */
  char key[65];       /* SHA-256 of sig, hex */
  char *sig;          /* signature text */
  gr_tmpl *t;
  gr_field *field;    /* while its template is being built */
  int need;           /* template must be computed in this run */
} gr_vclass;

struct gr_job {
  gr_job_opts o;
  gr_grid grid;       /* from o: cell, origin, n, layer; N */
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
  double tsig;        /* the largest thickness sampled for the signatures, mm */
  gr_vclass *cls;
  int ncls;
  int nlayers;        /* N */
  gr_machine m;
  /* results */
  gr_job_stats st;
  char warning[1024];
  int *roworder;      /* per row: voxels with a class, in sequence order */
  int *rowcount;
  int rowlen;         /* nx*ny */
  long st_dropped;
  long st_split;      /* closed contours split between lasers (stitch.h) */
  struct gr_regions *regions; /* regions with their own build styles (regions.h) or NULL */
};

#endif
