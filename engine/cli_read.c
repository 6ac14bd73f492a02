/* cli_read.c: the machine-file reader of cli.h: CLI 2.0 in ASCII and binary
 * (long commands 127/130/132 and short commands 128/129/131), the header's
 * labels and the ASCII parameter commands; OVF files are handed to ovf.c.
 * Every count is checked against the bytes left before anything is
 * allocated, so a malformed file gives an error naming the file and the line
 * (ASCII) or byte offset (binary), never a crash. */
#define _GNU_SOURCE /* memmem */
#include "cli.h"
#include "ovf.h"
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const KIND[GR_NKINDS] = {"contour", "hatch", "edge"};

static int same(double a, double b) { return (isnan(a) && isnan(b)) || a == b; }

int gr_cli_style_index(gr_cli_header *h, int id, double power, double speed, double focus) {
  for (int i = 0; i < h->nstyles; i++) {
    const gr_cli_style *s = &h->style[i];
    if (s->id == id && same(s->power, power) && same(s->speed, speed) && same(s->focus, focus)) return i;
  }
  if (h->nstyles >= GR_CLI_MAXSTYLES) return -1;
  gr_cli_style *s = &h->style[h->nstyles];
  s->id = id;
  s->power = power;
  s->speed = speed;
  s->focus = focus;
  s->jump_speed = NAN;
  s->name[0] = 0;
  for (int i = 0; i < h->nlabels; i++)
    if (h->label[i].id == id) {
      size_t k = strnlen(h->label[i].text, sizeof h->label[i].text - 1);
      memcpy(s->name, h->label[i].text, k); /* both arrays live in h: no snprintf (restrict) */
      s->name[k] = 0;
    }
  if (!s->name[0]) snprintf(s->name, sizeof s->name, "laser%d-%s", id >= 1 ? (id - 1) / 3 + 1 : 1,
                            KIND[id >= 1 ? (id - 1) % 3 : GR_EDGE]);
  return h->nstyles++;
}

/* The file is mapped; pages already parsed are given back every 64 MiB so
 * that reading a multi-gigabyte CLI keeps a bounded resident set (a no-op on
 * memory that is not a mapping). */
static void drop_parsed(const char *base, size_t *dropped, size_t pos, int mapped) {
  size_t pg = (size_t)sysconf(_SC_PAGESIZE), upto = pos / pg * pg;
  if (!mapped || upto - *dropped < ((size_t)64 << 20)) return;
  madvise((void *)(base + *dropped), upto - *dropped, MADV_DONTNEED);
  *dropped = upto;
}

/* What the two CLI parsers share: the layer being filled, each block's
 * style, and the parameters in force. */
typedef struct rd {
  const char *path;
  gr_cli_header *h;
  gr_cli_layer_ex_fn fn;
  void *ud;
  gr_layer *l;
  int *style;
  size_t capstyle;
  double *xy;
  size_t capxy;
  double power, speed, focus; /* ASCII $$POWER, $$SPEED, $$FOCUS in force (NaN: none) */
  int have, mapped;
  int line0;          /* line number at the start position (0: count it) */
  size_t dropped;
} rd;

static int rd_flush(rd *r, gr_err *e) { return r->have ? r->fn(r->ud, r->l, r->style, r->h, e) : GR_OK; }

/* Append the block of n points r->xy with CLI id and direction. */
static int rd_block(rd *r, int shape, int id, int dir, size_t n, gr_err *e) {
  if (n == 0) return GR_OK; /* an empty polyline or hatch block holds nothing to scan: skipped */
  int kind = id >= 1 ? (id - 1) % 3 : GR_EDGE, laser = id >= 1 ? (id - 1) / 3 % (GR_REGION_IDS / 3) : 0;
  int st = gr_cli_style_index(r->h, id, r->power, r->speed, r->focus);
  if (st < 0) return gr_fail(e, GR_EPARSE, "%s: more than %d build styles", r->path, GR_CLI_MAXSTYLES);
  if (gr_grow(&r->style, &r->capstyle, r->l->nb + 1, sizeof *r->style) ||
      gr_layer_add(r->l, shape, kind, laser, dir, r->xy, n))
    return gr_fail(e, GR_EMEM, "out of memory");
  r->l->b[r->l->nb - 1].region = id >= 1 ? (id - 1) / GR_REGION_IDS : 0;
  r->style[r->l->nb - 1] = st;
  return GR_OK;
}

static int shape_of(int poly, int dir) { return poly ? (dir == 2 ? GR_OPEN : GR_CLOSED) : GR_SEGMENTS; }

/* One ASCII geometry line s (NUL-terminated) of the geometry section. */
static int ascii_line(rd *r, char *s, size_t n, int line, int *end, gr_err *e) {
  const char *path = r->path;
  double u = r->h->units;
  if (n == 0 || strspn(s, " \t\r") == n || !strncmp(s, "//", 2)) return GR_OK;
  if (strncmp(s, "$$", 2)) return gr_fail(e, GR_EPARSE, "%s:%d: unknown line '%.40s'", path, line, s);
  if (!strncmp(s, "$$GEOMETRYEND", 13)) { *end = 1; return GR_OK; }
  if (!strncmp(s, "$$LAYER/", 8)) {
    char *q;
    double z = strtod(s + 8, &q);
    if (q == s + 8 || !isfinite(z)) return gr_fail(e, GR_EPARSE, "%s:%d: bad $$LAYER height", path, line);
    int rc = rd_flush(r, e);
    if (rc) return rc;
    gr_layer_clear(r->l, z * u);
    r->have = 1;
    return GR_OK;
  }
  static const char *const PARAM[3] = {"$$POWER/", "$$SPEED/", "$$FOCUS/"};
  for (int k = 0; k < 3; k++)
    if (!strncmp(s, PARAM[k], 8)) {
      char *q;
      double v = strtod(s + 8, &q);
      if (q == s + 8 || !isfinite(v)) return gr_fail(e, GR_EPARSE, "%s:%d: bad number in %.7s", path, line, s);
      *(k == 0 ? &r->power : k == 1 ? &r->speed : &r->focus) = v;
      return GR_OK;
    }
  int poly = !strncmp(s, "$$POLYLINE/", 11);
  if (!poly && strncmp(s, "$$HATCHES/", 10)) {
    size_t k = strcspn(s, "/ \r");
    return gr_fail(e, GR_EPARSE, "%s:%d: unknown command '%.*s'", path, line, (int)(k < 40 ? k : 40), s);
  }
  const char *c = s + (poly ? 11 : 10);
  char *q;
  long id = strtol(c, &q, 10), dir = 0;
  if (q == c || *q != ',') return gr_fail(e, GR_EPARSE, "%s:%d: bad id", path, line);
  if (poly) {
    c = q + 1;
    dir = strtol(c, &q, 10);
    if (q == c || *q != ',') return gr_fail(e, GR_EPARSE, "%s:%d: bad direction", path, line);
  }
  c = q + 1;
  long cnt = strtol(c, &q, 10);
  /* each coordinate takes at least two characters (",5"): a larger count cannot be on this line */
  if (q == c || cnt < 0) return gr_fail(e, GR_EPARSE, "%s:%d: bad count", path, line);
  if ((size_t)cnt > n / (poly ? 4 : 8))
    return gr_fail(e, GR_EPARSE, "%s:%d: count %ld exceeds what the line's %zu characters can hold", path, line, cnt, n);
  size_t npts = poly ? (size_t)cnt : 2 * (size_t)cnt;
  if (gr_grow(&r->xy, &r->capxy, npts + 1, 2 * sizeof(double))) return gr_fail(e, GR_EMEM, "out of memory");
  for (size_t k = 0; k < 2 * npts; k++) {
    if (*q != ',') return gr_fail(e, GR_EPARSE, "%s:%d: %zu coordinates expected, found %zu", path, line, 2 * npts, k);
    c = q + 1;
    r->xy[k] = strtod(c, &q) * u;
    if (q == c || !isfinite(r->xy[k])) return gr_fail(e, GR_EPARSE, "%s:%d: bad number at coordinate %zu", path, line, k + 1);
  }
  if (*q == ',') return gr_fail(e, GR_EPARSE, "%s:%d: more coordinates than the count %ld", path, line, cnt);
  if (!r->have) return gr_fail(e, GR_EPARSE, "%s:%d: geometry before the first $$LAYER", path, line);
  return rd_block(r, shape_of(poly, (int)dir), (int)id, poly ? (int)dir : 2, npts, e);
}

static int read_ascii(rd *r, const char *t, size_t len, size_t pos, gr_err *e) {
  char *s = NULL; /* the current line, NUL-terminated (the mapped file is not) */
  size_t scap = 0;
  int line = 1, end = 0, rc = GR_OK;
  if (r->line0 > 0) line = r->line0;
  else
    for (size_t i = 0; i < pos; i++) if (t[i] == '\n') line++;
  while (pos < len && rc == GR_OK && !end) {
    const char *nl = memchr(t + pos, '\n', len - pos);
    size_t stop = nl ? (size_t)(nl - t) : len, n = stop - pos;
    if (gr_grow(&s, &scap, n + 1, 1)) { rc = gr_fail(e, GR_EMEM, "out of memory"); break; }
    memcpy(s, t + pos, n);
    s[n] = 0;
    if (!strncmp(s, "$$LAYER/", 8)) drop_parsed(t, &r->dropped, pos, r->mapped);
    rc = ascii_line(r, s, n, line, &end, e);
    pos = stop + 1;
    line++;
  }
  if (rc == GR_OK) rc = rd_flush(r, e);
  free(s);
  return rc;
}

static unsigned rd_u16(const unsigned char *p) { return p[0] | (p[1] << 8); }
static int32_t rd_i32(const unsigned char *p) { return (int32_t)((uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24)); }
static double rd_f32(const unsigned char *p) { uint32_t u = (uint32_t)rd_i32(p); float f; memcpy(&f, &u, 4); return f; }

/* One binary geometry command (polyline or hatches, long or short) at `at`;
 * *pos is past the command word on entry and past the data on return. */
static int binary_geometry(rd *r, unsigned cmd, const unsigned char *t, size_t len, size_t at, size_t *pos, gr_err *e) {
  int poly = cmd == 129 || cmd == 130, lng = cmd == 130 || cmd == 132;
  size_t w = lng ? 4 : 2, hd = (poly ? 3 : 2) * w;
  const char *what = poly ? "polyline" : "hatches";
  if (len - *pos < hd) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated %s", r->path, at, what);
  const unsigned char *p = t + *pos;
  long id = lng ? rd_i32(p) : (long)rd_u16(p), dir = poly ? (lng ? rd_i32(p + 4) : (long)rd_u16(p + 2)) : 2;
  long cnt = lng ? rd_i32(p + hd - 4) : (long)rd_u16(p + hd - 2);
  *pos += hd;
  size_t npts = poly ? (size_t)cnt : 2 * (size_t)cnt;
  if (cnt < 0 || (len - *pos) / (2 * w) < npts)
    return gr_fail(e, GR_EPARSE, "%s: byte %zu: %s of %ld %s runs past the end of the file", r->path, at, what, cnt,
                   poly ? "points" : "lines");
  if (!r->have) return gr_fail(e, GR_EPARSE, "%s: byte %zu: geometry before the first layer", r->path, at);
  if (gr_grow(&r->xy, &r->capxy, npts + 1, 2 * sizeof(double))) return gr_fail(e, GR_EMEM, "out of memory");
  double u = r->h->units;
  p = t + *pos;
  if (lng)
    for (size_t k = 0; k < 2 * npts; k++) r->xy[k] = rd_f32(p + 4 * k) * u;
  else
    for (size_t k = 0; k < 2 * npts; k++) r->xy[k] = rd_u16(p + 2 * k) * u;
  *pos += 2 * w * npts;
  if (!lng) r->h->short_cmds++;
  return rd_block(r, shape_of(poly, (int)dir), (int)id, (int)dir, npts, e);
}

static int read_binary(rd *r, const unsigned char *t, size_t len, size_t pos, gr_err *e) {
  int rc = GR_OK;
  while (pos < len && rc == GR_OK) {
    if (len - pos < 2) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated command", r->path, pos); break; }
    unsigned cmd = rd_u16(t + pos);
    size_t at = pos;
    pos += 2;
    if (cmd == 127 || cmd == 128) {
      size_t k = cmd == 127 ? 4 : 2;
      if (len - pos < k) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated layer", r->path, at); break; }
      double z = cmd == 127 ? rd_f32(t + pos) : rd_u16(t + pos);
      if (!isfinite(z)) { rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: layer height is not a number", r->path, at); break; }
      if ((rc = rd_flush(r, e))) break;
      drop_parsed((const char *)t, &r->dropped, at, r->mapped);
      gr_layer_clear(r->l, z * r->h->units);
      if (cmd == 128) r->h->short_cmds++;
      r->have = 1;
      pos += k;
    } else if (cmd >= 129 && cmd <= 132) {
      rc = binary_geometry(r, cmd, t, len, at, &pos, e);
    } else {
      rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: unknown command %u", r->path, at, cmd);
    }
  }
  if (rc == GR_OK) rc = rd_flush(r, e);
  return rc;
}

/* The header lines between $$HEADERSTART and he: format, units, layers,
 * dimension and labels. */
static int read_header(const char *path, const char *t, const char *he, gr_cli_header *h, gr_err *e) {
  int line = 1;
  for (const char *hl = t; hl < he; hl++) {
    if (*hl == '\n') { line++; continue; }
    if (hl != t && hl[-1] != '\n') continue;
    /* a NUL-terminated copy of the line: the mapped file has no NUL, and
     * sscanf would otherwise measure the whole file (or run past its end) */
    char c[256];
    size_t k = 0;
    while (k + 1 < sizeof c && hl + k < he && hl[k] != '\n') { c[k] = hl[k]; k++; }
    c[k] = 0;
    c[strcspn(c, "\r")] = 0;
    if (!strncmp(c, "$$BINARY", 8)) h->binary = 1;
    else if (!strncmp(c, "$$UNITS/", 8)) {
      h->units = strtod(c + 8, NULL);
      if (!(h->units > 0) || !isfinite(h->units)) return gr_fail(e, GR_EPARSE, "%s:%d: bad $$UNITS", path, line);
    } else if (!strncmp(c, "$$LAYERS/", 9)) {
      long nl = strtol(c + 9, NULL, 10); /* atoi is undefined out of range */
      h->layers = nl < 0 ? -1 : nl > INT_MAX ? INT_MAX : (int)nl;
    }
    else if (!strncmp(c, "$$DIMENSION/", 12))
      sscanf(c + 12, "%lf,%lf,%lf,%lf,%lf,%lf", &h->lo[0], &h->lo[1], &h->lo[2], &h->hi[0], &h->hi[1], &h->hi[2]);
    else if (!strncmp(c, "$$LABEL/", 8) && h->nlabels < GR_CLI_MAXSTYLES) {
      char *q;
      long id = strtol(c + 8, &q, 10);
      if (q == c + 8 || *q != ',') return gr_fail(e, GR_EPARSE, "%s:%d: bad $$LABEL (id,text expected)", path, line);
      gr_cli_label *lb = &h->label[h->nlabels++];
      lb->id = (int)id;
      snprintf(lb->text, sizeof lb->text, "%s", q + 1);
    }
  }
  return GR_OK;
}

static int read_cli(rd *r, const char *t, size_t len, size_t from, gr_err *e) {
  const char *path = r->path;
  const char *he = len >= 13 ? memmem(t, len, "$$HEADEREND", 11) : NULL;
  if (len < 13 || memcmp(t, "$$HEADERSTART", 13) || !he)
    return gr_fail(e, GR_EPARSE, "%s:1: not a CLI file (no $$HEADERSTART ... $$HEADEREND at byte 0) and not an OVF file (no magic \"LVF!\")", path);
  if (read_header(path, t, he, r->h, e)) return e->code;
  size_t pos = (size_t)(he - t) + 11;
  if (from) {
    if (from < pos || from >= len) return gr_fail(e, GR_EARG, "%s: byte %zu is not in the geometry", path, from);
    return r->h->binary ? read_binary(r, (const unsigned char *)t, len, from, e) : read_ascii(r, t, len, from, e);
  }
  if (r->h->binary) return read_binary(r, (const unsigned char *)t, len, pos, e);
  const char *g = memmem(t + pos, len - pos, "$$GEOMETRYSTART", 15);
  if (!g) return gr_fail(e, GR_EPARSE, "%s: no $$GEOMETRYSTART", path);
  pos = (size_t)(g - t);
  while (pos < len && t[pos] != '\n') pos++;
  return read_ascii(r, t, len, pos + 1, e);
}

/* from > 0: the header is read, then the geometry from byte `from` on (a
 * layer command or $$LAYER line, at line `line` of an ASCII file). */
static int read_mem(const char *name, const unsigned char *t, size_t len, int mapped, size_t from, int line,
                    gr_cli_header *h, gr_cli_layer_ex_fn fn, void *ud, gr_err *e) {
  *h = gr_cli_header_defaults();
  h->layers = -1;
  if (len >= 4 && !memcmp(t, GR_OVF_MAGIC, 4)) {
    if (from) return gr_fail(e, GR_EARG, "%s: an OVF file is read through its LUTs, not from a byte offset", name);
    return gr_ovf_read_mem(name, t, len, h, fn, ud, e);
  }
  rd r;
  memset(&r, 0, sizeof r);
  r.path = name;
  r.h = h;
  r.fn = fn;
  r.ud = ud;
  r.mapped = mapped;
  r.power = r.speed = r.focus = NAN;
  r.l = gr_layer_new(0);
  r.line0 = line;
  int rc = r.l ? read_cli(&r, (const char *)t, len, from, e) : gr_fail(e, GR_EMEM, "out of memory");
  gr_layer_free(r.l);
  free(r.xy);
  free(r.style);
  return rc;
}

int gr_cli_read_mem(const char *name, const unsigned char *t, size_t len, gr_cli_header *h, gr_cli_layer_ex_fn fn,
                    void *ud, gr_err *e) {
  return read_mem(name, t, len, 0, 0, 0, h, fn, ud, e);
}

/* The file is mapped, not read into memory, so that a multi-gigabyte CLI
 * costs page cache, not heap. */
int gr_cli_map(const char *path, void **map, size_t *len, gr_err *e) {
  FILE *f = fopen(path, "rb");
  if (!f) return gr_fail(e, GR_EIO, "cannot read %s: %s", path, strerror(errno));
  struct stat stt;
  if (fstat(fileno(f), &stt) || !S_ISREG(stt.st_mode)) {
    fclose(f);
    return gr_fail(e, GR_EIO, "cannot read %s: not a regular file", path);
  }
  *len = (size_t)stt.st_size;
  *map = *len ? mmap(NULL, *len, PROT_READ, MAP_PRIVATE, fileno(f), 0) : NULL;
  fclose(f);
  if (*len && *map == MAP_FAILED) return gr_fail(e, GR_EIO, "cannot map %s: %s", path, strerror(errno));
  return GR_OK;
}

/* Layers are handed to fn one at a time. */
static int read_file(const char *path, size_t from, int line, gr_cli_header *h, gr_cli_layer_ex_fn fn, void *ud,
                     gr_err *e) {
  void *map;
  size_t len;
  if (gr_cli_map(path, &map, &len, e)) return e->code;
  if (map) madvise(map, len, from ? MADV_RANDOM : MADV_SEQUENTIAL);
  static const unsigned char none[1] = {0};
  int rc = read_mem(path, map ? map : none, len, 1, from, line, h, fn, ud, e);
  if (map) munmap(map, len);
  return rc;
}

int gr_cli_read_ex(const char *path, gr_cli_header *h, gr_cli_layer_ex_fn fn, void *ud, gr_err *e) {
  return read_file(path, 0, 0, h, fn, ud, e);
}

typedef struct plain { gr_cli_layer_fn fn; void *ud; } plain;
static int plain_layer(void *ud, const gr_layer *l, const int *style, const gr_cli_header *h, gr_err *e) {
  (void)style;
  (void)h;
  plain *p = ud;
  return p->fn(p->ud, l, e);
}

int gr_cli_read(const char *path, gr_cli_header *h, gr_cli_layer_fn fn, void *ud, gr_err *e) {
  plain p = {fn, ud};
  return gr_cli_read_ex(path, h, plain_layer, &p, e);
}

int gr_cli_read_from(const char *path, size_t from, int line, gr_cli_header *h, gr_cli_layer_fn fn, void *ud,
                     gr_err *e) {
  plain p = {fn, ud};
  return read_file(path, from, line, h, plain_layer, &p, e);
}
