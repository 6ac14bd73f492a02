/* lasers.h: the lasers stage (paper s.3.5, multi-laser machines).
 *
 * Takes: the machine (lasers, their reachable fields and speeds per vector
 * kind, jump speed and delays, recoat time), a layer's voxel slots with each
 * slot's contour and hatch length and fixed laser (if any). Gives: the laser
 * of every slot (fixed ones as given, the others longest-processing-time
 * first onto the laser that would finish first among those that reach the
 * voxel), and per layer the statistics: vectors and lengths per kind and
 * laser, jumps, estimated time per laser, the layer's build time (slowest
 * laser) and the balanced time. */
#ifndef GR_LASERS_H
#define GR_LASERS_H
#include "grid.h"
#include "place.h"

/* Lasers of the nslot voxel slots vox[] (voxel indices into grid) into las[];
 * vlaser[v]: voxel v's fixed laser or -1; lc, lh: slot contour and hatch
 * lengths, mm. Fails (GR_EARG) when no laser reaches a voxel. */
int gr_lasers_assign(const gr_machine *m, const gr_grid *grid, const int *vlaser, const int *vox, int nslot,
                     const double *lc, const double *lh, int *las, gr_err *e);
/* Fails (GR_EARG, naming the voxel) when a voxel slot's fixed laser, the only
 * laser, or every laser misses it: run before any work (gr_job_run) and again
 * by gr_lasers_assign. */
int gr_lasers_check(const gr_machine *m, const gr_grid *grid, const int *vlaser, const int *vox, int nslot,
                    gr_err *e);
/* 1 if laser l's field holds the box [lo, hi] (mm), else 0. */
int gr_lasers_reach_box(const gr_machine *m, int l, const double lo[2], const double hi[2]);
/* Add layer l's figures (blocks of one laser in order) to st. */
void gr_lasers_account(const gr_machine *m, const gr_layer *l, gr_job_stats *st);
/* Add one layer's figures (gr_lasers_account into a zeroed struct) to st. */
void gr_lasers_add(gr_job_stats *st, const gr_job_stats *l);

#endif
