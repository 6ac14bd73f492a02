/* libFuzzer harness: the mesh readers (engine/mesh.c): ASCII and binary STL,
 * ASCII and binary PLY, OBJ. The first byte picks the name the reader sees
 * (".obj" selects OBJ; PLY and STL are told apart by content); the rest is
 * the file. A mesh that reads is also checked for its topology. */
#include <stdint.h>
#include "mesh.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1 || size > (1 << 20)) return 0;
  static const char *const names[3] = {"fuzz.stl", "fuzz.obj", "fuzz.ply"};
  gr_err e;
  gr_mesh *m = gr_mesh_read_mem(names[data[0] % 3], data + 1, size - 1, &e);
  if (m) {
    gr_mesh_topo t;
    gr_mesh_topology(m, &t, &e);
  }
  gr_mesh_free(m);
  return 0;
}
