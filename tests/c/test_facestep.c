/* The voxel-owned section across faces (engine/facestep.c), analytic: each
 * voxel's "section" is a horizontal strip |y - 1| < w (closed along its
 * window, as a template's is); the centre voxel has w = 0.3, its right
 * neighbour w = 0.1, every other neighbour w = 0.3 (or missing). The true
 * section steps at x = L: area, ring count, orientation, and the step's edges
 * lying on the face between the two half-widths. */
#include <math.h>
#include <stdlib.h>
#include "facestep.h"
#include "check.h"

#define L 2.0
#define M 0.175
static const double LL[2] = {L, L};

/* A strip |y - 1| < w over the window [-M, L + M]^2, voxel-local, CCW. */
static gr_rings *strip(double w) {
  gr_rings *r = gr_rings_new();
  double p[8] = {-M, 1 - w, L + M, 1 - w, L + M, 1 + w, -M, 1 + w};
  gr_rings_add(r, p, 4);
  return r;
}

/* Total length of the section's edges lying on x = L (within 1e-12) and
 * whether each of them lies between y = 1 +- 0.1 and 1 +- 0.3. */
static double face_length(const gr_rings *s, int *outside) {
  double len = 0;
  *outside = 0;
  for (size_t i = 0; i < s->nrings; i++) {
    const double *p = gr_ring_xy(s, i);
    size_t n = gr_ring_len(s, i);
    for (size_t k = 0; k < n; k++) {
      const double *a = p + 2 * k, *b = p + 2 * ((k + 1) % n);
      if (fabs(a[0] - L) > 1e-12 || fabs(b[0] - L) > 1e-12) continue;
      len += fabs(b[1] - a[1]);
      double lo = fmin(a[1], b[1]), hi = fmax(a[1], b[1]);
      int in_upper = lo >= 1.1 - 1e-12 && hi <= 1.3 + 1e-12, in_lower = lo >= 0.7 - 1e-12 && hi <= 0.9 + 1e-12;
      if (!in_upper && !in_lower) *outside = 1;
    }
  }
  return len;
}

TEST(step_at_x_face) {
  gr_rings *wide = strip(0.3), *narrow = strip(0.1), *out = gr_rings_new();
  const gr_rings *nb[9] = {wide, wide, wide, wide, wide, narrow, wide, wide, wide};
  gr_err e = {0};
  CHECK(gr_fstep_section(LL, M, nb, out, &e) == GR_OK, "%s", e.msg);
  /* the window is drawn 1e-6 inside the templates' */
  double W = L + 2 * M - 2e-6, right = M - 1e-6;
  CHECK(out->nrings == 1, "one ring, got %zu", out->nrings);
  CHECK_NEAR(gr_rings_area(out), 0.6 * (W - right) + 0.2 * right, 1e-9);
  CHECK(gr_ring_area(out, 0) > 0, "counter-clockwise (solid on the left)");
  int outside;
  CHECK_NEAR(face_length(out, &outside), 0.4, 1e-9);
  CHECK(!outside, "the face edges are the step: between 1.1 and 1.3, 0.7 and 0.9");
  CHECK(gr_rings_contains(out, L - 0.01, 1.25) && !gr_rings_contains(out, L + 0.01, 1.25), "step at the face");
  gr_rings_free(wide);
  gr_rings_free(narrow);
  gr_rings_free(out);
}

TEST(equal_neighbours_and_missing_ones) {
  gr_rings *wide = strip(0.3), *out = gr_rings_new();
  const gr_rings *nb[9] = {NULL, wide, NULL, wide, wide, wide, NULL, NULL, NULL};
  gr_err e = {0};
  CHECK(gr_fstep_section(LL, M, nb, out, &e) == GR_OK, "%s", e.msg);
  int outside;
  CHECK(out->nrings == 1, "one ring, got %zu", out->nrings);
  CHECK_NEAR(gr_rings_area(out), 0.6 * (L + 2 * M - 2e-6), 1e-9);
  CHECK_NEAR(face_length(out, &outside), 0, 1e-12);
  gr_rings_free(wide);
  gr_rings_free(out);
}

int main(void) {
  RUN(step_at_x_face);
  RUN(equal_neighbours_and_missing_ones);
  DONE();
}
