/* template.h: the templates stage (paper s.3.2-3.4): one unique voxel (a
 * class's representative) to its layers of scan paths.
 *
 * Takes: the job's process parameters (gr_job_opts: L, t, d, b, contours,
 * slice resolution), the voxel's corner and first global layer, the voxel's
 * graded field (the offset of H by T, eq. 5-6, trimmed by the part's domain
 * where it cuts the voxel) and optionally a shared closest-point table.
 * Gives, per local layer, in voxel-local coordinates:
 *  - section: the section rings in a window a margin wider than the voxel
 *    (the in-plane offsets near the voxel's border depend on the section just
 *    outside it);
 *  - region: the hatch region (section offset inward, see hatch.h);
 *  - paths: contour loops (and thin-wall scans) clipped to the voxel square:
 *    closed loops and open pieces that end on the square's border, joined
 *    with the pieces of the neighbouring voxels at layer assembly;
 *  - faces: the contour segments along the voxel's sides, used where the
 *    voxel is on the part's boundary;
 *  - quality figures (verify) and the qualification verdict.
 * A template converts to and from a knowledge-base record (kb.h). */
#ifndef GR_TEMPLATE_H
#define GR_TEMPLATE_H
#include "cptab.h"
#include "grid.h"
#include "kb.h"
#include "place.h"
#include <stdatomic.h>

struct gr_fxing; /* facestep.c: where the section crosses the face-check lines */

typedef struct gr_tlayer {
  double area;        /* section area inside the voxel square, mm^2 */
  double q[3];        /* verify(): pore, overmelt, max contour deviation (mm); NaN = not verified */
  gr_rings *section;  /* window, voxel-local */
  double cut[4];      /* the window's rectangle as the section's coordinates have it
                         (its edges along it are cuts, no walls); NaN: none */
  gr_rings *region;   /* hatch region, voxel-local */
  gr_layer *paths;    /* contours (+ thin-wall scans) clipped to [0,L]^2 */
  gr_layer *faces;    /* contour segments along the voxel's sides at the contour
                         offsets, for voxels on the part's boundary (block.laser
                         = side: 0 x=0, 1 x=L, 2 y=0, 3 y=L) */
  _Atomic(struct gr_fxing *) fx; /* made by the first face-step check that needs it
                                    (facestep.c; one malloc'd block, freed with the layer):
                                    the section's crossings of the lines near each face,
                                    shared by every voxel of the template */
} gr_tlayer;

typedef struct gr_tmpl {
  int j0, nl;         /* local layers j0 .. j0+nl-1 */
  gr_tlayer *l;
  double quality[4];  /* worst pore, worst overmelt, max contour deviation (mm), layers verified */
  int qualified;      /* passed the qualification rules */
  int from_kb;
} gr_tmpl;

/* Where a template's voxel is: what the stage needs of the job. */
typedef struct gr_tmpl_in {
  const gr_job_opts *o; /* process parameters */
  const gr_grid *grid;
  double vo[3];         /* the voxel's min corner, mm */
  int g0;               /* the voxel row's first global layer */
  int faces;            /* 1: the side segments too (a voxel of the class lies on the part's
                           boundary); 0: tl->faces left NULL (no assembly reads them) */
  double win;           /* the slice window's margin (gr_tmpl_window), mm */
} gr_tmpl_in;

/* A template for local layers [ja, jb), layers empty; NULL when out of memory. */
gr_tmpl *gr_tmpl_new(int ja, int jb);
void gr_tmpl_free(gr_tmpl *t);
/* Free layers [qa, qb)'s section, region, paths and face data once no layer
 * assembly reads them (layer bands, place.c); their area, verify figures and
 * thin-wall counts stay for qualification. */
void gr_tmpl_release(gr_tmpl *t, int qa, int qb);
/* Margin of a template's slice window around the voxel (mm): whole slice
 * cells, wide enough for the contours and hatch region of the voxel's edge;
 * deep: the most contours scanned along a boundary (the job's, or more
 * along a skin: gr_job_window). */
double gr_tmpl_window(const gr_job_opts *o, int deep);

/* Where the section's edge runs along a voxel's outer side (a domain whose
 * face lies on the part's box), the contour at c and the side moved in by c
 * coincide to the offset's tolerance (1e-6 mm): the side's segment is
 * taken only where the section reaches more than this beyond it (mm), and
 * contours are kept to this outside it, so that one of the two is scanned,
 * not both, nor neither. */
#define GR_FACE_EPS 5e-6
/* Compute template layers [qa, qb) (indices into t) from the voxel's field f,
 * through the shared closest points tab if not NULL. Thread-safe for
 * disjoint layer ranges. */
int gr_tmpl_layers(const gr_tmpl_in *in, gr_tmpl *t, const gr_field *f, const gr_cptab *tab, int qa, int qb,
                   gr_err *e);
/* From tl->section (voxel-local window, as the templates slice it): the
 * contours and thin-wall scans clipped to the voxel (tl->paths), the hatch
 * region (tl->region) and, with `faces`, the side segments (tl->faces), each
 * created when NULL and cleared first. Used by the templates and, for a
 * voxel next to a differently graded one, by the assembly on the window's
 * true section. The offsets' chords are refined to the templates' chord
 * tolerance, as the sections' are. */
int gr_tmpl_paths(const gr_job_opts *o, gr_tlayer *tl, int faces, gr_err *e);
/* A built template's quality (worst verified layer; NaN when o->verify is 0)
 * and qualification: the contract's targets (doc/contract.md) when verified, then the recipe's rule
 * fn (may be NULL). Sets t->quality and t->qualified; why: the reason when
 * not qualified. */
void gr_tmpl_qualify(const gr_job_opts *o, gr_tmpl *t, const char *key, gr_qualify_fn fn, void *ud,
                     char *why, size_t n);
/* Template <-> knowledge-base record (sig: the class's signature, count:
 * voxels of the class, for the record's metadata). from_record returns NULL
 * when the record does not fit (nl layers expected) or memory runs out; it
 * makes the side segments with `faces` (as gr_tmpl_in.faces). */
gr_template *gr_tmpl_to_record(const gr_job_opts *o, const gr_tmpl *t, const char *sig, int count, gr_err *e);
gr_tmpl *gr_tmpl_from_record(const gr_job_opts *o, const gr_template *r, int nl, int faces);

#endif
