/* PNG layer pictures decode (libpng) to the requested size, with ink where
 * the vectors are and white elsewhere. */
#include <png.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "raster.h"

static unsigned char *decode(const char *path, int *w, int *h) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  png_structp p = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png_create_info_struct(p);
  unsigned char *img = NULL;
  if (setjmp(png_jmpbuf(p))) { fclose(f); png_destroy_read_struct(&p, &info, NULL); free(img); return NULL; }
  png_init_io(p, f);
  png_read_info(p, info);
  *w = (int)png_get_image_width(p, info);
  *h = (int)png_get_image_height(p, info);
  if (png_get_color_type(p, info) != PNG_COLOR_TYPE_RGB) { fclose(f); png_destroy_read_struct(&p, &info, NULL); return NULL; }
  img = malloc((size_t)*w * *h * 3);
  for (int y = 0; y < *h; y++) png_read_row(p, img + (size_t)y * *w * 3, NULL);
  png_destroy_read_struct(&p, &info, NULL);
  fclose(f);
  return img;
}

TEST(picture_has_vectors_where_they_are) {
  gr_layer *l = gr_layer_new(0.04);
  /* a square contour 0..10 mm and one hatch along y = 5 */
  double sq[] = {0, 0, 10, 0, 10, 10, 0, 10, 0, 0};
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, sq, 5);
  gr_layer_add_segment(l, GR_HATCH, 0, 1, 5, 9, 5);
  char path[] = "/tmp/gradus_test_rasterXXXXXX";
  int fd = mkstemp(path);
  close(fd);
  gr_png_opts o = {400, 2.0, 0};
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_png_layer(path, l, &o, &e) == GR_OK, "%s", e.msg);
  int w = 0, h = 0;
  unsigned char *img = decode(path, &w, &h);
  CHECK(img != NULL, "PNG decodes");
  if (img) {
    CHECK(w == 400, "width %d", w);
    CHECK(h == 400, "height %d (square layer)", h);
    /* mapping: 5 % padding of the 10 mm span on each side: x_px = (x + 0.5) * 400 / 11 */
    double s = 400.0 / 11.0;
    int hx = (int)((5 + 0.5) * s), hy = (int)((10.5 - 5) * s); /* on the hatch */
    int ex = (int)((2.5 + 0.5) * s), ey = (int)((10.5 - 7.5) * s); /* empty inside */
    const unsigned char *on = img + 3 * ((size_t)hy * w + hx), *off = img + 3 * ((size_t)ey * w + ex);
    CHECK(!(on[0] == 255 && on[1] == 255 && on[2] == 255), "ink on the hatch at (%d,%d)", hx, hy);
    CHECK(off[0] == 255 && off[1] == 255 && off[2] == 255, "white inside at (%d,%d)", ex, ey);
    int cx = (int)((0 + 0.5) * s), cy = (int)((10.5 - 5) * s); /* on the left contour edge */
    const unsigned char *c = img + 3 * ((size_t)cy * w + cx);
    CHECK(!(c[0] == 255 && c[1] == 255 && c[2] == 255), "ink on the contour");
  }
  free(img);
  remove(path);
  /* an unwritable path fails and leaves nothing */
  CHECK(gr_png_layer("/nonexistent_dir/x.png", l, &o, &e) == GR_EIO, "unwritable path");
  gr_layer_free(l);
}

int main(void) {
  RUN(picture_has_vectors_where_they_are);
  DONE();
}
