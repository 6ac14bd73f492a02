/* plate.c: several parts placed on one build plate, merged by z (plate.h). */
#include "plate.h"
#include "cli.h"
#include <stdlib.h>
#include <string.h>

typedef struct pl_part {
  char *path, *name;
  gr_layer **layer;  /* placed layers, by increasing z; NULL once written */
  size_t n, cap;
  double zlo, zhi;   /* $$DIMENSION z range */
  double c[2];       /* centre of the own x-y extent */
  double *hull;      /* placed footprint, CCW */
  size_t nhull, caphull; /* points; capacity in doubles */
  int lasers;
  double length;
} pl_part;

struct gr_plate {
  pl_part *part;
  int n, cap;
};

gr_plate *gr_plate_new(void) { return calloc(1, sizeof(gr_plate)); }

static void pl_part_free(pl_part *q) {
  for (size_t k = 0; k < q->n; k++) gr_layer_free(q->layer[k]);
  free(q->layer);
  free(q->hull);
  free(q->path);
  free(q->name);
}

void gr_plate_free(gr_plate *p) {
  if (!p) return;
  for (int i = 0; i < p->n; i++) pl_part_free(&p->part[i]);
  free(p->part);
  free(p);
}

int gr_plate_count(const gr_plate *p) { return p->n; }

static int pl_keep_layer(void *ud, const gr_layer *l, gr_err *e) {
  pl_part *q = ud;
  if (gr_grow(&q->layer, &q->cap, q->n + 1, sizeof *q->layer)) return gr_fail(e, GR_EMEM, "out of memory");
  gr_layer *c = gr_layer_new(l->z);
  if (!c || gr_layer_append(c, l, 0, 0)) {
    gr_layer_free(c);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  q->layer[q->n++] = c;
  return GR_OK;
}

static double pl_cross(const double *o, const double *a, const double *b) {
  return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

static int pl_by_xy(const void *a, const void *b) {
  const double *u = a, *v = b;
  if (u[0] != v[0]) return u[0] < v[0] ? -1 : 1;
  return (u[1] > v[1]) - (u[1] < v[1]);
}

/* Convex hull of the n points in pts (sorted and overwritten): Andrew's
 * monotone chain, collinear points dropped; the hull goes to out (room for
 * n + 1 points), CCW. Returns its size. */
static size_t pl_hull(double *pts, size_t n, double *out) {
  if (n < 3) {
    memcpy(out, pts, n * 2 * sizeof *pts);
    return n;
  }
  qsort(pts, n, 2 * sizeof *pts, pl_by_xy);
  size_t k = 0;
  for (size_t i = 0; i < n; i++) { /* lower chain */
    while (k >= 2 && pl_cross(out + 2 * (k - 2), out + 2 * (k - 1), pts + 2 * i) <= 0) k--;
    memcpy(out + 2 * k++, pts + 2 * i, 2 * sizeof *pts);
  }
  for (size_t i = n - 1, t = k + 1; i-- > 0;) { /* upper chain */
    while (k >= t && pl_cross(out + 2 * (k - 2), out + 2 * (k - 1), pts + 2 * i) <= 0) k--;
    memcpy(out + 2 * k++, pts + 2 * i, 2 * sizeof *pts);
  }
  return k - 1; /* the last point repeats the first */
}

/* Rotate and translate every layer of q; the footprint hull grows layer by
 * layer (the hull so far plus the layer's points), so memory stays small. */
static int pl_place(pl_part *q, double ax, double ay, double deg, gr_err *e) {
  double r = deg * M_PI / 180.0, cs = cos(r), sn = sin(r);
  double *buf = NULL;
  size_t cap = 0;
  for (size_t k = 0; k < q->n; k++) {
    gr_layer *l = q->layer[k];
    for (size_t i = 0; i < l->npts; i++) {
      double x = l->xy[2 * i] - q->c[0], y = l->xy[2 * i + 1] - q->c[1];
      l->xy[2 * i] = ax + cs * x - sn * y;
      l->xy[2 * i + 1] = ay + sn * x + cs * y;
    }
    for (size_t b = 0; b < l->nb; b++) {
      if (l->b[b].laser + 1 > q->lasers) q->lasers = l->b[b].laser + 1;
      q->length += gr_block_length(l, &l->b[b]);
    }
    size_t m = q->nhull + l->npts;
    if (gr_grow(&buf, &cap, 2 * m + 2, sizeof *buf) || gr_grow(&q->hull, &q->caphull, 2 * m + 2, sizeof *q->hull)) {
      free(buf);
      return gr_fail(e, GR_EMEM, "out of memory");
    }
    memcpy(buf, q->hull, q->nhull * 2 * sizeof *buf);
    if (l->npts) memcpy(buf + 2 * q->nhull, l->xy, l->npts * 2 * sizeof *buf);
    q->nhull = pl_hull(buf, m, q->hull);
  }
  free(buf);
  return GR_OK;
}

static char *pl_strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

int gr_plate_add(gr_plate *p, const char *path, const char *name, double at_x, double at_y, double angle_deg,
                 gr_err *e) {
  if (!isfinite(at_x) || !isfinite(at_y) || !isfinite(angle_deg))
    return gr_fail(e, GR_ENUM, "part '%s': placement at (%g, %g), rotation %g: finite numbers expected", name, at_x,
                   at_y, angle_deg);
  size_t cap = (size_t)p->cap;
  if (gr_grow(&p->part, &cap, (size_t)p->n + 1, sizeof *p->part)) return gr_fail(e, GR_EMEM, "out of memory");
  p->cap = (int)cap;
  pl_part *q = &p->part[p->n];
  memset(q, 0, sizeof *q);
  q->path = pl_strdup(path);
  q->name = pl_strdup(name);
  gr_cli_header h;
  int rc = (q->path && q->name) ? gr_cli_read(path, &h, pl_keep_layer, q, e) : gr_fail(e, GR_EMEM, "out of memory");
  if (rc) { /* say which part (the reader's message names the file) */
    char m[sizeof e->msg];
    snprintf(m, sizeof m, "%s", e->msg);
    if (strstr(m, path)) gr_fail(e, rc, "part '%s': %s", name, m);
    else gr_fail(e, rc, "part '%s' (%s): %s", name, path, m);
  }
  if (!rc && q->n == 0) rc = gr_fail(e, GR_EARG, "part '%s' (%s): no layers", name, path);
  if (!rc) {
    int has_dim = h.hi[0] > h.lo[0] || h.hi[1] > h.lo[1];
    double lo[2] = {h.lo[0], h.lo[1]}, hi[2] = {h.hi[0], h.hi[1]};
    if (!has_dim) { /* no $$DIMENSION: the box of the vectors */
      lo[0] = lo[1] = INFINITY;
      hi[0] = hi[1] = -INFINITY;
      for (size_t k = 0; k < q->n; k++) {
        double a[2], b[2];
        if (!q->layer[k]->npts) continue;
        gr_layer_bounds(q->layer[k], a, b);
        for (int d = 0; d < 2; d++) lo[d] = fmin(lo[d], a[d]), hi[d] = fmax(hi[d], b[d]);
      }
      if (!(lo[0] <= hi[0])) lo[0] = lo[1] = hi[0] = hi[1] = 0;
    }
    q->c[0] = 0.5 * (lo[0] + hi[0]);
    q->c[1] = 0.5 * (lo[1] + hi[1]);
    q->zlo = h.hi[2] > h.lo[2] ? h.lo[2] : 0;
    q->zhi = h.hi[2] > h.lo[2] ? h.hi[2] : q->layer[q->n - 1]->z;
    rc = pl_place(q, at_x, at_y, angle_deg, e);
  }
  if (rc) {
    pl_part_free(q);
    return rc;
  }
  p->n++;
  return GR_OK;
}

int gr_plate_part(const gr_plate *p, int i, gr_plate_part_info *info) {
  if (i < 0 || i >= p->n) return GR_EARG;
  const pl_part *q = &p->part[i];
  info->layers = (int)q->n;
  info->lasers = q->lasers;
  info->zlo = q->zlo;
  info->zhi = q->zhi;
  info->centre[0] = q->c[0];
  info->centre[1] = q->c[1];
  info->lo[0] = info->lo[1] = INFINITY;
  info->hi[0] = info->hi[1] = -INFINITY;
  for (size_t k = 0; k < q->nhull; k++)
    for (int d = 0; d < 2; d++) {
      info->lo[d] = fmin(info->lo[d], q->hull[2 * k + d]);
      info->hi[d] = fmax(info->hi[d], q->hull[2 * k + d]);
    }
  info->length = q->length;
  return GR_OK;
}

const double *gr_plate_hull(const gr_plate *p, int i, size_t *n) {
  if (i < 0 || i >= p->n) { *n = 0; return NULL; }
  *n = p->part[i].nhull;
  return p->part[i].hull;
}

/* Projections of polygon a (n points) on the axis (nx, ny). */
static void pl_project(const double *a, size_t n, double nx, double ny, double *lo, double *hi) {
  *lo = INFINITY;
  *hi = -INFINITY;
  for (size_t k = 0; k < n; k++) {
    double s = a[2 * k] * nx + a[2 * k + 1] * ny;
    if (s < *lo) *lo = s;
    if (s > *hi) *hi = s;
  }
}

/* 1 when an edge normal (or, for a segment, its direction) of a separates a
 * from b by at least -tol (they are apart or overlap by no more than tol). */
static int pl_separated(const double *a, size_t na, const double *b, size_t nb, double tol) {
  for (size_t k = 0; k < na; k++) {
    const double *u = a + 2 * k, *v = a + 2 * ((k + 1) % na);
    double dx = v[0] - u[0], dy = v[1] - u[1], len = gr_len2d(dx, dy);
    if (len <= 0) continue;
    for (int t = 0; t < (na == 2 ? 2 : 1); t++) {
      double nx = t ? dx / len : dy / len, ny = t ? dy / len : -dx / len;
      double alo, ahi, blo, bhi;
      pl_project(a, na, nx, ny, &alo, &ahi);
      pl_project(b, nb, nx, ny, &blo, &bhi);
      if (ahi <= blo + tol || bhi <= alo + tol) return 1;
    }
  }
  return 0;
}

int gr_plate_poly_overlap(const double *a, size_t na, const double *b, size_t nb, double tol) {
  if (na == 0 || nb == 0 || (na == 1 && nb == 1)) return 0;
  return !pl_separated(a, na, b, nb, tol) && !pl_separated(b, nb, a, na, tol);
}

int gr_plate_overlap(const gr_plate *p, int i, int j, double tol) {
  if (i < 0 || j < 0 || i >= p->n || j >= p->n || i == j) return 0;
  const pl_part *a = &p->part[i], *b = &p->part[j];
  return gr_plate_poly_overlap(a->hull, a->nhull, b->hull, b->nhull, tol);
}

int gr_plate_map_lasers(gr_plate *p, int i, const int *map, int n, gr_err *e) {
  if (i < 0 || i >= p->n) return gr_fail(e, GR_EARG, "no part %d on the plate", i + 1);
  pl_part *q = &p->part[i];
  if (q->lasers > n)
    return gr_fail(e, GR_EARG, "part '%s': it uses laser %d but only %d are mapped", q->name, q->lasers, n);
  for (int k = 0; k < n; k++)
    if (map[k] < 0 || map[k] >= GR_CLI_MAXSTYLES / 3)
      return gr_fail(e, GR_EARG, "part '%s': laser %d mapped to %d (1..%d expected)", q->name, k + 1, map[k] + 1,
                     GR_CLI_MAXSTYLES / 3);
  int top = 0;
  for (size_t k = 0; k < q->n; k++)
    for (size_t b = 0; b < q->layer[k]->nb; b++) {
      int *las = &q->layer[k]->b[b].laser;
      *las = map[*las];
      if (*las + 1 > top) top = *las + 1;
    }
  q->lasers = top;
  return GR_OK;
}

/* Each part's plate layer numbers, checked against the grid; also the floor,
 * the top layer and the x-y box of every footprint. */
static int pl_grid(gr_plate *p, double t, int **num, double *floor_z, int *top, gr_plate_info *info, gr_err *e) {
  double fl = INFINITY;
  for (int i = 0; i < p->n; i++) fl = fmin(fl, p->part[i].zlo);
  *floor_z = fl;
  *top = 0;
  info->lo[0] = info->lo[1] = INFINITY;
  info->hi[0] = info->hi[1] = -INFINITY;
  info->lo[2] = fl;
  info->hi[2] = fl;
  for (int i = 0; i < p->n; i++) {
    pl_part *q = &p->part[i];
    num[i] = malloc((q->n ? q->n : 1) * sizeof **num);
    if (!num[i]) return gr_fail(e, GR_EMEM, "out of memory");
    for (size_t k = 0; k < q->n; k++) {
      double f = (q->layer[k]->z - fl) / t;
      int g = (int)lround(f);
      if (fabs(f - g) > 0.05 || g < 1 || (k > 0 && g <= num[i][k - 1]))
        return gr_fail(e, GR_EARG,
                       "part '%s' (%s): layer %zu at z = %.6f mm is off the plate's layer grid (%.6f mm from z = %.6f "
                       "mm): a part must use the plate's layer thickness",
                       q->name, q->path, k + 1, q->layer[k]->z, t, fl);
      num[i][k] = g;
      if (g > *top) *top = g;
    }
    for (size_t k = 0; k < q->nhull; k++)
      for (int d = 0; d < 2; d++) {
        info->lo[d] = fmin(info->lo[d], q->hull[2 * k + d]);
        info->hi[d] = fmax(info->hi[d], q->hull[2 * k + d]);
      }
  }
  info->hi[2] = fl + *top * t;
  if (!(info->lo[0] <= info->hi[0])) info->lo[0] = info->lo[1] = info->hi[0] = info->hi[1] = 0;
  return GR_OK;
}

/* Write plate layers 1..top: layer g gathers every part's layer g. */
static int pl_layers(gr_plate *p, gr_cli_writer *w, int *const *num, double fl, int top, const gr_plate_opts *o,
                     gr_plate_info *info, gr_err *e) {
  size_t *at = calloc((size_t)p->n, sizeof *at);
  gr_layer *l = gr_layer_new(0);
  int rc = (at && l) ? GR_OK : gr_fail(e, GR_EMEM, "out of memory");
  for (int g = 1; g <= top && !rc; g++) {
    gr_layer_clear(l, fl + g * o->layer_mm);
    for (int i = 0; i < p->n && !rc; i++) {
      pl_part *q = &p->part[i];
      if (at[i] < q->n && num[i][at[i]] == g) {
        if (gr_layer_append(l, q->layer[at[i]], 0, 0)) rc = gr_fail(e, GR_EMEM, "out of memory");
        gr_layer_free(q->layer[at[i]]);
        q->layer[at[i]++] = NULL;
      }
    }
    for (size_t b = 0; b < l->nb && !rc; b++) info->length += gr_block_length(l, &l->b[b]);
    info->blocks += (long)l->nb;
    if (!rc) rc = gr_cli_write_layer(w, l, e);
    if (!rc && g == o->keep) {
      info->kept = gr_layer_new(l->z);
      if (!info->kept || gr_layer_append(info->kept, l, 0, 0)) rc = gr_fail(e, GR_EMEM, "out of memory");
    }
  }
  gr_layer_free(l);
  free(at);
  return rc;
}


/* Bit r set when a block of region r (paths.h) is in any part: the header
 * then labels that region's styles too. */
static int pl_regions(const gr_plate *p) {
  int bits = 0;
  for (int i = 0; i < p->n; i++)
    for (size_t k = 0; k < p->part[i].n; k++) {
      const gr_layer *l = p->part[i].layer[k];
      for (size_t b = 0; l && b < l->nb; b++) bits |= 1 << l->b[b].region;
    }
  return bits;
}

int gr_plate_write(gr_plate *p, const char *out, const gr_plate_opts *o, gr_plate_info *info, gr_err *e) {
  memset(info, 0, sizeof *info);
  if (p->n < 1) return gr_fail(e, GR_EARG, "plate: no parts");
  if (!(o->layer_mm > 0) || !isfinite(o->layer_mm))
    return gr_fail(e, GR_EARG, "plate: layer thickness must be > 0 mm, got %g", o->layer_mm);
  if (!(o->units > 0)) return gr_fail(e, GR_EARG, "plate: units must be > 0 mm, got %g", o->units);
  for (int i = 0; i < p->n; i++)
    for (size_t k = 0; k < p->part[i].n; k++)
      if (!p->part[i].layer[k]) return gr_fail(e, GR_EARG, "plate: already written");
  int **num = calloc((size_t)p->n, sizeof *num);
  if (!num) return gr_fail(e, GR_EMEM, "out of memory");
  double fl = 0;
  int top = 0;
  int rc = pl_grid(p, o->layer_mm, num, &fl, &top, info, e);
  gr_cli_writer *w = NULL;
  if (!rc) {
    gr_cli_header h = gr_cli_header_defaults();
    h.binary = o->binary;
    h.short_form = o->short_form;
    h.units = o->units;
    h.layers = top;
    h.nlasers = o->nlasers > 0 ? o->nlasers : 1;
    h.regions = pl_regions(p);
    h.buffered = 1;
    memcpy(h.lo, info->lo, sizeof h.lo);
    memcpy(h.hi, info->hi, sizeof h.hi);
    w = gr_cli_open(out, &h, e);
    if (!w) rc = e->code ? e->code : GR_EIO;
  }
  if (!rc) rc = pl_layers(p, w, num, fl, top, o, info, e);
  if (w) {
    if (!rc) snprintf(info->form, sizeof info->form, "%s", gr_cli_form(w));
    gr_cli_rounded(w, &info->rounded_points, &info->rounded_vectors);
    int crc = gr_cli_close(w, rc == GR_OK, rc ? NULL : e);
    if (!rc) rc = crc;
  }
  if (!rc) info->layers = top;
  if (rc) {
    gr_layer_free(info->kept);
    info->kept = NULL;
  }
  for (int i = 0; i < p->n; i++) free(num[i]);
  free(num);
  return rc;
}
