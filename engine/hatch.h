/* hatch.h: the hatch primitive (paper s.3.4, doc/contract.md s.5): contours along the
 * in-plane inward offsets of a section and parallel / zigzag / island hatch
 * infill on a GLOBAL family of lines, so that separately hatched neighbouring
 * regions produce collinear vectors whose endpoints meet.
 *
 * Offsets and the hatch region (a documented rule; d = spacing, b = beam
 * offset, n = contours):
 *  - contour i (i = 0..n-1) follows the section offset inward by b + i*d;
 *  - the hatch region is the section offset inward by
 *        h = b + gap                      when n = 0,
 *        h = b + (n-1)*d + gap            when n >= 1,
 *    i.e. by default the hatch vectors end ON the last contour line. Why:
 *    where the boundary meets the hatch lines at an angle theta, the points
 *    no hatch track reaches (slivers between line ends) lie less than
 *    (d/2) cos(theta) <= d/2 deeper than the hatch-region boundary, so the
 *    last contour's track (half width d/2) covers them: contour and hatch
 *    tracks of width d tile the section without holes. The hatch end caps
 *    reach d/2 outside the last contour line, which is still inside the
 *    section when b >= d/2 (no overmelt). A positive gap (<= d/2) reduces
 *    the double melt under the contour at the risk of slivers; measure it
 *    with gr_verify_layer.
 *  - thin walls: where the contour at b and the hatches cannot reach - the
 *    "slivers", section points farther than b from the offset by b: a
 *    component whose offset is empty, or a thin tail of a thick one - the
 *    sliver's centre line is scanned: an open polyline (GR_OPEN, GR_CONTOUR,
 *    dir GR_DIR_THIN) along the ridge of the section's distance field,
 *    stopped where the half width drops below d/16 and 0.8 b before a tip
 *    (less overmelt), and where it reaches the contour's melt. A component
 *    thinner than 2b everywhere always gets a scan (a dot if tiny).
 *    Each scanned sliver counts in gr_layer.thin_walls; gr_verify_layer
 *    counts these lines apart from the contours. The slivers are found on a
 *    grid of d/16 over the section's box, at most 4M nodes: boxes wider than
 *    about 125 d get a coarser grid, which may miss slivers narrower than a
 *    few of its cells (a whole component it misses still gets a line). */
#ifndef GR_HATCH_H
#define GR_HATCH_H
#include "paths.h"

enum gr_hatch_pattern {
  GR_PARALLEL = 0, /* independent straight vectors (GR_SEGMENTS blocks) */
  GR_ZIGZAG = 1,   /* vectors of adjacent lines joined into GR_OPEN polylines
                      (directions always alternate, whatever `alternate`) */
  GR_ISLAND = 2    /* checkerboard islands, direction alternating 90 degrees */
};

/* Inward offset of a region (same contract as gr_offset_rings_coarse in
 * slice.h: box, x0 y0 x1 y1 or NULL, where the offset's parts narrower than
 * its grid are looked for; cut, x0 y0 x1 y1 or NULL, the rectangle the
 * region was cut to, whose sides are no walls). */
typedef int (*gr_offset_fn)(const gr_rings *in, double b, double cell, const double *box, const double *cut,
                            gr_rings *out, gr_err *e);

typedef struct gr_hatch_opts {
  double spacing;      /* hatch spacing d, mm (> 0) */
  double beam_offset;  /* beam offset b, mm (>= 0); NaN = d/2 */
  int contours;        /* number of contours, 0..100 */
  int contour_first;   /* 1: contours before hatches in the block order */
  double gap;          /* hatch region offset beyond the last contour line, mm (see above) */
  int pattern;         /* enum gr_hatch_pattern */
  int alternate;       /* 1: reverse every other line (by global line index) */
  double angle;        /* hatch direction of this layer, degrees from +x */
  double island;       /* island size s, mm (> 0 for GR_ISLAND) */
  double island_origin[2]; /* origin of the global island grid, mm */
  double min_length;   /* shorter hatch vectors are dropped and counted, mm */
  int laser;           /* 0-based laser index of every block */
  double cell;         /* offset distance-field cell, mm; NaN = d/4 */
  gr_offset_fn offset; /* region offset; NULL = gr_offset_rings */
  double thin_box[4];  /* thin walls are looked for only where they reach this box
                          (x0, y0, x1, y1, mm; default everywhere): a section cut from a
                          larger one has slivers along the cut that are not walls */
  double cut[4];       /* the rectangle the section was cut to (x0, y0, x1, y1, mm): its
                          edges lying on it are no walls, and the offsets move them out
                          (the contours and region beyond the rectangle's sides differ);
                          NaN (the default): none */
} gr_hatch_opts;

/* Defaults: spacing 0.1, b = d/2, 1 contour, contours first, gap 0,
 * parallel, alternate on, angle 45, island 5, origin (0,0), min length 0,
 * laser 0, cell d/4, offset gr_offset_rings, thin_box everywhere, no cut. */
gr_hatch_opts gr_hatch_defaults(void);

typedef struct gr_hatch_report {
  size_t contours;      /* contour blocks emitted */
  size_t hatches;       /* hatch vectors emitted (links of zigzags excluded) */
  size_t links;         /* zigzag links joining adjacent vectors */
  size_t dropped;       /* vectors dropped for being shorter than min_length */
  double dropped_length;/* their total length, mm */
  int thin_walls;       /* slivers / components scanned by the thin-wall rule */
  size_t thin_scans;    /* thin-wall centre lines emitted (not in contours) */
  double thin_length;   /* their length, mm */
  double hatch_offset;  /* the offset h of the hatch region used, mm */
} gr_hatch_report;

/* Check options; GR_EARG naming the parameter and its value. */
int gr_hatch_check(const gr_hatch_opts *o, gr_err *e);

/* Contours + infill of one section. Blocks are APPENDED to `out` (its z is
 * not changed); rep may be NULL. section must be nested (gr_rings_nest) or
 * is nested on a private copy. */
int gr_hatch_layer(const gr_rings *section, const gr_hatch_opts *o,
                   gr_layer *out, gr_hatch_report *rep, gr_err *e);

/* Contours and thin-wall scans only (the blocks gr_hatch_layer gives before
 * or after its hatches), and the hatch region (the inward offset of the
 * section by rep->hatch_offset) into `region` (cleared first) instead of
 * hatching it: each offset is computed once. */
int gr_hatch_contours(const gr_rings *section, const gr_hatch_opts *o, gr_layer *out,
                      gr_rings *region, gr_hatch_report *rep, gr_err *e);

/* Infill only: hatch vectors of the given region (no offset applied), on
 * the global line family of o->angle. Appends to `out`; rep may be NULL
 * (its counters are added to, not reset). */
int gr_hatch_region(const gr_rings *region, const gr_hatch_opts *o,
                    gr_layer *out, gr_hatch_report *rep, gr_err *e);

/* Miter offset: each vertex moves to the intersection of its two edges'
 * lines shifted inward by b. Exact for convex polygons (a regular N-gon
 * stays a regular N-gon); rings that collapse are dropped; no
 * self-intersection handling, so use gr_offset_rings for general shapes.
 * Same contract as gr_offset_fn (cell, box and cut unused). */
int gr_hatch_miter_offset(const gr_rings *in, double b, double cell, const double *box, const double *cut,
                          gr_rings *out, gr_err *e);

/* Layer rotation: first + k*increment in [0, 360) degrees, k the GLOBAL
 * layer index (e.g. 45 + 67k, or 0 + 90k). */
double gr_hatch_angle(long k, double first, double increment);

#endif
