/* cli.c: CLI 2.0 writer, see cli.h (the reader: cli_read.c). */
#define _GNU_SOURCE /* O_DIRECT, memmem */
#include "cli.h"
#include "outbuf.h"
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

gr_cli_header gr_cli_header_defaults(void) {
  gr_cli_header h;
  memset(&h, 0, sizeof h);
  h.units = 0.001;
  h.nlasers = 1;
  return h;
}

/* Output through gr_outbuf (outbuf.h): O_DIRECT where the file system allows it. */
struct gr_cli_writer {
  gr_outbuf o;
  gr_cli_header h;
  int layers_written;
  long shorts, longs; /* geometry commands written in short and long form */
  long rounded_points, rounded_vectors; /* left out by the short form (short_block) */
};

static const char *const KIND[GR_NKINDS] = {"contour", "hatch", "edge"};

static int reserve(gr_cli_writer *w, size_t k, gr_err *e) { return gr_outbuf_reserve(&w->o, k, e); }
static int put(gr_cli_writer *w, const void *p, size_t k, gr_err *e) { return gr_outbuf_put(&w->o, p, k, e); }

static int putf(gr_cli_writer *w, gr_err *e, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
#include <stdarg.h>
static int putf(gr_cli_writer *w, gr_err *e, const char *fmt, ...) {
  if (reserve(w, 512, e)) return e->code;
  va_list ap;
  va_start(ap, fmt);
  gr_outbuf *o = &w->o;
  int k = vsnprintf(o->buf + o->n, o->cap - o->n, fmt, ap);
  va_end(ap);
  if (k < 0 || (size_t)k >= o->cap - o->n) return gr_fail(e, GR_EARG, "CLI line too long");
  o->n += (size_t)k;
  return GR_OK;
}

gr_cli_writer *gr_cli_open(const char *path, const gr_cli_header *h, gr_err *e) {
  if (!(h->units > 0)) return gr_fail(e, GR_EARG, "CLI units must be > 0 mm, got %g", h->units), NULL;
  gr_cli_writer *w = calloc(1, sizeof *w);
  if (!w) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  w->h = *h;
  if (gr_outbuf_open(&w->o, path, h->buffered, 4 << 20, e)) { free(w); return NULL; }
  time_t now = time(NULL);
  struct tm tm;
  gmtime_r(&now, &tm);
  int rc = putf(w, e, "$$HEADERSTART\n%s\n$$UNITS/%.9g\n$$VERSION/200\n", h->binary ? "$$BINARY" : "$$ASCII", h->units);
  for (int l = 0; l < (h->nlasers > 0 ? h->nlasers : 1) && !rc; l++)
    for (int k = 0; k < GR_NKINDS && !rc; k++) rc = putf(w, e, "$$LABEL/%d,laser%d-%s\n", l * 3 + k + 1, l + 1, KIND[k]);
  for (int r = 1; r < GR_NREGIONS && !rc; r++) /* regions.h: each region's styles after the core's */
    for (int l = 0; (h->regions >> r & 1) && l < (h->nlasers > 0 ? h->nlasers : 1) && !rc; l++)
      for (int k = 0; k < GR_NKINDS && !rc; k++)
        rc = putf(w, e, "$$LABEL/%d,laser%d-%s-%s\n", r * GR_REGION_IDS + l * 3 + k + 1, l + 1, gr_region_name(r), KIND[k]);
  if (!rc)
    rc = putf(w, e, "$$DATE/%02d%02d%02d\n$$DIMENSION/%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n$$LAYERS/%d\n$$HEADEREND",
              tm.tm_mday, tm.tm_mon + 1, tm.tm_year % 100, h->lo[0], h->lo[1], h->lo[2], h->hi[0], h->hi[1], h->hi[2],
              h->layers);
  if (!rc && !h->binary) rc = putf(w, e, "\n$$GEOMETRYSTART\n");
  if (rc) { gr_cli_close(w, 0, NULL); return NULL; }
  return w;
}

static void put_u16(unsigned char *p, unsigned v) { p[0] = v & 255; p[1] = (v >> 8) & 255; }
static void put_i32(unsigned char *p, int32_t v) { uint32_t u = (uint32_t)v; for (int i = 0; i < 4; i++) p[i] = (u >> (8 * i)) & 255; }
static void put_f32(unsigned char *p, double v) {
  float f = (float)v;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  memcpy(p, &f, 4); /* the file is little-endian */
#else
  uint32_t u;
  memcpy(&u, &f, 4);
  for (int i = 0; i < 4; i++) p[i] = (u >> (8 * i)) & 255;
#endif
}

/* v as printf("%.4f") would print it, at a fraction of the cost: the value
 * times 1e4 rounded to an integer, digits by hand. Near a rounding tie (where
 * the product's own rounding could decide) and for huge or non-finite values
 * it defers to snprintf, so the text is always exactly printf's. Returns the
 * number of characters written to o (at most 40, no NUL). */
static int fmt_fixed4(char *o, double v) {
  double x = fabs(v) * 1e4, r = floor(x), f = x - r;
  if (!(x < 1e15) || fabs(f - 0.5) < 1e-6) {
    char t[64];
    int n = snprintf(t, sizeof t, "%.4f", v);
    if (n < 0 || n > 40) n = snprintf(t, sizeof t, "%.4e", v);
    memcpy(o, t, (size_t)n);
    return n;
  }
  unsigned long long m = (unsigned long long)r + (f > 0.5);
  char d[24];
  int k = 0;
  for (int i = 0; i < 4; i++, m /= 10) d[k++] = (char)('0' + m % 10);
  d[k++] = '.';
  do { d[k++] = (char)('0' + m % 10); m /= 10; } while (m);
  int n = 0;
  if (signbit(v)) o[n++] = '-';
  while (k) o[n++] = d[--k];
  return n;
}

/* v in units as a short-form coordinate (0..65535), or -1 when it does not fit. */
static long short_of(double v) {
  /* floor(t) lies in 0..65535 exactly when t does in [0, 65536), and
   * there truncation is floor (NaN fails both tests) */
  double t = v + 0.5;
  return t >= 0 && t < 65536 ? (long)t : -1;
}

/* Block bk (points p, CLI id) as a short command 129/131 with uint16
 * coordinates; 0 (nothing written) when its id, count or a coordinate does
 * not fit 16 bits: the caller writes the long command instead. Rounded to
 * the unit, a polyline's point equal to the one before it is left out (a
 * polyline that rounds to one point stays a dot of two), and so is a hatch
 * vector whose ends round to one point: zero-length marks the rounding
 * made, counted in w->rounded_points / rounded_vectors. */
static int short_block(gr_cli_writer *w, const gr_block *bk, const double *p, int id, int *done, gr_err *e) {
  double u = w->h.units;
  int seg = bk->shape == GR_SEGMENTS;
  size_t cnt = seg ? bk->n / 2 : bk->n, npts = seg ? 2 * cnt : cnt, hd = seg ? 6 : 8;
  *done = 0;
  if (id < 0 || id > 65535 || cnt > 65535) return GR_OK;
  /* convert straight into the reserved room; a coordinate that does not
   * fit abandons it (w->o.n not advanced: nothing written) */
  if (reserve(w, hd + 4 * npts, e)) return e->code;
  unsigned char *o = (unsigned char *)w->o.buf + w->o.n + hd;
  size_t kept = 0; /* polylines: points; hatches: vectors */
  long px = -1, py = -1;
  for (size_t k = 0; k < cnt; k++) {
    if (seg) {
      long c[4];
      for (int i = 0; i < 4; i++)
        if ((c[i] = short_of(p[4 * k + i] / u)) < 0) return GR_OK;
      if (c[0] == c[2] && c[1] == c[3]) continue;
      for (int i = 0; i < 4; i++) put_u16(o + 8 * kept + 2 * i, (unsigned)c[i]);
    } else {
      long cx = short_of(p[2 * k] / u), cy = short_of(p[2 * k + 1] / u);
      if (cx < 0 || cy < 0) return GR_OK;
      if (cx == px && cy == py) continue;
      put_u16(o + 4 * kept, (unsigned)cx);
      put_u16(o + 4 * kept + 2, (unsigned)cy);
      px = cx;
      py = cy;
    }
    kept++;
  }
  for (size_t q = 2 * npts; q < 2 * bk->n; q++) if (short_of(p[q] / u) < 0) return GR_OK; /* an odd segment end */
  if (!seg && kept == 1 && cnt > 1) { /* a dot: its point twice */
    memcpy(o + 4, o, 4);
    kept = 2;
  }
  if (seg) w->rounded_vectors += (long)(cnt - kept);
  else w->rounded_points += (long)(cnt - kept);
  *done = 1;
  if (kept == 0) return GR_OK; /* every vector rounded to a point: no block */
  o -= hd;
  put_u16(o, seg ? 131 : 129);
  put_u16(o + 2, (unsigned)id);
  if (!seg) put_u16(o + 4, (unsigned)(bk->shape == GR_OPEN ? 2 : bk->dir));
  put_u16(o + hd - 2, (unsigned)kept);
  w->o.n += hd + (seg ? 8 : 4) * kept;
  w->shorts++;
  return GR_OK;
}

/* A binary layer: long commands (127, 130, 132), or short ones (128, 129,
 * 131) where h.short_form asks and the values fit. */
static int binary_layer(gr_cli_writer *w, const gr_layer *l, gr_err *e) {
  double u = w->h.units;
  long zs = w->h.short_form ? short_of(l->z / u) : -1;
  unsigned char hd[16];
  put_u16(hd, zs >= 0 ? 128 : 127);
  if (zs >= 0) put_u16(hd + 2, (unsigned)zs);
  else put_f32(hd + 2, l->z / u);
  if (put(w, hd, zs >= 0 ? 4 : 6, e)) return e->code;
  for (size_t b = 0; b < l->nb; b++) {
    const gr_block *bk = &l->b[b];
    const double *p = l->xy + 2 * bk->start;
    int id = gr_style_id(bk), done = 0;
    if (w->h.short_form && short_block(w, bk, p, id, &done, e)) return e->code;
    if (done) continue;
    w->longs++;
    if (bk->shape == GR_SEGMENTS) {
      size_t ns = bk->n / 2;
      if (reserve(w, 10 + 16 * ns, e)) return e->code;
      unsigned char *o = (unsigned char *)w->o.buf + w->o.n;
      put_u16(o, 132);
      put_i32(o + 2, id);
      put_i32(o + 6, (int32_t)ns);
      for (size_t q = 0; q < 2 * ns; q++) {
        put_f32(o + 10 + 8 * q, p[2 * q] / u);
        put_f32(o + 14 + 8 * q, p[2 * q + 1] / u);
      }
      w->o.n += 10 + 16 * ns;
    } else {
      if (reserve(w, 14 + 8 * bk->n, e)) return e->code;
      unsigned char *o = (unsigned char *)w->o.buf + w->o.n;
      put_u16(o, 130);
      put_i32(o + 2, id);
      put_i32(o + 6, bk->shape == GR_OPEN ? 2 : bk->dir);
      put_i32(o + 10, (int32_t)bk->n);
      for (size_t q = 0; q < bk->n; q++) {
        put_f32(o + 14 + 8 * q, p[2 * q] / u);
        put_f32(o + 18 + 8 * q, p[2 * q + 1] / u);
      }
      w->o.n += 14 + 8 * bk->n;
    }
  }
  return GR_OK;
}

int gr_cli_write_layer(gr_cli_writer *w, const gr_layer *l, gr_err *e) {
  double u = w->h.units;
  if (w->h.binary) {
    if (binary_layer(w, l, e)) return e->code;
  } else {
    if (putf(w, e, "$$LAYER/%.6f\n", l->z / u)) return e->code;
    for (size_t b = 0; b < l->nb; b++) {
      const gr_block *bk = &l->b[b];
      const double *p = l->xy + 2 * bk->start;
      int id = gr_style_id(bk);
      if (bk->shape == GR_SEGMENTS) {
        if (putf(w, e, "$$HATCHES/%d,%zu", id, bk->n / 2)) return e->code;
      } else {
        if (putf(w, e, "$$POLYLINE/%d,%d,%zu", id, bk->shape == GR_OPEN ? 2 : bk->dir, bk->n)) return e->code;
      }
      if (reserve(w, 82 * bk->n + 1, e)) return e->code;
      char *o = w->o.buf + w->o.n;
      for (size_t q = 0; q < 2 * bk->n; q++) {
        *o++ = ',';
        o += fmt_fixed4(o, p[q] / u);
      }
      *o++ = '\n';
      w->o.n = (size_t)(o - w->o.buf);
    }
  }
  w->layers_written++;
  return GR_OK;
}

int gr_cli_close(gr_cli_writer *w, int commit, gr_err *e) {
  if (!w) return GR_OK;
  int rc = GR_OK;
  if (commit && !w->h.binary) rc = putf(w, e, "$$GEOMETRYEND\n");
  int crc = gr_outbuf_close(&w->o, commit && !rc, e);
  free(w);
  if (!rc) rc = crc;
  return rc;
}

void gr_cli_rounded(const gr_cli_writer *w, long *points, long *vectors) {
  *points = w->rounded_points;
  *vectors = w->rounded_vectors;
}

const char *gr_cli_form(const gr_cli_writer *w) {
  if (!w || !w->h.binary) return "ascii";
  return !w->shorts ? "long" : w->longs ? "short+long" : "short";
}
