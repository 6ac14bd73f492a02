/* verify.c: pore / overmelt fractions and contour deviation, see verify.h. */
#include "verify.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

gr_verify_opts gr_verify_defaults(void) {
  gr_verify_opts o;
  o.track = 0.1;
  o.pixel = NAN;
  o.offset = NAN;
  o.spacing = NAN;
  o.contours = 1;
  o.max_pixels = 100000000L;
  o.clip = 0;
  o.clip_lo[0] = o.clip_lo[1] = o.clip_hi[0] = o.clip_hi[1] = 0;
  return o;
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Pixels of row y (centres x0 + (i+0.5)px) inside [a, b]. */
static void fill_row(unsigned char *row, int nx, double x0, double px, double a, double b,
                     unsigned char bit) {
  long i0 = (long)ceil((a - x0) / px - 0.5), i1 = (long)floor((b - x0) / px - 0.5);
  if (i0 < 0) i0 = 0;
  if (i1 > nx - 1) i1 = nx - 1;
  for (long i = i0; i <= i1; i++) row[i] |= bit;
}

/* Melt one capsule (segment A-B, radius r) row by row: the capsule meets a
 * row in one interval, the hull of the end discs' and the rectangle's. */
static void melt_capsule(unsigned char *img, int nx, int ny, const double lo[2], double px,
                         double ax, double ay, double bx, double by, double r) {
  double ymin = fmin(ay, by) - r, ymax = fmax(ay, by) + r;
  long j0 = (long)ceil((ymin - lo[1]) / px - 0.5), j1 = (long)floor((ymax - lo[1]) / px - 0.5);
  if (j0 < 0) j0 = 0;
  if (j1 > ny - 1) j1 = ny - 1;
  double dx = bx - ax, dy = by - ay, L = hypot(dx, dy);
  double nxv = L > 0 ? -dy / L * r : 0, nyv = L > 0 ? dx / L * r : 0;
  double q[8] = {ax + nxv, ay + nyv, bx + nxv, by + nyv, bx - nxv, by - nyv, ax - nxv, ay - nyv};
  for (long j = j0; j <= j1; j++) {
    double y = lo[1] + ((double)j + 0.5) * px, a = INFINITY, b = -INFINITY;
    double ends[4] = {ax, ay, bx, by};
    for (int k = 0; k < 2; k++) {
      double h = y - ends[2 * k + 1];
      if (fabs(h) <= r) {
        double w = sqrt(r * r - h * h);
        a = fmin(a, ends[2 * k] - w);
        b = fmax(b, ends[2 * k] + w);
      }
    }
    if (L > 0)
      for (int k = 0; k < 4; k++) {
        int m = (k + 1) & 3;
        double y1 = q[2 * k + 1], y2 = q[2 * m + 1], x1 = q[2 * k], x2 = q[2 * m];
        if ((y < y1 && y < y2) || (y > y1 && y > y2)) continue;
        if (y1 == y2) { a = fmin(a, fmin(x1, x2)); b = fmax(b, fmax(x1, x2)); continue; }
        double x = x1 + (y - y1) * (x2 - x1) / (y2 - y1);
        a = fmin(a, x);
        b = fmax(b, x);
      }
    if (a <= b) fill_row(img + (size_t)j * nx, nx, lo[0], px, a, b, 2);
  }
}

/* Points measured inside every contour segment, besides its vertices. */
#define DEV_INSIDE 3

static double dist_boundary(const gr_rings *s, double x, double y) {
  double best = INFINITY;
  for (size_t i = 0; i < s->nrings; i++) {
    const double *p = gr_ring_xy(s, i);
    size_t n = gr_ring_len(s, i);
    for (size_t a = 0, b = n - 1; a < n; b = a++) {
      double ex = p[2 * a] - p[2 * b], ey = p[2 * a + 1] - p[2 * b + 1];
      double qx = x - p[2 * b], qy = y - p[2 * b + 1];
      double l2 = ex * ex + ey * ey, t = l2 > 0 ? (qx * ex + qy * ey) / l2 : 0;
      t = t < 0 ? 0 : t > 1 ? 1 : t;
      double dx = qx - t * ex, dy = qy - t * ey, d2 = dx * dx + dy * dy;
      if (d2 < best) best = d2;
    }
  }
  return sqrt(best);
}

/* The x of every ring edge crossing the row y (half-open in y, so that a
 * vertex on the row counts once), into xs; returns their number. */
static size_t row_crossings(const gr_rings *s, double y, double *xs) {
  size_t n = 0;
  for (size_t i = 0; i < s->nrings; i++) {
    const double *p = gr_ring_xy(s, i);
    size_t m = gr_ring_len(s, i);
    for (size_t a = 0, c = m - 1; a < m; c = a++) {
      double ya = p[2 * a + 1], yc = p[2 * c + 1];
      if ((ya <= y && y < yc) || (yc <= y && y < ya))
        xs[n++] = p[2 * a] + (y - ya) * (p[2 * c] - p[2 * a]) / (yc - ya);
    }
  }
  return n;
}

/* Even-odd: is (x, y) inside the section? xs: scratch for npts values. */
static int inside(const gr_rings *s, double x, double y, double *xs) {
  size_t n = row_crossings(s, y, xs), left = 0;
  for (size_t k = 0; k < n; k++) left += xs[k] < x;
  return (int)(left & 1);
}

/* Clip segment A-B to the box [lo, hi] (Liang-Barsky): the parameters
 * t0 <= t1 of the part inside, or 0 when none is. */
static int clip_segment(const double A[2], const double B[2], const double lo[2], const double hi[2],
                        double *t0, double *t1) {
  *t0 = 0;
  *t1 = 1;
  for (int c = 0; c < 2; c++) {
    double d = B[c] - A[c];
    double p[2] = {-d, d}, q[2] = {A[c] - lo[c], hi[c] - A[c]};
    for (int k = 0; k < 2; k++) {
      if (p[k] == 0) {
        if (q[k] < 0) return 0;
        continue;
      }
      double t = q[k] / p[k];
      if (p[k] < 0) *t0 = fmax(*t0, t);
      else *t1 = fmin(*t1, t);
    }
  }
  return *t0 < *t1;
}

/* Length of segment A-B (the part in the clip box, if any) and of its parts
 * outside the section: the segment is cut at every crossing of a ring edge,
 * each piece's midpoint decides (exact, no raster). ts, xs: scratch room for
 * npts + 2 values each. */
static void segment_outside(const gr_rings *s, const gr_verify_opts *o, const double A[2], const double B[2],
                            double *ts, double *xs, double *len, double *out) {
  double t0 = 0, t1 = 1;
  if (o->clip && !clip_segment(A, B, o->clip_lo, o->clip_hi, &t0, &t1)) return;
  double dx = B[0] - A[0], dy = B[1] - A[1], L = hypot(dx, dy);
  size_t n = 0;
  ts[n++] = t0;
  for (size_t i = 0; i < s->nrings; i++) {
    const double *p = gr_ring_xy(s, i);
    size_t m = gr_ring_len(s, i);
    for (size_t a = 0, c = m - 1; a < m; c = a++) {
      double ex = p[2 * a] - p[2 * c], ey = p[2 * a + 1] - p[2 * c + 1];
      double den = dx * ey - dy * ex;
      if (den == 0) continue; /* parallel: the pieces' midpoints decide */
      double wx = p[2 * c] - A[0], wy = p[2 * c + 1] - A[1];
      double t = (wx * ey - wy * ex) / den, u = (wx * dy - wy * dx) / den;
      if (t > t0 && t < t1 && u >= 0 && u <= 1) ts[n++] = t;
    }
  }
  ts[n++] = t1;
  qsort(ts, n, sizeof *ts, cmp_double);
  *len += (t1 - t0) * L;
  for (size_t k = 0; k + 1 < n; k++) {
    double tm = 0.5 * (ts[k] + ts[k + 1]);
    if (ts[k + 1] > ts[k] && !inside(s, A[0] + tm * dx, A[1] + tm * dy, xs)) *out += (ts[k + 1] - ts[k]) * L;
  }
}

/* Hatch length and its part outside the section, over every hatch vector
 * (GR_HATCH blocks: segments and zigzag polylines). */
static void hatch_outside(const gr_rings *s, const gr_layer *l, const gr_verify_opts *o, double *ts,
                          double *xs, gr_verify_result *r) {
  for (size_t bi = 0; bi < l->nb; bi++) {
    const gr_block *B = &l->b[bi];
    if (B->kind != GR_HATCH) continue;
    const double *p = l->xy + 2 * B->start;
    size_t step = B->shape == GR_SEGMENTS ? 2 : 1;
    for (size_t k = 0; k + 1 < B->n; k += step)
      segment_outside(s, o, p + 2 * k, p + 2 * k + 2, ts, xs, &r->hatch_length, &r->hatch_outside);
  }
}

int gr_verify_layer(const gr_rings *section, const gr_layer *l, const gr_verify_opts *o,
                    gr_verify_result *r, gr_err *e) {
  if (!section || !l || !o || !r) return gr_fail(e, GR_EARG, "verify: NULL argument");
  memset(r, 0, sizeof *r);
  double tr = o->track;
  if (!(tr > 0) || !isfinite(tr)) return gr_fail(e, GR_EARG, "verify track must be > 0, got %g", tr);
  double px = isnan(o->pixel) ? tr / 10 : o->pixel;
  if (!(px > 0) || !isfinite(px)) return gr_fail(e, GR_EARG, "verify pixel must be > 0, got %g", o->pixel);
  double b = isnan(o->offset) ? tr / 2 : o->offset;
  if (!(b >= 0) || !isfinite(b)) return gr_fail(e, GR_EARG, "verify offset must be >= 0, got %g", o->offset);
  double sp = isnan(o->spacing) ? tr : o->spacing;
  if (!(sp > 0) || !isfinite(sp)) return gr_fail(e, GR_EARG, "verify spacing must be > 0, got %g", o->spacing);
  if (o->contours < 1) return gr_fail(e, GR_EARG, "verify contours must be >= 1, got %d", o->contours);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < section->npts; k++)
    for (int c = 0; c < 2; c++) {
      lo[c] = fmin(lo[c], section->xy[2 * k + c]);
      hi[c] = fmax(hi[c], section->xy[2 * k + c]);
    }
  if (l->npts) {
    double a[2], c2[2];
    gr_layer_bounds(l, a, c2);
    for (int c = 0; c < 2; c++) { lo[c] = fmin(lo[c], a[c]); hi[c] = fmax(hi[c], c2[c]); }
  }
  if (!(lo[0] <= hi[0]) || !(lo[1] <= hi[1])) return GR_OK; /* nothing at all */
  if (!isfinite(lo[0]) || !isfinite(lo[1]) || !isfinite(hi[0]) || !isfinite(hi[1]))
    return gr_fail(e, GR_ENUM, "verify: coordinates are not finite");
  for (int c = 0; c < 2; c++) { lo[c] -= tr / 2 + px; hi[c] += tr / 2 + px; }
  double fx = ceil((hi[0] - lo[0]) / px), fy = ceil((hi[1] - lo[1]) / px);
  if (fx * fy > (double)o->max_pixels)
    return gr_fail(e, GR_EARG, "verify: raster of %.0f x %.0f pixels at pixel %g exceeds %ld pixels",
                   fx, fy, px, o->max_pixels);
  int nx = (int)fx, ny = (int)fy;
  r->nx = nx;
  r->ny = ny;
  unsigned char *img = calloc((size_t)nx * ny, 1);
  double *xs = malloc(2 * (section->npts + 2) * sizeof *xs);
  if (!img || !xs) { free(img); free(xs); return gr_fail(e, GR_EMEM, "verify: out of memory (%d x %d pixels)", nx, ny); }
  /* solid: even-odd scanline over every ring edge */
  for (int j = 0; j < ny; j++) {
    double y = lo[1] + (j + 0.5) * px;
    size_t n = row_crossings(section, y, xs);
    qsort(xs, n, sizeof *xs, cmp_double);
    for (size_t k = 0; k + 1 < n; k += 2) fill_row(img + (size_t)j * nx, nx, lo[0], px, xs[k], xs[k + 1], 1);
  }
  /* melt: capsules of every scanned segment */
  double dsum = 0;
  for (size_t bi = 0; bi < l->nb; bi++) {
    const gr_block *B = &l->b[bi];
    const double *p = l->xy + 2 * B->start;
    if (B->shape == GR_SEGMENTS) {
      for (size_t k = 0; k + 1 < B->n; k += 2)
        melt_capsule(img, nx, ny, lo, px, p[2 * k], p[2 * k + 1], p[2 * k + 2], p[2 * k + 3], tr / 2);
    } else {
      for (size_t k = 0; k + 1 < B->n; k++)
        melt_capsule(img, nx, ny, lo, px, p[2 * k], p[2 * k + 1], p[2 * k + 2], p[2 * k + 3], tr / 2);
      if (B->n == 1) melt_capsule(img, nx, ny, lo, px, p[0], p[1], p[0], p[1], tr / 2);
    }
    if (B->kind == GR_CONTOUR && B->dir == GR_DIR_THIN) { /* centre lines: not at b by design */
      int in = 0;
      for (size_t k = 0; k < B->n; k++) {
        if (o->clip && (p[2 * k] < o->clip_lo[0] || p[2 * k] > o->clip_hi[0] ||
                        p[2 * k + 1] < o->clip_lo[1] || p[2 * k + 1] > o->clip_hi[1]))
          continue;
        in = 1;
        r->thin_points++;
        if (k + 1 < B->n) r->thin_length += hypot(p[2 * k + 2] - p[2 * k], p[2 * k + 3] - p[2 * k + 1]);
      }
      r->thin_scans += (size_t)in;
    } else if (B->kind == GR_CONTOUR && B->shape != GR_SEGMENTS) {
      /* the vertices and DEV_INSIDE points inside every segment: the laser
       * follows the chord, which can leave a curve both its ends lie on */
      for (size_t k = 0; k < B->n; k++)
        for (int s = 0; s <= DEV_INSIDE && (s == 0 || k + 1 < B->n); s++) {
          if (s == 0 && B->shape == GR_CLOSED && B->n > 1 && k + 1 == B->n) continue; /* the first point again */
          double f = (double)s / (DEV_INSIDE + 1), x = p[2 * k], y = p[2 * k + 1];
          if (s) { x += f * (p[2 * k + 2] - x); y += f * (p[2 * k + 3] - y); }
          if (o->clip && (x < o->clip_lo[0] + 2 * tr || x > o->clip_hi[0] - 2 * tr ||
                          y < o->clip_lo[1] + 2 * tr || y > o->clip_hi[1] - 2 * tr))
            continue;
          double dist = dist_boundary(section, x, y), dev = INFINITY;
          for (int c = 0; c < o->contours; c++) dev = fmin(dev, fabs(dist - (b + c * sp)));
          dsum += dev;
          r->max_dev = fmax(r->max_dev, dev);
          r->contour_points++;
        }
    }
  }
  size_t solid = 0, melt = 0, pore = 0, over = 0;
  for (size_t k = 0; k < (size_t)nx * ny; k++) {
    if (o->clip) {
      double cx = lo[0] + ((double)(k % (size_t)nx) + 0.5) * px, cy = lo[1] + ((double)(k / (size_t)nx) + 0.5) * px;
      if (cx < o->clip_lo[0] || cx > o->clip_hi[0] || cy < o->clip_lo[1] || cy > o->clip_hi[1]) continue;
    }
    unsigned char v = img[k];
    solid += v & 1;
    melt += (v >> 1) & 1;
    pore += v == 1;
    over += v == 2;
  }
  r->solid_area = (double)solid * px * px;
  r->melt_area = (double)melt * px * px;
  r->pore = solid ? (double)pore / (double)solid : 0;
  r->overmelt = solid ? (double)over / (double)solid : (melt ? INFINITY : 0);
  r->mean_dev = r->contour_points ? dsum / (double)r->contour_points : 0;
  hatch_outside(section, l, o, xs, xs + section->npts + 2, r);
  free(img);
  free(xs);
  return GR_OK;
}
