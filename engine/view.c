/* view.c: layer index of a CLI file and the viewer's layer encoding, see view.h. */
#define _GNU_SOURCE /* memmem */
#include "view.h"
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#define VIEW_STOP 1000 /* callback code: the layer wanted has been seen */

static int stop_at_first(void *ud, const gr_layer *l, gr_err *e) {
  (void)ud, (void)l, (void)e;
  return VIEW_STOP;
}

static int add_layer(gr_view_index *ix, size_t at, int line, double z, gr_err *e) {
  if (gr_grow(&ix->layer, &ix->cap, ix->n + 1, sizeof *ix->layer)) return gr_fail(e, GR_EMEM, "out of memory");
  ix->layer[ix->n++] = (gr_view_entry){at, line, z};
  return GR_OK;
}

/* Give back the pages already scanned (every 16 MiB), so that indexing a
 * file of many gigabytes keeps a small resident set. */
static void release(const unsigned char *base, size_t *done, size_t pos) {
  size_t pg = (size_t)sysconf(_SC_PAGESIZE), upto = pos / pg * pg;
  if (upto - *done < ((size_t)16 << 20)) return;
  madvise((void *)(base + *done), upto - *done, MADV_DONTNEED);
  *done = upto;
}

static unsigned u16at(const unsigned char *p) { return p[0] | (p[1] << 8); }
static uint32_t u32at(const unsigned char *p) {
  return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* Binary geometry: walk the commands by their sizes (CLI 2.0: 127/128 layer,
 * 129/130 polyline, 131/132 hatches, short and long). */
static int scan_binary(gr_view_index *ix, const unsigned char *t, size_t len, size_t pos, gr_err *e) {
  size_t done = 0;
  while (pos < len) {
    size_t at = pos, need;
    if (len - pos < 2) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated command", ix->path, at);
    unsigned cmd = u16at(t + pos);
    pos += 2;
    size_t left = len - pos;
    if (cmd == 127 || cmd == 128) {
      need = cmd == 127 ? 4 : 2;
      if (left < need) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated layer", ix->path, at);
      double z;
      if (cmd == 127) {
        uint32_t u = u32at(t + pos);
        float f;
        memcpy(&f, &u, 4);
        z = f;
      } else {
        z = u16at(t + pos);
      }
      if (add_layer(ix, at, 0, z * ix->h.units, e)) return e->code;
      release(t, &done, at);
    } else if (cmd >= 129 && cmd <= 132) {
      int lng = cmd == 130 || cmd == 132, poly = cmd <= 130;
      size_t w = lng ? 4 : 2, hd = (poly ? 3 : 2) * w;
      if (left < hd) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated %s", ix->path, at, poly ? "polyline" : "hatches");
      size_t cnt = lng ? u32at(t + pos + hd - 4) : u16at(t + pos + hd - 2);
      if (lng && (int32_t)cnt < 0) return gr_fail(e, GR_EPARSE, "%s: byte %zu: negative count", ix->path, at);
      need = hd + cnt * (poly ? 2 : 4) * w;
      if (left < need)
        return gr_fail(e, GR_EPARSE, "%s: byte %zu: %s of %zu points runs past the end of the file", ix->path, at,
                       poly ? "polyline" : "hatches", cnt);
      if (!ix->n) return gr_fail(e, GR_EPARSE, "%s: byte %zu: geometry before the first layer", ix->path, at);
    } else {
      return gr_fail(e, GR_EPARSE, "%s: byte %zu: unknown command %u", ix->path, at, cmd);
    }
    pos += need;
  }
  return GR_OK;
}

/* ASCII geometry: every line starting "$$LAYER/" up to $$GEOMETRYEND. */
static int scan_ascii(gr_view_index *ix, const unsigned char *t, size_t len, size_t pos, gr_err *e) {
  const unsigned char *g = memmem(t + pos, len - pos, "$$GEOMETRYSTART", 15);
  if (!g) return gr_fail(e, GR_EPARSE, "%s: no $$GEOMETRYSTART", ix->path);
  int line = 1;
  for (const unsigned char *q = t; q < g; q++) line += *q == '\n';
  size_t done = 0;
  for (pos = (size_t)(g - t); pos < len; line++) {
    const unsigned char *nl = memchr(t + pos, '\n', len - pos);
    size_t end = nl ? (size_t)(nl - t) : len;
    if (end - pos >= 8 && !memcmp(t + pos, "$$LAYER/", 8)) {
      char c[64];
      size_t k = end - pos - 8 < sizeof c - 1 ? end - pos - 8 : sizeof c - 1;
      memcpy(c, t + pos + 8, k);
      c[k] = 0;
      char *q;
      double z = strtod(c, &q);
      if (q == c) return gr_fail(e, GR_EPARSE, "%s:%d: bad $$LAYER height", ix->path, line);
      if (add_layer(ix, pos, line, z * ix->h.units, e)) return e->code;
      release(t, &done, pos);
    } else if (end - pos >= 13 && !memcmp(t + pos, "$$GEOMETRYEND", 13)) {
      break;
    }
    pos = end + 1;
  }
  return GR_OK;
}

static int scan(gr_view_index *ix, gr_err *e) {
  int fd = open(ix->path, O_RDONLY);
  if (fd < 0) return gr_fail(e, GR_EIO, "cannot read %s: %s", ix->path, strerror(errno));
  struct stat st;
  if (fstat(fd, &st)) { close(fd); return gr_fail(e, GR_EIO, "cannot read %s: %s", ix->path, strerror(errno)); }
  size_t len = (size_t)st.st_size;
  ix->bytes = len;
  void *map = len ? mmap(NULL, len, PROT_READ, MAP_PRIVATE, fd, 0) : MAP_FAILED;
  close(fd);
  if (map == MAP_FAILED) return gr_fail(e, GR_EIO, "cannot map %s: %s", ix->path, strerror(errno));
  madvise(map, len, MADV_SEQUENTIAL);
  const unsigned char *t = map, *he = memmem(t, len, "$$HEADEREND", 11);
  int rc = !he ? gr_fail(e, GR_EPARSE, "%s:1: not a CLI file (no $$HEADEREND)", ix->path)
       : ix->h.binary ? scan_binary(ix, t, len, (size_t)(he - t) + 11, e)
       : scan_ascii(ix, t, len, (size_t)(he - t) + 11, e);
  munmap(map, len);
  return rc;
}

gr_view_index *gr_view_index_open(const char *path, gr_err *e) {
  gr_view_index *ix = calloc(1, sizeof *ix);
  if (!ix || !(ix->path = strdup(path))) { free(ix); return gr_fail(e, GR_EMEM, "out of memory"), NULL; }
  /* the header as the reader understands it (it stops at the first layer) */
  int rc = gr_cli_read(path, &ix->h, stop_at_first, NULL, e);
  if (rc == VIEW_STOP || rc == GR_OK) rc = scan(ix, e);
  if (rc == GR_OK && ix->n == 0) rc = gr_fail(e, GR_EPARSE, "%s: no layers in the file", path);
  if (rc) { gr_view_index_free(ix); return NULL; }
  return ix;
}

void gr_view_index_free(gr_view_index *ix) {
  if (!ix) return;
  free(ix->path);
  free(ix->layer);
  free(ix);
}

typedef struct one_layer { gr_cli_layer_fn fn; void *ud; int seen; } one_layer;

static int take_one(void *ud, const gr_layer *l, gr_err *e) {
  one_layer *o = ud;
  o->seen = 1;
  int rc = o->fn(o->ud, l, e);
  return rc ? rc : VIEW_STOP;
}

int gr_view_layer(const gr_view_index *ix, size_t k, gr_cli_layer_fn fn, void *ud, gr_err *e) {
  if (k >= ix->n) return gr_fail(e, GR_EARG, "layer %zu is out of range: %s has %zu layers", k + 1, ix->path, ix->n);
  one_layer o = {fn, ud, 0};
  gr_cli_header h;
  int rc = gr_cli_read_from(ix->path, ix->layer[k].at, ix->layer[k].line, &h, take_one, &o, e);
  if (rc == VIEW_STOP) rc = GR_OK;
  if (rc == GR_OK && !o.seen) rc = gr_fail(e, GR_EIO, "%s: layer %zu is gone (the file changed?)", ix->path, k + 1);
  return rc;
}

/* ---- encoding ---- */
static int reserve(gr_view_buf *b, size_t k, gr_err *e) {
  if (gr_grow(&b->p, &b->cap, b->n + k, 1)) return gr_fail(e, GR_EMEM, "out of memory");
  return GR_OK;
}

static void put_u(gr_view_buf *b, uint64_t v) {
  while (v >= 128) { b->p[b->n++] = (unsigned char)(v | 128); v >>= 7; }
  b->p[b->n++] = (unsigned char)v;
}
static void put_s(gr_view_buf *b, int64_t v) { put_u(b, ((uint64_t)v << 1) ^ (uint64_t)(v >> 63)); }

#define VIEW_MAXQ 1125899906842624.0 /* 2^50 quanta: exact in a JavaScript number after zigzag */

static int quant(double x, double q, int64_t *out, gr_err *e) {
  double v = x / q;
  if (!(fabs(v) < VIEW_MAXQ)) return gr_fail(e, GR_ENUM, "coordinate %g mm cannot be encoded (not finite or too large)", x);
  *out = llround(v);
  return GR_OK;
}

int gr_view_encode(const gr_layer *l, double quantum, gr_view_buf *b, gr_err *e) {
  if (!(quantum > 0)) return gr_fail(e, GR_EARG, "quantum must be > 0 mm, got %g", quantum);
  int64_t zq = 0, px = 0, py = 0;
  if (quant(l->z, quantum, &zq, e) || reserve(b, 20 + 60 * l->nb + 20 * l->npts, e)) return e->code;
  put_u(b, 1);
  put_s(b, zq);
  put_u(b, l->nb);
  for (size_t i = 0; i < l->nb; i++) {
    const gr_block *bk = &l->b[i];
    put_s(b, gr_style_id(bk));
    put_u(b, (uint64_t)bk->kind);
    put_u(b, (uint64_t)bk->laser);
    put_u(b, (uint64_t)bk->shape);
    put_s(b, bk->dir);
    put_u(b, bk->n);
  }
  for (size_t i = 0; i < l->nb; i++) {
    const double *p = l->xy + 2 * l->b[i].start;
    for (size_t k = 0; k < l->b[i].n; k++) {
      int64_t x = 0, y = 0;
      if (quant(p[2 * k], quantum, &x, e) || quant(p[2 * k + 1], quantum, &y, e)) return e->code;
      put_s(b, x - px);
      put_s(b, y - py);
      px = x, py = y;
    }
  }
  return GR_OK;
}

char *gr_view_base64(const unsigned char *p, size_t n, size_t *outlen) {
  static const char A[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  size_t m = (n + 2) / 3 * 4;
  char *o = malloc(m + 1), *q = o;
  if (!o) return NULL;
  size_t i = 0;
  for (; i + 2 < n; i += 3) {
    uint32_t v = (uint32_t)p[i] << 16 | (uint32_t)p[i + 1] << 8 | p[i + 2];
    *q++ = A[v >> 18], *q++ = A[(v >> 12) & 63], *q++ = A[(v >> 6) & 63], *q++ = A[v & 63];
  }
  if (i < n) {
    uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0);
    *q++ = A[v >> 18], *q++ = A[(v >> 12) & 63];
    *q++ = i + 1 < n ? A[(v >> 6) & 63] : '=';
    *q++ = '=';
  }
  *q = 0;
  if (outlen) *outlen = m;
  return o;
}
