/* Regressions for inputs that crashed or hit undefined behaviour (issue 17):
 * each case once crashed, overflowed or allocated without bound; each must
 * now give a clear error (or the correct result). Run plain and under
 * ASan+UBSan like every C test; the fuzzing harnesses (tests/fuzz/) replay
 * the same inputs under clang's sanitizers. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "cli.h"
#include "expr.h"
#include "mesh.h"
#include "place.h"

static int count_layer(void *ud, const gr_layer *l, gr_err *e) {
  (void)e;
  long *n = ud;
  n[0]++;
  n[1] += (long)l->nb;
  return GR_OK;
}

/* write `text` to a fresh temporary file; returns its path (static buffer) */
static const char *temp_file(const char *text, size_t n) {
  static char path[64];
  strcpy(path, "/tmp/gradus_robust_XXXXXX");
  int fd = mkstemp(path);
  if (fd < 0) return NULL;
  ssize_t w = write(fd, text, n);
  close(fd);
  return w == (ssize_t)n ? path : NULL;
}

static int read_cli_text(const char *text, long counts[2], gr_err *e) {
  const char *p = temp_file(text, strlen(text));
  if (!p) return -1;
  gr_cli_header h;
  counts[0] = counts[1] = 0;
  gr_err_clear(e);
  int rc = gr_cli_read(p, &h, count_layer, counts, e);
  unlink(p);
  return rc;
}

#define CLI_HEAD "$$HEADERSTART\n$$ASCII\n$$UNITS/1\n$$HEADEREND\n$$GEOMETRYSTART\n$$LAYER/0.03\n"

/* `$$POLYLINE/1,0,0` passed NULL to memcpy: an empty polyline is skipped */
TEST(cli_empty_polyline) {
  long c[2];
  gr_err e;
  int rc = read_cli_text(CLI_HEAD "$$POLYLINE/1,0,0\n$$HATCHES/1,0\n$$POLYLINE/1,0,2,0,0,1,1\n$$GEOMETRYEND\n", c, &e);
  CHECK(rc == GR_OK, "%s", e.msg);
  CHECK(c[0] == 1 && c[1] == 1, "layers %ld blocks %ld (want 1 and 1: the empty ones skipped)", c[0], c[1]);
}

/* a count of 10^9 points allocated 16 GB before reading one: refused by the
 * line's length first */
TEST(cli_huge_count) {
  long c[2];
  gr_err e;
  int rc = read_cli_text(CLI_HEAD "$$POLYLINE/1,0,1000000000,0,0,1,1\n$$GEOMETRYEND\n", c, &e);
  CHECK(rc == GR_EPARSE, "rc %d", rc);
  CHECK(strstr(e.msg, ":7: count 1000000000 exceeds") != NULL, "message '%s'", e.msg);
  rc = read_cli_text(CLI_HEAD "$$HATCHES/1,9223372036854775807,0,0,1,1\n$$GEOMETRYEND\n", c, &e);
  CHECK(rc == GR_EPARSE && strstr(e.msg, "exceeds"), "hatches: rc %d '%s'", rc, e.msg);
}

/* binary: the most negative id (id - 1 overflowed) reads as an edge block */
TEST(cli_binary_min_id) {
  unsigned char f[128];
  const char *hd = "$$HEADERSTART\n$$BINARY\n$$UNITS/1\n$$HEADEREND";
  size_t n = strlen(hd);
  memcpy(f, hd, n);
  unsigned char body[] = {127, 0, 0, 0, 0, 0,                   /* layer z = 0 */
                          130, 0, 0, 0, 0, 0x80, 0, 0, 0, 0,    /* polyline id INT_MIN, dir 0 */
                          1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}; /* 1 point (0, 0) */
  memcpy(f + n, body, sizeof body);
  const char *p = temp_file((const char *)f, n + sizeof body);
  CHECK(p != NULL, "temporary file");
  if (!p) return;
  long c[2] = {0, 0};
  gr_cli_header h;
  gr_err e;
  gr_err_clear(&e);
  int rc = gr_cli_read(p, &h, count_layer, c, &e);
  unlink(p);
  CHECK(rc == GR_OK && c[1] == 1, "rc %d blocks %ld: %s", rc, c[1], e.msg);
}

/* PLY element count 1e20 was cast to long (undefined): refused against the
 * file's size */
TEST(ply_huge_count) {
  const char *s = "ply\nformat ascii 1.0\nelement vertex 1e20\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
  gr_err e;
  gr_mesh *m = gr_mesh_read_mem("huge.ply", s, strlen(s), &e);
  CHECK(m == NULL, "accepted");
  CHECK(strstr(e.msg, "huge.ply:3: element count 100000000000000000000 exceeds") != NULL, "message '%s'", e.msg);
  gr_mesh_free(m);
  const char *f = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                  "1e30 0 1 2\n";
  m = gr_mesh_read_mem("face.ply", f, strlen(f), &e);
  CHECK(m == NULL && strstr(e.msg, "bad face vertex count"), "face count 1e30: '%s'", e.msg);
  gr_mesh_free(m);
}

/* the memory reader and the file reader agree (one triangle) */
TEST(mesh_mem_reader) {
  const char *s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  gr_err e;
  gr_mesh *m = gr_mesh_read_mem("t.obj", s, strlen(s), &e);
  CHECK(m && m->nv == 3 && m->nf == 1, "%s", m ? "wrong counts" : e.msg);
  gr_mesh_free(m);
}

/* the evaluator formed pointers before its stack on every evaluation; the
 * result of a deep expression is still exact */
TEST(expr_stack) {
  const char *v[] = {"x"};
  gr_err e;
  gr_expr *x = gr_expr_compile("-(x + 1) * (2 - sin(0)) + max(x, 3) / 3", 1, v, 0, NULL, NULL, &e);
  CHECK(x != NULL, "%s", e.msg);
  if (!x) return;
  double xs[300], out[300];
  for (int i = 0; i < 300; i++) xs[i] = i;
  const double *vars[] = {xs};
  CHECK(gr_expr_eval(x, 300, vars, out, &e) == GR_OK, "%s", e.msg);
  CHECK_NEAR(out[0], -2 + 1, 0);
  CHECK_NEAR(out[299], -600 + 299.0 / 3, 1e-12);
  gr_expr_free(x);
}

TEST(job_too_many_voxels) {
  /* 100000 x 100000 x 1 cells: the voxel count (1e10) overflowed an int
   * before the arrays were sized; 1000^3 (10^3 meant) allocated for
   * minutes. Both are refused at once; 1e8 voxels is the bound. */
  gr_job_opts o = gr_job_defaults();
  const int n[3][3] = {{100000, 100000, 1}, {1000, 1000, 1000}, {1000, 1000, 101}};
  for (int c = 0; c < 3; c++) {
    memcpy(o.n, n[c], sizeof o.n);
    gr_err e;
    gr_err_clear(&e);
    gr_job *j = gr_job_new(&o, &e);
    CHECK(!j && e.code == GR_EARG && strstr(e.msg, "more than a job holds"), "case %d: %s", c, e.msg);
    gr_job_free(j);
  }
  /* 1000 cells of 1000 mm in layers of 1e-4 mm: 1e10 layers, more than an int counts */
  o.n[0] = o.n[1] = 1;
  o.n[2] = 1000;
  o.cell[0] = o.cell[1] = o.cell[2] = 1000;
  o.layer = 1e-4;
  o.hatch = 1;
  gr_err e2;
  gr_err_clear(&e2);
  gr_job *j = gr_job_new(&o, &e2);
  CHECK(!j && e2.code == GR_EARG && strstr(e2.msg, "layers, more than a job holds"), "layers: %s", e2.msg);
  gr_job_free(j);
  o = gr_job_defaults();
  int ok[3] = {1000, 1000, 100};
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_job_check_size(ok, o.cell, &e) == GR_OK, "1e8 voxels are allowed: %s", e.msg);
}

int main(void) {
  RUN(cli_empty_polyline);
  RUN(cli_huge_count);
  RUN(cli_binary_min_id);
  RUN(ply_huge_count);
  RUN(mesh_mem_reader);
  RUN(expr_stack);
  RUN(job_too_many_voxels);
  DONE();
}
