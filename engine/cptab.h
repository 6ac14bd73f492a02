/* cptab.h: shared closest points (templates stage, exact mode).
 *
 * Classes that differ only in thickness (same surface, level, kind, z-phase
 * and layers: the rows of a part graded along its height, say) share H. The
 * closest point on H of every slice-grid node is computed once for the group,
 * over one period of the grid (Lx = Px h, Ly = Py h), and each class only evaluates its
 * own T there; crossings are refined from the nearest node's closest point
 * instead of searching the mesh. Mesh mode's H depends on the voxel's box, so
 * only exact mode shares.
 *
 * Takes: a reference field (its H), the reference voxel's corner, the slice
 * grid (spacing h, window corner) and the layers' heights. Gives:
 * per template layer, the closest points and signed distances of one period
 * of grid nodes, and from them any member class's section. */
#ifndef GR_CPTAB_H
#define GR_CPTAB_H
#include "field.h"
#include "slice.h"

typedef struct gr_cptab {
  int P[2];              /* nodes per period along x, y */
  int nl;                /* template layers */
  double z0, t;          /* height of table layer 0, layer thickness, mm */
  double h, cell[2];     /* slice grid spacing, cell Lx, Ly, mm */
  double lo[2];          /* slice window corner of the reference voxel, mm */
  double oref[3];        /* reference voxel origin, mm */
  double dmax;           /* closest points are exact within this distance of H, mm */
  double *ldmax;         /* per layer: the dmax it was filled to (0: not yet) */
  const gr_field *field; /* the reference class's field */
  double *q, *sd;        /* per template layer, Px*Py nodes: closest point, signed distance */
  /* the strict check of a node's closest point (gr_offset_strict: it does
   * not depend on T), made once for the group when a member first needs
   * it: st 0 not made, 1 being made, 2 made (atomic); sq, ssd its result.
   * Twice over: without H's local reach (nodes 0..N-1) and with it (N..2N-1),
   * for members that use it (gr_offset_uses_local_reach), so that a
   * member's answer does not depend on which member asked first. */
  unsigned char *st;
  double *sq, *ssd;
} gr_cptab;

/* Nodes per period, or 0 when the slice grid (spacing h) is not periodic with
 * the cell length `cell`. */
int gr_cptab_period(double cell, double h);
/* 1 when the slice grid is periodic with both in-plane lengths cell[0], cell[1]. */
int gr_cptab_periodic(const double cell[3], double h);
/* How far from H (mm) a member field f's section reads the table's closest
 * points on a slice grid of spacing h: its exact band (the thickness plus
 * a few grid cells, everywhere for a trimmed field) plus four cells for the
 * chord search's points (cptab.c). A table whose dmax covers every
 * member's serves them all. */
double gr_cptab_reach(const gr_field *f, double h);
/* The same estimated for a member not yet made, of thickness up to tmax
 * (mm), from the table's own field ref. */
double gr_cptab_reach_est(const gr_field *ref, double tmax, double h);
/* An empty table (fill it with gr_cptab_layer for q = 0..nl-1); NULL + e on failure. */
gr_cptab *gr_cptab_new(const double cell[3], double h, double margin, const gr_field *ref, const double oref[3], double z0,
                       double t_layer, int nl, double dmax, gr_err *e);
void gr_cptab_free(gr_cptab *t);
/* Closest points of table layer q (thread-safe for distinct q): all its
 * nodes within dmax of H; a layer filled before to a smaller dmax (the
 * caller raised t->dmax for members with thicker walls) gains the nodes
 * between the two only. */
int gr_cptab_layer(gr_cptab *t, int q, gr_err *e);
/* Section of a member class (field f, voxel corner o) at height z (table layer q).
 * f may be a trimmed field (gr_domain_trim of a member's field, domain.h):
 * the member's values from the table are then cut by the domain, which is
 * evaluated near its boundary only (gr_domain_grid) and at refined points
 * only where it may decide. */
int gr_cptab_slice(const gr_cptab *t, const gr_field *f, const double o[3], int q,
                   double z, const gr_slice_opts *so, gr_rings *out, gr_err *e);

#endif
