/* clicat.c: merge CLI part files byte for byte (clicat.h). */
#define _GNU_SOURCE
#include "clicat.h"
#include "cli.h"
#include <errno.h>
#include <math.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct cc_part {
  const char *path;
  const char *map; /* the whole file, mapped */
  size_t len;
  size_t hdr_end;  /* just past "$$HEADEREND" */
  size_t gs, ge;   /* geometry bytes [gs, ge): the layers */
  gr_cli_header h;
  double *z;       /* layer table: z of every layer, mm */
  size_t nz, cap;
  int first, last; /* layer numbers */
  double dim[6];   /* $$DIMENSION: x, y, z min, x, y, z max (mm; z: the layers this part holds) */
  int has_dim;
} cc_part;

static int cc_add_z(void *ud, const gr_layer *l, gr_err *e) {
  cc_part *p = ud;
  if (gr_grow(&p->z, &p->cap, p->nz + 1, sizeof *p->z)) return gr_fail(e, GR_EMEM, "out of memory");
  p->z[p->nz++] = l->z;
  return GR_OK;
}

static int cc_map(cc_part *p, gr_err *e) {
  int fd = open(p->path, O_RDONLY);
  if (fd < 0) return gr_fail(e, GR_EIO, "cannot read %s: %s", p->path, strerror(errno));
  struct stat st;
  if (fstat(fd, &st) || !S_ISREG(st.st_mode) || st.st_size == 0) {
    close(fd);
    return gr_fail(e, GR_EIO, "cannot read %s: not a regular, non-empty file", p->path);
  }
  p->len = (size_t)st.st_size;
  void *m = mmap(NULL, p->len, PROT_READ, MAP_PRIVATE, fd, 0);
  close(fd);
  if (m == MAP_FAILED) return gr_fail(e, GR_EIO, "cannot map %s: %s", p->path, strerror(errno));
  p->map = m;
  return GR_OK;
}

/* The header line starting at *pos (advanced past it), length in *n. */
static const char *cc_line(const cc_part *p, size_t *pos, size_t *n) {
  const char *s = p->map + *pos;
  const char *nl = memchr(s, '\n', p->hdr_end - *pos);
  *n = nl ? (size_t)(nl - s) : p->hdr_end - *pos;
  *pos += *n + (nl ? 1 : 0);
  return s;
}

static uint32_t cc_u32(const char *p) {
  const unsigned char *u = (const unsigned char *)p;
  return (uint32_t)u[0] | (uint32_t)u[1] << 8 | (uint32_t)u[2] << 16 | (uint32_t)u[3] << 24;
}

/* The layer table of a binary part written by gradus (LONG commands 127
 * layer, 130 polyline, 132 hatches), jumping from command to command.
 * Returns 1 when another command shows up (the caller then reads the file
 * with the full reader), 0 or an error. */
static int cc_table_binary(cc_part *p, gr_err *e) {
  size_t pos = p->gs;
  while (pos < p->len) {
    if (p->len - pos < 2) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated command", p->path, pos);
    unsigned cmd = (unsigned char)p->map[pos] | (unsigned)(unsigned char)p->map[pos + 1] << 8;
    size_t need = cmd == 127 ? 6 : cmd == 130 ? 14 : cmd == 132 ? 10 : 0;
    if (!need) return 1;
    if (p->len - pos < need) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated command %u", p->path, pos, cmd);
    if (cmd == 127) {
      uint32_t u = cc_u32(p->map + pos + 2);
      float z;
      memcpy(&z, &u, 4);
      if (gr_grow(&p->z, &p->cap, p->nz + 1, sizeof *p->z)) return gr_fail(e, GR_EMEM, "out of memory");
      p->z[p->nz++] = z * p->h.units;
      pos += 6;
      continue;
    }
    int32_t n = (int32_t)cc_u32(p->map + pos + (cmd == 130 ? 10 : 6));
    size_t body = (size_t)(cmd == 130 ? 8 : 16) * (size_t)(n < 0 ? 0 : n);
    if (n < 0 || (p->len - pos - need) < body)
      return gr_fail(e, GR_EPARSE, "%s: byte %zu: command %u with %d points runs past the end", p->path, pos, cmd, n);
    pos += need + body;
  }
  return 0;
}

/* The layer table of an ASCII part: its $$LAYER/ lines. */
static int cc_table_ascii(cc_part *p, gr_err *e) {
  const char *s = p->map + p->gs, *end = p->map + p->ge;
  while (s < end) {
    if (end - s > 8 && !memcmp(s, "$$LAYER/", 8)) {
      char num[64];
      size_t k = 0;
      while (k + 1 < sizeof num && s + 8 + k < end && s[8 + k] != '\n') { num[k] = s[8 + k]; k++; }
      num[k] = 0;
      char *stop;
      double z = strtod(num, &stop);
      if (stop == num || *stop) return gr_fail(e, GR_EPARSE, "%s: byte %zu: bad $$LAYER '%s'", p->path, (size_t)(s - p->map), num);
      if (gr_grow(&p->z, &p->cap, p->nz + 1, sizeof *p->z)) return gr_fail(e, GR_EMEM, "out of memory");
      p->z[p->nz++] = z * p->h.units;
    }
    const char *nl = memchr(s, '\n', (size_t)(end - s));
    s = nl ? nl + 1 : end;
  }
  return 0;
}

/* Header fields: units, layers, format, floor. */
static int cc_header(cc_part *p, gr_err *e) {
  const char *he = memmem(p->map, p->len, "$$HEADEREND", 11);
  if (p->len < 13 || memcmp(p->map, "$$HEADERSTART", 13) || !he)
    return gr_fail(e, GR_EPARSE, "%s:1: not a CLI file (no $$HEADERSTART ... $$HEADEREND)", p->path);
  p->hdr_end = (size_t)(he - p->map) + 11;
  p->h = gr_cli_header_defaults();
  p->h.layers = -1;
  size_t pos = 0, n;
  while (pos < p->hdr_end) {
    const char *l = cc_line(p, &pos, &n);
    char c[256];
    snprintf(c, sizeof c, "%.*s", (int)(n < 255 ? n : 255), l);
    if (!strncmp(c, "$$BINARY", 8)) p->h.binary = 1;
    else if (!strncmp(c, "$$UNITS/", 8)) p->h.units = strtod(c + 8, NULL);
    else if (!strncmp(c, "$$LAYERS/", 9)) p->h.layers = atoi(c + 9);
    else if (!strncmp(c, "$$DIMENSION/", 12)) {
      double *d = p->dim;
      p->has_dim = sscanf(c + 12, "%lf,%lf,%lf,%lf,%lf,%lf", &d[0], &d[1], &d[2], &d[3], &d[4], &d[5]) == 6;
      p->h.lo[2] = d[2];
    }
  }
  if (!(p->h.units > 0)) return gr_fail(e, GR_EPARSE, "%s: bad $$UNITS", p->path);
  return GR_OK;
}

/* Read one part: where its header and geometry lie, and its layer table
 * (from the layer commands alone; through the full CLI reader when the part
 * holds commands the gradus writer does not write). */
static int cc_open(cc_part *p, gr_err *e) {
  int rc = cc_map(p, e);
  if (!rc) rc = cc_header(p, e);
  if (rc) return rc;
  static const char gs[] = "\n$$GEOMETRYSTART\n", ge[] = "$$GEOMETRYEND\n";
  size_t ngs = sizeof gs - 1, nge = sizeof ge - 1;
  if (p->h.binary) {
    p->gs = p->hdr_end;
    p->ge = p->len;
    rc = cc_table_binary(p, e);
  } else {
    if (p->len < p->hdr_end + ngs + nge || memcmp(p->map + p->hdr_end, gs, ngs) ||
        memcmp(p->map + p->len - nge, ge, nge))
      return gr_fail(e, GR_EPARSE,
                     "%s: not a complete CLI laid out as the gradus writer does ($$GEOMETRYSTART after "
                     "$$HEADEREND, $$GEOMETRYEND as the last line): cannot merge it byte for byte", p->path);
    p->gs = p->hdr_end + ngs;
    p->ge = p->len - nge;
    rc = cc_table_ascii(p, e);
  }
  if (rc == 1) { /* another writer's commands: the full reader gives the table */
    p->nz = 0;
    gr_cli_header h;
    rc = gr_cli_read(p->path, &h, cc_add_z, p, e);
    if (rc && !strstr(e->msg, p->path)) { /* say which part */
      char m[sizeof e->msg];
      snprintf(m, sizeof m, "%s", e->msg);
      gr_fail(e, rc, "%s: %s", p->path, m);
    }
  }
  if (rc) return rc;
  if (p->nz == 0) return gr_fail(e, GR_EARG, "%s: no layers", p->path);
  if (p->h.layers != (int)p->nz)
    return gr_fail(e, GR_EPARSE, "%s: $$LAYERS/%d but the file holds %zu layers", p->path, p->h.layers, p->nz);
  return GR_OK;
}

/* The next header line that must agree between parts (all but $$LAYERS,
 * $$DATE and $$DIMENSION, whose z range is that of the part's own layers: its
 * x and y are compared in cc_same_header), or NULL at the end of the header. */
static const char *cc_kept_line(const cc_part *p, size_t *pos, size_t *n) {
  while (*pos < p->hdr_end) {
    const char *s = cc_line(p, pos, n);
    if (!((*n >= 9 && !memcmp(s, "$$LAYERS/", 9)) || (*n >= 7 && !memcmp(s, "$$DATE/", 7)) ||
          (*n >= 12 && !memcmp(s, "$$DIMENSION/", 12))))
      return s;
  }
  *n = 0;
  return NULL;
}

/* Same job: the headers agree but for $$LAYERS and $$DATE. */
static int cc_same_header(const cc_part *a, const cc_part *b, gr_err *e) {
  size_t pa = 0, pb = 0, na, nb;
  static const int XY[4] = {0, 1, 3, 4};
  for (int k = 0; k < 4; k++)
    if (a->has_dim != b->has_dim || (a->has_dim && fabs(a->dim[XY[k]] - b->dim[XY[k]]) > 1e-6))
      return gr_fail(e, GR_EARG, "%s and %s are not parts of one job: their $$DIMENSION x, y extents differ", a->path,
                     b->path);
  for (;;) {
    const char *sa = cc_kept_line(a, &pa, &na), *sb = cc_kept_line(b, &pb, &nb);
    if (!sa && !sb) return GR_OK;
    if (!sa || !sb || na != nb || memcmp(sa, sb, na))
      return gr_fail(e, GR_EARG,
                     "%s and %s are not parts of one job: their headers differ ('%.*s' against '%.*s')",
                     a->path, b->path, (int)(na > 80 ? 80 : na), sa ? sa : "", (int)(nb > 80 ? 80 : nb),
                     sb ? sb : "");
  }
}

/* The layer thickness: the smallest spacing of consecutive layers inside a
 * part; with only one-layer parts, the smallest spacing between them or
 * above the floor. */
static double cc_step(const cc_part *p, int n, double floor_z) {
  double step = INFINITY;
  for (int i = 0; i < n; i++)
    for (size_t q = 1; q < p[i].nz; q++)
      if (p[i].z[q] - p[i].z[q - 1] > 0 && p[i].z[q] - p[i].z[q - 1] < step) step = p[i].z[q] - p[i].z[q - 1];
  if (isfinite(step)) return step;
  for (int i = 0; i < n; i++) {
    if (p[i].z[0] - floor_z > 0 && p[i].z[0] - floor_z < step) step = p[i].z[0] - floor_z;
    for (int k = 0; k < n; k++) {
      double d = fabs(p[i].z[0] - p[k].z[0]);
      if (d > 0 && d < step) step = d;
    }
  }
  return step;
}

/* Number every part's layers; each part must be a run of consecutive layers. */
static int cc_number(cc_part *p, int n, double *step_out, gr_err *e) {
  /* the floor: the lowest part's bottom ($$DIMENSION z min = the bottom of its first layer) */
  double lo = p[0].h.lo[2];
  for (int i = 1; i < n; i++) lo = fmin(lo, p[i].h.lo[2]);
  double step = cc_step(p, n, lo);
  if (!isfinite(step) || !(step > 0)) {
    if (n == 1) { p[0].first = p[0].last = 1; *step_out = 0; return GR_OK; }
    return gr_fail(e, GR_EARG, "%s and %s: every part is one layer at the same height", p[0].path, p[1].path);
  }
  *step_out = step;
  for (int i = 0; i < n; i++) {
    int prev = 0;
    for (size_t q = 0; q < p[i].nz; q++) {
      double f = (p[i].z[q] - lo) / step;
      int g = (int)lround(f);
      if (fabs(f - g) > 0.05)
        return gr_fail(e, GR_EARG, "%s: layer %zu (z = %.6f mm) is off the layer grid (%.6f mm from z = %.6f mm)",
                       p[i].path, q + 1, p[i].z[q], step, lo);
      if (q > 0 && g != prev + 1)
        return gr_fail(e, GR_EARG, "%s: layers not consecutive inside the part (layer %d follows layer %d)",
                       p[i].path, g, prev);
      if (q == 0) p[i].first = g;
      prev = p[i].last = g;
    }
  }
  return GR_OK;
}

static int cc_by_first(const void *a, const void *b) {
  const cc_part *x = a, *y = b;
  return (x->first > y->first) - (x->first < y->first);
}

/* Sorted by first layer, each part must start right after the previous. */
static int cc_check_ranges(cc_part *p, int n, gr_err *e) {
  qsort(p, (size_t)n, sizeof *p, cc_by_first);
  for (int i = 1; i < n; i++) {
    const cc_part *a = &p[i - 1], *b = &p[i];
    if (b->first <= a->last)
      return gr_fail(e, GR_EARG, "%s (layers %d-%d) and %s (layers %d-%d) overlap in layers %d-%d", a->path,
                     a->first, a->last, b->path, b->first, b->last, b->first, a->last < b->last ? a->last : b->last);
    if (b->first > a->last + 1)
      return gr_fail(e, GR_EARG, "layers %d-%d are missing: a gap between %s (layers %d-%d) and %s (layers %d-%d)",
                     a->last + 1, b->first - 1, a->path, a->first, a->last, b->path, b->first, b->last);
  }
  return GR_OK;
}

/* Append bytes [off, off + n) of part p to the output: copy_file_range
 * (in the kernel; a server-side copy on NFS 4.2, a reflink where the file
 * system shares extents), else through the mapping. */
static int cc_copy(FILE *out, const cc_part *p, size_t off, size_t n) {
  if (fflush(out)) return -1;
  int in = open(p->path, O_RDONLY);
  loff_t o = (loff_t)off;
  size_t done = 0;
  while (in >= 0 && done < n) {
    ssize_t k = copy_file_range(in, &o, fileno(out), NULL, n - done, 0);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) break; /* not supported here (EXDEV, ENOSYS, EINVAL...): the rest by hand */
    done += (size_t)k;
  }
  if (in >= 0) close(in);
  return fwrite(p->map + off + done, 1, n - done, out) == n - done ? 0 : -1;
}

/* First part's header and lead-in with $$LAYERS/ set to `layers`, then every
 * part's geometry, then the first part's tail. */
static int cc_write(const cc_part *p, int n, int layers, const char *out, gr_err *e) {
  gr_atomic a;
  if (gr_atomic_open(&a, out, e)) return e->code;
  size_t pos = 0, len;
  while (pos < p[0].hdr_end) {
    size_t at = pos;
    const char *s = cc_line(&p[0], &pos, &len);
    if (len >= 9 && !memcmp(s, "$$LAYERS/", 9)) {
      fprintf(a.fp, "$$LAYERS/%d", layers);
      fwrite(p[0].map + at + len, 1, pos - at - len, a.fp);
    } else if (len >= 12 && !memcmp(s, "$$DIMENSION/", 12) && p[0].has_dim) {
      /* the z range of all the parts' layers, as the writer formats it */
      double zlo = p[0].dim[2], zhi = p[0].dim[5];
      for (int i = 1; i < n; i++) zlo = fmin(zlo, p[i].dim[2]), zhi = fmax(zhi, p[i].dim[5]);
      fprintf(a.fp, "$$DIMENSION/%.6f,%.6f,%.6f,%.6f,%.6f,%.6f", p[0].dim[0], p[0].dim[1], zlo, p[0].dim[3], p[0].dim[4], zhi);
      fwrite(p[0].map + at + len, 1, pos - at - len, a.fp);
    } else {
      fwrite(p[0].map + at, 1, pos - at, a.fp);
    }
  }
  fwrite(p[0].map + p[0].hdr_end, 1, p[0].gs - p[0].hdr_end, a.fp);
  int rc = 0;
  for (int i = 0; i < n && !rc; i++) rc = cc_copy(a.fp, &p[i], p[i].gs, p[i].ge - p[i].gs);
  if (rc) {
    int err = errno;
    gr_atomic_abort(&a);
    return gr_fail(e, GR_EIO, "cannot write %s: %s", out, strerror(err));
  }
  fwrite(p[0].map + p[0].ge, 1, p[0].len - p[0].ge, a.fp);
  return gr_atomic_commit(&a, e);
}

static int cc_same_file(const char *a, const char *b) {
  struct stat sa, sb;
  return !stat(a, &sa) && !stat(b, &sb) && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

int gr_cli_cat(const char *const *parts, int n, const char *out, gr_clicat_info *info, gr_err *e) {
  if (n < 1) return gr_fail(e, GR_EARG, "cli cat: no part files given");
  cc_part *p = calloc((size_t)n, sizeof *p);
  if (!p) return gr_fail(e, GR_EMEM, "out of memory");
  int rc = GR_OK;
  for (int i = 0; i < n && rc == GR_OK; i++) {
    p[i].path = parts[i];
    if (cc_same_file(parts[i], out)) rc = gr_fail(e, GR_EARG, "cli cat: the output %s is also a part", out);
    else rc = cc_open(&p[i], e);
    if (rc == GR_OK && i > 0 && p[i].h.binary != p[0].h.binary)
      rc = gr_fail(e, GR_EARG, "%s is %s but %s is %s", p[0].path, p[0].h.binary ? "binary" : "ASCII", p[i].path,
                   p[i].h.binary ? "binary" : "ASCII");
    if (rc == GR_OK && i > 0) rc = cc_same_header(&p[0], &p[i], e);
  }
  double step = 0;
  if (rc == GR_OK) rc = cc_number(p, n, &step, e);
  if (rc == GR_OK) rc = cc_check_ranges(p, n, e);
  int total = 0;
  for (int i = 0; i < n && rc == GR_OK; i++) total += (int)p[i].nz;
  if (rc == GR_OK) rc = cc_write(p, n, total, out, e);
  if (rc == GR_OK && info) {
    info->layers = total;
    info->first = p[0].first;
    info->last = p[n - 1].last;
    info->layer_mm = step;
  }
  for (int i = 0; i < n; i++) {
    if (p[i].map) munmap((void *)p[i].map, p[i].len);
    free(p[i].z);
  }
  free(p);
  return rc;
}
