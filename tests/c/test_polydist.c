/* gr_polydist_within (issue 14): the yes/no query "is the boundary within r"
 * agrees with |gr_polydist_at| <= r everywhere, and with the analytic
 * distance to a unit square and to a square with a square hole. */
#include "check.h"
#include "slice.h"

static gr_rings *squares(int hole) {
  gr_rings *r = gr_rings_new();
  double outer[] = {0, 0, 1, 0, 1, 1, 0, 1}, inner[] = {0.3, 0.3, 0.3, 0.7, 0.7, 0.7, 0.7, 0.3};
  for (int k = 0; k < 4; k++) gr_rings_point(r, outer[2 * k], outer[2 * k + 1]);
  gr_rings_close(r);
  if (hole) {
    for (int k = 0; k < 4; k++) gr_rings_point(r, inner[2 * k], inner[2 * k + 1]);
    gr_rings_close(r);
  }
  gr_err e;
  gr_err_clear(&e);
  gr_rings_nest(r, &e);
  return r;
}

TEST(within_matches_the_distance) {
  for (int hole = 0; hole < 2; hole++) {
    gr_rings *r = squares(hole);
    gr_err e;
    gr_err_clear(&e);
    gr_polydist *pd = gr_polydist_new(r, 0.05, &e);
    CHECK(pd != NULL, "%s", e.msg);
    int bad = 0, n = 0;
    const double radii[] = {0, 0.01, 0.05, 0.13, 0.4, 2};
    for (int i = 0; i <= 60 && pd; i++)
      for (int j = 0; j <= 60; j++)
        for (int k = 0; k < 6; k++) {
          double x = -0.7 + i * 0.04, y = -0.7 + j * 0.04, rr = radii[k];
          int want = fabs(gr_polydist_at(pd, x, y, NULL)) <= rr;
          bad += gr_polydist_within(pd, x, y, rr) != want;
          n++;
        }
    CHECK(bad == 0, "hole %d: %d of %d queries disagree with |distance| <= r", hole, bad, n);
    gr_polydist_free(pd);
    gr_rings_free(r);
  }
}

TEST(within_analytic) {
  gr_rings *r = squares(1);
  gr_err e;
  gr_err_clear(&e);
  gr_polydist *pd = gr_polydist_new(r, 0.05, &e);
  CHECK(pd != NULL, "%s", e.msg);
  if (pd) {
    /* (0.15, 0.5): 0.15 from the outer square, 0.15 from the hole */
    CHECK(!gr_polydist_within(pd, 0.15, 0.5, 0.149), "0.15 from both boundaries");
    CHECK(gr_polydist_within(pd, 0.15, 0.5, 0.151), "0.15 from both boundaries");
    /* (0.5, 0.5): the hole's centre, 0.2 from its sides */
    CHECK(!gr_polydist_within(pd, 0.5, 0.5, 0.199), "0.2 from the hole");
    CHECK(gr_polydist_within(pd, 0.5, 0.5, 0.201), "0.2 from the hole");
    /* (3, 0.5): 2 to the right of the square, far outside the buckets */
    CHECK(!gr_polydist_within(pd, 3, 0.5, 1.99), "2 outside");
    CHECK(gr_polydist_within(pd, 3, 0.5, 2.01), "2 outside");
    CHECK(!gr_polydist_within(pd, 3, 0.5, NAN), "NaN radius: no");
  }
  gr_polydist_free(pd);
  gr_rings_free(r);
}

int main(void) {
  RUN(within_matches_the_distance);
  RUN(within_analytic);
  DONE();
}
