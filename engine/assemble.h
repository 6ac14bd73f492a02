/* assemble.h: the layer-assembly stage (paper s.3.5: "populating" the
 * templates into the part).
 *
 * Takes: the classified job with its templates, and a global layer g. Gives:
 * the part's layer g as scan paths (paths.h), in the fabrication sequence:
 * each voxel of the layer's row gets its template layer translated to its
 * place; voxels on the part's boundary get their contours cut by the part's
 * sides plus the side segments (template faces); hatches are generated on
 * the global line family at the layer's angle, per voxel, clipped to the
 * voxel square; lasers are assigned per voxel (lasers.h). In continuous mode
 * collinear touching hatches and meeting contour pieces of neighbouring
 * voxels (same laser) are joined across voxels; in island mode each voxel is
 * scanned on its own, its hatches turned 90 degrees on alternate voxels. */
#ifndef GR_ASSEMBLE_H
#define GR_ASSEMBLE_H
#include "job.h"
#include "stitch.h"

/* One worker's scratch space (reused from layer to layer). */
typedef gr_hseg gr_asm_seg;
typedef struct gr_asm_scratch {
  gr_rings *rg;          /* region translated to global coordinates */
  gr_layer *hl;          /* hatch output of one voxel */
  gr_layer *cont;        /* contour pieces of the layer, block.laser = voxel slot */
  gr_asm_seg *segs, *segs2; /* the layer's hatch segments; segs2: sorting space */
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
  struct gr_fstep_cache *fs; /* stepped layers of the layer being assembled */
} gr_asm_scratch;

/* nrow: voxels per row (nx*ny). Returns GR_OK or GR_EMEM (free it either way). */
int gr_asm_scratch_init(gr_asm_scratch *s, int nrow);
void gr_asm_scratch_free(gr_asm_scratch *s);
/* Place global layer g (1..N) into `out` (cleared first). Thread-safe for
 * distinct scratch spaces and layers. */
int gr_asm_layer(gr_job *j, int g, gr_asm_scratch *s, gr_layer *out, gr_err *e);

#endif
