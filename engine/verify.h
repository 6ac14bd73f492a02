/* verify.h: quality figures of a layer's scan vectors against its section
 * (doc/contract.md s.5): pore fraction, overmelt fraction and contour deviation.
 * Section and melt tracks are rasterised on a pixel grid: a pixel is solid
 * when its centre is inside the section (even-odd), melted when its centre
 * lies within track/2 of any scanned segment (contours, hatches, edges,
 * zigzag polylines). */
#ifndef GR_VERIFY_H
#define GR_VERIFY_H
#include "paths.h"

typedef struct gr_verify_opts {
  double track;   /* melt track width, mm (> 0; typically the hatch spacing d) */
  double pixel;   /* raster pixel size, mm; NaN = track/10 */
  double offset;  /* expected contour offset b, mm; NaN = track/2 */
  double spacing; /* distance between successive contours, mm; NaN = track */
  int contours;   /* contour levels expected (b + i*spacing, i < contours); >= 1 */
  long max_pixels;/* refuse larger rasters (GR_EARG); default 1e8 */
  int clip;       /* 1: count only pixels (and contour points) inside clip_lo..clip_hi */
  double clip_lo[2], clip_hi[2]; /* mm; contour points are measured only when at
                    least 2 tracks inside the clip box (the window's border edges
                    of a windowed section are not part boundary) */
} gr_verify_opts;

/* track 0.1, pixel NaN, offset NaN, spacing NaN, contours 1, max 1e8. */
gr_verify_opts gr_verify_defaults(void);

typedef struct gr_verify_result {
  double pore;        /* solid pixels not melted / solid pixels */
  double overmelt;    /* melted pixels outside the solid / solid pixels */
  double solid_area;  /* solid pixels * pixel^2, mm^2 */
  double melt_area;   /* melted pixels * pixel^2, mm^2 */
  double max_dev;     /* max over contour points of |dist to boundary - b_i|, mm */
  double mean_dev;    /* mean of the same, mm (0 when there are no contours) */
  size_t contour_points; /* contour points measured: vertices and 3 points inside every
                            segment (thin-wall scans excluded) */
  size_t thin_points; /* points of thin-wall centre lines (dir GR_DIR_THIN), not in
                         the deviation: they follow a wall's middle, not b */
  size_t thin_scans;  /* thin-wall centre lines with a point counted */
  double thin_length; /* their length from counted points, mm */
  double hatch_length;  /* hatch vectors' length (inside the clip box, if any), mm */
  double hatch_outside; /* the part of it outside the section, mm (exact: the
                           vectors cut at every ring edge they cross) */
  int nx, ny;         /* raster size, pixels */
} gr_verify_result;

/* Quality figures of layer l over section (rings need not be nested:
 * even-odd). Deviation of a contour point is the distance to the nearest
 * expected level b + i*spacing, its distance to the section boundary being
 * exact (nearest ring edge). Thin-wall centre lines (dir GR_DIR_THIN) are
 * counted apart (thin_*) and have no deviation. Hatch vectors are measured
 * exactly for the length they run outside the section (hatch_outside). With
 * clip, points are counted inside the clip box (contour points 2 tracks
 * inside it), and hatch vectors for their part inside it. */
int gr_verify_layer(const gr_rings *section, const gr_layer *l,
                    const gr_verify_opts *o, gr_verify_result *r, gr_err *e);

#endif
