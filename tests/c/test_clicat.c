/* gr_cli_cat: parts written layer range by layer range merge into the bytes
 * of one file with every layer (ASCII and binary, parts in any order); a
 * gap, an overlap, mixed formats and another job's header are refused with
 * the layer numbers, and nothing is written then. */
#define _GNU_SOURCE
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "cli.h"
#include "clicat.h"

static char dir[] = "/tmp/gradus_test_clicatXXXXXX";

/* layers a..b (z = 0.05 g mm, a square whose size depends on g) into name */
static const char *job(const char *name, int binary, int a, int b, double width) {
  static char paths[16][256];
  static int np;
  char *path = paths[np++ % 16];
  snprintf(path, 256, "%s/%s", dir, name);
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = binary;
  h.layers = b - a + 1;
  h.hi[0] = width;
  h.hi[1] = h.hi[2] = 2;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(path, &h, &e);
  CHECK(w != NULL, "%s", e.msg);
  for (int g = a; g <= b && w; g++) {
    gr_layer *l = gr_layer_new(0.05 * g);
    double s = 0.5 + 0.01 * g, sq[] = {0, 0, s, 0, s, s, 0, s};
    gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, sq, 4);
    gr_layer_add_segment(l, GR_HATCH, 0, 0.1, 0.1 * g / 40, s - 0.1, 0.1);
    CHECK(gr_cli_write_layer(w, l, &e) == GR_OK, "%s", e.msg);
    gr_layer_free(l);
  }
  CHECK(gr_cli_close(w, 1, &e) == GR_OK, "%s", e.msg);
  return path;
}

static char *slurp(const char *path, long *n) {
  FILE *f = fopen(path, "rb");
  if (!f) { *n = -1; return NULL; }
  fseek(f, 0, SEEK_END);
  *n = ftell(f);
  rewind(f);
  char *p = malloc((size_t)*n + 1);
  if (p && fread(p, 1, (size_t)*n, f) != (size_t)*n) *n = -1;
  fclose(f);
  return p;
}

/* The $$DATE digits (the files may be written either side of midnight). */
static void undate(char *p, long n) {
  char *d = p && n > 20 ? memmem(p, (size_t)n, "$$DATE/", 7) : NULL;
  if (d && d + 13 <= p + n) memset(d + 7, '0', 6);
}

static void merge_equals_whole(int binary) {
  const char *whole = job(binary ? "wb.cli" : "wa.cli", binary, 1, 40, 2);
  const char *parts[] = {job("p3.cli", binary, 28, 40, 2), job("p1.cli", binary, 1, 13, 2),
                         job("p2.cli", binary, 14, 27, 2)};
  char out[256];
  snprintf(out, sizeof out, "%s/m.cli", dir);
  gr_clicat_info info;
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_cli_cat(parts, 3, out, &info, &e) == GR_OK, "%s", e.msg);
  CHECK(info.layers == 40 && info.first == 1 && info.last == 40, "%d layers %d-%d", info.layers, info.first,
        info.last);
  CHECK_NEAR(info.layer_mm, 0.05, 1e-6);
  long na, nb;
  char *a = slurp(whole, &na), *b = slurp(out, &nb);
  undate(a, na);
  undate(b, nb);
  CHECK(a && b && na == nb && na > 0 && !memcmp(a, b, (size_t)na), "merged %ld bytes vs whole %ld", nb, na);
  free(a);
  free(b);
}
TEST(ascii_parts_merge_to_the_whole) { merge_equals_whole(0); }
TEST(binary_parts_merge_to_the_whole) { merge_equals_whole(1); }

/* cat must fail with `want` in the message and leave no output */
static void refused(const char *const *parts, int n, const char *want) {
  char out[256];
  snprintf(out, sizeof out, "%s/never.cli", dir);
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_cli_cat(parts, n, out, NULL, &e) != GR_OK, "accepted, wanted '%s'", want);
  CHECK(strstr(e.msg, want) != NULL, "message '%s', wanted '%s'", e.msg, want);
  CHECK(access(out, F_OK) != 0, "%s was written", out);
}

TEST(gap_and_overlap_refused_with_layer_numbers) {
  const char *gap[] = {job("g1.cli", 0, 1, 10, 2), job("g2.cli", 0, 15, 20, 2)};
  refused(gap, 2, "layers 11-14 are missing");
  const char *over[] = {job("o1.cli", 0, 1, 10, 2), job("o2.cli", 0, 8, 20, 2)};
  refused(over, 2, "overlap in layers 8-10");
}

TEST(other_jobs_refused) {
  const char *mixed[] = {job("x1.cli", 0, 1, 10, 2), job("x2.cli", 1, 11, 20, 2)};
  refused(mixed, 2, "is ASCII but");
  const char *other[] = {job("y1.cli", 0, 1, 10, 2), job("y2.cli", 0, 11, 20, 3)};
  refused(other, 2, "are not parts of one job");
  const char *cut[] = {job("t1.cli", 1, 1, 10, 2), job("t2.cli", 1, 11, 20, 2)};
  CHECK(truncate(cut[1], 700) == 0, "cannot truncate %s", cut[1]);
  refused(cut, 2, "t2.cli: byte "); /* names the part and the byte */
  const char *none[] = {"/nonexistent/part.cli"};
  refused(none, 1, "/nonexistent/part.cli");
}

int main(void) {
  if (!mkdtemp(dir)) return 1;
  RUN(ascii_parts_merge_to_the_whole);
  RUN(binary_parts_merge_to_the_whole);
  RUN(gap_and_overlap_refused_with_layer_numbers);
  RUN(other_jobs_refused);
  char cmd[300];
  snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
  if (system(cmd)) return 1;
  DONE();
}
