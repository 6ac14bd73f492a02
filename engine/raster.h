/* raster.h: layer pictures as PNG through libpng. */
#ifndef GR_RASTER_H
#define GR_RASTER_H
#include "paths.h"

typedef struct gr_png_opts {
  int width;          /* picture width, pixels (height from the aspect ratio) */
  double line_width;  /* contour line width, pixels (hatches 0.7 of it) */
  int jumps;          /* 1: draw jumps as thin grey lines */
} gr_png_opts;

/* Scan vectors coloured by laser and kind on white, y up, a scale bar of a
 * round length (1, 2 or 5 x 10^k mm) at the bottom left. Written atomically. */
int gr_png_layer(const char *path, const gr_layer *l, const gr_png_opts *o, gr_err *e);

#endif
