/* clicat.c: merge CLI part files byte for byte (clicat.h). */
#define _GNU_SOURCE
#include "clicat.h"
#include "cli.h"
#include <errno.h>
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

/* Read one part: its layer table through the CLI reader, then where its
 * header and geometry lie. */
static int cc_open(cc_part *p, gr_err *e) {
  int rc = gr_cli_read(p->path, &p->h, cc_add_z, p, e);
  if (rc) {
    if (!strstr(e->msg, p->path)) { /* say which part */
      char m[sizeof e->msg];
      snprintf(m, sizeof m, "%s", e->msg);
      gr_fail(e, rc, "%s: %s", p->path, m);
    }
    return rc;
  }
  if (p->nz == 0) return gr_fail(e, GR_EARG, "%s: no layers", p->path);
  if (p->h.layers != (int)p->nz)
    return gr_fail(e, GR_EPARSE, "%s: $$LAYERS/%d but the file holds %zu layers", p->path, p->h.layers, p->nz);
  if ((rc = cc_map(p, e))) return rc;
  const char *he = memmem(p->map, p->len, "$$HEADEREND", 11);
  p->hdr_end = (size_t)(he - p->map) + 11; /* the reader found it */
  if (p->h.binary) {
    p->gs = p->hdr_end;
    p->ge = p->len;
    return GR_OK;
  }
  static const char gs[] = "\n$$GEOMETRYSTART\n", ge[] = "$$GEOMETRYEND\n";
  size_t ngs = sizeof gs - 1, nge = sizeof ge - 1;
  if (p->len < p->hdr_end + ngs + nge || memcmp(p->map + p->hdr_end, gs, ngs) ||
      memcmp(p->map + p->len - nge, ge, nge))
    return gr_fail(e, GR_EPARSE,
                   "%s: not laid out as the gradus writer does ($$HEADEREND, $$GEOMETRYSTART on the next line, "
                   "$$GEOMETRYEND as the last line): cannot merge it byte for byte", p->path);
  p->gs = p->hdr_end + ngs;
  p->ge = p->len - nge;
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

/* The next header line that must agree between parts (all but $$LAYERS and
 * $$DATE), or NULL at the end of the header. */
static const char *cc_kept_line(const cc_part *p, size_t *pos, size_t *n) {
  while (*pos < p->hdr_end) {
    const char *s = cc_line(p, pos, n);
    if (!((*n >= 9 && !memcmp(s, "$$LAYERS/", 9)) || (*n >= 7 && !memcmp(s, "$$DATE/", 7)))) return s;
  }
  *n = 0;
  return NULL;
}

/* Same job: the headers agree but for $$LAYERS and $$DATE. */
static int cc_same_header(const cc_part *a, const cc_part *b, gr_err *e) {
  size_t pa = 0, pb = 0, na, nb;
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
  double lo = p[0].h.lo[2], step = cc_step(p, n, lo);
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
