/* CLI 2.0: ASCII and binary round trips within float32 / print precision,
 * closed polylines repeat their first point, header fields, and errors that
 * name the line or byte of malformed and truncated files. */
#include <stdlib.h>
#include <math.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "cli.h"

typedef struct got { gr_layer *l[8]; int n; } got;

static int keep(void *ud, const gr_layer *l, gr_err *e) {
  got *g = ud;
  (void)e;
  if (g->n < 8) {
    g->l[g->n] = gr_layer_new(l->z);
    gr_layer_append(g->l[g->n], l, 0, 0);
    g->n++;
  }
  return GR_OK;
}

/* read a whole file into g (fresh), the error into e */
static int read_all(const char *path, got *g, gr_cli_header *h, gr_err *e) {
  memset(g, 0, sizeof *g);
  gr_err_clear(e);
  return gr_cli_read(path, h, keep, g, e);
}

static gr_layer *sample_layer(double z) {
  gr_layer *l = gr_layer_new(z);
  double ring[] = {1.25, 1.5, 38.123456, 1.5, 38.123456, 39.987654, 1.25, 1.5};
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, ring, 4);
  double open[] = {0.5, 0.5, 0.75, 0.8, 1.0, 0.5};
  gr_layer_add(l, GR_OPEN, GR_CONTOUR, 1, 2, open, 3);
  gr_layer_add_segment(l, GR_HATCH, 1, 2, 2, 30, 2);
  gr_layer_add_segment(l, GR_HATCH, 1, 30, 2.05, 2, 2.05);
  return l;
}

static void roundtrip(int binary) {
  char path[] = "/tmp/gradus_test_cliXXXXXX";
  int fd = mkstemp(path);
  close(fd);
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = binary;
  h.layers = 2;
  h.nlasers = 2;
  h.hi[0] = h.hi[1] = 40;
  h.hi[2] = 0.08;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(path, &h, &e);
  CHECK(w != NULL, "%s", e.msg);
  gr_layer *a = sample_layer(0.04), *b = sample_layer(0.08);
  CHECK(gr_cli_write_layer(w, a, &e) == GR_OK && gr_cli_write_layer(w, b, &e) == GR_OK, "%s", e.msg);
  CHECK(gr_cli_close(w, 1, &e) == GR_OK, "%s", e.msg);
  /* header text */
  FILE *f = fopen(path, "rb");
  char head[1024] = {0};
  size_t n = fread(head, 1, sizeof head - 1, f);
  fclose(f);
  head[n] = 0;
  CHECK(strstr(head, "$$HEADERSTART") == head, "starts with $$HEADERSTART");
  CHECK(strstr(head, binary ? "$$BINARY" : "$$ASCII") != NULL, "format line");
  CHECK(strstr(head, "$$VERSION/200") && strstr(head, "$$UNITS/0.001") && strstr(head, "$$LAYERS/2"), "version, units, layers");
  CHECK(strstr(head, "$$LABEL/5,laser2-hatch") != NULL, "labels for laser 2");
  if (!binary) CHECK(strstr(head, "$$POLYLINE/1,1,4,1250.0000,1500.0000") != NULL, "closed polyline repeats its first point: n = 4");
  got g;
  memset(&g, 0, sizeof g);
  gr_cli_header hr;
  CHECK(gr_cli_read(path, &hr, keep, &g, &e) == GR_OK, "%s", e.msg);
  CHECK(g.n == 2, "layers read %d", g.n);
  CHECK(hr.binary == binary && hr.layers == 2, "header read back");
  double tol = binary ? 4e-6 : 1e-7; /* float32 of um values; %.4f of um */
  for (int k = 0; k < g.n; k++) {
    const gr_layer *x = k ? b : a, *y = g.l[k];
    CHECK_NEAR(y->z, x->z, 1e-9);
    CHECK(y->nb == x->nb && y->npts == x->npts, "blocks %zu/%zu points %zu/%zu", y->nb, x->nb, y->npts, x->npts);
    for (size_t i = 0; i < x->nb && i < y->nb; i++)
      CHECK(y->b[i].shape == x->b[i].shape && y->b[i].kind == x->b[i].kind && y->b[i].laser == x->b[i].laser &&
                y->b[i].dir == x->b[i].dir, "block %zu attributes", i);
    for (size_t i = 0; i < 2 * x->npts && x->npts == y->npts; i++) CHECK_NEAR(y->xy[i], x->xy[i], tol);
  }
  for (int k = 0; k < g.n; k++) gr_layer_free(g.l[k]);
  /* truncated: cut 5 bytes */
  f = fopen(path, "rb");
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  fclose(f);
  CHECK(truncate(path, size - (binary ? 5 : 30)) == 0, "truncate");
  memset(&g, 0, sizeof g);
  int rc = gr_cli_read(path, &hr, keep, &g, &e);
  for (int k = 0; k < g.n; k++) gr_layer_free(g.l[k]);
  CHECK(rc == GR_EPARSE, "truncated file refused (rc %d)", rc);
  CHECK(strstr(e.msg, path) != NULL && strstr(e.msg, binary ? "byte" : ":"), "names the file and place: %s", e.msg);
  gr_layer_free(a);
  gr_layer_free(b);
  remove(path);
}

TEST(ascii_roundtrip) { roundtrip(0); }
TEST(binary_roundtrip) { roundtrip(1); }

TEST(malformed_ascii_names_the_line) {
  char path[] = "/tmp/gradus_test_cliXXXXXX";
  int fd = mkstemp(path);
  const char *t = "$$HEADERSTART\n$$ASCII\n$$UNITS/1\n$$HEADEREND\n$$GEOMETRYSTART\n$$LAYER/0.04\n$$HATCHES/1,2,0,0,1,1,2,2\n$$GEOMETRYEND\n";
  CHECK(write(fd, t, strlen(t)) == (ssize_t)strlen(t), "write");
  close(fd);
  got g;
  gr_cli_header h;
  gr_err e;
  int rc = read_all(path, &g, &h, &e);
  for (int k = 0; k < g.n; k++) gr_layer_free(g.l[k]);
  CHECK(rc == GR_EPARSE && strstr(e.msg, ":7:"), "hatch count mismatch on line 7: %s", e.msg);
  remove(path);
  gr_cli_header hd = gr_cli_header_defaults();
  CHECK(gr_cli_open("/nonexistent_dir/x.cli", &hd, &e) == NULL && strstr(e.msg, "/nonexistent_dir/x.cli"), "unwritable path named");
  CHECK(access("/nonexistent_dir/x.cli", F_OK) != 0, "nothing left");
}

/* The reader maps the file: a file that ends exactly on a page boundary, in
 * the middle of a number and without a newline, must still parse (no read
 * past the end); an empty file and a directory are refused by name. */
TEST(file_ending_on_a_page_boundary) {
  char path[] = "/tmp/gradus_test_cliXXXXXX";
  int fd = mkstemp(path);
  const char *head = "$$HEADERSTART\n$$ASCII\n$$UNITS/0.5\n$$DIMENSION/1,2,3,4,5,6.5\n$$HEADEREND\n$$GEOMETRYSTART\n$$LAYER/0.04\n";
  const char *tail = "$$HATCHES/1,1,0,0,1,1.25";
  size_t page = (size_t)sysconf(_SC_PAGESIZE), used = strlen(head) + strlen(tail);
  CHECK(write(fd, head, strlen(head)) == (ssize_t)strlen(head), "write");
  for (size_t i = used; i < page; i++) CHECK(write(fd, "\n", 1) == 1, "pad");
  CHECK(write(fd, tail, strlen(tail)) == (ssize_t)strlen(tail), "write");
  close(fd);
  got g;
  gr_cli_header h;
  gr_err e;
  CHECK(read_all(path, &g, &h, &e) == GR_OK, "%s", e.msg);
  CHECK(g.n == 1 && g.l[0]->npts == 2, "one layer, one hatch");
  CHECK(h.lo[0] == 1 && h.hi[2] == 6.5, "header dimension read (%g .. %g)", h.lo[0], h.hi[2]);
  if (g.n == 1 && g.l[0]->npts == 2) {
    CHECK_NEAR(g.l[0]->z, 0.02, 1e-12);
    CHECK_NEAR(g.l[0]->xy[3], 0.625, 1e-12); /* the last number, scaled by the units */
  }
  for (int k = 0; k < g.n; k++) gr_layer_free(g.l[k]);
  CHECK(truncate(path, 0) == 0, "empty");
  CHECK(gr_cli_read(path, &h, keep, &g, &e) == GR_EPARSE && strstr(e.msg, path), "empty file refused: %s", e.msg);
  remove(path);
  CHECK(gr_cli_read("/tmp", &h, keep, &g, &e) == GR_EIO && strstr(e.msg, "/tmp"), "directory refused: %s", e.msg);
}

/* The ASCII writer formats numbers by hand; its text must be exactly
 * printf's "%.4f" (ties, negative zero, rounding up through a carry, huge
 * values), so that files do not depend on which path printed them. */
TEST(ascii_numbers_as_printf) {
  char path[] = "/tmp/gradus_test_cliXXXXXX";
  int fd = mkstemp(path);
  close(fd);
  gr_cli_header h = gr_cli_header_defaults();
  h.units = 1;
  h.layers = 1;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(path, &h, &e);
  CHECK(w != NULL, "%s", e.msg);
  double v[] = {0.00005, 1.23455, 2.5e-5, -0.00001, -0.0, 0.0, 9.99995, 9.99996, 123.456789, -987.65432,
                1e12 + 0.12345, 3e15, 0.1, 0.7, 1.00015, 39.987654, 12345.67895, -0.00005, 7.0, 1e-300};
  size_t n = sizeof v / sizeof *v / 2;
  gr_layer *l = gr_layer_new(0.04);
  gr_layer_add(l, GR_OPEN, GR_CONTOUR, 0, 2, v, n);
  CHECK(gr_cli_write_layer(w, l, &e) == GR_OK && gr_cli_close(w, 1, &e) == GR_OK, "%s", e.msg);
  gr_layer_free(l);
  char want[2048] = "", one[64], got_text[65536];
  for (size_t i = 0; i < 2 * n; i++) {
    snprintf(one, sizeof one, ",%.4f", v[i]);
    strcat(want, one);
  }
  FILE *f = fopen(path, "rb");
  size_t len = f ? fread(got_text, 1, sizeof got_text - 1, f) : 0;
  if (f) fclose(f);
  got_text[len] = 0;
  const char *line = strstr(got_text, "$$POLYLINE/");
  const char *nums = line ? strchr(line, ',') : NULL;          /* after the id */
  nums = nums ? strchr(nums + 1, ',') : NULL;                    /* after dir */
  nums = nums ? strchr(nums + 1, ',') : NULL;                    /* after the count */
  CHECK(nums && !strncmp(nums, want, strlen(want)) && nums[strlen(want)] == '\n', "numbers as printf:\n got  %.300s\n want %s",
        nums ? nums : "(none)", want);
  remove(path);
}

/* The writer sends whole blocks with O_DIRECT where the file system allows
 * it and writes through the page cache otherwise (or when asked): both must
 * give the same bytes, also for a layer larger than the writer's buffer and
 * sizes that are not a multiple of the block size. */
static long write_big(const char *path, int buffered) {
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = 1;
  h.buffered = buffered;
  h.layers = 3;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(path, &h, &e);
  if (!w) return -1;
  int rc = GR_OK;
  for (int k = 0; k < 3 && rc == GR_OK; k++) {
    gr_layer *l = gr_layer_new(0.04 * (k + 1));
    long ns = k == 1 ? 400001 : 7 + k; /* layer 2: 6.4 MB of hatches, over the 4 MiB buffer */
    for (long i = 0; i < ns; i++) gr_layer_add_segment(l, GR_HATCH, 0, 0.001 * i, 1, 0.001 * i + 0.5, 2);
    rc = gr_cli_write_layer(w, l, &e);
    gr_layer_free(l);
  }
  if (gr_cli_close(w, rc == GR_OK, &e) != GR_OK || rc) return -1;
  FILE *f = fopen(path, "rb");
  if (!f) return -1;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fclose(f);
  return n;
}

TEST(direct_and_buffered_writes_agree) {
  const char *a = "/tmp/gradus_test_cli_direct.cli", *b = "/tmp/gradus_test_cli_buffered.cli";
  long na = write_big(a, 0);
  CHECK(na > 6400000, "direct file written (%ld bytes)", na);
  got g;
  gr_cli_header h;
  gr_err e;
  CHECK(read_all(a, &g, &h, &e) == GR_OK && g.n == 3, "reads back: %s", e.msg);
  if (g.n == 3) CHECK(g.l[1]->npts == 800002 && fabs(g.l[1]->xy[2 * 800001] - 400.5) < 1e-3, "the big layer's last point");
  for (int k = 0; k < g.n; k++) gr_layer_free(g.l[k]);
  {
    long nb = write_big(b, 1);
    CHECK(nb == na, "same size through the page cache: %ld vs %ld", nb, na);
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    long diff = -1, pos = 0;
    if (fa && fb)
      for (;; pos++) {
        int ca = getc(fa), cb = getc(fb);
        if (ca != cb) { diff = pos; break; }
        if (ca == EOF) break;
      }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    CHECK(diff < 0, "identical bytes (first difference at %ld)", diff);
    remove(b);
  }
  remove(a);
}

int main(void) {
  RUN(ascii_roundtrip);
  RUN(binary_roundtrip);
  RUN(malformed_ascii_names_the_line);
  RUN(file_ending_on_a_page_boundary);
  RUN(ascii_numbers_as_printf);
  RUN(direct_and_buffered_writes_agree);
  DONE();
}
