/* facing.h: down- and up-facing contour pieces, the contours' share of the
 * down-skin and up-skin regions (regions.h).
 *
 * Takes: a job with down-skin and/or up-skin regions (job:regions), global
 * layer g and its assembled scan vectors (global coordinates, after layer
 * assembly joined the contours across voxels).
 * Gives: every contour and edge polyline cut where it leaves or enters the
 * section of one of the n layers below or above (the layers the hatch's
 * down- and up-skin test reads), each piece tagged with its region:
 *  - down-skin: outside the section of one of the layers g-1 .. g-n (below
 *    layer 1 is the build plate: solid);
 *  - else up-skin: outside the section of one of the layers g+1 .. g+n
 *    (above the part: open space);
 *  - else the block's region (core).
 * A region not asked for falls through, as for hatches. Thin-wall lines and
 * hatches are left as they are. A contour runs b (the beam offset) inside
 * its section's edge, so a piece is down-facing where the layer below's edge
 * lies more than b inside this layer's: a vertical wall's contour stays core.
 * Cuts are exact (segment against the neighbour sections' edges); a closed
 * contour with pieces of two regions becomes open polylines, in order. */
#ifndef GR_FACING_H
#define GR_FACING_H
#include "place.h"

int gr_facing_contours(gr_job *j, int g, gr_layer *l, gr_err *e);

#endif
