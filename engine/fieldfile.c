/* fieldfile.c: VTK legacy STRUCTURED_POINTS and NumPy .npy grids as
 * trilinear fields, see fieldfile.h. */
#include "fieldfile.h"
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

typedef struct ffield {
  char path[1024];
  int n[3];
  double o[3], h[3], pad;
  double *v; /* v[i + n0*(j + n1*k)] */
} ffield;

gr_fieldfile_opts gr_fieldfile_defaults(void) {
  gr_fieldfile_opts o;
  memset(&o, 0, sizeof o);
  return o;
}

static void ff_free(void *ud) {
  ffield *f = ud;
  if (f) free(f->v);
  free(f);
}

static int ff_eval(void *ud, size_t n, const double *x, const double *y, const double *z, double *out, gr_err *e) {
  const ffield *f = ud;
  for (size_t p = 0; p < n; p++) {
    double c[3] = {x[p], y[p], z[p]}, t[3];
    int i[3];
    for (int a = 0; a < 3; a++) {
      double s = (c[a] - f->o[a]) / f->h[a], top = f->n[a] - 1;
      if (!(s >= -f->pad / f->h[a] && s <= top + f->pad / f->h[a]))
        return gr_fail(e, GR_EARG, "%s: point (%g, %g, %g) is outside the grid (%g..%g, %g..%g, %g..%g mm)", f->path,
                       x[p], y[p], z[p], f->o[0], f->o[0] + (f->n[0] - 1) * f->h[0], f->o[1],
                       f->o[1] + (f->n[1] - 1) * f->h[1], f->o[2], f->o[2] + (f->n[2] - 1) * f->h[2]);
      s = fmin(fmax(s, 0), top);
      i[a] = (int)floor(s);
      if (i[a] > f->n[a] - 2) i[a] = f->n[a] - 2;
      if (i[a] < 0) i[a] = 0;
      t[a] = f->n[a] > 1 ? s - i[a] : 0;
    }
    double acc = 0;
    for (int q = 0; q < 8; q++) {
      int di = q & 1, dj = (q >> 1) & 1, dk = (q >> 2) & 1;
      double w = (di ? t[0] : 1 - t[0]) * (dj ? t[1] : 1 - t[1]) * (dk ? t[2] : 1 - t[2]);
      if (w == 0) continue;
      int ii = i[0] + di, jj = i[1] + dj, kk = i[2] + dk;
      acc += w * f->v[ii + (size_t)f->n[0] * (jj + (size_t)f->n[1] * kk)];
    }
    out[p] = acc;
  }
  return GR_OK;
}

/* The whole file in memory. */
static unsigned char *slurp(const char *path, size_t *len, gr_err *e) {
  FILE *fp = fopen(path, "rb");
  if (!fp) return gr_fail(e, GR_EIO, "%s: cannot open", path), NULL;
  size_t cap = 1 << 16, n = 0;
  unsigned char *b = malloc(cap + 1);
  while (b) {
    size_t k = fread(b + n, 1, cap - n, fp);
    n += k;
    if (n < cap) break;
    unsigned char *nb = realloc(b, 2 * cap + 1);
    if (!nb) { free(b); b = NULL; break; }
    b = nb;
    cap *= 2;
  }
  int bad = ferror(fp);
  fclose(fp);
  if (!b) return gr_fail(e, GR_EMEM, "%s: out of memory", path), NULL;
  if (bad) return free(b), gr_fail(e, GR_EIO, "%s: read error", path), NULL;
  b[n] = 0;
  *len = n;
  return b;
}

static double load_be(const unsigned char *p, int size) {
  if (size == 4) {
    uint32_t u = (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
    float f;
    memcpy(&f, &u, 4);
    return f;
  }
  uint64_t u = 0;
  for (int k = 0; k < 8; k++) u = u << 8 | p[k];
  double d;
  memcpy(&d, &u, 8);
  return d;
}

static double load_le(const unsigned char *p, int size) {
  unsigned char r[8];
  for (int k = 0; k < size; k++) r[k] = p[size - 1 - k];
  return load_be(r, size);
}

/* Check finiteness, naming the index. */
static int check_values(const ffield *f, gr_err *e) {
  size_t m = (size_t)f->n[0] * f->n[1] * f->n[2];
  for (size_t q = 0; q < m; q++)
    if (!isfinite(f->v[q]))
      return gr_fail(e, GR_ENUM, "%s: value %g at index (%zu, %zu, %zu) is not finite", f->path, f->v[q],
                     q % f->n[0], q / f->n[0] % f->n[1], q / ((size_t)f->n[0] * f->n[1]));
  return GR_OK;
}

/* Next whitespace-separated word of a VTK header at *p (advanced). */
static int word(const char *b, size_t len, size_t *p, char *out, size_t n) {
  while (*p < len && isspace((unsigned char)b[*p])) (*p)++;
  size_t k = 0;
  while (*p < len && !isspace((unsigned char)b[*p])) {
    if (k + 1 < n) out[k++] = b[*p];
    (*p)++;
  }
  out[k] = 0;
  return k > 0;
}

static int line_of(const char *b, size_t p) {
  int l = 1;
  for (size_t i = 0; i < p; i++) l += b[i] == '\n';
  return l;
}

static int vtk_data(ffield *f, const char *b, size_t len, size_t p, int binary, const char *type, gr_err *e) {
  size_t m = (size_t)f->n[0] * f->n[1] * f->n[2];
  if (!binary) {
    for (size_t q = 0; q < m; q++) {
      while (p < len && isspace((unsigned char)b[p])) p++;
      char *end;
      double v = strtod(b + p, &end);
      if (p >= len || end == b + p)
        return gr_fail(e, GR_EPARSE, "%s:%d: value %zu of %zu (index %zu, %zu, %zu) %s", f->path, line_of(b, p), q + 1, m,
                       q % f->n[0], q / f->n[0] % f->n[1], q / ((size_t)f->n[0] * f->n[1]), p >= len ? "missing: the file is truncated" : "is not a number");
      f->v[q] = v;
      p = (size_t)(end - b);
    }
    return GR_OK;
  }
  int size = !strcmp(type, "float") ? 4 : (!strcmp(type, "double") ? 8 : 0);
  if (!size) return gr_fail(e, GR_EPARSE, "%s: binary SCALARS type '%s' not supported (float or double)", f->path, type);
  if (p < len && b[p] == '\r') p++;
  if (p < len && b[p] == '\n') p++;
  if (len - p < m * size) {
    size_t q = (len - p) / size;
    return gr_fail(e, GR_EPARSE, "%s: byte %zu: data truncated at value %zu of %zu (index %zu, %zu, %zu)", f->path, len, q + 1, m,
                   q % f->n[0], q / f->n[0] % f->n[1], q / ((size_t)f->n[0] * f->n[1]));
  }
  for (size_t q = 0; q < m; q++) f->v[q] = load_be((const unsigned char *)b + p + q * size, size);
  return GR_OK;
}

static int read_vtk(ffield *f, const char *b, size_t len, gr_err *e) {
  size_t p = strcspn(b, "\n"); /* version line */
  p += p < len;
  p += strcspn(b + p, "\n");  /* title */
  p += p < len;
  char w[64], type[32] = "";
  if (!word(b, len, &p, w, sizeof w) || (strcmp(w, "ASCII") && strcmp(w, "BINARY")))
    return gr_fail(e, GR_EPARSE, "%s:3: ASCII or BINARY expected, got '%s'", f->path, w);
  int binary = !strcmp(w, "BINARY"), have = 0;
  f->h[0] = f->h[1] = f->h[2] = 1;
  size_t npts = 0;
  while (word(b, len, &p, w, sizeof w)) {
    int ln = line_of(b, p);
    double d[3];
    char a[3][64];
    if (!strcmp(w, "DATASET")) {
      if (!word(b, len, &p, w, sizeof w) || strcmp(w, "STRUCTURED_POINTS"))
        return gr_fail(e, GR_EPARSE, "%s:%d: DATASET %s is not supported (STRUCTURED_POINTS)", f->path, ln, w);
    } else if (!strcmp(w, "DIMENSIONS") || !strcmp(w, "ORIGIN") || !strcmp(w, "SPACING") || !strcmp(w, "ASPECT_RATIO")) {
      for (int k = 0; k < 3; k++) {
        char *end;
        if (!word(b, len, &p, a[k], sizeof a[k]) || (d[k] = strtod(a[k], &end), *end))
          return gr_fail(e, GR_EPARSE, "%s:%d: %s needs three numbers", f->path, ln, w);
      }
      if (w[0] == 'D') {
        for (int k = 0; k < 3; k++) {
          if (!(d[k] >= 1 && d[k] <= 1e5) || d[k] != floor(d[k]))
            return gr_fail(e, GR_EPARSE, "%s:%d: DIMENSIONS %s %s %s: whole numbers >= 1 expected", f->path, ln, a[0], a[1], a[2]);
          f->n[k] = (int)d[k];
        }
        have |= 1;
      } else if (w[0] == 'O') {
        memcpy(f->o, d, sizeof d);
      } else {
        for (int k = 0; k < 3; k++)
          if (!(d[k] > 0) || !isfinite(d[k])) return gr_fail(e, GR_EPARSE, "%s:%d: %s %s must be > 0", f->path, ln, w, a[k]);
        memcpy(f->h, d, sizeof d);
      }
    } else if (!strcmp(w, "POINT_DATA")) {
      if (!word(b, len, &p, w, sizeof w)) return gr_fail(e, GR_EPARSE, "%s:%d: POINT_DATA needs a count", f->path, ln);
      npts = (size_t)strtoull(w, NULL, 10);
    } else if (!strcmp(w, "SCALARS")) {
      if (!word(b, len, &p, w, sizeof w) || !word(b, len, &p, type, sizeof type))
        return gr_fail(e, GR_EPARSE, "%s:%d: SCALARS needs a name and a type", f->path, ln);
      size_t save = p;
      if (word(b, len, &p, w, sizeof w) && isdigit((unsigned char)w[0]) && strcmp(w, "1"))
        return gr_fail(e, GR_EPARSE, "%s:%d: SCALARS with %s components: one expected", f->path, ln, w);
      if (!isdigit((unsigned char)w[0])) p = save;
      have |= 2;
    } else if (!strcmp(w, "LOOKUP_TABLE")) {
      word(b, len, &p, w, sizeof w);
      if (have != 3) return gr_fail(e, GR_EPARSE, "%s:%d: DIMENSIONS and SCALARS must come before the data", f->path, ln);
      size_t m = (size_t)f->n[0] * f->n[1] * f->n[2];
      if (npts != m)
        return gr_fail(e, GR_EPARSE, "%s: POINT_DATA %zu does not match DIMENSIONS %d %d %d (%zu points)", f->path, npts, f->n[0], f->n[1], f->n[2], m);
      if (!(f->v = malloc(m * sizeof *f->v))) return gr_fail(e, GR_EMEM, "%s: out of memory", f->path);
      return vtk_data(f, b, len, p, binary, type, e);
    } else {
      return gr_fail(e, GR_EPARSE, "%s:%d: unexpected '%s' (STRUCTURED_POINTS with one SCALARS array expected)", f->path, ln, w);
    }
  }
  return gr_fail(e, GR_EPARSE, "%s: no LOOKUP_TABLE and data found", f->path);
}

/* The value of 'key': in a .npy header dict (points after the colon). */
static const char *npy_key(const char *h, const char *key) {
  const char *s = strstr(h, key);
  if (!s) return NULL;
  s = strchr(s + strlen(key), ':');
  if (!s) return NULL;
  s++;
  while (*s == ' ') s++;
  return s;
}

static int read_npy(ffield *f, const unsigned char *b, size_t len, const gr_fieldfile_opts *o, gr_err *e) {
  if (len < 10) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated .npy header", f->path, len);
  int major = b[6];
  size_t hl = major == 1 ? (size_t)(b[8] | b[9] << 8) : (len >= 12 ? (size_t)b[8] | (size_t)b[9] << 8 | (size_t)b[10] << 16 | (size_t)b[11] << 24 : len);
  size_t start = (major == 1 ? 10 : 12) + hl;
  if (start > len) return gr_fail(e, GR_EPARSE, "%s: byte %zu: truncated .npy header (%zu bytes announced)", f->path, len, hl);
  char h[4096];
  size_t hn = hl < sizeof h - 1 ? hl : sizeof h - 1;
  memcpy(h, b + (major == 1 ? 10 : 12), hn);
  h[hn] = 0;
  const char *d = npy_key(h, "'descr'"), *fo = npy_key(h, "'fortran_order'"), *sh = npy_key(h, "'shape'");
  if (!d || !fo || !sh) return gr_fail(e, GR_EPARSE, "%s: byte 10: .npy header without descr, fortran_order or shape", f->path);
  int size = 0, big = 0;
  if (!strncmp(d, "'<f4'", 5) || !strncmp(d, "'>f4'", 5)) size = 4;
  else if (!strncmp(d, "'<f8'", 5) || !strncmp(d, "'>f8'", 5)) size = 8;
  if (!size) return gr_fail(e, GR_EPARSE, "%s: dtype %.8s not supported (float32 or float64)", f->path, d);
  big = d[1] == '>';
  int fortran = !strncmp(fo, "True", 4);
  long dims[4];
  int nd = 0;
  const char *s = sh + 1;
  while (*s && *s != ')' && nd < 4) {
    char *end;
    long v = strtol(s, &end, 10);
    if (end == s) break;
    dims[nd++] = v;
    s = end;
    while (*s == ',' || *s == ' ') s++;
  }
  if (nd != 3) return gr_fail(e, GR_EPARSE, "%s: shape has %d dimension(s): a 3-D array (nx, ny, nz) is needed", f->path, nd);
  for (int a = 0; a < 3; a++) {
    if (dims[a] < 1 || dims[a] > 100000) return gr_fail(e, GR_EPARSE, "%s: shape dimension %d is %ld", f->path, a, dims[a]);
    f->n[a] = (int)dims[a];
    if (!(o->spacing[a] > 0) || !isfinite(o->spacing[a]))
      return gr_fail(e, GR_EARG, "%s: bad option 'spacing' (%g along axis %d: > 0 mm needed for .npy)", f->path, o->spacing[a], a);
    if (!isfinite(o->origin[a])) return gr_fail(e, GR_EARG, "%s: bad option 'origin' (not finite)", f->path);
  }
  memcpy(f->o, o->origin, sizeof f->o);
  memcpy(f->h, o->spacing, sizeof f->h);
  size_t m = (size_t)f->n[0] * f->n[1] * f->n[2];
  if (len - start < m * size) {
    size_t q = (len - start) / size; /* the first missing value, in file order */
    size_t i = fortran ? q % f->n[0] : q / ((size_t)f->n[1] * f->n[2]);
    size_t j = fortran ? q / f->n[0] % f->n[1] : q / f->n[2] % f->n[1];
    size_t k = fortran ? q / ((size_t)f->n[0] * f->n[1]) : q % f->n[2];
    return gr_fail(e, GR_EPARSE, "%s: byte %zu: data truncated at value %zu of %zu (index %zu, %zu, %zu)", f->path, len, q + 1, m, i, j, k);
  }
  if (!(f->v = malloc(m * sizeof *f->v))) return gr_fail(e, GR_EMEM, "%s: out of memory", f->path);
  for (size_t k = 0; k < (size_t)f->n[2]; k++)
    for (size_t j = 0; j < (size_t)f->n[1]; j++)
      for (size_t i = 0; i < (size_t)f->n[0]; i++) {
        size_t q = fortran ? i + f->n[0] * (j + f->n[1] * k) : k + f->n[2] * (j + f->n[1] * i);
        const unsigned char *p = b + start + q * size;
        f->v[i + f->n[0] * (j + f->n[1] * k)] = big ? load_be(p, size) : load_le(p, size);
      }
  return GR_OK;
}

gr_field *gr_field_file(const char *path, const gr_fieldfile_opts *o, gr_err *e) {
  if (!(o->pad >= 0)) return gr_fail(e, GR_EARG, "%s: bad option 'pad' (must be >= 0 mm, got %g)", path, o->pad), NULL;
  ffield *f = calloc(1, sizeof *f);
  if (!f) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  snprintf(f->path, sizeof f->path, "%s", path);
  f->pad = o->pad;
  size_t len;
  unsigned char *b = slurp(path, &len, e);
  if (!b) return ff_free(f), NULL;
  int rc;
  if (len >= 6 && !memcmp(b, "\x93NUMPY", 6)) rc = read_npy(f, b, len, o, e);
  else if (len >= 5 && !memcmp(b, "# vtk", 5)) rc = read_vtk(f, (const char *)b, len, e);
  else rc = gr_fail(e, GR_EPARSE, "%s: neither a VTK legacy file ('# vtk' first) nor a .npy file", path);
  free(b);
  if (!rc) rc = check_values(f, e);
  if (rc) return ff_free(f), NULL;
  char desc[128];
  snprintf(desc, sizeof desc, "file %.100s", path);
  gr_field *g = gr_field_callback(ff_eval, NULL, f, ff_free, 1, desc);
  if (!g) return ff_free(f), gr_fail(e, GR_EMEM, "out of memory"), NULL;
  return g;
}

int gr_fieldfile_info(const gr_field *g, int n[3], double lo[3], double hi[3]) {
  const ffield *f = gr_field_callback_data(g, ff_eval);
  if (!f) return 0;
  for (int a = 0; a < 3; a++) {
    n[a] = f->n[a];
    lo[a] = f->o[a];
    hi[a] = f->o[a] + (f->n[a] - 1) * f->h[a];
  }
  return 1;
}
