/* clip.h: clipping scan paths to a voxel square (a primitive of the
 * templates and layer-assembly stages).
 *
 * Takes: polylines or segments in the plane and an axis-aligned box (the
 * voxel square [0, L]^2, possibly with sides moved in). Gives: the pieces
 * inside it (open pieces end on the box border, ready to be joined with the
 * neighbouring voxel's pieces), and the area of a section inside the box. */
#ifndef GR_CLIP_H
#define GR_CLIP_H
#include <stddef.h>
#include "paths.h"
#include "slice.h"

/* Liang-Barsky: clip segment p->q to the box; returns 0 if nothing is left,
 * else the parameters t0 <= t1 in [0,1]. */
int gr_clip_seg(double px, double py, double qx, double qy, const double lo[2],
                const double hi[2], double *t0, double *t1);
/* CLI direction of an open piece cut from a block of direction dir:
 * thin-wall lines keep their tag, everything else becomes "open" (2). */
int gr_clip_open_dir(int dir);
/* Clip one polyline (closed: the last point joins the first; the first point
 * may or may not be repeated) to the box and append the pieces to `out`: a
 * closed polyline wholly inside stays GR_CLOSED (first point repeated), the
 * rest become GR_OPEN pieces that start and end on the box border. buf/cap:
 * the caller's scratch space. Returns GR_OK or GR_EMEM. */
int gr_clip_poly(const double *p, size_t n, int closed, int kind, int dir,
                 const double lo[2], const double hi[2], gr_layer *out,
                 double **buf, size_t *cap);
/* Points this close to a box side (mm) are put on it by gr_clip_ring_owned:
 * two voxels' templates put a contour along their shared face within
 * rounding of it (1e-15 mm measured), far below this. */
#define GR_CLIP_SNAP 1e-9
/* As gr_clip_poly for a closed ring (kind, dir as there) whose inside lies
 * on its left (outer rings counter-clockwise, holes clockwise), except on the
 * box's sides: its points within GR_CLIP_SNAP of a side are put on the side,
 * and an edge lying on a side is kept only if the ring's inside is towards
 * the box. A contour running along a face shared by two voxels (a domain's
 * face on a voxel face, offset by the beam offset or not) is then scanned
 * once, by the voxel whose section it bounds, not by both. */
int gr_clip_ring_owned(const double *p, size_t n, int kind, int dir, const double lo[2], const double hi[2],
                       gr_layer *out, double **buf, size_t *cap);
/* Area of the region bounded by `r` (signed ring areas) inside the box, mm^2. */
double gr_clip_area(const gr_rings *r, const double lo[2], const double hi[2]);

#endif
