/* test_verify.c: pore / overmelt fractions and contour deviation against
 * analytic areas and distances. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "hatch.h"
#include "verify.h"

static const double PI = 3.14159265358979323846;

static void add_circle(gr_rings *r, double cx, double cy, double R, int n, int ccw) {
  for (int i = 0; i < n; i++) {
    double t = 2 * PI * i / n * (ccw ? 1 : -1);
    gr_rings_point(r, cx + R * cos(t), cy + R * sin(t));
  }
  gr_rings_close(r);
}

static gr_rings *rect(double x0, double y0, double x1, double y1) {
  gr_rings *r = gr_rings_new();
  double p[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
  gr_rings_add(r, p, 4);
  return r;
}

/* A disc hatched with one contour at b = d/2 and the hatch region at d:
 * melted everywhere, nothing outside (up to pixel effects). */
TEST(disc_properly_hatched) {
  gr_rings *r = gr_rings_new();
  add_circle(r, 0.011, 0.007, 1.0, 720, 1);
  for (int a = 0; a < 180; a += 45) {
    gr_layer *l = gr_layer_new(0);
    gr_hatch_opts o = gr_hatch_defaults();
    o.spacing = 0.1;
    o.angle = a;
    o.offset = gr_hatch_miter_offset; /* exact for the convex 720-gon */
    gr_err e;
    CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
    gr_verify_opts vo = gr_verify_defaults();
    vo.track = 0.1;
    gr_verify_result v;
    CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
    CHECK(v.pore < 0.005, "pore %g at %d deg", v.pore, a);
    CHECK(v.overmelt < 0.01, "overmelt %g", v.overmelt);
    CHECK_NEAR(v.solid_area, PI, 0.01 * PI);
    /* the contour's chords run parallel to the section's: points inside them too */
    CHECK(v.max_dev < 1e-6, "contour deviation %g", v.max_dev);
    CHECK(v.contour_points == 4 * 720, "%zu contour points (the vertices and 3 inside each chord)", v.contour_points);
    gr_layer_free(l);
  }
  gr_rings_free(r);
}

/* The same with the default offset (the distance-field gr_offset_rings
 * when linked) and with two contours: still dense, no overmelt. */
TEST(disc_default_offset) {
  gr_rings *r = gr_rings_new();
  add_circle(r, 0.011, 0.007, 1.0, 720, 1);
  add_circle(r, 0.2, 0.1, 0.3, 180, 0); /* a hole */
  double area = PI * (1 - 0.09);
  for (int nc = 1; nc <= 2; nc++) {
    gr_layer *l = gr_layer_new(0);
    gr_hatch_opts o = gr_hatch_defaults();
    o.spacing = 0.1;
    o.angle = 67;
    o.contours = nc;
    gr_err e;
    CHECK(gr_hatch_layer(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
    gr_verify_opts vo = gr_verify_defaults();
    vo.track = 0.1;
    vo.contours = nc;
    gr_verify_result v;
    CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
    CHECK(v.pore < 0.005, "pore %g with %d contours", v.pore, nc);
    CHECK(v.overmelt < 0.01, "overmelt %g", v.overmelt);
    CHECK_NEAR(v.solid_area, area, 0.01 * area);
    CHECK(v.max_dev < 0.01, "contour deviation %g", v.max_dev); /* within a tenth of d */
    gr_layer_free(l);
  }
  gr_rings_free(r);
}

/* Spacing 3d with track d melts a third of the area: pore ~ 2/3. */
TEST(under_hatched_shows_pores) {
  gr_rings *r = rect(0.013, 0.027, 3.013, 3.027);
  gr_layer *l = gr_layer_new(0);
  gr_hatch_opts o = gr_hatch_defaults();
  o.spacing = 0.3;
  o.angle = 0;
  gr_err e;
  CHECK(gr_hatch_region(r, &o, l, NULL, &e) == GR_OK, "%s", e.msg);
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = 0.1;
  gr_verify_result v;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
  /* 10 lines of 3 mm x 0.1 inside a 9 mm^2 square, caps half outside */
  CHECK_NEAR(v.pore, 2.0 / 3.0, 0.02);
  CHECK_NEAR(v.solid_area, 9.0, 0.05);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* One vector outside a unit square: a capsule of area 1*0.1 + pi*0.05^2
 * melted outside, the whole square a pore. */
TEST(vector_outside_overmelts) {
  gr_rings *r = rect(0, 0, 1, 1);
  gr_layer *l = gr_layer_new(0);
  gr_layer_add_segment(l, GR_HATCH, 0, 3, 0.5, 4, 0.5);
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = 0.1;
  vo.pixel = 0.005;
  gr_verify_result v;
  gr_err e;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(v.overmelt, 0.1 + PI * 0.0025, 0.003);
  CHECK_NEAR(v.pore, 1.0, 1e-12);
  CHECK_NEAR(v.melt_area, 0.1 + PI * 0.0025, 0.003);
  /* a diagonal capsule inside: melted area 0.1 * sqrt(2) + caps */
  gr_layer_clear(l, 0);
  gr_layer_add_segment(l, GR_HATCH, 0, 0.2, 0.2, 0.8, 0.8);
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(1 - v.pore, 0.1 * 0.6 * sqrt(2) + PI * 0.0025, 0.003);
  CHECK_NEAR(v.overmelt, 0, 1e-12);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* An exact circle contour at radius R - b deviates ~0; at R - b - 0.01 it
 * deviates by 0.01. */
TEST(contour_deviation) {
  gr_rings *r = gr_rings_new();
  add_circle(r, 0, 0, 1.0, 4000, 1);
  double b = 0.05;
  for (int shift = 0; shift < 2; shift++) {
    gr_layer *l = gr_layer_new(0);
    int n = 500;
    double *p = malloc((n + 1) * 2 * sizeof *p), R = 1 - b - 0.01 * shift;
    for (int i = 0; i <= n; i++) {
      p[2 * i] = R * cos(2 * PI * (i % n) / n);
      p[2 * i + 1] = R * sin(2 * PI * (i % n) / n);
    }
    gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, p, n + 1);
    gr_verify_opts vo = gr_verify_defaults();
    vo.track = 0.1;
    gr_verify_result v;
    gr_err e;
    CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
    /* the vertices and three points inside every chord: a point at fraction
     * f of a chord of the n-gon lies at radius R sqrt(1 - 4 f (1 - f)
     * sin^2(pi/n)), inside the contour's circle (up to 19 nm here at the
     * middle); the boundary's own 4000-gon sagitta 1 - cos(pi/4000) ~ 3e-7 */
    CHECK(v.contour_points == (size_t)(4 * n), "%zu points", v.contour_points);
    double mx = 0, sum = 0, s2 = sin(PI / n) * sin(PI / n);
    for (int k = 0; k < 4; k++) {
      double f = k / 4.0, dev = fabs(1 - R * sqrt(1 - 4 * f * (1 - f) * s2) - b);
      mx = fmax(mx, dev);
      sum += dev / 4;
    }
    CHECK(mx > 0.01 * shift + 1.5e-5, "the chords' middles are measured: %g", mx);
    CHECK_NEAR(v.max_dev, mx, 1e-6);
    CHECK_NEAR(v.mean_dev, sum, 1e-6);
    free(p);
    gr_layer_free(l);
  }
  gr_rings_free(r);
}

TEST(bad_input) {
  gr_rings *r = rect(0, 0, 1, 1);
  gr_layer *l = gr_layer_new(0);
  gr_verify_opts vo = gr_verify_defaults();
  gr_verify_result v;
  gr_err e;
  vo.track = -1;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_EARG && strstr(e.msg, "track") && strstr(e.msg, "-1"), "%s", e.msg);
  vo = gr_verify_defaults();
  vo.pixel = 0;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_EARG && strstr(e.msg, "pixel"), "%s", e.msg);
  vo = gr_verify_defaults();
  vo.pixel = 1e-7;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_EARG && strstr(e.msg, "pixels"), "%s", e.msg);
  gr_layer_free(l);
  gr_rings_free(r);
}

/* Hatch length outside the section, exact: a unit square with a round hole
 * of radius 0.2 at its centre; vectors across it, one along y through the
 * hole, a zigzag polyline leaving and re-entering; with a clip box only the
 * part inside it counts. */
TEST(hatch_outside_exact) {
  gr_rings *r = rect(0, 0, 1, 1);
  add_circle(r, 0.5, 0.5, 0.2, 4000, 0);
  double chord = 0.4; /* the 4000-gon has a vertex on each axis: its chord along x = 0.5 is 0.4 */
  gr_layer *l = gr_layer_new(0);
  gr_layer_add_segment(l, GR_HATCH, 0, -0.5, 0.1, 1.5, 0.1); /* 2 long, 1 outside */
  gr_layer_add_segment(l, GR_HATCH, 0, 0.5, 0.05, 0.5, 0.95); /* 0.9 long, the hole's chord outside */
  gr_layer_add_segment(l, GR_HATCH, 0, 0.05, 0.9, 0.95, 0.9); /* inside */
  double zig[8] = {0.1, 0.2, 0.1, -0.3, 0.2, -0.3, 0.2, 0.2}; /* 0.5 + 0.1 + 0.5: 0.3 + 0.1 + 0.3 out */
  gr_layer_add(l, GR_OPEN, GR_HATCH, 0, 2, zig, 4);
  double ctr[10] = {-1, -1, 2, -1, 2, 2, -1, 2, -1, -1}; /* a contour: not hatch, not counted */
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, ctr, 5);
  gr_verify_opts vo = gr_verify_defaults();
  vo.track = 0.05;
  gr_verify_result v;
  gr_err e;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(v.hatch_length, 2 + 0.9 + 0.9 + 1.1, 1e-12);
  CHECK_NEAR(v.hatch_outside, 1 + chord + 0.7, 1e-9);
  vo.clip = 1; /* x in [0, 0.5], y in [0, 1] */
  vo.clip_lo[0] = vo.clip_lo[1] = 0;
  vo.clip_hi[0] = 0.5;
  vo.clip_hi[1] = 1;
  CHECK(gr_verify_layer(r, l, &vo, &v, &e) == GR_OK, "%s", e.msg);
  /* 0.5 + 0.9 (the vertical one lies on the clip border) + 0.45 + the
   * zigzag's legs above y = 0 (0.2 + 0.2; its bottom leg is outside the box) */
  CHECK_NEAR(v.hatch_length, 0.5 + 0.9 + 0.45 + 0.4, 1e-12);
  CHECK_NEAR(v.hatch_outside, chord, 1e-9);
  gr_layer_free(l);
  gr_rings_free(r);
}

int main(void) {
  RUN(disc_properly_hatched);
  RUN(disc_default_offset);
  RUN(under_hatched_shows_pores);
  RUN(vector_outside_overmelts);
  RUN(contour_deviation);
  RUN(bad_input);
  RUN(hatch_outside_exact);
  DONE();
}
