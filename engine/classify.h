/* classify.h: the classification stage (paper s.3.1, "unique voxels").
 *
 * Takes: the job's voxel grid with each voxel's cell spec (surface, level,
 * kind, thickness T(x,y,z,u,v,w)), the design domain and skin, and the
 * fabrication sequence keys. Gives: each voxel's state against the domain
 * (outside: skipped; inside; cut: trimmed, computed on its own), its class
 * (voxels with equal signatures - surface, level, kind, z-phase, layers,
 * process parameters and T sampled on a 4^3 lattice quantised to `quant` -
 * share one template; the class key is the signature's SHA-256, the
 * knowledge base's key), and per voxel row the voxels in sequence order. */
#ifndef GR_CLASSIFY_H
#define GR_CLASSIFY_H
#include "job.h"

/* Group the voxels into classes (j->cls, j->vcls, j->vstate, j->st voxel
 * counts). direct != 0: one class per voxel (kb=off). */
int gr_classify_run(gr_job *j, int direct, gr_err *e);
/* Sides of voxel v on the part's boundary (no lattice beyond): bits 1 x=0,
 * 2 x=L, 4 y=0, 8 y=L; 0 when the job leaves cut sides open (faces off).
 * Valid once gr_classify_run has set every voxel's class. */
int gr_voxel_sides(const gr_job *j, int v);
/* Rows: the voxels of each z-row that have a class, in sequence order
 * (j->roworder, j->rowcount). */
int gr_classify_rows(gr_job *j, gr_err *e);

#endif
