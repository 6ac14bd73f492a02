/* cli.c: CLI 2.0 writer and reader, see cli.h. */
#define _GNU_SOURCE /* O_DIRECT, memmem */
#include "cli.h"
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <limits.h>
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

/* Output goes through a second descriptor on the temporary file opened with
 * O_DIRECT where the file system allows it: whole 4 KiB blocks from an
 * aligned buffer go straight to the disk instead of being copied into the
 * page cache (on this machine 2.3 GB/s instead of 0.4-1.4 GB/s, and a
 * gigabyte-scale CLI no longer floods the cache). The last partial block is
 * written after clearing O_DIRECT. Without O_DIRECT (tmpfs, some network
 * file systems) the same code writes through the page cache. */
#define CLI_ALIGN 4096

struct gr_cli_writer {
  gr_atomic a;
  gr_cli_header h;
  int fd;         /* writes go here (O_DIRECT when `direct`) */
  int direct;
  char *buf;      /* output buffer, CLI_ALIGN-aligned */
  size_t n, cap;
  int layers_written;
};

static const char *const KIND[GR_NKINDS] = {"contour", "hatch", "edge"};

static int write_all(gr_cli_writer *w, const char *p, size_t k, gr_err *e) {
  while (k > 0) {
    ssize_t r = write(w->fd, p, k);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0 && errno == EINVAL && w->direct) { /* the file system refuses direct I/O after all */
      w->direct = 0;
      fcntl(w->fd, F_SETFL, fcntl(w->fd, F_GETFL) & ~O_DIRECT);
      continue;
    }
    if (r <= 0) return gr_fail(e, GR_EIO, "cannot write %s: %s", w->a.path, strerror(r < 0 ? errno : ENOSPC));
    p += r;
    k -= (size_t)r;
  }
  return GR_OK;
}

/* Write the buffer out; with `all` == 0 and direct I/O only whole blocks go,
 * the rest (< CLI_ALIGN bytes) moves to the buffer's start. */
static int flush_some(gr_cli_writer *w, int all, gr_err *e) {
  size_t k = w->n;
  if (w->direct) {
    if (all) {
      fcntl(w->fd, F_SETFL, fcntl(w->fd, F_GETFL) & ~O_DIRECT);
      w->direct = 0;
    } else {
      k -= k % CLI_ALIGN;
    }
  }
  if (write_all(w, w->buf, k, e)) return e->code;
  memmove(w->buf, w->buf + k, w->n - k);
  w->n -= k;
  return GR_OK;
}

static int reserve(gr_cli_writer *w, size_t k, gr_err *e) {
  if (w->n + k <= w->cap) return GR_OK;
  if (flush_some(w, 0, e)) return e->code;
  if (w->n + k > w->cap) {
    size_t cap = (w->n + k + CLI_ALIGN - 1) / CLI_ALIGN * CLI_ALIGN;
    void *nb = NULL;
    if (posix_memalign(&nb, CLI_ALIGN, cap)) return gr_fail(e, GR_EMEM, "out of memory");
    memcpy(nb, w->buf, w->n);
    free(w->buf);
    w->buf = nb;
    w->cap = cap;
  }
  return GR_OK;
}

static int put(gr_cli_writer *w, const void *p, size_t k, gr_err *e) {
  if (reserve(w, k, e)) return e->code;
  memcpy(w->buf + w->n, p, k);
  w->n += k;
  return GR_OK;
}

static int putf(gr_cli_writer *w, gr_err *e, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
#include <stdarg.h>
static int putf(gr_cli_writer *w, gr_err *e, const char *fmt, ...) {
  if (reserve(w, 512, e)) return e->code;
  va_list ap;
  va_start(ap, fmt);
  int k = vsnprintf(w->buf + w->n, w->cap - w->n, fmt, ap);
  va_end(ap);
  if (k < 0 || (size_t)k >= w->cap - w->n) return gr_fail(e, GR_EARG, "CLI line too long");
  w->n += (size_t)k;
  return GR_OK;
}

gr_cli_writer *gr_cli_open(const char *path, const gr_cli_header *h, gr_err *e) {
  if (!(h->units > 0)) return gr_fail(e, GR_EARG, "CLI units must be > 0 mm, got %g", h->units), NULL;
  gr_cli_writer *w = calloc(1, sizeof *w);
  if (!w) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  w->h = *h;
  w->cap = 4 << 20;
  void *buf = NULL;
  if (posix_memalign(&buf, CLI_ALIGN, w->cap)) { free(w); return gr_fail(e, GR_EMEM, "out of memory"), NULL; }
  w->buf = buf;
  if (gr_atomic_open(&w->a, path, e)) { free(w->buf); free(w); return NULL; }
  w->fd = h->buffered ? -1 : open(w->a.tmp, O_WRONLY | O_DIRECT);
  w->direct = w->fd >= 0;
  if (w->fd < 0) w->fd = fileno(w->a.fp); /* no direct I/O here: the stream's descriptor, unbuffered use */
  time_t now = time(NULL);
  struct tm tm;
  gmtime_r(&now, &tm);
  int rc = putf(w, e, "$$HEADERSTART\n%s\n$$UNITS/%.9g\n$$VERSION/200\n", h->binary ? "$$BINARY" : "$$ASCII", h->units);
  for (int l = 0; l < (h->nlasers > 0 ? h->nlasers : 1) && !rc; l++)
    for (int k = 0; k < GR_NKINDS && !rc; k++) rc = putf(w, e, "$$LABEL/%d,laser%d-%s\n", l * 3 + k + 1, l + 1, KIND[k]);
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

int gr_cli_write_layer(gr_cli_writer *w, const gr_layer *l, gr_err *e) {
  double u = w->h.units;
  if (w->h.binary) {
    unsigned char hd[16];
    put_u16(hd, 127);
    put_f32(hd + 2, l->z / u);
    if (put(w, hd, 6, e)) return e->code;
    for (size_t b = 0; b < l->nb; b++) {
      const gr_block *bk = &l->b[b];
      const double *p = l->xy + 2 * bk->start;
      int id = bk->laser * 3 + bk->kind + 1;
      if (bk->shape == GR_SEGMENTS) {
        size_t ns = bk->n / 2;
        if (reserve(w, 10 + 16 * ns, e)) return e->code;
        unsigned char *o = (unsigned char *)w->buf + w->n;
        put_u16(o, 132);
        put_i32(o + 2, id);
        put_i32(o + 6, (int32_t)ns);
        for (size_t q = 0; q < 2 * ns; q++) {
          put_f32(o + 10 + 8 * q, p[2 * q] / u);
          put_f32(o + 14 + 8 * q, p[2 * q + 1] / u);
        }
        w->n += 10 + 16 * ns;
      } else {
        if (reserve(w, 14 + 8 * bk->n, e)) return e->code;
        unsigned char *o = (unsigned char *)w->buf + w->n;
        put_u16(o, 130);
        put_i32(o + 2, id);
        put_i32(o + 6, bk->shape == GR_OPEN ? 2 : bk->dir);
        put_i32(o + 10, (int32_t)bk->n);
        for (size_t q = 0; q < bk->n; q++) {
          put_f32(o + 14 + 8 * q, p[2 * q] / u);
          put_f32(o + 18 + 8 * q, p[2 * q + 1] / u);
        }
        w->n += 14 + 8 * bk->n;
      }
    }
  } else {
    if (putf(w, e, "$$LAYER/%.6f\n", l->z / u)) return e->code;
    for (size_t b = 0; b < l->nb; b++) {
      const gr_block *bk = &l->b[b];
      const double *p = l->xy + 2 * bk->start;
      int id = bk->laser * 3 + bk->kind + 1;
      if (bk->shape == GR_SEGMENTS) {
        if (putf(w, e, "$$HATCHES/%d,%zu", id, bk->n / 2)) return e->code;
      } else {
        if (putf(w, e, "$$POLYLINE/%d,%d,%zu", id, bk->shape == GR_OPEN ? 2 : bk->dir, bk->n)) return e->code;
      }
      if (reserve(w, 82 * bk->n + 1, e)) return e->code;
      char *o = w->buf + w->n;
      for (size_t q = 0; q < 2 * bk->n; q++) {
        *o++ = ',';
        o += fmt_fixed4(o, p[q] / u);
      }
      *o++ = '\n';
      w->n = (size_t)(o - w->buf);
    }
  }
  w->layers_written++;
  return GR_OK;
}

int gr_cli_close(gr_cli_writer *w, int commit, gr_err *e) {
  if (!w) return GR_OK;
  int rc = GR_OK;
  if (commit) {
    if (!w->h.binary) rc = putf(w, e, "$$GEOMETRYEND\n");
    if (!rc) rc = flush_some(w, 1, e);
  }
  if (w->fd >= 0 && w->fd != fileno(w->a.fp) && close(w->fd) && !rc && commit)
    rc = gr_fail(e, GR_EIO, "cannot write %s: %s", w->a.path, strerror(errno));
  if (commit && !rc) rc = gr_atomic_commit(&w->a, e);
  else gr_atomic_abort(&w->a);
  free(w->buf);
  free(w);
  return rc;
}

/* ---- reader ---- */
/* The file is mapped; pages already parsed are given back every 64 MiB so
 * that reading a multi-gigabyte CLI keeps a bounded resident set. */
static void drop_parsed(const char *base, size_t *dropped, size_t pos) {
  size_t pg = (size_t)sysconf(_SC_PAGESIZE), upto = pos / pg * pg;
  if (upto - *dropped < ((size_t)64 << 20)) return;
  madvise((void *)(base + *dropped), upto - *dropped, MADV_DONTNEED);
  *dropped = upto;
}

static int layer_block(gr_layer *l, int shape, int id, int dir, const double *xy, size_t n) {
  int kind = GR_EDGE, laser = 0; /* ids below 1 (even INT_MIN: no id - 1) */
  if (id >= 1) kind = (id - 1) % 3, laser = (id - 1) / 3;
  return gr_layer_add(l, shape, kind, laser, dir, xy, n);
}

static int read_ascii(const char *path, const char *t, size_t len, size_t pos, int line0, gr_cli_header *h,
                      gr_cli_layer_fn fn, void *ud, gr_err *e) {
  gr_layer *l = gr_layer_new(0);
  double *xy = NULL;
  char *s = NULL; /* the current line, NUL-terminated (the mapped file is not) */
  size_t cap = 0, scap = 0, dropped = 0;
  int line = 1, have = 0, rc = GR_OK;
  if (line0 > 0) line = line0;
  else for (size_t i = 0; i < pos; i++) if (t[i] == '\n') line++;
  while (pos < len && rc == GR_OK) {
    const char *nl = memchr(t + pos, '\n', len - pos);
    size_t end = nl ? (size_t)(nl - t) : len, n = end - pos;
    if (gr_grow(&s, &scap, n + 1, 1)) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    memcpy(s, t + pos, n);
    s[n] = 0;
    if (n >= 8 && !strncmp(s, "$$LAYER/", 8)) {
      if (have) rc = fn(ud, l, e);
      drop_parsed(t, &dropped, pos);
      gr_layer_clear(l, strtod(s + 8, NULL) * h->units);
      have = 1;
    } else if ((n >= 11 && !strncmp(s, "$$POLYLINE/", 11)) || (n >= 10 && !strncmp(s, "$$HATCHES/", 10))) {
      int poly = s[2] == 'P';
      const char *c = s + (poly ? 11 : 10);
      char *q;
      long id = strtol(c, &q, 10), dir = 0;
      if (q == c || *q != ',') { rc = gr_fail(e, GR_EPARSE, "%s:%d: bad id", path, line); break; }
      if (poly) { c = q + 1; dir = strtol(c, &q, 10); if (q == c || *q != ',') { rc = gr_fail(e, GR_EPARSE, "%s:%d: bad direction", path, line); break; } }
      c = q + 1;
      long cnt = strtol(c, &q, 10);
      if (q == c || cnt < 0) { rc = gr_fail(e, GR_EPARSE, "%s:%d: bad count", path, line); break; }
      size_t npts = poly ? (size_t)cnt : 2 * (size_t)cnt;
      /* each coordinate takes at least 2 bytes of the line (",5"): a count
       * the line cannot hold is refused before anything is allocated */
      if ((size_t)cnt > n / 4 || 4 * npts > n) { rc = gr_fail(e, GR_EPARSE, "%s:%d: count %ld exceeds what the line's %zu bytes can hold", path, line, cnt, n); break; }
      if (gr_grow(&xy, &cap, npts + 1, 2 * sizeof(double))) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
      for (size_t k = 0; k < 2 * npts; k++) {
        if (*q != ',') { rc = gr_fail(e, GR_EPARSE, "%s:%d: %zu coordinates expected, found %zu", path, line, 2 * npts, k); break; }
        c = q + 1;
        xy[k] = strtod(c, &q) * h->units;
        if (q == c) { rc = gr_fail(e, GR_EPARSE, "%s:%d: bad number at coordinate %zu", path, line, k + 1); break; }
      }
      if (rc) break;
      if (*q == ',') { rc = gr_fail(e, GR_EPARSE, "%s:%d: more coordinates than the count %ld", path, line, cnt); break; }
      if (!have) { rc = gr_fail(e, GR_EPARSE, "%s:%d: geometry before the first $$LAYER", path, line); break; }
      if (npts && layer_block(l, poly ? (dir == 2 ? GR_OPEN : GR_CLOSED) : GR_SEGMENTS, (int)id, poly ? (int)dir : 2, xy, npts))
        rc = gr_fail(e, GR_EMEM, "out of memory");
    } else if (n >= 13 && !strncmp(s, "$$GEOMETRYEND", 13)) {
      break;
    } else if (n > 0 && strncmp(s, "$$", 2) && strspn(s, " \t\r") != n) {
      rc = gr_fail(e, GR_EPARSE, "%s:%d: unknown line '%.40s'", path, line, s);
    }
    pos = end + 1;
    line++;
  }
  if (rc == GR_OK && have) rc = fn(ud, l, e);
  free(xy);
  free(s);
  gr_layer_free(l);
  return rc;
}

static unsigned rd_u16(const unsigned char *p) { return p[0] | (p[1] << 8); }
static int32_t rd_i32(const unsigned char *p) { return (int32_t)((uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24)); }
static double rd_f32(const unsigned char *p) { uint32_t u = (uint32_t)rd_i32(p); float f; memcpy(&f, &u, 4); return f; }

static int read_binary(const char *path, const unsigned char *t, size_t len, size_t pos, gr_cli_header *h,
                       gr_cli_layer_fn fn, void *ud, gr_err *e) {
  gr_layer *l = gr_layer_new(0);
  double *xy = NULL;
  size_t cap = 0, dropped = 0;
  int have = 0, rc = GR_OK;
  while (pos < len && rc == GR_OK) {
    if (len - pos < 2) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated command", path, pos); break; }
    unsigned cmd = rd_u16(t + pos);
    size_t at = pos;
    pos += 2;
    if (cmd == 127) {
      if (len - pos < 4) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated layer", path, at); break; }
      if (have) rc = fn(ud, l, e);
      drop_parsed((const char *)t, &dropped, at);
      gr_layer_clear(l, rd_f32(t + pos) * h->units);
      have = 1;
      pos += 4;
    } else if (cmd == 130 || cmd == 132) {
      int poly = cmd == 130;
      size_t hd = poly ? 12 : 8;
      if (len - pos < hd) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated %s", path, at, poly ? "polyline" : "hatches"); break; }
      int id = rd_i32(t + pos), dir = poly ? rd_i32(t + pos + 4) : 0;
      int32_t cnt = rd_i32(t + pos + (poly ? 8 : 4));
      pos += hd;
      size_t npts = poly ? (size_t)cnt : 2 * (size_t)cnt;
      if (cnt < 0 || (len - pos) / 8 < npts) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: %s of %d points runs past the end of the file", path, at, poly ? "polyline" : "hatches", cnt); break; }
      if (!have) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: geometry before the first layer", path, at); break; }
      if (gr_grow(&xy, &cap, npts + 1, 2 * sizeof(double))) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
      for (size_t k = 0; k < 2 * npts; k++) xy[k] = rd_f32(t + pos + 4 * k) * h->units;
      pos += 8 * npts;
      if (npts && layer_block(l, poly ? (dir == 2 ? GR_OPEN : GR_CLOSED) : GR_SEGMENTS, id, poly ? dir : 2, xy, npts))
        rc = gr_fail(e, GR_EMEM, "out of memory");
    } else {
      rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: unknown command %u", path, at, cmd);
    }
  }
  if (rc == GR_OK && have) rc = fn(ud, l, e);
  free(xy);
  gr_layer_free(l);
  return rc;
}

/* The file is mapped, not read into memory, so that a multi-gigabyte CLI
 * costs page cache, not heap; layers are handed to fn one at a time. */
int gr_cli_read(const char *path, gr_cli_header *h, gr_cli_layer_fn fn, void *ud, gr_err *e) {
  return gr_cli_read_from(path, 0, 0, h, fn, ud, e);
}

int gr_cli_read_from(const char *path, size_t from, int from_line, gr_cli_header *h, gr_cli_layer_fn fn, void *ud,
                     gr_err *e) {
  FILE *f = fopen(path, "rb");
  if (!f) return gr_fail(e, GR_EIO, "cannot read %s: %s", path, strerror(errno));
  struct stat stt;
  if (fstat(fileno(f), &stt) || !S_ISREG(stt.st_mode)) {
    fclose(f);
    return gr_fail(e, GR_EIO, "cannot read %s: not a regular file", path);
  }
  size_t len = (size_t)stt.st_size;
  void *map = len ? mmap(NULL, len, PROT_READ, MAP_PRIVATE, fileno(f), 0) : NULL;
  fclose(f);
  if (len && map == MAP_FAILED) return gr_fail(e, GR_EIO, "cannot map %s: %s", path, strerror(errno));
  if (map) madvise(map, len, MADV_SEQUENTIAL);
  const char *t = map;
  *h = gr_cli_header_defaults();
  h->layers = -1;
  const char *he = len >= 13 ? memmem(t, len - 2, "$$HEADEREND", 11) : NULL;
  int rc = GR_OK;
  if (len < 14 || memcmp(t, "$$HEADERSTART", 13) || !he) {
    rc = gr_fail(e, GR_EPARSE, "%s:1: not a CLI file (no $$HEADERSTART ... $$HEADEREND)", path);
    goto done;
  }
  int binary = 0, line = 1;
  for (const char *hl = t; hl < he; hl++) {
    if (*hl == '\n') { line++; continue; }
    if (hl != t && hl[-1] != '\n') continue;
    /* a NUL-terminated copy of the line: the mapped file has no NUL, and
     * sscanf would otherwise measure the whole file (or run past its end) */
    char c[256];
    size_t k = 0;
    while (k + 1 < sizeof c && hl + k < he && hl[k] != '\n') { c[k] = hl[k]; k++; }
    c[k] = 0;
    if (!strncmp(c, "$$BINARY", 8)) binary = 1;
    else if (!strncmp(c, "$$UNITS/", 8)) {
      h->units = strtod(c + 8, NULL);
      if (!(h->units > 0)) { rc = gr_fail(e, GR_EPARSE, "%s:%d: bad $$UNITS", path, line); goto done; }
    } else if (!strncmp(c, "$$LAYERS/", 9)) {
      long nl = strtol(c + 9, NULL, 10); /* atoi is undefined out of range */
      h->layers = nl < 0 ? -1 : nl > INT_MAX ? INT_MAX : (int)nl;
    }
    else if (!strncmp(c, "$$DIMENSION/", 12))
      sscanf(c + 12, "%lf,%lf,%lf,%lf,%lf,%lf", &h->lo[0], &h->lo[1], &h->lo[2], &h->hi[0], &h->hi[1], &h->hi[2]);
  }
  h->binary = binary;
  size_t pos = (size_t)(he - t) + 11;
  int at = from > pos && from < len;
  if (at) pos = from;
  if (binary) {
    rc = read_binary(path, (const unsigned char *)t, len, pos, h, fn, ud, e);
  } else {
    if (!at) {
      const char *g = memmem(t + pos, len - pos, "$$GEOMETRYSTART", 15);
      if (!g) { rc = gr_fail(e, GR_EPARSE, "%s: no $$GEOMETRYSTART", path); goto done; }
      pos = (size_t)(g - t);
      while (pos < len && t[pos] != '\n') pos++;
      pos++;
    }
    rc = read_ascii(path, t, len, pos, at ? from_line : 0, h, fn, ud, e);
  }
done:
  if (map) munmap(map, len);
  return rc;
}
