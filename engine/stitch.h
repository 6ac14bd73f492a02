/* stitch.h: closed loops per laser and stitching between lasers (multi-laser
 * machines, paper s.3.5).
 *
 * Takes: the machine (laser fields, stitching length), a contour chain (the
 * pieces of neighbouring voxels joined end to start, each piece with the
 * laser of its voxel), or a layer's hatch segments joined per laser. Gives:
 * the chain scanned whole by one laser that reaches all of it (the laser
 * with the largest share of the chain's length among those that reach it:
 * the laser rule decided the voxels, the loop follows its majority); where
 * no laser reaches the whole chain, one open piece per run of equal lasers,
 * each extended along its neighbours by half the stitching length so that
 * neighbouring pieces overlap by the stitching length (less only where a
 * laser's field or the neighbour's length stops it). Hatch segments that
 * meet on one hatch line at a boundary between two lasers are extended into
 * each other the same way. */
#ifndef GR_STITCH_H
#define GR_STITCH_H
#include "place.h"

/* A hatch segment on the global line family (layer assembly). */
typedef struct gr_hseg {
  double x0, y0, x1, y1; /* global, mm */
  long line;             /* index on the global line family */
  double s0, s1;         /* positions along the line direction (s0 < s1) */
  int laser;
  int voxel;             /* position in the row order */
  int region;            /* enum gr_region (regions.h) */
} gr_hseg;

/* A contour chain: points p[0..m) (closed: p[m-1] meets p[0] within the
 * join tolerance), made of np pieces, piece k from point ps[k] to point
 * ps[k+1] (ps[np] = m - 1), scanned by laser pl[k] as its voxel was assigned.
 * kind: vector kind; dir: the pieces' direction tag (GR_DIR_THIN for
 * thin-wall centre lines, which stay open lines even when closed). */
typedef struct gr_stitch_chain {
  double *p;
  size_t m;
  int closed, kind, dir;
  const size_t *ps;
  const int *pl;
  size_t np;
} gr_stitch_chain;

/* Append chain c to out: whole with one laser, or split per laser with the
 * stitching overlap (then *split += 1 for a closed contour loop). The points
 * of c may be changed (a closed loop's ends are made equal). GR_OK or GR_EMEM. */
int gr_stitch_chain_emit(const gr_machine *m, gr_stitch_chain *c, gr_layer *out, long *split);

/* Extend the n hatch segments s[] (joined per laser: segments of one laser
 * on one line do not touch) where two of different lasers meet on a line:
 * each into the other by half the stitching length, at most the other's
 * length, never out of its own laser's field. GR_OK or GR_EMEM. */
int gr_stitch_hatches(const gr_machine *m, gr_hseg *s, size_t n);

#endif
