/* bench_mc.c: marching cubes on one primitive cell (L = 2 mm) at 150
 * samples per axis, from the field (slab sampling, with refinement). */
#include <stdio.h>
#include "mc.h"

int main(void) {
  gr_err e;
  gr_field *f = gr_field_tpms("primitive", 2, NULL, 0, &e);
  if (!f) { fprintf(stderr, "%s\n", e.msg); return 1; }
  double lo[3] = {0, 0, 0}, hi[3] = {2, 2, 2};
  int n[3] = {150, 150, 150};
  for (int refine = 0; refine < 2; refine++) {
    double t0 = gr_now();
    gr_mesh *m = gr_mc_field(f, lo, hi, n, refine, &e);
    double dt = gr_now() - t0;
    if (!m) { fprintf(stderr, "%s\n", e.msg); return 1; }
    printf("mc primitive cell res 150 refine=%d: %.3f s, %zu triangles, %.3g triangles/s\n",
           refine, dt, m->nf, m->nf / dt);
    gr_mesh_free(m);
  }
  gr_field_free(f);
  return 0;
}
