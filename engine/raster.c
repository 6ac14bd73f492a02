/* raster.c: layer pictures as PNG (libpng): scan vectors drawn as anti-aliased
 * lines coloured by laser and kind on white, with a scale bar, y up. */
#include "raster.h"
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

/* per laser: contour, hatch, edge (RGB) */
static const unsigned char PALETTE[4][3][3] = {
    {{31, 59, 153}, {217, 72, 15}, {43, 138, 62}},
    {{123, 44, 191}, {232, 163, 23}, {11, 114, 133}},
    {{194, 37, 92}, {92, 148, 13}, {73, 80, 87}},
    {{54, 79, 199}, {247, 103, 7}, {8, 127, 91}}};

typedef struct canvas { int w, h; unsigned char *rgb; } canvas;

/* Blend colour c with coverage a (0..1) into pixel (x, y). */
static void plot(canvas *cv, int x, int y, const unsigned char *c, double a) {
  if (x < 0 || y < 0 || x >= cv->w || y >= cv->h || a <= 0) return;
  if (a > 1) a = 1;
  unsigned char *p = cv->rgb + 3 * ((size_t)y * cv->w + x);
  for (int k = 0; k < 3; k++) p[k] = (unsigned char)(p[k] * (1 - a) + c[k] * a + 0.5);
}

/* A line of width wd pixels: coverage from the distance to the segment. */
static void line(canvas *cv, double x0, double y0, double x1, double y1, double wd, const unsigned char *c) {
  double r = 0.5 * wd;
  int xa = (int)floor(fmin(x0, x1) - r - 1), xb = (int)ceil(fmax(x0, x1) + r + 1);
  int ya = (int)floor(fmin(y0, y1) - r - 1), yb = (int)ceil(fmax(y0, y1) + r + 1);
  if (xa < 0) xa = 0;
  if (ya < 0) ya = 0;
  if (xb >= cv->w) xb = cv->w - 1;
  if (yb >= cv->h) yb = cv->h - 1;
  double dx = x1 - x0, dy = y1 - y0, l2 = dx * dx + dy * dy;
  for (int y = ya; y <= yb; y++)
    for (int x = xa; x <= xb; x++) {
      double px = x + 0.5 - x0, py = y + 0.5 - y0;
      double t = l2 > 0 ? (px * dx + py * dy) / l2 : 0;
      t = t < 0 ? 0 : (t > 1 ? 1 : t);
      double ex = px - t * dx, ey = py - t * dy, d = sqrt(ex * ex + ey * ey);
      plot(cv, x, y, c, r + 0.5 - d);
    }
}

int gr_png_layer(const char *path, const gr_layer *l, const gr_png_opts *o, gr_err *e) {
  double lo[2], hi[2];
  gr_layer_bounds(l, lo, hi);
  if (!(hi[0] >= lo[0])) { lo[0] = lo[1] = 0; hi[0] = hi[1] = 1; }
  int W = o->width > 16 ? o->width : 800;
  double span = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), 1e-3), pad = 0.05 * span;
  lo[0] -= pad; lo[1] -= pad; hi[0] += pad; hi[1] += pad;
  double s = W / (hi[0] - lo[0]);
  int H = (int)ceil((hi[1] - lo[1]) * s - 1e-6);
  if ((double)W * H > 1e8) return gr_fail(e, GR_EARG, "picture of %d x %d pixels is too large", W, H);
  canvas cv = {W, H, malloc((size_t)W * H * 3)};
  if (!cv.rgb) return gr_fail(e, GR_EMEM, "out of memory for a %d x %d picture", W, H);
  memset(cv.rgb, 255, (size_t)W * H * 3);
  double wd = o->line_width > 0 ? o->line_width : 1.2;
  static const unsigned char grey[3] = {173, 181, 189}, black[3] = {0, 0, 0};
  double px = 0, py = 0;
  int have = 0;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    const double *p = l->xy + 2 * bk->start;
    const unsigned char *c = PALETTE[(bk->laser >= 0 ? bk->laser : 0) % 4][bk->kind >= 0 && bk->kind < 3 ? bk->kind : 2];
    size_t step = bk->shape == GR_SEGMENTS ? 2 : 1;
    for (size_t q = 0; q + 1 < bk->n; q += step) {
      double ax = (p[2 * q] - lo[0]) * s, ay = (hi[1] - p[2 * q + 1]) * s;
      double bx = (p[2 * q + 2] - lo[0]) * s, by = (hi[1] - p[2 * q + 3]) * s;
      if (o->jumps && have && (step == 2 || q == 0) && hypot(ax - px, ay - py) > 1) line(&cv, px, py, ax, ay, 0.6, grey);
      line(&cv, ax, ay, bx, by, bk->kind == GR_HATCH ? wd * 0.7 : wd, c);
      px = bx;
      py = by;
      have = 1;
    }
  }
  /* scale bar: a round length near a fifth of the width */
  double target = (hi[0] - lo[0]) / 5, bar = pow(10, floor(log10(target)));
  if (bar * 5 <= target) bar *= 5;
  else if (bar * 2 <= target) bar *= 2;
  for (int k = 0; k < 3; k++) line(&cv, 10, H - 10 - k, 10 + bar * s, H - 10 - k, 1, black);
  gr_atomic a;
  int rc = gr_atomic_open(&a, path, e);
  png_structp png = NULL;
  png_infop info = NULL;
  if (rc == GR_OK) {
    png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info || setjmp(png_jmpbuf(png))) {
      rc = gr_fail(e, GR_EIO, "cannot write PNG %s", path);
    } else {
      png_init_io(png, a.fp);
      png_set_IHDR(png, info, W, H, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                   PNG_FILTER_TYPE_DEFAULT);
      png_write_info(png, info);
      for (int y = 0; y < H; y++) png_write_row(png, cv.rgb + (size_t)y * W * 3);
      png_write_end(png, NULL);
    }
    png_destroy_write_struct(&png, &info);
    if (rc == GR_OK) rc = gr_atomic_commit(&a, e);
    else gr_atomic_abort(&a);
  }
  free(cv.rgb);
  if (rc == GR_OK) {
    /* the bar's length, for the caller's caption */
    (void)bar;
  }
  return rc;
}
