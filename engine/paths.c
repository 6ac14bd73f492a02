/* paths.c: rings and layers, see paths.h. */
#include "paths.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

gr_rings *gr_rings_new(void) {
  gr_rings *r = calloc(1, sizeof *r);
  if (!r) return NULL;
  if (gr_grow(&r->start, &r->caprings, 1, sizeof *r->start)) { free(r); return NULL; }
  r->start[0] = 0;
  return r;
}

void gr_rings_free(gr_rings *r) {
  if (!r) return;
  free(r->xy);
  free(r->start);
  free(r->parent);
  free(r);
}

void gr_rings_clear(gr_rings *r) {
  r->npts = 0;
  r->nrings = 0;
  r->start[0] = 0;
}

int gr_rings_close(gr_rings *r) {
  if (r->npts == r->start[r->nrings]) return GR_OK; /* empty ring: ignore */
  if (gr_grow(&r->start, &r->caprings, r->nrings + 2, sizeof *r->start)) return GR_EMEM;
  r->nrings++;
  r->start[r->nrings] = r->npts;
  free(r->parent); /* nesting is stale now */
  r->parent = NULL;
  return GR_OK;
}

int gr_rings_add(gr_rings *r, const double *xy, size_t n) {
  if (gr_grow(&r->xy, &r->cappts, r->npts + n, 2 * sizeof(double))) return GR_EMEM;
  memcpy(r->xy + 2 * r->npts, xy, n * 2 * sizeof(double));
  r->npts += n;
  return gr_rings_close(r);
}

double gr_ring_area(const gr_rings *r, size_t i) {
  const double *p = gr_ring_xy(r, i);
  size_t n = gr_ring_len(r, i);
  double a = 0;
  for (size_t k = 0, j = n - 1; k < n; j = k++)
    a += (p[2 * j] - p[0]) * (p[2 * k + 1] - p[1]) - (p[2 * k] - p[0]) * (p[2 * j + 1] - p[1]);
  return 0.5 * a;
}

double gr_ring_length(const gr_rings *r, size_t i) {
  const double *p = gr_ring_xy(r, i);
  size_t n = gr_ring_len(r, i);
  double s = 0;
  for (size_t k = 0, j = n - 1; k < n; j = k++)
    s += gr_len2d(p[2 * k] - p[2 * j], p[2 * k + 1] - p[2 * j + 1]);
  return s;
}

double gr_rings_area(const gr_rings *r) {
  double a = 0;
  for (size_t i = 0; i < r->nrings; i++) a += gr_ring_area(r, i);
  return a;
}

void gr_ring_box(const gr_rings *r, size_t i, double b[4]) {
  const double *p = gr_ring_xy(r, i);
  size_t n = gr_ring_len(r, i);
  double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY; /* NaN points pass, as with fmin */
  for (size_t k = 0; k < n; k++) {
    x0 = gr_lo(x0, p[2 * k]); x1 = gr_hi(x1, p[2 * k]);
    y0 = gr_lo(y0, p[2 * k + 1]); y1 = gr_hi(y1, p[2 * k + 1]);
  }
  b[0] = x0; b[1] = y0; b[2] = x1; b[3] = y1;
}

int gr_ring_contains(const gr_rings *r, size_t i, double x, double y) {
  const double *p = gr_ring_xy(r, i);
  size_t n = gr_ring_len(r, i);
  int in = 0;
  for (size_t k = 0, j = n - 1; k < n; j = k++) {
    double xk = p[2 * k], yk = p[2 * k + 1], xj = p[2 * j], yj = p[2 * j + 1];
    double xc;
    if (gr_edge_at_y(xk, yk, xj, yj, y, &xc) && x < xc) in = !in;
  }
  return in;
}

int gr_rings_contains(const gr_rings *r, double x, double y) {
  int in = 0;
  for (size_t i = 0; i < r->nrings; i++) in ^= gr_ring_contains(r, i, x, y);
  return in;
}

static void ring_reverse(gr_rings *r, size_t i) {
  double *p = r->xy + 2 * r->start[i];
  size_t n = gr_ring_len(r, i);
  for (size_t a = 0, b = n - 1; a < b; a++, b--) {
    double tx = p[2 * a], ty = p[2 * a + 1];
    p[2 * a] = p[2 * b];
    p[2 * a + 1] = p[2 * b + 1];
    p[2 * b] = tx;
    p[2 * b + 1] = ty;
  }
}

int gr_rings_nest(gr_rings *r, gr_err *e) {
  size_t n = r->nrings;
  free(r->parent);
  r->parent = malloc((n ? n : 1) * sizeof *r->parent);
  double *box = malloc((n ? n : 1) * 6 * sizeof *box); /* x0 y0 x1 y1 |area| area */
  int *depth = malloc((n ? n : 1) * sizeof *depth);
  if (!r->parent || !box || !depth) {
    free(box);
    free(depth);
    return gr_fail(e, GR_EMEM, "out of memory nesting %zu rings", n);
  }
  for (size_t i = 0; i < n; i++) {
    gr_ring_box(r, i, box + 6 * i);
    box[6 * i + 5] = gr_ring_area(r, i);
    box[6 * i + 4] = fabs(box[6 * i + 5]);
  }
  for (size_t i = 0; i < n; i++) {
    const double *p = gr_ring_xy(r, i);
    long best = -1;
    for (size_t j = 0; j < n; j++) {
      if (j == i) continue;
      const double *b = box + 6 * j, *bi = box + 6 * i;
      /* boxes compared to 1e-9 mm: a ring touching its parent's border
       * segment may differ from it by rounding */
      if (b[4] <= bi[4] || b[0] > bi[0] + 1e-9 || b[1] > bi[1] + 1e-9 || b[2] < bi[2] - 1e-9 || b[3] < bi[3] - 1e-9)
        continue;
      if (best >= 0 && box[6 * best + 4] <= b[4]) continue;
      if (gr_ring_contains(r, j, p[0], p[1])) best = (long)j;
    }
    r->parent[i] = (int)best;
  }
  for (size_t i = 0; i < n; i++) {
    int d = 0;
    for (int q = r->parent[i]; q >= 0 && d <= (int)n; q = r->parent[q]) d++;
    depth[i] = d;
  }
  for (size_t i = 0; i < n; i++) {
    double a = box[6 * i + 5];
    if ((depth[i] % 2 == 0 && a < 0) || (depth[i] % 2 == 1 && a > 0)) ring_reverse(r, i);
  }
  free(box);
  free(depth);
  return GR_OK;
}

void gr_rings_translate(gr_rings *r, double dx, double dy) {
  for (size_t k = 0; k < r->npts; k++) {
    r->xy[2 * k] += dx;
    r->xy[2 * k + 1] += dy;
  }
}

int gr_rings_append(gr_rings *dst, const gr_rings *src, double dx, double dy) {
  for (size_t i = 0; i < src->nrings; i++) {
    const double *p = gr_ring_xy(src, i);
    for (size_t k = 0; k < gr_ring_len(src, i); k++)
      if (gr_rings_point(dst, p[2 * k] + dx, p[2 * k + 1] + dy)) return GR_EMEM;
    if (gr_rings_close(dst)) return GR_EMEM;
  }
  return GR_OK;
}

int gr_rings_copy(gr_rings *dst, const gr_rings *src) {
  gr_rings_clear(dst);
  int rc = gr_rings_append(dst, src, 0, 0);
  if (rc == GR_OK && src->parent) {
    dst->parent = malloc((src->nrings ? src->nrings : 1) * sizeof *dst->parent);
    if (!dst->parent) return GR_EMEM;
    memcpy(dst->parent, src->parent, src->nrings * sizeof *dst->parent);
  }
  return rc;
}

double gr_seg_dist(const double *p, const double *a, const double *b) { return sqrt(gr_seg_dist2(p, a, b)); }

void gr_rings_successors(const gr_rings *r, size_t *nxt) {
  for (size_t i = 0; i < r->nrings; i++)
    for (size_t k = r->start[i], end = r->start[i + 1]; k < end; k++) nxt[k] = k + 1 < end ? k + 1 : r->start[i];
}

/* The point strictly between a and b (indices into p) farthest from the
 * segment pa-pb and farther than tol from it (0: none). No division per
 * point: a point whose foot falls inside the segment is farther than the
 * worst so far w when its cross product with the segment, squared, exceeds
 * w^2 L^2; one beyond an end by its distance to that end. Only a new worst
 * point takes a root. */
static size_t chain_worst(const double *p, size_t a, size_t b, const double *pa, const double *pb, double tol) {
  double ex = pb[0] - pa[0], ey = pb[1] - pa[1], L2 = ex * ex + ey * ey;
  double dw2 = tol * tol, lim = L2 > 0 ? dw2 * L2 : dw2;
  size_t worst = 0;
  for (size_t k = a + 1; k < b; k++) {
    double ux = p[2 * k] - pa[0], uy = p[2 * k + 1] - pa[1], dot = ux * ex + uy * ey, d2;
    if (dot > 0 && dot < L2) {
      double cr = ux * ey - uy * ex;
      if (!(cr * cr > lim)) continue;
      d2 = cr * cr / L2;
    } else {
      double vx = dot > 0 ? p[2 * k] - pb[0] : ux, vy = dot > 0 ? p[2 * k + 1] - pb[1] : uy;
      d2 = vx * vx + vy * vy;
    }
    if (!(d2 > dw2)) continue;
    dw2 = d2;
    lim = L2 > 0 ? d2 * L2 : d2;
    worst = k;
  }
  return worst;
}

int gr_rings_simplify(gr_rings *r, double tol) {
  size_t cap = 0, *stack = NULL;
  unsigned char *keep = malloc(r->npts + 1);
  if (!keep) return GR_EMEM;
  size_t out = 0;
  for (size_t i = 0; i < r->nrings; i++) {
    size_t n = gr_ring_len(r, i), st = r->start[i];
    const double *p = r->xy + 2 * st;
    memset(keep, n < 4, n);
    if (n >= 4) {
      /* anchors: point 0 and the point farthest from it; chains between */
      size_t far = 0;
      double best = -1;
      for (size_t k = 1; k < n; k++) {
        double d = gr_len2d(p[2 * k] - p[0], p[2 * k + 1] - p[1]);
        if (d > best) { best = d; far = k; }
      }
      keep[0] = keep[far] = 1;
      size_t ns = 0;
      if (gr_grow(&stack, &cap, 4, sizeof *stack)) { free(keep); free(stack); return GR_EMEM; }
      stack[ns++] = 0; stack[ns++] = far;
      stack[ns++] = far; stack[ns++] = n;
      while (ns) {
        size_t b = stack[--ns], a = stack[--ns];
        const double *pa = p + 2 * a, *pb = p + 2 * (b % n);
        size_t worst = chain_worst(p, a, b, pa, pb, tol);
        if (!worst) continue;
        keep[worst] = 1;
        if (gr_grow(&stack, &cap, ns + 4, sizeof *stack)) { free(keep); free(stack); return GR_EMEM; }
        stack[ns++] = a; stack[ns++] = worst;
        stack[ns++] = worst; stack[ns++] = b;
      }
      size_t m = 0;
      for (size_t k = 0; k < n; k++) m += keep[k];
      if (m < 3) memset(keep, 1, n);
    }
    size_t o0 = out;
    for (size_t k = 0; k < n; k++)
      if (keep[k]) {
        r->xy[2 * out] = r->xy[2 * (st + k)];
        r->xy[2 * out + 1] = r->xy[2 * (st + k) + 1];
        out++;
      }
    r->start[i] = o0;
  }
  r->start[r->nrings] = out;
  r->npts = out;
  free(keep);
  free(stack);
  return GR_OK;
}

/* ---- layers ---- */
gr_layer *gr_layer_new(double z) {
  gr_layer *l = calloc(1, sizeof *l);
  if (l) l->z = z;
  return l;
}

void gr_layer_free(gr_layer *l) {
  if (!l) return;
  free(l->xy);
  free(l->b);
  free(l);
}

void gr_layer_clear(gr_layer *l, double z) {
  l->z = z;
  l->npts = 0;
  l->nb = 0;
  l->thin_walls = 0;
  l->short_loops = 0;
  l->short_length = 0;
  l->area = 0;
}

int gr_layer_add(gr_layer *l, int shape, int kind, int laser, int dir,
                 const double *xy, size_t n) {
  if (gr_grow(&l->xy, &l->cappts, l->npts + n, 2 * sizeof(double))) return GR_EMEM;
  if (gr_grow(&l->b, &l->capb, l->nb + 1, sizeof *l->b)) return GR_EMEM;
  if (n) memcpy(l->xy + 2 * l->npts, xy, n * 2 * sizeof(double)); /* l->xy may be NULL when n == 0 */
  l->b[l->nb++] = (gr_block){shape, kind, laser, dir, l->npts, n, GR_CORE};
  l->npts += n;
  return GR_OK;
}

int gr_layer_add_segment(gr_layer *l, int kind, int laser, double x0,
                         double y0, double x1, double y1) {
  return gr_layer_add_segment_r(l, kind, GR_CORE, laser, x0, y0, x1, y1);
}

int gr_layer_add_segment_r(gr_layer *l, int kind, int region, int laser, double x0,
                           double y0, double x1, double y1) {
  double s[4] = {x0, y0, x1, y1};
  gr_block *last = l->nb ? &l->b[l->nb - 1] : NULL;
  if (last && last->shape == GR_SEGMENTS && last->kind == kind && last->region == region &&
      last->laser == laser && last->start + last->n == l->npts) {
    if (gr_grow(&l->xy, &l->cappts, l->npts + 2, 2 * sizeof(double))) return GR_EMEM;
    memcpy(l->xy + 2 * l->npts, s, sizeof s);
    l->npts += 2;
    last->n += 2;
    return GR_OK;
  }
  if (gr_layer_add(l, GR_SEGMENTS, kind, laser, 2, s, 2)) return GR_EMEM;
  l->b[l->nb - 1].region = region;
  return GR_OK;
}

int gr_layer_append(gr_layer *dst, const gr_layer *src, double dx, double dy) {
  if (gr_grow(&dst->xy, &dst->cappts, dst->npts + src->npts, 2 * sizeof(double))) return GR_EMEM;
  if (gr_grow(&dst->b, &dst->capb, dst->nb + src->nb, sizeof *dst->b)) return GR_EMEM;
  for (size_t i = 0; i < src->nb; i++) {
    gr_block b = src->b[i];
    const double *p = b.n ? src->xy + 2 * b.start : NULL; /* an empty block has no points to offset */
    b.start = dst->npts;
    for (size_t k = 0; k < b.n; k++) {
      dst->xy[2 * (dst->npts + k)] = p[2 * k] + dx;
      dst->xy[2 * (dst->npts + k) + 1] = p[2 * k + 1] + dy;
    }
    dst->npts += b.n;
    dst->b[dst->nb++] = b;
  }
  dst->thin_walls += src->thin_walls;
  dst->short_loops += src->short_loops;
  dst->short_length += src->short_length;
  dst->area += src->area;
  return GR_OK;
}

double gr_block_length(const gr_layer *l, const gr_block *b) {
  if (b->n < 2) return 0; /* no segment (and an empty layer has no points: xy may be NULL) */
  const double *p = l->xy + 2 * b->start;
  double s = 0;
  if (b->shape == GR_SEGMENTS) {
    for (size_t k = 0; k + 1 < b->n; k += 2)
      s += gr_len2d(p[2 * k + 2] - p[2 * k], p[2 * k + 3] - p[2 * k + 1]);
  } else {
    for (size_t k = 0; k + 1 < b->n; k++)
      s += gr_len2d(p[2 * k + 2] - p[2 * k], p[2 * k + 3] - p[2 * k + 1]);
  }
  return s;
}

void gr_layer_stats_get(const gr_layer *l, gr_layer_stats *s) {
  memset(s, 0, sizeof *s);
  int have = 0;
  double px = 0, py = 0;
  for (size_t i = 0; i < l->nb; i++) {
    const gr_block *b = &l->b[i];
    const double *p = l->xy + 2 * b->start;
    int k = (b->kind >= 0 && b->kind < GR_NKINDS) ? b->kind : GR_EDGE;
    if (b->n == 0) continue;
    if (b->shape == GR_SEGMENTS) {
      for (size_t j = 0; j + 1 < b->n; j += 2) {
        double jl = gr_len2d(p[2 * j] - px, p[2 * j + 1] - py);
        if (have && jl > 1e-9) { s->jumps++; s->jump_length += jl; }
        have = 1;
        s->vectors[k]++;
        px = p[2 * j + 2];
        py = p[2 * j + 3];
      }
    } else {
      double jl = gr_len2d(p[0] - px, p[1] - py);
      if (have && jl > 1e-9) { s->jumps++; s->jump_length += jl; }
      have = 1;
      s->vectors[k] += b->n > 1 ? b->n - 1 : 0;
      px = p[2 * (b->n - 1)];
      py = p[2 * (b->n - 1) + 1];
    }
    s->length[k] += gr_block_length(l, b);
  }
}

void gr_layer_bounds(const gr_layer *l, double lo[2], double hi[2]) {
  lo[0] = lo[1] = INFINITY;
  hi[0] = hi[1] = -INFINITY;
  for (size_t k = 0; k < l->npts; k++) {
    lo[0] = fmin(lo[0], l->xy[2 * k]);
    hi[0] = fmax(hi[0], l->xy[2 * k]);
    lo[1] = fmin(lo[1], l->xy[2 * k + 1]);
    hi[1] = fmax(hi[1], l->xy[2 * k + 1]);
  }
}
