/* facestep.h: the voxel-owned section around a voxel whose neighbours are
 * graded differently (a primitive of the layer-assembly stage).
 *
 * Under voxel-owned grading each voxel's solid comes from its own grading;
 * where neighbours differ, the solid steps exactly on their shared face. A
 * template's section covers a window a margin m wider than its voxel, with
 * the voxel's own grading continued beyond its faces, so near a face between
 * differently graded voxels its contours are those of the wrong solid. This
 * builds the true section of the window: the union, over the voxel and its
 * eight neighbours, of each one's section cut to its own part of the window,
 * the face segments where only one side is solid included (exact polygons:
 * no sampling). Contours and hatch regions computed from it then run along
 * the step at the beam offset and hatch offset (template.h: gr_tmpl_paths).
 *
 * Takes: the cell lengths L = {Lx, Ly} and margin m (mm) and nine section ring sets in
 * the voxel-local coordinates of their own voxels (nb[3 * (dj + 1) + di + 1]
 * for the neighbour at (di, dj), di, dj in -1..1; NULL = no neighbour: the
 * centre's own section is used there, as the template does). Gives: closed
 * rings of the window [-m, Lx + m] x [-m, Ly + m] in the centre voxel's coordinates, solid
 * on the left, closed along the window's border like a template section. */
#ifndef GR_FACESTEP_H
#define GR_FACESTEP_H
#include "job.h"
#include "paths.h"
#include "template.h"

/* The window's section into out (cleared first). GR_OK, GR_EMEM, or GR_EARG
 * when the pieces do not close into rings (degenerate input: a section edge
 * lying along a face); out is then empty and the caller keeps the template. */
int gr_fstep_section(const double L[2], double m, const gr_rings *const nb[9], gr_rings *out, gr_err *e);
/* The stepped layers of one layer's assembly, shared by the voxels whose
 * neighbourhoods are the same (the nine template layers around them and
 * which of their faces are continuous): along a flat part face or a run of
 * equal classes the same layer serves many voxels. Owned by one assembly
 * thread; cleared between layers (the template layers it keys on change). */
typedef struct gr_fstep_cache gr_fstep_cache;
gr_fstep_cache *gr_fstep_cache_new(void); /* NULL when out of memory */
void gr_fstep_cache_clear(gr_fstep_cache *c);
void gr_fstep_cache_free(gr_fstep_cache *c);
/* Voxel v of job j on its row's local layer jl: when its template's section,
 * continued past a side with the voxel's own grading, differs from the side
 * neighbour's own section within the hatch offset of their face (crossings of
 * the face and of three lines parallel to it more than 0.2 um apart: a step,
 * or a grading that changes across the face, such as a sine in u), its layer
 * recomputed on the window's true section (gr_tmpl_paths) into *out, held by
 * the cache c until it is cleared; *out = NULL when not needed or degenerate
 * (keep the template's layer). GR_OK, GR_EMEM or GR_EARG (e filled). */
int gr_fstep_voxel(const gr_job *j, int v, int jl, gr_fstep_cache *c, const gr_tlayer **out, gr_err *e);
void gr_fstep_free(gr_tlayer *tl); /* frees the members, zeroes tl */

#endif
