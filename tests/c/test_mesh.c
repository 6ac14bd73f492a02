/* test_mesh.c: mesh measures, topology and file round trips on a unit
 * tetrahedron-free analytic shape: the unit cube (area 6, volume 1). */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "mesh.h"

static gr_mesh *cube(void) {
  gr_mesh *m = gr_mesh_new();
  for (int c = 0; c < 8; c++) gr_mesh_add_vertex(m, c & 1, c >> 1 & 1, c >> 2 & 1);
  static const int F[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                              {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (int f = 0; f < 6; f++) { /* corners CCW seen from outside */
    gr_mesh_add_face(m, F[f][0], F[f][1], F[f][2]);
    gr_mesh_add_face(m, F[f][0], F[f][2], F[f][3]);
  }
  return m;
}

TEST(measures) {
  gr_mesh *m = cube();
  gr_err e;
  gr_mesh_topo t;
  CHECK_NEAR(gr_mesh_area(m), 6, 1e-12);
  CHECK_NEAR(gr_mesh_volume(m), 1, 1e-12);
  gr_mesh_topology(m, &t, &e);
  CHECK(t.edges == 18 && t.boundary_edges == 0 && t.euler == 2 && t.misoriented_edges == 0,
        "edges %zu euler %ld", t.edges, t.euler);
  m->f[0] ^= 0; uint32_t tmp = m->f[1]; m->f[1] = m->f[2]; m->f[2] = tmp; /* flip one */
  gr_mesh_topology(m, &t, &e);
  CHECK(t.misoriented_edges == 3, "misoriented %zu", t.misoriented_edges);
  gr_mesh_free(m);
}

TEST(round_trips) {
  const char *fmt[4] = {"stl", "stl_ascii", "ply", "obj"};
  const char *path[4] = {"/tmp/gr_tm.stl", "/tmp/gr_tm_a.stl", "/tmp/gr_tm.ply", "/tmp/gr_tm.obj"};
  gr_mesh *m = cube();
  for (int i = 0; i < 4; i++) {
    gr_err e;
    CHECK(gr_mesh_write(m, path[i], fmt[i], &e) == GR_OK, "%s", e.msg);
    gr_mesh *r = gr_mesh_read(path[i], &e);
    CHECK(r != NULL, "%s: %s", fmt[i], e.msg);
    if (!r) continue;
    CHECK(r->nv == 8 && r->nf == 12, "%s: %zu %zu", fmt[i], r->nv, r->nf);
    CHECK_NEAR(gr_mesh_volume(r), 1, 1e-6);
    gr_mesh_free(r);
    unlink(path[i]);
  }
  gr_err e;
  CHECK(gr_mesh_write(m, "/nonexistent_dir/x.stl", NULL, &e) == GR_EIO, "code %d", e.code);
  CHECK(access("/nonexistent_dir/x.stl", F_OK) != 0, "file left");
  gr_mesh_write(m, "/tmp/gr_tr.stl", "stl", &e);
  CHECK(truncate("/tmp/gr_tr.stl", 84 + 50 * 5) == 0, "truncate");
  gr_mesh *r = gr_mesh_read("/tmp/gr_tr.stl", &e);
  CHECK(r == NULL && e.code == GR_EPARSE && strstr(e.msg, "gr_tr.stl"), "%s", e.msg);
  unlink("/tmp/gr_tr.stl");
  gr_mesh_free(m);
}
int main(void) {
  RUN(measures);
  RUN(round_trips);
  DONE();
}
