/* pngread.h: reading a PNG picture (libpng), e.g. a browser's screenshot
 * that a test compares with the geometry it should show. */
#ifndef GR_PNGREAD_H
#define GR_PNGREAD_H
#include "common.h"

/* Read path as 8-bit RGBA, rows top to bottom: *rgba holds 4*w*h bytes, the
 * caller frees it. Errors: GR_EIO (cannot open), GR_EPARSE (not a PNG, or
 * libpng's message), GR_EMEM. */
int gr_pngread(const char *path, unsigned char **rgba, int *w, int *h, gr_err *e);

#endif
