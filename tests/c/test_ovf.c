/* Machine files: OVF written and read back (through the LUTs, one work plane
 * alone too) with shapes, lasers, kinds, keys and marking parameters; every
 * CLI command form (ASCII and binary, long and short) read to the same
 * geometry with the header's labels and the ASCII parameter commands; CLI ->
 * OVF -> CLI; and each malformed file refused with its name and byte offset. */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "check.h"
#include "cli.h"
#include "convert.h"
#include "ovf.h"

typedef struct got {
  gr_layer *l[8];
  int style[8][16];
  gr_cli_style st[8][16]; /* the style of each block, copied */
  int n;
} got;

static int keep(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  got *g = ud;
  (void)e;
  if (g->n < 8) {
    g->l[g->n] = gr_layer_new(l->z);
    gr_layer_append(g->l[g->n], l, 0, 0);
    for (size_t b = 0; b < l->nb && b < 16; b++) {
      g->style[g->n][b] = style[b];
      g->st[g->n][b] = h->style[style[b]];
    }
    g->n++;
  }
  return GR_OK;
}

static void got_free(got *g) {
  for (int i = 0; i < g->n; i++) gr_layer_free(g->l[i]);
  g->n = 0;
}

static int read_all(const char *path, got *g, gr_cli_header *h, gr_err *e) {
  memset(g, 0, sizeof *g);
  gr_err_clear(e);
  return gr_cli_read_ex(path, h, keep, g, e);
}

static void tmpname(char *p, const char *ext) {
  static int k;
  snprintf(p, 256, "/tmp/gradus_test_ovf_%d_%d%s", (int)getpid(), k++, ext);
}

static int exists(const char *p) { struct stat s; return stat(p, &s) == 0; }

/* a unit square CCW (closed), a thin-wall line of laser 2, hatches of laser 2 */
static gr_layer *sample_layer(double z) {
  gr_layer *l = gr_layer_new(z);
  double ring[] = {1.25, 1.5, 38.125, 1.5, 38.125, 39.75, 1.25, 1.5};
  gr_layer_add(l, GR_CLOSED, GR_CONTOUR, 0, 1, ring, 4);
  double thin[] = {0.5, 0.5, 0.75, 0.8, 1.0, 0.5};
  gr_layer_add(l, GR_OPEN, GR_CONTOUR, 1, GR_DIR_THIN, thin, 3);
  gr_layer_add_segment(l, GR_HATCH, 1, 2, 2, 30, 2);
  gr_layer_add_segment(l, GR_HATCH, 1, 30, 2.05, 2, 2.05);
  return l;
}

static void same_layer(const gr_layer *x, const gr_layer *y, double tol) {
  CHECK_NEAR(y->z, x->z, tol);
  CHECK(y->nb == x->nb && y->npts == x->npts, "blocks %zu/%zu points %zu/%zu", y->nb, x->nb, y->npts, x->npts);
  for (size_t b = 0; b < x->nb && b < y->nb; b++)
    CHECK(x->b[b].shape == y->b[b].shape && x->b[b].kind == y->b[b].kind && x->b[b].laser == y->b[b].laser,
          "block %zu: shape %d/%d kind %d/%d laser %d/%d", b, y->b[b].shape, x->b[b].shape, y->b[b].kind, x->b[b].kind,
          y->b[b].laser, x->b[b].laser);
  double worst = 0;
  for (size_t q = 0; q < 2 * x->npts && q < 2 * y->npts; q++) worst = fmax(worst, fabs(x->xy[q] - y->xy[q]));
  CHECK(worst <= tol, "coordinates differ by %g > %g", worst, tol);
}

static const gr_cli_style STYLES[2] = {
    {1, 150, 700, NAN, 5000, "laser1-contour"},
    {5, 250, 1200, NAN, 5000, "laser2-hatch"},
};

static void write_sample(const char *path, int layers) {
  gr_ovf_job j;
  memset(&j, 0, sizeof j);
  j.name = "sample";
  j.nstyles = 2;
  j.style = STYLES;
  j.hatch = 0.05;
  j.layer = 0.04;
  gr_err e;
  gr_err_clear(&e);
  gr_ovf_writer *w = gr_ovf_open(path, &j, &e);
  CHECK(w != NULL, "%s", e.msg);
  CHECK(!exists(path), "nothing at the path before close");
  for (int k = 1; k <= layers && w; k++) {
    gr_layer *l = sample_layer(0.04 * k);
    CHECK(gr_ovf_write_layer(w, l, NULL, &e) == GR_OK, "%s", e.msg);
    gr_layer_free(l);
  }
  CHECK(gr_ovf_close(w, 1, &e) == GR_OK, "%s", e.msg);
}

TEST(ovf_roundtrip) {
  char path[256];
  tmpname(path, ".ovf");
  write_sample(path, 3);
  got g;
  gr_cli_header h;
  gr_err e;
  CHECK(read_all(path, &g, &h, &e) == GR_OK, "%s", e.msg);
  CHECK(h.ovf == 1 && g.n == 3 && h.layers == 3, "ovf %d, %d layers (%d declared)", h.ovf, g.n, h.layers);
  for (int k = 0; k < g.n; k++) {
    gr_layer *x = sample_layer(0.04 * (k + 1));
    same_layer(x, g.l[k], 2e-6 * 40); /* float32 of values up to 40 mm */
    gr_layer_free(x);
  }
  if (g.n) {
    const gr_layer *l = g.l[0];
    CHECK(l->b[0].dir == 1, "the CCW closed contour is outer (dir 1), got %d", l->b[0].dir);
    CHECK(l->b[1].dir == GR_DIR_THIN, "the thin-wall line comes back as one, dir %d", l->b[1].dir);
    /* keys laser*3+kind+1 and the job's marking parameters */
    CHECK(g.st[0][0].id == 1 && g.st[0][0].power == 150 && g.st[0][0].speed == 700 && !strcmp(g.st[0][0].name, "laser1-contour"),
          "contour block: key %d power %g speed %g '%s'", g.st[0][0].id, g.st[0][0].power, g.st[0][0].speed, g.st[0][0].name);
    CHECK(g.st[0][2].id == 5 && g.st[0][2].power == 250 && g.st[0][2].speed == 1200 && g.st[0][2].jump_speed == 5000,
          "hatch block of laser 2: key %d power %g speed %g", g.st[0][2].id, g.st[0][2].power, g.st[0][2].speed);
    CHECK(g.st[0][1].id == 4 && !strcmp(g.st[0][1].name, "laser2-contour"), "undescribed key 4 named '%s'", g.st[0][1].name);
  }
  got_free(&g);
  /* one work plane through the LUTs */
  gr_err_clear(&e);
  gr_ovf_file *f = gr_ovf_open_read(path, &e);
  CHECK(f != NULL && gr_ovf_planes(f) == 3, "%s", e.msg);
  if (f) {
    gr_ovf_header(f, &h);
    gr_layer *l = gr_layer_new(0), *x = sample_layer(0.12);
    int *style = NULL;
    size_t cap = 0;
    CHECK(gr_ovf_read_plane(f, 2, l, &style, &cap, &h, &e) == GR_OK, "%s", e.msg);
    same_layer(x, l, 2e-6 * 40);
    CHECK(gr_ovf_read_plane(f, 3, l, &style, &cap, &h, &e) == GR_EARG && strstr(e.msg, "no work plane 3"), "%s", e.msg);
    free(style);
    gr_layer_free(l);
    gr_layer_free(x);
    gr_ovf_free(f);
  }
  unlink(path);
}

/* The file bytes, for crafting broken copies. */
static unsigned char *slurp(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  *n = (size_t)ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *p = malloc(*n + 1);
  if (p && fread(p, 1, *n, f) != *n) { free(p); p = NULL; }
  fclose(f);
  return p;
}

static int ignore(void *ud, const gr_layer *l, const int *s, const gr_cli_header *h, gr_err *e) {
  (void)ud; (void)l; (void)s; (void)h; (void)e;
  return GR_OK;
}

/* bytes t (len) must be refused with `want` and "byte" in the message */
static void refused(const char *what, const unsigned char *t, size_t len, const char *want) {
  gr_cli_header h;
  gr_err e;
  gr_err_clear(&e);
  int rc = gr_cli_read_mem("bad.ovf", t, len, &h, ignore, NULL, &e);
  CHECK(rc == GR_EPARSE && strstr(e.msg, "bad.ovf") && strstr(e.msg, "byte") && strstr(e.msg, want),
        "%s: rc %d '%s' (wanted '%s')", what, rc, e.msg, want);
}

static void put64(unsigned char *p, int64_t v) { for (int i = 0; i < 8; i++) p[i] = (unsigned char)((uint64_t)v >> (8 * i)); }

TEST(ovf_bad_input) {
  char path[256];
  tmpname(path, ".ovf");
  write_sample(path, 2);
  size_t n = 0;
  unsigned char *t = slurp(path, &n), *c = malloc(n + 16);
  CHECK(t && c && n > 100, "sample written");
  if (!t || !c) return;
  memcpy(c, t, n);
  c[0] = 'X';
  refused("wrong magic", c, n, "magic \"LVF!\"");
  memcpy(c, t, n);
  put64(c + 4, (int64_t)n + 100);
  refused("job LUT outside", c, n, "job LUT position outside the file");
  memcpy(c, t, n);
  put64(c + 12, 5);
  refused("work-plane LUT outside", c, n, "work-plane LUT position outside the file");
  refused("truncated file", t, n - 3, "past the end of the file");
  /* a work plane's LUT position pointing at a run of 0xff: a varint that never ends */
  memcpy(c, t, n);
  memset(c + n, 0xff, 8);
  put64(c + 12, (int64_t)n);
  refused("unending varint", c, n + 8, "never ends");
  /* a length that runs past the end */
  c[n] = 0x7f;
  refused("length past the end", c, n + 1, "runs past the end");
  /* the first vector block's length made larger than the file */
  memcpy(c, t, n);
  c[20] = 0xff; c[21] = 0xff; c[22] = 0x03;
  refused("block length past the end", c, n, "runs past the end");
  refused("too short for a header", t, 7, "magic \"LVF!\"");
  free(t);
  free(c);
  unlink(path);
}

/* The same geometry in every CLI form: a layer at z = 0.1 mm (units 0.01 mm)
 * with a closed triangle (id 1) and two hatches (id 5), then a second layer
 * at z = 0.2 mm with an open polyline (id 4). */
static const double TRI[] = {1, 2, 5, 2, 3, 6, 1, 2};   /* mm */
static const double HAT[] = {0.5, 0.5, 4.5, 0.5, 4.5, 1.0, 0.5, 1.0};
static const double OPN[] = {2, 2, 3, 3.5, 4, 2};

static void check_forms(const got *g, const char *what) {
  CHECK(g->n == 2, "%s: %d layers", what, g->n);
  if (g->n != 2) return;
  const gr_layer *a = g->l[0], *b = g->l[1];
  CHECK_NEAR(a->z, 0.1, 1e-7); /* float32 in OVF */
  CHECK_NEAR(b->z, 0.2, 1e-7);
  CHECK(a->nb == 2 && b->nb == 1, "%s: blocks %zu, %zu", what, a->nb, b->nb);
  if (a->nb != 2 || b->nb != 1) return;
  CHECK(a->b[0].shape == GR_CLOSED && a->b[0].n == 4 && a->b[0].laser == 0 && a->b[0].kind == GR_CONTOUR, "%s: triangle", what);
  CHECK(a->b[1].shape == GR_SEGMENTS && a->b[1].n == 4 && a->b[1].laser == 1 && a->b[1].kind == GR_HATCH, "%s: hatches", what);
  CHECK(b->b[0].shape == GR_OPEN && b->b[0].n == 3 && b->b[0].laser == 1 && b->b[0].kind == GR_CONTOUR, "%s: open line", what);
  double worst = 0;
  for (int q = 0; q < 8; q++) worst = fmax(worst, fmax(fabs(a->xy[q] - TRI[q]), fabs(a->xy[8 + q] - HAT[q])));
  for (int q = 0; q < 6; q++) worst = fmax(worst, fabs(b->xy[q] - OPN[q]));
  CHECK(worst < 1e-6, "%s: coordinates off by %g", what, worst);
}

static void put16(FILE *f, unsigned v) { fputc((int)(v & 255), f); fputc((int)(v >> 8), f); }
static void put32(FILE *f, int32_t v) { for (int i = 0; i < 4; i++) fputc((int)(((uint32_t)v >> (8 * i)) & 255), f); }
static void putf(FILE *f, double v) { float x = (float)v; uint32_t u; memcpy(&u, &x, 4); put32(f, (int32_t)u); }

static const char *HEAD_BIN = "$$HEADERSTART\n$$BINARY\n$$UNITS/0.01\n$$VERSION/200\n$$LABEL/1,Box_support_solid\n$$LAYERS/2\n$$HEADEREND";

/* binary: short = 1 uses commands 128/129/131 (uint16), else 127/130/132 */
static void write_binary(const char *path, int shrt) {
  FILE *f = fopen(path, "wb");
  fputs(HEAD_BIN, f);
  double u = 0.01;
  for (int k = 0; k < 2; k++) {
    if (shrt) { put16(f, 128); put16(f, (unsigned)lround((k + 1) * 0.1 / u)); }
    else { put16(f, 127); putf(f, (k + 1) * 0.1 / u); }
    if (k == 0) {
      if (shrt) { put16(f, 129); put16(f, 1); put16(f, 1); put16(f, 4); for (int q = 0; q < 8; q++) put16(f, (unsigned)lround(TRI[q] / u)); }
      else { put16(f, 130); put32(f, 1); put32(f, 1); put32(f, 4); for (int q = 0; q < 8; q++) putf(f, TRI[q] / u); }
      if (shrt) { put16(f, 131); put16(f, 5); put16(f, 2); for (int q = 0; q < 8; q++) put16(f, (unsigned)lround(HAT[q] / u)); }
      else { put16(f, 132); put32(f, 5); put32(f, 2); for (int q = 0; q < 8; q++) putf(f, HAT[q] / u); }
    } else {
      if (shrt) { put16(f, 129); put16(f, 4); put16(f, 2); put16(f, 3); for (int q = 0; q < 6; q++) put16(f, (unsigned)lround(OPN[q] / u)); }
      else { put16(f, 130); put32(f, 4); put32(f, 2); put32(f, 3); for (int q = 0; q < 6; q++) putf(f, OPN[q] / u); }
    }
  }
  fclose(f);
}

static void write_ascii(const char *path) {
  FILE *f = fopen(path, "wb");
  fputs("$$HEADERSTART\r\n$$ASCII\r\n$$UNITS/0.01\r\n$$VERSION/200\r\n$$LABEL/1,Box_support_solid\r\n$$LAYERS/2\r\n$$HEADEREND\r\n"
        "$$GEOMETRYSTART\r\n// a comment\r\n$$LAYER/10\r\n$$POWER/180\r\n$$SPEED/900\r\n$$FOCUS/-0.5\r\n"
        "$$POLYLINE/1,1,4,100,200,500,200,300,600,100,200\r\n$$POWER/220\r\n$$HATCHES/5,2,50,50,450,50,450,100,50,100\r\n"
        "$$LAYER/20.0\r\n$$POLYLINE/4,2,3,200,200,300,350,400,200\r\n$$GEOMETRYEND\r\n", f);
  fclose(f);
}

TEST(cli_every_form) {
  char p[3][256];
  got g;
  gr_cli_header h;
  gr_err e;
  tmpname(p[0], ".cli");
  tmpname(p[1], ".cli");
  tmpname(p[2], ".cli");
  write_binary(p[0], 1);
  write_binary(p[1], 0);
  write_ascii(p[2]);
  const char *what[3] = {"binary short", "binary long", "ascii"};
  for (int i = 0; i < 3; i++) {
    CHECK(read_all(p[i], &g, &h, &e) == GR_OK, "%s: %s", what[i], e.msg);
    check_forms(&g, what[i]);
    CHECK(h.nlabels == 1 && h.label[0].id == 1 && !strcmp(h.label[0].text, "Box_support_solid"), "%s: label kept", what[i]);
    if (g.n) CHECK(!strcmp(g.st[0][0].name, "Box_support_solid"), "%s: id 1 named by its label: '%s'", what[i], g.st[0][0].name);
    CHECK(i == 0 ? h.short_cmds == 5 : h.short_cmds == 0, "%s: %ld short commands", what[i], h.short_cmds);
    if (i == 2 && g.n == 2) {
      const gr_cli_style *a = &g.st[0][0], *b = &g.st[0][1], *c = &g.st[1][0];
      CHECK(a->power == 180 && a->speed == 900 && a->focus == -0.5, "polyline after $$POWER/180 $$SPEED/900 $$FOCUS/-0.5: %g %g %g", a->power, a->speed, a->focus);
      CHECK(b->power == 220 && b->speed == 900, "hatches after $$POWER/220: %g %g", b->power, b->speed);
      CHECK(c->power == 220 && c->id == 4, "parameters carry over the layer: %g", c->power);
    }
    got_free(&g);
  }
  /* ASCII with parameters -> OVF keeps them per block; OVF -> CLI -> same geometry */
  char o[256], c2[256];
  tmpname(o, ".ovf");
  tmpname(c2, ".cli");
  CHECK(gr_convert(p[2], o, GR_FMT_OVF, &e) == GR_OK, "%s", e.msg);
  CHECK(read_all(o, &g, &h, &e) == GR_OK, "%s", e.msg);
  check_forms(&g, "ascii -> ovf");
  if (g.n == 2) CHECK(g.st[0][0].power == 180 && g.st[0][1].power == 220 && !strcmp(g.st[0][0].name, "Box_support_solid"),
                      "parameters in OVF marking params: %g %g '%s'", g.st[0][0].power, g.st[0][1].power, g.st[0][0].name);
  got_free(&g);
  CHECK(gr_convert(o, c2, GR_FMT_BINARY, &e) == GR_OK, "%s", e.msg);
  CHECK(read_all(c2, &g, &h, &e) == GR_OK, "%s", e.msg);
  check_forms(&g, "ascii -> ovf -> binary cli");
  got_free(&g);
  for (int i = 0; i < 3; i++) unlink(p[i]);
  unlink(o);
  unlink(c2);
}

static void cli_refused(const char *what, const char *path, const char *want) {
  got g;
  gr_cli_header h;
  gr_err e;
  int rc = read_all(path, &g, &h, &e);
  got_free(&g);
  CHECK(rc == GR_EPARSE && strstr(e.msg, path) && strstr(e.msg, want), "%s: rc %d '%s' (wanted '%s')", what, rc, e.msg, want);
}

TEST(cli_bad_input) {
  char p[256], out[256];
  tmpname(p, ".cli");
  tmpname(out, ".ovf");
  FILE *f = fopen(p, "wb");
  fputs(HEAD_BIN, f);
  put16(f, 128); put16(f, 10);
  put16(f, 133); put16(f, 1);
  fclose(f);
  size_t at = strlen(HEAD_BIN) + 4;
  char want[64];
  snprintf(want, sizeof want, "byte %zu: unknown command 133", at);
  cli_refused("unknown binary command", p, want);
  f = fopen(p, "wb");
  fputs(HEAD_BIN, f);
  put16(f, 128); put16(f, 10);
  put16(f, 129); put16(f, 1); put16(f, 1); put16(f, 60000); put16(f, 5);
  fclose(f);
  snprintf(want, sizeof want, "byte %zu: polyline of 60000 points runs past the end", at);
  cli_refused("short count larger than the file", p, want);
  f = fopen(p, "wb");
  fputs(HEAD_BIN, f);
  put16(f, 127); putf(f, 10);
  put16(f, 132); put32(f, 1); put32(f, 2000000000);
  fclose(f);
  cli_refused("long count larger than the file", p, "hatches of 2000000000 lines runs past the end");
  f = fopen(p, "wb");
  fputs("$$HEADERSTART\n$$ASCII\n$$HEADEREND\n$$GEOMETRYSTART\n$$LAYER/1\n$$ARC/1,2,3\n", f);
  fclose(f);
  cli_refused("unknown ASCII command", p, ":6: unknown command '$$ARC'");
  f = fopen(p, "wb");
  fputs("$$HEADERSTART\n$$ASCII\n$$HEADEREND\n$$GEOMETRYSTART\n$$LAYER/1\n$$HATCHES/1,900000000,1,2\n", f);
  fclose(f);
  cli_refused("ASCII count larger than the line", p, ":6: count 900000000 exceeds");
  /* nothing written when the input is bad */
  gr_err e;
  gr_err_clear(&e);
  CHECK(gr_convert(p, out, GR_FMT_OVF, &e) == GR_EPARSE && !exists(out), "convert of a bad file writes nothing: %s", e.msg);
  unlink(p);
}

/* The binary short form: coordinates rounded to whole units (here 1 um), a
 * block that does not fit 16 bits (a negative coordinate) written long. */
TEST(cli_short_writer) {
  char p[256];
  tmpname(p, ".cli");
  gr_cli_header h = gr_cli_header_defaults();
  h.binary = 1;
  h.short_form = 1;
  h.layers = 1;
  h.nlasers = 2;
  gr_err e;
  gr_err_clear(&e);
  gr_cli_writer *w = gr_cli_open(p, &h, &e);
  CHECK(w != NULL, "%s", e.msg);
  if (!w) return;
  gr_layer *l = sample_layer(0.04);
  CHECK(gr_cli_write_layer(w, l, &e) == GR_OK, "%s", e.msg);
  CHECK(!strcmp(gr_cli_form(w), "short"), "all short: %s", gr_cli_form(w));
  gr_layer *m = gr_layer_new(0.08);
  double neg[] = {-1, 1, 2, 2};
  gr_layer_add(m, GR_OPEN, GR_CONTOUR, 0, 2, neg, 2);
  CHECK(gr_cli_write_layer(w, m, &e) == GR_OK, "%s", e.msg);
  CHECK(!strcmp(gr_cli_form(w), "short+long"), "a negative coordinate goes long: %s", gr_cli_form(w));
  CHECK(gr_cli_close(w, 1, &e) == GR_OK, "%s", e.msg);
  got g;
  gr_cli_header hr;
  CHECK(read_all(p, &g, &hr, &e) == GR_OK, "%s", e.msg);
  CHECK(g.n == 2 && hr.short_cmds == 5, "%d layers, %ld short commands (2 layers + 3 blocks)", g.n, hr.short_cmds);
  if (g.n == 2) {
    same_layer(l, g.l[0], 0.0005); /* rounded to whole micrometres */
    same_layer(m, g.l[1], 1e-6);
  }
  got_free(&g);
  gr_layer_free(l);
  gr_layer_free(m);
  unlink(p);
}

int main(void) {
  RUN(ovf_roundtrip);
  RUN(ovf_bad_input);
  RUN(cli_every_form);
  RUN(cli_bad_input);
  RUN(cli_short_writer);
  DONE();
}
