/* The viewer's data: the layer index finds every layer of ASCII and binary
 * files (short commands too) with its z, random access returns exactly the
 * layer the whole-file reader returns, errors name the same line or byte,
 * the layer encoding decodes back to the coordinates within half a quantum,
 * base64 matches RFC 4648's examples, and PNG reading. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "pngread.h"
#include "raster.h"
#include "view.h"

#define NL 5

/* layer k (0-based): a closed square of side k+1 (laser k%2) and k+1 hatch
 * vectors (laser (k+1)%2) */
static gr_layer *make_layer(int k) {
  gr_layer *l = gr_layer_new(0.1 * (k + 1));
  double s = k + 1;
  double sq[] = {0, 0, s, 0, s, s, 0, s, 0, 0};
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, k % 2, 1, sq, 5);
  for (int i = 0; i <= k; i++) gr_layer_add_segment(l, GR_HATCH, (k + 1) % 2, 0.1, 0.3 + 0.2 * i, s - 0.1, 0.3 + 0.2 * i);
  return l;
}

static void write_file(const char *path, int binary) {
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = binary;
  h.layers = NL;
  h.nlasers = 2;
  h.buffered = 1;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(path, &h, &e);
  CHECK(w != NULL, "%s", e.msg);
  for (int k = 0; k < NL && w; k++) {
    gr_layer *l = make_layer(k);
    CHECK(gr_cli_write_layer(w, l, &e) == GR_OK, "%s", e.msg);
    gr_layer_free(l);
  }
  CHECK(gr_cli_close(w, 1, &e) == GR_OK, "%s", e.msg);
}

typedef struct copy { gr_layer *l; int calls; } copy;
static int take(void *ud, const gr_layer *l, gr_err *e) {
  copy *c = ud;
  (void)e;
  c->calls++;
  if (!c->l) {
    c->l = gr_layer_new(l->z);
    gr_layer_append(c->l, l, 0, 0);
  }
  return GR_OK;
}

static int same_layer(const gr_layer *a, const gr_layer *b) {
  if (a->nb != b->nb || a->npts != b->npts || a->z != b->z) return 0;
  for (size_t i = 0; i < a->nb; i++)
    if (a->b[i].kind != b->b[i].kind || a->b[i].laser != b->b[i].laser || a->b[i].shape != b->b[i].shape ||
        a->b[i].n != b->b[i].n)
      return 0;
  return !memcmp(a->xy, b->xy, 2 * a->npts * sizeof(double));
}

/* the k-th layer as the whole-file reader gives it */
typedef struct nth { int want, seen; gr_layer *l; } nth;
static int keep_nth(void *ud, const gr_layer *l, gr_err *e) {
  nth *n = ud;
  (void)e;
  if (n->seen++ == n->want) {
    n->l = gr_layer_new(l->z);
    gr_layer_append(n->l, l, 0, 0);
  }
  return GR_OK;
}

static void index_and_read(int binary) {
  char path[] = "/tmp/gradus_test_viewXXXXXX";
  close(mkstemp(path));
  write_file(path, binary);
  gr_err e;
  gr_err_clear(&e);
  gr_view_index *ix = gr_view_index_open(path, &e);
  CHECK(ix != NULL, "%s", e.msg);
  if (!ix) { unlink(path); return; }
  CHECK(ix->n == NL, "%zu layers, want %d", ix->n, NL);
  CHECK(ix->h.binary == binary, "format");
  for (size_t k = 0; k < ix->n; k++) CHECK_NEAR(ix->layer[k].z, 0.1 * (double)(k + 1), 1e-6);
  int order[] = {3, 0, 4, 2, 1};
  for (int i = 0; i < NL; i++) {
    int k = order[i];
    copy c = {NULL, 0};
    CHECK(gr_view_layer(ix, (size_t)k, take, &c, &e) == GR_OK, "layer %d: %s", k, e.msg);
    CHECK(c.calls == 1, "layer %d handed over %d times", k, c.calls);
    nth want = {k, 0, NULL};
    gr_cli_header h;
    CHECK(gr_cli_read(path, &h, keep_nth, &want, &e) == GR_OK, "%s", e.msg);
    CHECK(c.l && want.l && same_layer(c.l, want.l), "layer %d differs from the whole-file reader's", k);
    CHECK(c.l && c.l->nb == 2 && c.l->npts == 5 + 2 * (size_t)(k + 1), "layer %d: %zu blocks", k, c.l ? c.l->nb : 0);
    gr_layer_free(c.l);
    gr_layer_free(want.l);
  }
  CHECK(gr_view_layer(ix, NL, take, &(copy){NULL, 0}, &e) == GR_EARG && strstr(e.msg, "out of range"), "%s", e.msg);
  gr_view_index_free(ix);
  unlink(path);
}
TEST(ascii_index) { index_and_read(0); }
TEST(binary_index) { index_and_read(1); }

/* a bad number in layer 4 of an ASCII file: random access names the same
 * line as reading the whole file */
TEST(ascii_error_line) {
  char path[] = "/tmp/gradus_test_viewXXXXXX";
  close(mkstemp(path));
  write_file(path, 0);
  FILE *f = fopen(path, "rb");
  char *t = calloc(1, 1 << 16);
  size_t n = fread(t, 1, (1 << 16) - 1, f);
  fclose(f);
  char *l4 = strstr(t, "$$LAYER/400"), *hl = l4 ? strstr(l4, "$$HATCHES/") : NULL;
  CHECK(hl != NULL, "no fourth layer in\n%s", t);
  if (!hl) { free(t); unlink(path); return; }
  char *comma = strchr(hl + 10, ','), *c2 = comma ? strchr(comma + 1, ',') : NULL;
  if (c2) c2[1] = 'x'; /* the first coordinate */
  f = fopen(path, "wb");
  fwrite(t, 1, n, f);
  fclose(f);
  free(t);
  gr_err e1, e2;
  gr_err_clear(&e1);
  gr_err_clear(&e2);
  gr_view_index *ix = gr_view_index_open(path, &e1);
  CHECK(ix && ix->n == NL, "the index does not parse coordinates: %s", e1.msg);
  gr_cli_header h;
  copy c = {NULL, 0};
  CHECK(gr_cli_read(path, &h, take, &c, &e1) == GR_EPARSE, "whole file read");
  gr_layer_free(c.l);
  c.l = NULL;
  CHECK(ix && gr_view_layer(ix, 3, take, &c, &e2) == GR_EPARSE, "layer 4 read");
  CHECK(!strcmp(e1.msg, e2.msg) && strstr(e1.msg, ":"), "'%s' vs '%s'", e1.msg, e2.msg);
  if (ix) CHECK(gr_view_layer(ix, 2, take, &c, &e2) == GR_OK, "layer 3 is fine: %s", e2.msg);
  gr_layer_free(c.l);
  gr_view_index_free(ix);
  unlink(path);
}

static void put16(FILE *f, unsigned v) { fputc(v & 255, f); fputc(v >> 8, f); }
static void put32(FILE *f, uint32_t v) { for (int i = 0; i < 4; i++) fputc((v >> (8 * i)) & 255, f); }
static void putf32(FILE *f, float x) { uint32_t u; memcpy(&u, &x, 4); put32(f, u); }

/* short and long commands: the index walks them all (the reader must
 * understand the first layer, which gives the header); a truncated command
 * is named by its byte offset */
TEST(binary_short_commands) {
  char path[] = "/tmp/gradus_test_viewXXXXXX";
  close(mkstemp(path));
  FILE *f = fopen(path, "wb");
  const char *hd = "$$HEADERSTART\n$$BINARY\n$$UNITS/0.01\n$$LAYERS/3\n$$HEADEREND";
  fputs(hd, f);
  put16(f, 127), putf32(f, 12.5f);                                /* layer z = 12.5 units */
  put16(f, 132), put32(f, 2), put32(f, 1), putf32(f, 0), putf32(f, 0), putf32(f, 1), putf32(f, 1);
  put16(f, 127), putf32(f, 20.0f);                                /* layer z = 20 units, short blocks */
  put16(f, 129), put16(f, 1), put16(f, 2), put16(f, 2), put16(f, 1), put16(f, 2), put16(f, 3), put16(f, 4);
  put16(f, 131), put16(f, 2), put16(f, 1), put16(f, 1), put16(f, 2), put16(f, 3), put16(f, 4);
  put16(f, 128), put16(f, 7);                                     /* short layer, z = 7 units */
  long at = ftell(f);
  put16(f, 127), putf32(f, 20.0f);
  put16(f, 130), put32(f, 1), put32(f, 1), put32(f, 3), putf32(f, 0), putf32(f, 0); /* 3 points promised, 1 given */
  fclose(f);
  gr_err e;
  gr_err_clear(&e);
  gr_view_index *ix = gr_view_index_open(path, &e);
  CHECK(ix == NULL, "a truncated file was indexed");
  char want[64];
  snprintf(want, sizeof want, "byte %ld:", at + 6);
  CHECK(strstr(e.msg, want) && strstr(e.msg, "past the end"), "'%s' should name %s", e.msg, want);
  gr_view_index_free(ix);
  /* cut the last layer off: now the index is complete */
  CHECK(truncate(path, at) == 0, "truncate");
  ix = gr_view_index_open(path, &e);
  if (ix) {
    CHECK(ix->n == 3, "%zu layers", ix->n);
    CHECK_NEAR(ix->layer[0].z, 0.125, 1e-9);
    CHECK_NEAR(ix->layer[1].z, 0.2, 1e-9);
    CHECK_NEAR(ix->layer[2].z, 0.07, 1e-9);
    CHECK(ix->layer[1].at == strlen(hd) + 32, "layer 2 at byte %zu", ix->layer[1].at);
    CHECK(ix->layer[2].at == strlen(hd) + 68, "layer 3 at byte %zu", ix->layer[2].at);
  }
  /* a non-CLI file */
  char txt[] = "/tmp/gradus_test_viewXXXXXX";
  int fd = mkstemp(txt);
  CHECK(write(fd, "solid x\nendsolid x\n", 20) == 20, "write");
  close(fd);
  gr_view_index *bad = gr_view_index_open(txt, &e);
  CHECK(!bad && strstr(e.msg, "not a CLI file"), "%s", e.msg);
  gr_view_index_free(ix);
  unlink(path);
  unlink(txt);
}

/* decoder of the viewer encoding (doc/formats.md), independent of the page's */
static uint64_t get_u(const unsigned char *p, size_t *i) {
  uint64_t v = 0;
  int sh = 0;
  unsigned char b;
  do { b = p[(*i)++]; v |= (uint64_t)(b & 127) << sh; sh += 7; } while (b & 128);
  return v;
}
static int64_t get_s(const unsigned char *p, size_t *i) {
  uint64_t v = get_u(p, i);
  return (int64_t)(v >> 1) ^ -(int64_t)(v & 1);
}

TEST(encoding_round_trip) {
  gr_layer *l = gr_layer_new(1.234567);
  double ring[] = {-3.14159, 2.71828, 100.00005, -0.00004, 55.5, 77.7, -3.14159, 2.71828};
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 1, 0, ring, 4);
  gr_layer_add_segment(l, GR_HATCH, 0, -1000.5, 0.25, 999.75, 0.25);
  double open[] = {1, 1, 2, 2, 3, 1};
  gr_layer_add(l, GR_OPEN, GR_EDGE, 2, GR_DIR_THIN, open, 3);
  double q = 1e-4;
  gr_view_buf b = {NULL, 0, 0};
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_view_encode(l, q, &b, &e) == GR_OK, "%s", e.msg);
  size_t i = 0;
  CHECK(get_u(b.p, &i) == 1, "version");
  CHECK_NEAR(get_s(b.p, &i) * q, 1.234567, q / 2);
  CHECK(get_u(b.p, &i) == l->nb, "blocks");
  for (size_t k = 0; k < l->nb; k++) {
    const gr_block *bk = &l->b[k];
    int64_t id = get_s(b.p, &i);
    uint64_t kind = get_u(b.p, &i), laser = get_u(b.p, &i), shape = get_u(b.p, &i);
    int64_t dir = get_s(b.p, &i);
    uint64_t n = get_u(b.p, &i);
    CHECK(id == bk->laser * 3 + bk->kind + 1 && kind == (uint64_t)bk->kind && laser == (uint64_t)bk->laser &&
          shape == (uint64_t)bk->shape && dir == bk->dir && n == bk->n, "block %zu head", k);
  }
  int64_t x = 0, y = 0;
  double worst = 0;
  for (size_t p = 0; p < l->npts; p++) {
    x += get_s(b.p, &i), y += get_s(b.p, &i);
    worst = fmax(worst, fmax(fabs(x * q - l->xy[2 * p]), fabs(y * q - l->xy[2 * p + 1])));
  }
  CHECK(worst <= q / 2 + 1e-12, "worst coordinate error %g mm", worst);
  CHECK(i == b.n, "%zu of %zu bytes used", i, b.n);
  /* a coordinate that cannot be encoded */
  gr_layer_clear(l, 0);
  gr_layer_add_segment(l, GR_HATCH, 0, 0, 0, NAN, 1);
  b.n = 0;
  CHECK(gr_view_encode(l, q, &b, &e) == GR_ENUM && strstr(e.msg, "cannot be encoded"), "NaN: %s", e.msg);
  free(b.p);
  gr_layer_free(l);
}

TEST(base64_rfc4648) {
  const char *in[] = {"", "f", "fo", "foo", "foob", "fooba", "foobar"};
  const char *out[] = {"", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy"};
  for (int k = 0; k < 7; k++) {
    size_t n;
    char *s = gr_view_base64((const unsigned char *)in[k], strlen(in[k]), &n);
    CHECK(s && !strcmp(s, out[k]) && n == strlen(out[k]), "'%s' -> '%s', want '%s'", in[k], s, out[k]);
    free(s);
  }
}

TEST(png_read_back) {
  gr_layer *l = make_layer(2);
  char path[] = "/tmp/gradus_test_viewXXXXXX";
  close(mkstemp(path));
  gr_png_opts o = {300, 2, 0};
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_png_layer(path, l, &o, &e) == GR_OK, "%s", e.msg);
  unsigned char *p = NULL;
  int w = 0, h = 0;
  CHECK(gr_pngread(path, &p, &w, &h, &e) == GR_OK, "%s", e.msg);
  CHECK(w == 300 && h > 0, "%d x %d", w, h);
  long dark = 0;
  for (long i = 0; p && i < (long)w * h; i++) dark += p[4 * i] < 128 || p[4 * i + 1] < 128 || p[4 * i + 2] < 128;
  CHECK(p && p[0] == 255 && p[1] == 255 && p[2] == 255, "corner not white");
  CHECK(dark > 100, "%ld coloured pixels", dark);
  free(p);
  CHECK(gr_pngread("Makefile", &p, &w, &h, &e) == GR_EPARSE && strstr(e.msg, "not a PNG"), "%s", e.msg);
  CHECK(gr_pngread("/nonexistent.png", &p, &w, &h, &e) == GR_EIO, "%s", e.msg);
  gr_layer_free(l);
  unlink(path);
}

int main(void) {
  RUN(ascii_index);
  RUN(binary_index);
  RUN(ascii_error_line);
  RUN(binary_short_commands);
  RUN(encoding_round_trip);
  RUN(base64_rfc4648);
  RUN(png_read_back);
  DONE();
}
