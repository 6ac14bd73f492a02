/* pngread.c: PNG input through libpng's simplified API, see pngread.h. */
#include "pngread.h"
#include <errno.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

int gr_pngread(const char *path, unsigned char **rgba, int *w, int *h, gr_err *e) {
  *rgba = NULL;
  FILE *f = fopen(path, "rb");
  if (!f) return gr_fail(e, GR_EIO, "cannot read %s: %s", path, strerror(errno));
  png_image im;
  memset(&im, 0, sizeof im);
  im.version = PNG_IMAGE_VERSION;
  int rc = GR_OK;
  if (!png_image_begin_read_from_stdio(&im, f)) {
    rc = gr_fail(e, GR_EPARSE, "%s: not a PNG picture (%s)", path, im.message);
  } else {
    im.format = PNG_FORMAT_RGBA;
    size_t n = PNG_IMAGE_SIZE(im);
    unsigned char *p = malloc(n ? n : 1);
    if (!p) {
      png_image_free(&im);
      rc = gr_fail(e, GR_EMEM, "out of memory for %s (%u x %u)", path, im.width, im.height);
    } else if (!png_image_finish_read(&im, NULL, p, 0, NULL)) {
      free(p);
      rc = gr_fail(e, GR_EPARSE, "%s: %s", path, im.message);
    } else {
      *rgba = p;
      *w = (int)im.width;
      *h = (int)im.height;
    }
  }
  fclose(f);
  return rc;
}
