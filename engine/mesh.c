/* mesh.c: indexed triangle meshes: building, measures, topology check, and
 * the STL/PLY/OBJ writers and readers. */
#include "mesh.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

gr_mesh *gr_mesh_new(void) { return calloc(1, sizeof(gr_mesh)); }

void gr_mesh_free(gr_mesh *m) {
  if (!m) return;
  free(m->v);
  free(m->f);
  free(m);
}

long gr_mesh_add_vertex(gr_mesh *m, double x, double y, double z) {
  if (m->nv >= UINT32_MAX - 1) return -1;
  if (gr_grow(&m->v, &m->capv, m->nv + 1, 3 * sizeof *m->v)) return -1;
  double *p = m->v + 3 * m->nv;
  p[0] = x; p[1] = y; p[2] = z;
  return (long)m->nv++;
}

int gr_mesh_add_face(gr_mesh *m, uint32_t a, uint32_t b, uint32_t c) {
  if (gr_grow(&m->f, &m->capf, m->nf + 1, 3 * sizeof *m->f)) return GR_EMEM;
  uint32_t *t = m->f + 3 * m->nf++;
  t[0] = a; t[1] = b; t[2] = c;
  return GR_OK;
}

/* Twice the area vector of face i. */
static void face_normal(const gr_mesh *m, size_t i, double n[3]) {
  const double *a = m->v + 3 * (size_t)m->f[3 * i], *b = m->v + 3 * (size_t)m->f[3 * i + 1],
               *c = m->v + 3 * (size_t)m->f[3 * i + 2];
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] = u[1] * v[2] - u[2] * v[1];
  n[1] = u[2] * v[0] - u[0] * v[2];
  n[2] = u[0] * v[1] - u[1] * v[0];
}

double gr_mesh_area(const gr_mesh *m) {
  double s = 0;
  for (size_t i = 0; i < m->nf; i++) {
    double n[3];
    face_normal(m, i, n);
    s += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  }
  return s;
}

/* Sum of signed tetrahedra (c, a, b, c') taken about the bounding-box centre
 * to limit cancellation. */
double gr_mesh_volume(const gr_mesh *m) {
  double lo[3], hi[3], c[3], s = 0;
  gr_mesh_bounds(m, lo, hi);
  for (int d = 0; d < 3; d++) c[d] = 0.5 * (lo[d] + hi[d]);
  for (size_t i = 0; i < m->nf; i++) {
    const double *p[3];
    double q[3][3];
    for (int k = 0; k < 3; k++) {
      p[k] = m->v + 3 * (size_t)m->f[3 * i + k];
      for (int d = 0; d < 3; d++) q[k][d] = p[k][d] - c[d];
    }
    s += q[0][0] * (q[1][1] * q[2][2] - q[1][2] * q[2][1]) -
         q[0][1] * (q[1][0] * q[2][2] - q[1][2] * q[2][0]) +
         q[0][2] * (q[1][0] * q[2][1] - q[1][1] * q[2][0]);
  }
  return s / 6;
}

void gr_mesh_bounds(const gr_mesh *m, double lo[3], double hi[3]) {
  for (int d = 0; d < 3; d++) { lo[d] = m->nv ? INFINITY : 0; hi[d] = m->nv ? -INFINITY : 0; }
  for (size_t i = 0; i < m->nv; i++)
    for (int d = 0; d < 3; d++) {
      double x = m->v[3 * i + d];
      if (x < lo[d]) lo[d] = x;
      if (x > hi[d]) hi[d] = x;
    }
}

typedef struct half { uint32_t a, b; int fwd; } half; /* a < b; fwd: a->b */

static int half_cmp(const void *x, const void *y) {
  const half *p = x, *q = y;
  if (p->a != q->a) return p->a < q->a ? -1 : 1;
  if (p->b != q->b) return p->b < q->b ? -1 : 1;
  return p->fwd - q->fwd;
}

/* Edges are found by sorting the (min, max) pairs of all face sides. */
int gr_mesh_topology(const gr_mesh *m, gr_mesh_topo *t, gr_err *e) {
  memset(t, 0, sizeof *t);
  half *h = malloc((3 * m->nf + 1) * sizeof *h);
  if (!h) return gr_fail(e, GR_EMEM, "out of memory for %zu face sides", 3 * m->nf);
  size_t nh = 0;
  for (size_t i = 0; i < m->nf; i++) {
    const uint32_t *f = m->f + 3 * i;
    double n[3];
    int bad = f[0] == f[1] || f[1] == f[2] || f[0] == f[2] || f[0] >= m->nv ||
              f[1] >= m->nv || f[2] >= m->nv;
    if (!bad) {
      face_normal(m, i, n);
      bad = n[0] == 0 && n[1] == 0 && n[2] == 0;
    }
    if (bad) t->degenerate_faces++;
    for (int k = 0; k < 3; k++) {
      uint32_t a = f[k], b = f[(k + 1) % 3];
      if (a == b) continue;
      h[nh].a = a < b ? a : b;
      h[nh].b = a < b ? b : a;
      h[nh++].fwd = a < b;
    }
  }
  qsort(h, nh, sizeof *h, half_cmp);
  for (size_t i = 0; i < nh;) {
    size_t j = i, nf = 0;
    while (j < nh && h[j].a == h[i].a && h[j].b == h[i].b) { nf += h[j].fwd; j++; }
    t->edges++;
    size_t use = j - i;
    if (use == 1) t->boundary_edges++;
    else if (use > 2) t->nonmanifold_edges++;
    else if (nf != 1) t->misoriented_edges++;
    i = j;
  }
  free(h);
  t->euler = (long)m->nv - (long)t->edges + (long)m->nf;
  return GR_OK;
}

/* ---------------------------------------------------------------- writers */

static void put_f32(FILE *fp, double x) {
  float f = (float)x;
  unsigned char b[4];
  uint32_t u;
  memcpy(&u, &f, 4);
  for (int i = 0; i < 4; i++) b[i] = (unsigned char)(u >> (8 * i));
  fwrite(b, 1, 4, fp);
}

static void put_u32(FILE *fp, uint32_t u) {
  unsigned char b[4];
  for (int i = 0; i < 4; i++) b[i] = (unsigned char)(u >> (8 * i));
  fwrite(b, 1, 4, fp);
}

static void unit_normal(const gr_mesh *m, size_t i, double n[3]) {
  face_normal(m, i, n);
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int d = 0; d < 3; d++) n[d] = l > 0 ? n[d] / l : 0;
}

static void write_stl_bin(const gr_mesh *m, FILE *fp) {
  char hdr[80];
  memset(hdr, 0, sizeof hdr);
  snprintf(hdr, sizeof hdr, "gradus binary STL, units mm");
  fwrite(hdr, 1, 80, fp);
  put_u32(fp, (uint32_t)m->nf);
  for (size_t i = 0; i < m->nf; i++) {
    double n[3];
    unit_normal(m, i, n);
    for (int d = 0; d < 3; d++) put_f32(fp, n[d]);
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 3; d++) put_f32(fp, m->v[3 * (size_t)m->f[3 * i + k] + d]);
    fputc(0, fp);
    fputc(0, fp);
  }
}

static void write_stl_ascii(const gr_mesh *m, FILE *fp) {
  fprintf(fp, "solid gradus\n");
  for (size_t i = 0; i < m->nf; i++) {
    double n[3];
    unit_normal(m, i, n);
    fprintf(fp, "facet normal %.9g %.9g %.9g\nouter loop\n", n[0], n[1], n[2]);
    for (int k = 0; k < 3; k++) {
      const double *p = m->v + 3 * (size_t)m->f[3 * i + k];
      fprintf(fp, "vertex %.9g %.9g %.9g\n", (float)p[0], (float)p[1], (float)p[2]);
    }
    fprintf(fp, "endloop\nendfacet\n");
  }
  fprintf(fp, "endsolid gradus\n");
}

static void write_ply(const gr_mesh *m, FILE *fp) {
  fprintf(fp, "ply\nformat binary_little_endian 1.0\ncomment gradus, units mm\n"
              "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
              "element face %zu\nproperty list uchar uint vertex_indices\nend_header\n",
          m->nv, m->nf);
  for (size_t i = 0; i < 3 * m->nv; i++) put_f32(fp, m->v[i]);
  for (size_t i = 0; i < m->nf; i++) {
    fputc(3, fp);
    for (int k = 0; k < 3; k++) put_u32(fp, m->f[3 * i + k]);
  }
}

static void write_obj(const gr_mesh *m, FILE *fp) {
  fprintf(fp, "# gradus, units mm\n");
  for (size_t i = 0; i < m->nv; i++)
    fprintf(fp, "v %.17g %.17g %.17g\n", m->v[3 * i], m->v[3 * i + 1], m->v[3 * i + 2]);
  for (size_t i = 0; i < m->nf; i++)
    fprintf(fp, "f %u %u %u\n", m->f[3 * i] + 1, m->f[3 * i + 1] + 1, m->f[3 * i + 2] + 1);
}

static int ends_with(const char *s, const char *suf) {
  size_t n = strlen(s), k = strlen(suf);
  if (n < k) return 0;
  for (size_t i = 0; i < k; i++)
    if (tolower((unsigned char)s[n - k + i]) != suf[i]) return 0;
  return 1;
}

int gr_mesh_write(const gr_mesh *m, const char *path, const char *format,
                  gr_err *e) {
  gr_err_clear(e);
  if (!m) return gr_fail(e, GR_EARG, "mesh must not be NULL");
  if (!path || !*path) return gr_fail(e, GR_EARG, "path must not be empty");
  if (!format) {
    format = ends_with(path, ".stl") ? "stl" : ends_with(path, ".ply") ? "ply"
             : ends_with(path, ".obj") ? "obj" : NULL;
    if (!format)
      return gr_fail(e, GR_EARG, "cannot tell the mesh format from path '%s' "
                                 "(use .stl, .ply or .obj, or give a format)", path);
  }
  int kind = !strcmp(format, "stl") ? 0 : !strcmp(format, "stl_ascii") ? 1
             : !strcmp(format, "ply") ? 2 : !strcmp(format, "obj") ? 3 : -1;
  if (kind < 0)
    return gr_fail(e, GR_EARG, "format must be stl, stl_ascii, ply or obj, got '%s'", format);
  if (kind == 0 && m->nf > UINT32_MAX)
    return gr_fail(e, GR_EARG, "too many faces for STL: %zu", m->nf);
  gr_atomic a;
  int rc = gr_atomic_open(&a, path, e);
  if (rc) return rc;
  switch (kind) {
  case 0: write_stl_bin(m, a.fp); break;
  case 1: write_stl_ascii(m, a.fp); break;
  case 2: write_ply(m, a.fp); break;
  default: write_obj(m, a.fp); break;
  }
  return gr_atomic_commit(&a, e);
}

/* ---------------------------------------------------------------- readers */

/* The whole file in memory, NUL-terminated. */
static char *slurp(const char *path, size_t *len, gr_err *e) {
  FILE *fp = fopen(path, "rb");
  if (!fp) { gr_fail(e, GR_EIO, "cannot read %s: %s", path, strerror(errno)); return NULL; }
  size_t cap = 1 << 16, n = 0;
  char *buf = malloc(cap);
  while (buf) {
    if (n + 1 >= cap) {
      char *nb = realloc(buf, cap * 2);
      if (!nb) { free(buf); buf = NULL; break; }
      buf = nb; cap *= 2;
    }
    size_t r = fread(buf + n, 1, cap - 1 - n, fp);
    n += r;
    if (r == 0) break;
  }
  int err = ferror(fp);
  fclose(fp);
  if (!buf) { gr_fail(e, GR_EMEM, "out of memory reading %s", path); return NULL; }
  if (err) { free(buf); gr_fail(e, GR_EIO, "cannot read %s", path); return NULL; }
  buf[n] = 0;
  *len = n;
  return buf;
}

static uint32_t get_u32(const unsigned char *b) {
  return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}
static double get_f32(const unsigned char *b) {
  uint32_t u = get_u32(b);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

/* Vertex welding for STL: open-addressing hash on exact coordinates. */
typedef struct weld { uint32_t *slot; size_t cap; } weld;

static uint64_t hash3(const double p[3]) {
  uint64_t h = 1469598103934665603ull;
  for (int d = 0; d < 3; d++) {
    double x = p[d] == 0 ? 0 : p[d]; /* -0 == 0 */
    uint64_t u;
    memcpy(&u, &x, 8);
    h = (h ^ u) * 1099511628211ull;
    h ^= h >> 29;
  }
  return h;
}

static int weld_grow(weld *w, const gr_mesh *m) {
  size_t cap = w->cap ? w->cap * 2 : 1024;
  uint32_t *s = malloc(cap * sizeof *s);
  if (!s) return GR_EMEM;
  for (size_t i = 0; i < cap; i++) s[i] = UINT32_MAX;
  for (size_t v = 0; v < m->nv; v++) {
    size_t k = hash3(m->v + 3 * v) & (cap - 1);
    while (s[k] != UINT32_MAX) k = (k + 1) & (cap - 1);
    s[k] = (uint32_t)v;
  }
  free(w->slot);
  w->slot = s;
  w->cap = cap;
  return GR_OK;
}

static long weld_vertex(weld *w, gr_mesh *m, const double p[3]) {
  if (2 * (m->nv + 1) > w->cap && weld_grow(w, m)) return -1;
  size_t k = hash3(p) & (w->cap - 1);
  for (; w->slot[k] != UINT32_MAX; k = (k + 1) & (w->cap - 1)) {
    const double *q = m->v + 3 * (size_t)w->slot[k];
    if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) return w->slot[k];
  }
  long id = gr_mesh_add_vertex(m, p[0], p[1], p[2]);
  if (id >= 0) w->slot[k] = (uint32_t)id;
  return id;
}

static int add_welded_face(weld *w, gr_mesh *m, double p[3][3]) {
  long id[3];
  for (int k = 0; k < 3; k++)
    if ((id[k] = weld_vertex(w, m, p[k])) < 0) return GR_EMEM;
  return gr_mesh_add_face(m, (uint32_t)id[0], (uint32_t)id[1], (uint32_t)id[2]);
}

static int read_stl_bin(const char *path, const unsigned char *b, size_t len,
                        gr_mesh *m, gr_err *e) {
  uint32_t n = get_u32(b + 80);
  if (len < 84 + 50 * (size_t)n)
    return gr_fail(e, GR_EPARSE, "%s: byte %zu: binary STL truncated (%u triangles need %zu bytes)",
                   path, len, n, 84 + 50 * (size_t)n);
  weld w = {0};
  int rc = GR_OK;
  for (uint32_t i = 0; i < n && !rc; i++) {
    const unsigned char *t = b + 84 + 50 * (size_t)i + 12;
    double p[3][3];
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 3; d++) {
        p[k][d] = get_f32(t + 12 * k + 4 * d);
        if (!isfinite(p[k][d])) {
          free(w.slot);
          return gr_fail(e, GR_EPARSE, "%s: byte %zu: non-finite coordinate", path,
                         (size_t)(t + 12 * k + 4 * d - b));
        }
      }
    rc = add_welded_face(&w, m, p);
  }
  free(w.slot);
  return rc ? gr_fail(e, GR_EMEM, "out of memory reading %s", path) : GR_OK;
}

/* A tiny line-aware tokenizer for the ASCII formats. */
typedef struct lex { const char *s, *path; size_t line; } lex;

static void skip_space(lex *x, int newlines) {
  for (;;) {
    while (*x->s == ' ' || *x->s == '\t' || *x->s == '\r' || (newlines && *x->s == '\n')) {
      if (*x->s == '\n') x->line++;
      x->s++;
    }
    return;
  }
}

/* Next word (up to whitespace) into w; 0 at end of input. */
static int word(lex *x, char *w, size_t cap) {
  skip_space(x, 1);
  size_t n = 0;
  while (*x->s && !isspace((unsigned char)*x->s)) {
    if (n + 1 < cap) w[n++] = *x->s;
    x->s++;
  }
  w[n] = 0;
  return n > 0;
}

static int number(lex *x, double *out) {
  skip_space(x, 1);
  char *end;
  errno = 0;
  *out = strtod(x->s, &end);
  if (end == x->s || !isfinite(*out)) return 0;
  x->s = end;
  return 1;
}

static int expect(lex *x, const char *w, gr_err *e) {
  char buf[64];
  if (!word(x, buf, sizeof buf) || strcmp(buf, w))
    return gr_fail(e, GR_EPARSE, "%s:%zu: expected '%s', got '%s'", x->path, x->line, w,
                   buf);
  return GR_OK;
}

static int read_stl_ascii(const char *path, const char *s, gr_mesh *m, gr_err *e) {
  lex x = {s, path, 1};
  char w[64];
  weld wd = {0};
  int rc = GR_OK;
  word(&x, w, sizeof w); /* solid */
  while (*x.s && *x.s != '\n') x.s++; /* the solid's name */
  for (;;) {
    if (!word(&x, w, sizeof w)) {
      rc = gr_fail(e, GR_EPARSE, "%s:%zu: ASCII STL ends without 'endsolid'", path, x.line);
      break;
    }
    if (!strcmp(w, "endsolid")) break;
    if (strcmp(w, "facet")) {
      rc = gr_fail(e, GR_EPARSE, "%s:%zu: expected 'facet' or 'endsolid', got '%s'", path,
                   x.line, w);
      break;
    }
    double n, p[3][3];
    if ((rc = expect(&x, "normal", e))) break;
    for (int d = 0; d < 3; d++)
      if (!number(&x, &n)) { rc = gr_fail(e, GR_EPARSE, "%s:%zu: bad normal", path, x.line); break; }
    if (rc || (rc = expect(&x, "outer", e)) || (rc = expect(&x, "loop", e))) break;
    for (int k = 0; k < 3 && !rc; k++) {
      if ((rc = expect(&x, "vertex", e))) break;
      for (int d = 0; d < 3; d++)
        if (!number(&x, &p[k][d])) {
          rc = gr_fail(e, GR_EPARSE, "%s:%zu: bad vertex coordinate", path, x.line);
          break;
        }
    }
    if (rc || (rc = expect(&x, "endloop", e)) || (rc = expect(&x, "endfacet", e))) break;
    if (add_welded_face(&wd, m, p)) { rc = gr_fail(e, GR_EMEM, "out of memory reading %s", path); break; }
  }
  free(wd.slot);
  return rc;
}

static int read_obj(const char *path, const char *s, gr_mesh *m, gr_err *e) {
  lex x = {s, path, 1};
  char w[64];
  while (*x.s) {
    skip_space(&x, 0);
    if (*x.s == '\n') { x.s++; x.line++; continue; }
    if (!word(&x, w, sizeof w)) break;
    if (!strcmp(w, "v")) {
      double p[3];
      for (int d = 0; d < 3; d++) {
        skip_space(&x, 0);
        if (!number(&x, &p[d]))
          return gr_fail(e, GR_EPARSE, "%s:%zu: bad vertex coordinate", path, x.line);
      }
      if (gr_mesh_add_vertex(m, p[0], p[1], p[2]) < 0)
        return gr_fail(e, GR_EMEM, "out of memory reading %s", path);
    } else if (!strcmp(w, "f")) {
      long first = -1, prev = -1;
      int k = 0;
      for (;;) {
        skip_space(&x, 0);
        if (!*x.s || *x.s == '\n' || *x.s == '#') break;
        char *end;
        long idx = strtol(x.s, &end, 10);
        if (end == x.s || idx == 0)
          return gr_fail(e, GR_EPARSE, "%s:%zu: bad face index", path, x.line);
        x.s = end;
        while (*x.s && !isspace((unsigned char)*x.s)) x.s++; /* /vt/vn */
        if (idx < 0) idx += (long)m->nv + 1;
        if (idx < 1 || (size_t)idx > m->nv)
          return gr_fail(e, GR_EPARSE, "%s:%zu: face index %ld out of range (1..%zu)", path,
                         x.line, idx, m->nv);
        idx--;
        if (k == 0) first = idx;
        else if (k >= 2 && gr_mesh_add_face(m, (uint32_t)first, (uint32_t)prev, (uint32_t)idx))
          return gr_fail(e, GR_EMEM, "out of memory reading %s", path);
        prev = idx;
        k++;
      }
      if (k < 3) return gr_fail(e, GR_EPARSE, "%s:%zu: face with %d vertices", path, x.line, k);
    }
    while (*x.s && *x.s != '\n') x.s++; /* rest of line: comments, other records */
  }
  return GR_OK;
}

static int read_ply(const char *path, const char *s, size_t len, gr_mesh *m, gr_err *e) {
  lex x = {s, path, 1};
  char w[64];
  int binary = 0;
  long nv = -1, nf = -1;
  int cur = 0, nprop = 0, xyz[3] = {-1, -1, -1}, vsize = 0;
  int list_count = 1, list_index = 4; /* face list sizes in bytes */
  if ((expect(&x, "ply", e))) return GR_EPARSE;
  for (;;) {
    if (!word(&x, w, sizeof w))
      return gr_fail(e, GR_EPARSE, "%s:%zu: PLY header without end_header", path, x.line);
    if (!strcmp(w, "end_header")) break;
    if (!strcmp(w, "format")) {
      word(&x, w, sizeof w);
      if (!strcmp(w, "binary_little_endian")) binary = 1;
      else if (strcmp(w, "ascii"))
        return gr_fail(e, GR_EPARSE, "%s:%zu: unsupported PLY format '%s'", path, x.line, w);
    } else if (!strcmp(w, "element")) {
      word(&x, w, sizeof w);
      double n;
      if (!number(&x, &n) || n < 0 || n != floor(n))
        return gr_fail(e, GR_EPARSE, "%s:%zu: bad element count", path, x.line);
      /* every element takes at least one byte: bound the count by the file
       * (this also keeps the conversion to long defined) */
      if (n > (double)len || n > UINT32_MAX)
        return gr_fail(e, GR_EPARSE, "%s:%zu: element count %.0f exceeds what the file's %zu bytes can hold",
                       path, x.line, n, len);
      if (!strcmp(w, "vertex")) { nv = (long)n; cur = 1; }
      else if (!strcmp(w, "face")) { nf = (long)n; cur = 2; }
      else if (n > 0) return gr_fail(e, GR_EPARSE, "%s:%zu: unsupported PLY element '%s'", path, x.line, w);
      else cur = 3;
    } else if (!strcmp(w, "property")) {
      char ty[32], nm[64];
      word(&x, ty, sizeof ty);
      if (!strcmp(ty, "list")) {
        char ct[32], it[32];
        word(&x, ct, sizeof ct); word(&x, it, sizeof it); word(&x, nm, sizeof nm);
        list_count = !strcmp(ct, "uchar") || !strcmp(ct, "uint8") ? 1 : !strcmp(ct, "ushort") ? 2 : 4;
        list_index = !strcmp(it, "int") || !strcmp(it, "uint") || !strcmp(it, "int32") || !strcmp(it, "uint32") ? 4 : 0;
        if (binary && list_index == 0)
          return gr_fail(e, GR_EPARSE, "%s:%zu: unsupported face index type '%s'", path, x.line, it);
      } else {
        word(&x, nm, sizeof nm);
        if (cur == 1) {
          int d = !strcmp(nm, "x") ? 0 : !strcmp(nm, "y") ? 1 : !strcmp(nm, "z") ? 2 : -1;
          if (binary && strcmp(ty, "float") && strcmp(ty, "float32"))
            return gr_fail(e, GR_EPARSE, "%s:%zu: unsupported vertex property type '%s'", path, x.line, ty);
          if (d >= 0) xyz[d] = nprop;
          nprop++;
          vsize += 4;
        }
      }
    }
    while (*x.s && *x.s != '\n') x.s++;
  }
  while (*x.s && *x.s != '\n') x.s++;
  if (*x.s) x.s++;
  x.line++;
  if (nv < 0 || nf < 0 || xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
    return gr_fail(e, GR_EPARSE, "%s: PLY header lacks vertex x y z or face elements", path);
  if (!binary) {
    for (long i = 0; i < nv; i++) {
      double p[3] = {0, 0, 0}, t; /* every one set: x, y and z were found */
      for (int k = 0; k < nprop; k++) {
        if (!number(&x, &t)) return gr_fail(e, GR_EPARSE, "%s:%zu: bad vertex value", path, x.line);
        for (int d = 0; d < 3; d++) if (xyz[d] == k) p[d] = t;
      }
      if (gr_mesh_add_vertex(m, p[0], p[1], p[2]) < 0) return gr_fail(e, GR_EMEM, "out of memory");
    }
    for (long i = 0; i < nf; i++) {
      double c, t;
      long idx[3] = {0, 0, 0};
      if (!number(&x, &c) || c < 3 || c > (double)len)
        return gr_fail(e, GR_EPARSE, "%s:%zu: bad face vertex count", path, x.line);
      for (int k = 0; k < (int)c; k++) {
        if (!number(&x, &t) || t < 0 || t >= (double)nv)
          return gr_fail(e, GR_EPARSE, "%s:%zu: bad face index", path, x.line);
        if (k < 2) idx[k] = (long)t;
        else {
          idx[2] = (long)t;
          if (gr_mesh_add_face(m, (uint32_t)idx[0], (uint32_t)idx[1], (uint32_t)idx[2]))
            return gr_fail(e, GR_EMEM, "out of memory");
          idx[1] = idx[2];
        }
      }
    }
    return GR_OK;
  }
  const unsigned char *b = (const unsigned char *)x.s, *end = (const unsigned char *)s + len;
  for (long i = 0; i < nv; i++) {
    if (end - b < vsize)
      return gr_fail(e, GR_EPARSE, "%s: byte %zu: PLY vertex data truncated", path,
                     (size_t)(b - (const unsigned char *)s));
    double p[3];
    for (int d = 0; d < 3; d++) p[d] = get_f32(b + 4 * xyz[d]);
    b += vsize;
    if (gr_mesh_add_vertex(m, p[0], p[1], p[2]) < 0) return gr_fail(e, GR_EMEM, "out of memory");
  }
  for (long i = 0; i < nf; i++) {
    size_t off = (size_t)(b - (const unsigned char *)s);
    if (end - b < list_count) return gr_fail(e, GR_EPARSE, "%s: byte %zu: PLY face data truncated", path, off);
    uint32_t c = list_count == 1 ? b[0] : list_count == 2 ? (uint32_t)(b[0] | b[1] << 8) : get_u32(b);
    b += list_count;
    if (c < 3 || (size_t)(end - b) < (size_t)c * 4)
      return gr_fail(e, GR_EPARSE, "%s: byte %zu: bad or truncated PLY face", path, off);
    uint32_t idx[3];
    for (uint32_t k = 0; k < c; k++, b += 4) {
      uint32_t t = get_u32(b);
      if (t >= (uint32_t)nv)
        return gr_fail(e, GR_EPARSE, "%s: byte %zu: face index %u out of range", path, off, t);
      if (k < 2) idx[k] = t;
      else {
        idx[2] = t;
        if (gr_mesh_add_face(m, idx[0], idx[1], idx[2])) return gr_fail(e, GR_EMEM, "out of memory");
        idx[1] = t;
      }
    }
  }
  return GR_OK;
}

static gr_mesh *parse_mesh(const char *path, char *s, size_t len, gr_err *e);

gr_mesh *gr_mesh_read(const char *path, gr_err *e) {
  gr_err_clear(e);
  if (!path) { gr_fail(e, GR_EARG, "path must not be NULL"); return NULL; }
  size_t len;
  char *s = slurp(path, &len, e);
  if (!s) return NULL;
  return parse_mesh(path, s, len, e);
}

gr_mesh *gr_mesh_read_mem(const char *name, const void *data, size_t len, gr_err *e) {
  gr_err_clear(e);
  if (!name || (!data && len)) { gr_fail(e, GR_EARG, "name and data must not be NULL"); return NULL; }
  char *s = malloc(len + 1);
  if (!s) { gr_fail(e, GR_EMEM, "out of memory reading %s", name); return NULL; }
  if (len) memcpy(s, data, len);
  s[len] = 0;
  return parse_mesh(name, s, len, e);
}

/* Parse the NUL-terminated contents s (len bytes) of `path` and free s. */
static gr_mesh *parse_mesh(const char *path, char *s, size_t len, gr_err *e) {
  gr_mesh *m = gr_mesh_new();
  int rc;
  if (!m) rc = gr_fail(e, GR_EMEM, "out of memory reading %s", path);
  else if (len >= 3 && !strncmp(s, "ply", 3)) rc = read_ply(path, s, len, m, e);
  else if (ends_with(path, ".obj")) rc = read_obj(path, s, m, e);
  else {
    /* STL: binary when the size matches the triangle count, else ASCII if it
     * starts with 'solid', else a binary file that is too short. */
    size_t n = len >= 84 ? get_u32((unsigned char *)s + 80) : 0;
    int is_bin = len >= 84 && len == 84 + 50 * n;
    const char *p = s;
    while (isspace((unsigned char)*p)) p++;
    if (is_bin) rc = read_stl_bin(path, (unsigned char *)s, len, m, e);
    else if (!strncmp(p, "solid", 5) && memchr(s, 0, len) == NULL) rc = read_stl_ascii(path, s, m, e);
    else if (len < 84) rc = gr_fail(e, GR_EPARSE, "%s: byte %zu: file too short for binary STL (84 bytes)", path, len);
    else rc = read_stl_bin(path, (unsigned char *)s, len, m, e);
  }
  free(s);
  if (rc) { gr_mesh_free(m); return NULL; }
  return m;
}
