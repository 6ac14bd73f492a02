/* gr_plate: parts placed on a plate (rotation about z about the centre of
 * their extent, then translation) and merged by z. Square contours of known
 * corners are checked analytically after a 90 degree turn; two parts of
 * different heights give the tallest part's layer count and $$DIMENSION; a
 * part of another layer thickness is refused and nothing is written. */
#define _GNU_SOURCE
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "cli.h"
#include "plate.h"

static char dir[] = "/tmp/gradus_test_plateXXXXXX";

/* A part of `layers` layers of thickness t: each a closed square contour
 * [0, w] x [0, h] (laser `laser`) and one hatch from (0, 0) to (w, h). */
static const char *part(const char *name, int layers, double t, double w, double h, int laser) {
  static char paths[8][256];
  static int np;
  char *path = paths[np++ % 8];
  snprintf(path, 256, "%s/%s", dir, name);
  gr_cli_header hd = gr_cli_header_defaults();
  hd.layers = layers;
  hd.hi[0] = w;
  hd.hi[1] = h;
  hd.hi[2] = layers * t;
  hd.nlasers = laser + 1;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *wr = gr_cli_open(path, &hd, &e);
  CHECK(wr != NULL, "%s", e.msg);
  gr_layer *l = gr_layer_new(0);
  for (int g = 1; g <= layers && wr; g++) {
    gr_layer_clear(l, g * t);
    double sq[10] = {0, 0, w, 0, w, h, 0, h, 0, 0};
    gr_layer_add(l, GR_CLOSED, GR_CONTOUR, laser, 1, sq, 5);
    gr_layer_add_segment(l, GR_HATCH, laser, 0, 0, w, h);
    CHECK(gr_cli_write_layer(wr, l, &e) == GR_OK, "%s", e.msg);
  }
  gr_layer_free(l);
  if (wr) CHECK(gr_cli_close(wr, 1, &e) == GR_OK, "%s", e.msg);
  return path;
}

typedef struct { gr_layer *l[16]; int n; gr_cli_header h; } got_t;
static int keep(void *ud, const gr_layer *l, gr_err *e) {
  (void)e;
  got_t *g = ud;
  if (g->n < 16) {
    g->l[g->n] = gr_layer_new(l->z);
    gr_layer_append(g->l[g->n++], l, 0, 0);
  }
  return GR_OK;
}
static void got_free(got_t *g) {
  for (int i = 0; i < g->n; i++) gr_layer_free(g->l[i]);
}

TEST(turned_square_corners) {
  /* a 4 x 2 square, centre (2, 1), turned 90 degrees and put at (50, 60):
   * (x, y) -> (50 - (y - 1), 60 + (x - 2)) */
  const char *a = part("a.cli", 2, 0.05, 4, 2, 0);
  gr_plate *p = gr_plate_new();
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_plate_add(p, a, "a", 50, 60, 90, &e) == GR_OK, "%s", e.msg);
  size_t n;
  const double *hull = gr_plate_hull(p, 0, &n);
  CHECK(n == 4, "hull of a rectangle: 4 corners, got %zu", n);
  double lo[2] = {1e9, 1e9}, hi[2] = {-1e9, -1e9};
  for (size_t k = 0; k < n; k++)
    for (int d = 0; d < 2; d++) lo[d] = fmin(lo[d], hull[2 * k + d]), hi[d] = fmax(hi[d], hull[2 * k + d]);
  CHECK_NEAR(lo[0], 49, 1e-6);
  CHECK_NEAR(hi[0], 51, 1e-6);
  CHECK_NEAR(lo[1], 58, 1e-6);
  CHECK_NEAR(hi[1], 62, 1e-6);
  char out[300];
  snprintf(out, sizeof out, "%s/turned.cli", dir);
  gr_plate_opts o = {.layer_mm = 0.05, .units = 0.001, .nlasers = 1};
  gr_plate_info in;
  CHECK(gr_plate_write(p, out, &o, &in, &e) == GR_OK, "%s", e.msg);
  CHECK(in.layers == 2, "layers %d", in.layers);
  got_t g = {0};
  CHECK(gr_cli_read(out, &g.h, keep, &g, &e) == GR_OK, "%s", e.msg);
  CHECK(g.n == 2, "layers read %d", g.n);
  if (g.n >= 1 && g.l[0]->nb == 2) {
    const double want[10] = {51, 58, 51, 62, 49, 62, 49, 58, 51, 58}; /* (0,0) (4,0) (4,2) (0,2) (0,0) */
    const double *xy = g.l[0]->xy + 2 * g.l[0]->b[0].start;
    CHECK(g.l[0]->b[0].n == 5, "contour points %zu", g.l[0]->b[0].n);
    for (int k = 0; k < 10; k++) CHECK_NEAR(xy[k], want[k], 1e-6);
    const double *hx = g.l[0]->xy + 2 * g.l[0]->b[1].start; /* hatch (0,0)-(4,2) -> (51,58)-(49,62) */
    CHECK_NEAR(hx[0], 51, 1e-6);
    CHECK_NEAR(hx[1], 58, 1e-6);
    CHECK_NEAR(hx[2], 49, 1e-6);
    CHECK_NEAR(hx[3], 62, 1e-6);
  } else {
    CHECK(0, "layer 1 should hold 2 blocks");
  }
  CHECK_NEAR(g.h.lo[0], 49, 1e-6);
  CHECK_NEAR(g.h.hi[1], 62, 1e-6);
  got_free(&g);
  gr_plate_free(p);
}

TEST(heights_merged_by_z) {
  const char *lo = part("low.cli", 2, 0.05, 2, 2, 0), *hi = part("high.cli", 5, 0.05, 2, 2, 0);
  gr_plate *p = gr_plate_new();
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_plate_add(p, lo, "low", 10, 10, 0, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_plate_add(p, hi, "high", 20, 10, 30, &e) == GR_OK, "%s", e.msg);
  CHECK(!gr_plate_overlap(p, 0, 1, 1e-6), "apart");
  int map[1] = {1};
  CHECK(gr_plate_map_lasers(p, 1, map, 1, &e) == GR_OK, "%s", e.msg);
  char out[300];
  snprintf(out, sizeof out, "%s/heights.cli", dir);
  gr_plate_opts o = {.layer_mm = 0.05, .units = 0.001, .nlasers = 2, .keep = 2};
  gr_plate_info in;
  CHECK(gr_plate_write(p, out, &o, &in, &e) == GR_OK, "%s", e.msg);
  CHECK(in.layers == 5, "the tallest part's 5 layers, got %d", in.layers);
  CHECK_NEAR(in.hi[2], 0.25, 1e-9);
  CHECK(in.kept && in.kept->nb == 4, "layer 2 holds both parts' 2 blocks");
  if (in.kept) CHECK(in.kept->b[0].laser == 0 && in.kept->b[2].laser == 1, "the second part mapped to laser 2");
  gr_layer_free(in.kept);
  got_t g = {0};
  CHECK(gr_cli_read(out, &g.h, keep, &g, &e) == GR_OK, "%s", e.msg);
  CHECK(g.n == 5 && g.h.layers == 5, "layers %d, header %d", g.n, g.h.layers);
  if (g.n == 5) {
    CHECK(g.l[1]->nb == 4 && g.l[2]->nb == 2, "layer 2: both parts, layer 3: the tall one (%zu, %zu)", g.l[1]->nb,
          g.l[2]->nb);
    CHECK_NEAR(g.l[4]->z, 0.25, 1e-6);
  }
  CHECK_NEAR(g.h.lo[2], 0, 1e-9);
  CHECK_NEAR(g.h.hi[2], 0.25, 1e-6);
  got_free(&g);
  gr_plate_free(p);
}

TEST(refused_and_nothing_written) {
  const char *a = part("t05.cli", 2, 0.05, 2, 2, 0), *b = part("t03.cli", 3, 0.03, 2, 2, 0);
  gr_plate *p = gr_plate_new();
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_plate_add(p, a, "a", 10, 10, 0, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_plate_add(p, b, "thin", 30, 10, 0, &e) == GR_OK, "%s", e.msg);
  char out[300];
  snprintf(out, sizeof out, "%s/refused.cli", dir);
  gr_plate_opts o = {.layer_mm = 0.05, .units = 0.001, .nlasers = 1};
  gr_plate_info in;
  CHECK(gr_plate_write(p, out, &o, &in, &e) == GR_EARG, "another layer thickness refused");
  CHECK(strstr(e.msg, "part 'thin'") && strstr(e.msg, "off the plate's layer grid"), "%s", e.msg);
  CHECK(access(out, F_OK) != 0, "no output");
  CHECK(gr_plate_add(p, "/nonexistent/x.cli", "ghost", 0, 0, 0, &e) != GR_OK && strstr(e.msg, "ghost"), "%s", e.msg);
  CHECK(gr_plate_add(p, a, "nan", NAN, 0, 0, &e) == GR_ENUM, "%s", e.msg);
  CHECK(gr_plate_count(p) == 2, "failed adds leave the plate as it was");
  int bad[1] = {-1};
  CHECK(gr_plate_map_lasers(p, 0, bad, 1, &e) == GR_EARG, "laser 0 refused");
  gr_plate_free(p);
  gr_plate_free(NULL);
}

TEST(convex_overlap) {
  const double sq[8] = {0, 0, 4, 0, 4, 4, 0, 4}, right[8] = {4, 0, 8, 0, 8, 4, 4, 4};
  const double in[8] = {3, 3, 5, 3, 5, 5, 3, 5};
  double h = 2 * sqrt(2.0); /* a 4 x 4 square turned 45 degrees, centred (0,0) and (3,3) */
  const double d0[8] = {h, 0, 0, h, -h, 0, 0, -h}, d1[8] = {3 + h, 3, 3, 3 + h, 3 - h, 3, 3, 3 - h};
  CHECK(!gr_plate_poly_overlap(sq, 4, right, 4, 1e-9), "sharing an edge");
  CHECK(gr_plate_poly_overlap(sq, 4, in, 4, 1e-9), "overlapping corners");
  CHECK(!gr_plate_poly_overlap(d0, 4, d1, 4, 1e-9), "turned squares whose axis boxes overlap");
}

int main(void) {
  if (!mkdtemp(dir)) return 1;
  RUN(turned_square_corners);
  RUN(heights_merged_by_z);
  RUN(refused_and_nothing_written);
  RUN(convex_overlap);
  char cmd[300];
  snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
  if (system(cmd)) return 1;
  DONE();
}
