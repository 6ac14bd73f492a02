/* skinring.h: more contours along a domain's skin than along the lattice
 * (the skin region's own contour count, regions.h).
 *
 * Takes: a job whose skin region asks for k contours (job:regions
 * skin_contours) where the job has n < k, a trimmed voxel's template layer
 * (its window section, voxel-local) at global layer g, the voxel's corner.
 * Gives:
 *  - the extra contours i = n .. k-1: the section's inward offsets by
 *    b + i d, kept where their nearest section boundary point lies on the
 *    domain's surface (|domain| < 5 um there: the part's outer surface, not
 *    a lattice pore's edge nor the window's cut), clipped to the voxel
 *    square, as contour blocks;
 *  - the hatch test: a hatch point of the skin is dropped when it lies
 *    within b + (k-1) d + gap of the section boundary in the plane and that
 *    nearest boundary point is on the domain's surface, so hatches end on
 *    the last skin contour as they end on the last lattice contour.
 * Near lattice pores the job's n contours and hatch offset stay. */
#ifndef GR_SKINRING_H
#define GR_SKINRING_H
#include "place.h"
#include "template.h"

typedef struct gr_skinring gr_skinring;

/* The skin's ring data of voxel v's template layer tl at global layer g (o:
 * the voxel's corner); NULL with e->code 0 when the skin asks for no more
 * contours than the job or the voxel is not trimmed. */
gr_skinring *gr_skinring_new(gr_job *j, int g, int v, const gr_tlayer *tl, gr_err *e);
void gr_skinring_free(gr_skinring *s);
/* Append the extra contours (global coordinates, laser = slot) to cont. */
int gr_skinring_contours(gr_skinring *s, int slot, gr_layer *cont, gr_err *e);
/* 1 when the hatch point (x, y) (global) is to be dropped (above), 0 if not,
 * negative with e on error. */
int gr_skinring_drop(gr_skinring *s, double x, double y, gr_err *e);

#endif
