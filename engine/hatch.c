/* hatch.c: hatch infill of a region (parallel, zigzag, islands), see
 * hatch.h; the contours and thin walls of a section are in contour.c. */
#include "hatch.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define DEG (3.14159265358979323846 / 180.0)
#define MAX_LINES 20000000L

gr_hatch_opts gr_hatch_defaults(void) {
  gr_hatch_opts o;
  memset(&o, 0, sizeof o);
  o.spacing = 0.1;
  o.beam_offset = NAN;
  o.contours = 1;
  o.contour_first = 1;
  o.gap = 0;
  o.pattern = GR_PARALLEL;
  o.alternate = 1;
  o.angle = 45;
  o.island = 5;
  o.min_length = 0;
  o.laser = 0;
  o.cell = NAN;
  o.offset = NULL;
  o.thin_box[0] = o.thin_box[1] = -INFINITY;
  o.thin_box[2] = o.thin_box[3] = INFINITY;
  o.cut[0] = o.cut[1] = o.cut[2] = o.cut[3] = NAN;
  return o;
}

double gr_hatch_angle(long k, double first, double increment) {
  double a = fmod(first + (double)k * increment, 360.0);
  if (a < 0) a += 360.0;
  if (a >= 360.0) a -= 360.0;
  return a;
}

int gr_hatch_check(const gr_hatch_opts *o, gr_err *e) {
  if (!o) return gr_fail(e, GR_EARG, "hatch: options are NULL");
  if (!(o->spacing > 0) || !isfinite(o->spacing))
    return gr_fail(e, GR_EARG, "hatch spacing must be > 0, got %g", o->spacing);
  if (!isnan(o->beam_offset) && (!(o->beam_offset >= 0) || !isfinite(o->beam_offset)))
    return gr_fail(e, GR_EARG, "hatch beam_offset must be >= 0, got %g", o->beam_offset);
  if (o->contours < 0 || o->contours > 100)
    return gr_fail(e, GR_EARG, "hatch contours must be in 0..100, got %d", o->contours);
  if (!isfinite(o->gap))
    return gr_fail(e, GR_EARG, "hatch gap must be finite, got %g", o->gap);
  if (o->pattern < GR_PARALLEL || o->pattern > GR_ISLAND)
    return gr_fail(e, GR_EARG, "hatch pattern must be parallel, zigzag or island, got %d", o->pattern);
  if (!isfinite(o->angle))
    return gr_fail(e, GR_EARG, "hatch angle must be finite (degrees), got %g", o->angle);
  if (o->pattern == GR_ISLAND && (!(o->island > 0) || !isfinite(o->island)))
    return gr_fail(e, GR_EARG, "hatch island size must be > 0, got %g", o->island);
  if (!isfinite(o->island_origin[0]) || !isfinite(o->island_origin[1]))
    return gr_fail(e, GR_EARG, "hatch island origin must be finite, got (%g, %g)",
                   o->island_origin[0], o->island_origin[1]);
  if (!(o->min_length >= 0) || !isfinite(o->min_length))
    return gr_fail(e, GR_EARG, "hatch min_length must be >= 0, got %g", o->min_length);
  if (o->laser < 0)
    return gr_fail(e, GR_EARG, "hatch laser must be >= 0, got %d", o->laser);
  if (!isnan(o->cell) && (!(o->cell > 0) || !isfinite(o->cell)))
    return gr_fail(e, GR_EARG, "hatch cell must be > 0, got %g", o->cell);
  if (!(o->thin_box[0] <= o->thin_box[2]) || !(o->thin_box[1] <= o->thin_box[3]))
    return gr_fail(e, GR_EARG, "hatch thin_box must be {x0, y0, x1, y1} with x0 <= x1 and y0 <= y1, got {%g, %g, %g, %g}",
                   o->thin_box[0], o->thin_box[1], o->thin_box[2], o->thin_box[3]);
  if (!isnan(o->cut[0]) && !(o->cut[0] < o->cut[2] && o->cut[1] < o->cut[3] && isfinite(o->cut[0]) &&
                             isfinite(o->cut[1]) && isfinite(o->cut[2]) && isfinite(o->cut[3])))
    return gr_fail(e, GR_EARG, "hatch cut must be NaN or {x0, y0, x1, y1} with x0 < x1 and y0 < y1, got {%g, %g, %g, %g}",
                   o->cut[0], o->cut[1], o->cut[2], o->cut[3]);
  return GR_OK;
}

/* ------------------------------------------------------------------ */
/* Scanline machinery in rotated coordinates: u along the hatch direction
 * t = (c, s), v along the normal n = (-s, c). Line k is v = k*d. */

typedef struct edge { double ua, va, ub, vb; } edge; /* va <= vb */
typedef struct seg { long k; double u0, u1; } seg;

typedef struct scan {
  double c, s, d;
  edge *ed; size_t ne;
  long kmin, kmax;       /* line range */
  seg *sg; size_t ns;    /* hatch intervals sorted by (k, u0) */
  size_t *lstart;        /* first seg of each line, nlines + 1 */
  size_t *bstart, *bed;  /* band k (between lines k and k+1) -> edge indices */
} scan;

static void scan_free(scan *sc) {
  free(sc->ed); free(sc->sg); free(sc->lstart); free(sc->bstart); free(sc->bed);
  memset(sc, 0, sizeof *sc);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* First line index k with k*d >= v (same expression k*d everywhere, so that
 * the line family is bit-identical across calls). */
static long line_at_or_above(double v, double d) {
  /* any guess within a line or two gives the same k (the loops below
   * settle it: k*d grows with k); truncation is cheaper than ceil */
  long k = (long)(v / d);
  while ((double)k * d < v) k++;
  while ((double)(k - 1) * d >= v) k--;
  return k;
}

/* Build the edges and the crossings of every line with the region's edges,
 * bucketed per line (counting sort), then sort and pair them by even-odd.
 * Edges are canonical (lower v first) so that an edge shared by two
 * regions gives the identical crossing in both. */
static int scan_build(scan *sc, const gr_rings *r, double angle, double d,
                      int want_bands, gr_err *e) {
  memset(sc, 0, sizeof *sc);
  sc->c = cos(angle * DEG); sc->s = sin(angle * DEG); sc->d = d;
  if (r->npts == 0) { sc->kmin = 0; sc->kmax = -1; return GR_OK; }
  sc->ed = malloc(r->npts * sizeof *sc->ed);
  if (!sc->ed) return gr_fail(e, GR_EMEM, "hatch: out of memory (%zu edges)", r->npts);
  double vlo = INFINITY, vhi = -INFINITY;
  for (size_t i = 0; i < r->nrings; i++) {
    const double *p = gr_ring_xy(r, i);
    size_t n = gr_ring_len(r, i);
    for (size_t a = 0; a < n; a++) {
      size_t b = gr_ring_next(a, n);
      double ua = p[2 * a] * sc->c + p[2 * a + 1] * sc->s;
      double va = -p[2 * a] * sc->s + p[2 * a + 1] * sc->c;
      double ub = p[2 * b] * sc->c + p[2 * b + 1] * sc->s;
      double vb = -p[2 * b] * sc->s + p[2 * b + 1] * sc->c;
      if (!isfinite(ua) || !isfinite(va))
        return gr_fail(e, GR_ENUM, "hatch: ring %zu point %zu is not finite", i, a);
      edge E = va <= vb ? (edge){ua, va, ub, vb} : (edge){ub, vb, ua, va};
      if (E.va == E.vb && a == b) continue;
      sc->ed[sc->ne++] = E;
      if (E.va < vlo) vlo = E.va;
      if (E.vb > vhi) vhi = E.vb;
    }
  }
  if (sc->ne == 0) { sc->kmin = 0; sc->kmax = -1; return GR_OK; }
  if (fabs(vlo / d) > 1e15 || fabs(vhi / d) > 1e15)
    return gr_fail(e, GR_EARG, "hatch: coordinates up to %g are too far from the origin for spacing %g",
                   fmax(fabs(vlo), fabs(vhi)), d);
  double span = (vhi - vlo) / d;
  if (span > (double)MAX_LINES)
    return gr_fail(e, GR_EARG, "hatch: region spans %.0f lines at spacing %g (limit %ld)",
                   span, d, MAX_LINES);
  sc->kmin = (long)floor(vlo / d) - 1;
  sc->kmax = (long)ceil(vhi / d) + 1;
  size_t nl = (size_t)(sc->kmax - sc->kmin + 1);
  size_t *cnt = calloc(nl + 1, sizeof *cnt);
  if (!cnt) return gr_fail(e, GR_EMEM, "hatch: out of memory (%zu lines)", nl);
  /* each edge's first line, found once for both passes (most edges of a
   * finely chorded region cross no line at all) */
  long *k0 = malloc(sc->ne * sizeof *k0);
  if (!k0) { free(cnt); return gr_fail(e, GR_EMEM, "hatch: out of memory (%zu edges)", sc->ne); }
  size_t total = 0;
  for (size_t i = 0; i < sc->ne; i++) {
    const edge *E = &sc->ed[i];
    k0[i] = line_at_or_above(E->va, d);
    for (long k = k0[i]; (double)k * d < E->vb; k++) {
      cnt[k - sc->kmin + 1]++;
      total++;
    }
  }
  for (size_t i = 0; i < nl; i++) cnt[i + 1] += cnt[i];
  double *cu = malloc((total ? total : 1) * sizeof *cu);
  size_t *fill = malloc(nl * sizeof *fill);
  sc->sg = malloc((total / 2 + 1) * sizeof *sc->sg);
  sc->lstart = malloc((nl + 1) * sizeof *sc->lstart);
  if (!cu || !fill || !sc->sg || !sc->lstart) {
    free(cnt); free(cu); free(fill); free(k0);
    return gr_fail(e, GR_EMEM, "hatch: out of memory (%zu crossings)", total);
  }
  memcpy(fill, cnt, nl * sizeof *fill);
  for (size_t i = 0; i < sc->ne; i++) {
    const edge *E = &sc->ed[i];
    for (long k = k0[i]; (double)k * d < E->vb; k++) {
      double v = (double)k * d;
      cu[fill[k - sc->kmin]++] = E->ua + (v - E->va) * (E->ub - E->ua) / (E->vb - E->va);
    }
  }
  for (size_t l = 0; l < nl; l++) {
    size_t a = cnt[l], b = cnt[l + 1];
    sc->lstart[l] = sc->ns;
    if (b - a > 1) qsort(cu + a, b - a, sizeof *cu, cmp_double);
    for (size_t j = a; j + 1 < b; j += 2)
      if (cu[j + 1] > cu[j]) sc->sg[sc->ns++] = (seg){sc->kmin + (long)l, cu[j], cu[j + 1]};
  }
  sc->lstart[nl] = sc->ns;
  free(cu); free(fill); free(cnt); free(k0);
  if (!want_bands) return GR_OK;
  /* bands: band k holds the edges whose v range meets [k d, (k+1) d] */
  size_t *bc = calloc(nl + 1, sizeof *bc);
  if (!bc) return gr_fail(e, GR_EMEM, "hatch: out of memory");
  size_t bt = 0;
  for (size_t i = 0; i < sc->ne; i++) {
    long k0 = (long)floor(sc->ed[i].va / d) - 1, k1 = (long)floor(sc->ed[i].vb / d);
    if (k0 < sc->kmin) k0 = sc->kmin;
    if (k1 > sc->kmax) k1 = sc->kmax;
    for (long k = k0; k <= k1; k++) { bc[k - sc->kmin + 1]++; bt++; }
  }
  for (size_t i = 0; i < nl; i++) bc[i + 1] += bc[i];
  sc->bstart = bc;
  sc->bed = malloc((bt ? bt : 1) * sizeof *sc->bed);
  size_t *bf = malloc(nl * sizeof *bf);
  if (!sc->bed || !bf) { free(bf); return gr_fail(e, GR_EMEM, "hatch: out of memory"); }
  memcpy(bf, bc, nl * sizeof *bf);
  for (size_t i = 0; i < sc->ne; i++) {
    long k0 = (long)floor(sc->ed[i].va / d) - 1, k1 = (long)floor(sc->ed[i].vb / d);
    if (k0 < sc->kmin) k0 = sc->kmin;
    if (k1 > sc->kmax) k1 = sc->kmax;
    for (long k = k0; k <= k1; k++) sc->bed[bf[k - sc->kmin]++] = i;
  }
  free(bf);
  return GR_OK;
}

static void to_xy(const scan *sc, double u, long k, double *x, double *y) {
  double v = (double)k * sc->d;
  *x = u * sc->c - v * sc->s;
  *y = u * sc->s + v * sc->c;
}

static double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/* Does the link from (pu, pv) to (qu, qv) stay inside the region? It must
 * not properly cross any edge of band k (touching at its ends is allowed:
 * the ends lie on the boundary), and its midpoint must be inside (even-odd
 * along the line v = v_mid over the band's edges). */
static int link_inside(const scan *sc, long k, double pu, double pv, double qu, double qv) {
  size_t l = (size_t)(k - sc->kmin);
  double lx = qu - pu, ly = qv - pv, L2 = lx * lx + ly * ly;
  double eps = 1e-9 * (L2 + sc->d * sc->d);
  double mu = 0.5 * (pu + qu), mv = 0.5 * (pv + qv);
  int odd = 0, onedge = 0;
  for (size_t j = sc->bstart[l]; j < sc->bstart[l + 1]; j++) {
    const edge *E = &sc->ed[sc->bed[j]];
    double d1 = cross2(lx, ly, E->ua - pu, E->va - pv);
    double d2 = cross2(lx, ly, E->ub - pu, E->vb - pv);
    double ex = E->ub - E->ua, ey = E->vb - E->va;
    double el = ex * ex + ey * ey;
    double e3 = 1e-9 * (el + sc->d * sc->d);
    double d3 = cross2(ex, ey, pu - E->ua, pv - E->va);
    double d4 = cross2(ex, ey, qu - E->ua, qv - E->va);
    if (((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps)) &&
        ((d3 > e3 && d4 < -e3) || (d3 < -e3 && d4 > e3)))
      return 0;
    if (E->va <= mv && mv < E->vb) {
      double u = E->ua + (mv - E->va) * (E->ub - E->ua) / (E->vb - E->va);
      if (u < mu) odd ^= 1;
    }
    /* a midpoint on an edge: the link runs along the boundary, which is
     * part of the (closed) region */
    double t = el > 0 ? ((mu - E->ua) * ex + (mv - E->va) * ey) / el : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double qx = E->ua + t * ex - mu, qy = E->va + t * ey - mv;
    if (qx * qx + qy * qy <= 1e-18 * (sc->d * sc->d + el)) onedge = 1;
  }
  return odd || onedge;
}

static int hatch_parallel(const scan *sc, const gr_hatch_opts *o, gr_layer *out,
                          gr_hatch_report *rep, gr_err *e) {
  for (size_t i = 0; i < sc->ns; i++) {
    const seg *g = &sc->sg[i];
    double len = g->u1 - g->u0;
    if (len < o->min_length) { rep->dropped++; rep->dropped_length += len; continue; }
    double x0, y0, x1, y1;
    to_xy(sc, g->u0, g->k, &x0, &y0);
    to_xy(sc, g->u1, g->k, &x1, &y1);
    int rev = o->alternate && (g->k & 1);
    int rc = rev ? gr_layer_add_segment(out, GR_HATCH, o->laser, x1, y1, x0, y0)
                 : gr_layer_add_segment(out, GR_HATCH, o->laser, x0, y0, x1, y1);
    if (rc) return gr_fail(e, GR_EMEM, "hatch: out of memory");
    rep->hatches++;
  }
  return GR_OK;
}

/* Zigzag: direction alternates with the global line index; the end of a
 * chain on line k is linked to the nearest free start on line k+1 when the
 * link stays inside the region. */
static int hatch_zigzag(const scan *sc, const gr_hatch_opts *o, gr_layer *out,
                        gr_hatch_report *rep, gr_err *e) {
  size_t ns = sc->ns;
  if (!ns) return GR_OK;
  long *next = malloc(ns * sizeof *next);
  char *keep = malloc(ns), *hasprev = calloc(ns, 1), *taken = calloc(ns, 1);
  double *pts = NULL;
  size_t cap = 0;
  int rc = GR_OK;
  if (!next || !keep || !hasprev || !taken) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  for (size_t i = 0; i < ns; i++) {
    next[i] = -1;
    double len = sc->sg[i].u1 - sc->sg[i].u0;
    keep[i] = len >= o->min_length;
    if (!keep[i]) { rep->dropped++; rep->dropped_length += len; }
  }
  long nl = sc->kmax - sc->kmin + 1;
  for (long l = 0; l + 1 < nl; l++) {
    long k = sc->kmin + l;
    int fwd = !(k & 1);
    size_t a0 = sc->lstart[l], a1 = sc->lstart[l + 1], b1 = sc->lstart[l + 2];
    for (size_t i = a0; i < a1; i++) {
      if (!keep[i]) continue;
      double eu = fwd ? sc->sg[i].u1 : sc->sg[i].u0, ev = (double)k * sc->d;
      long best = -1;
      double bd = INFINITY;
      for (size_t j = a1; j < b1; j++) {
        if (!keep[j] || taken[j]) continue;
        double su = fwd ? sc->sg[j].u1 : sc->sg[j].u0; /* next line runs the other way */
        double dd = fabs(su - eu);
        if (dd < bd) { bd = dd; best = (long)j; }
      }
      if (best < 0) continue;
      double su = fwd ? sc->sg[best].u1 : sc->sg[best].u0, sv = (double)(k + 1) * sc->d;
      if (!link_inside(sc, k, eu, ev, su, sv)) continue;
      next[i] = best;
      taken[best] = 1;
      hasprev[best] = 1;
      rep->links++;
    }
  }
  for (size_t i = 0; i < ns; i++) {
    if (!keep[i] || hasprev[i]) continue;
    size_t n = 0;
    for (long j = (long)i; j >= 0; j = next[j]) {
      const seg *g = &sc->sg[j];
      int fwd = !(g->k & 1);
      if (gr_grow(&pts, &cap, 2 * n + 4, sizeof *pts)) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
      to_xy(sc, fwd ? g->u0 : g->u1, g->k, &pts[2 * n], &pts[2 * n + 1]);
      to_xy(sc, fwd ? g->u1 : g->u0, g->k, &pts[2 * n + 2], &pts[2 * n + 3]);
      n += 2;
      rep->hatches++;
    }
    if (gr_layer_add(out, GR_OPEN, GR_HATCH, o->laser, 2, pts, n)) { rc = gr_fail(e, GR_EMEM, "hatch: out of memory"); goto done; }
  }
done:
  free(next); free(keep); free(hasprev); free(taken); free(pts);
  return rc;
}

typedef struct piece { long i, j, k; double u, x0, y0, x1, y1; } piece;

static int cmp_piece(const void *a, const void *b) {
  const piece *p = a, *q = b;
  if (p->j != q->j) return p->j < q->j ? -1 : 1;
  if (p->i != q->i) return p->i < q->i ? -1 : 1;
  if (p->k != q->k) return p->k < q->k ? -1 : 1;
  return (p->u > q->u) - (p->u < q->u);
}

/* Split the vectors of one line family at the island grid lines and keep
 * the pieces in islands of the given parity. */
static int island_pieces(const scan *sc, const gr_hatch_opts *o, int parity,
                         piece **pp, size_t *np, size_t *cap, gr_hatch_report *rep,
                         gr_err *e) {
  double s = o->island, ox = o->island_origin[0], oy = o->island_origin[1];
  double *ts = NULL;
  size_t tcap = 0;
  for (size_t g = 0; g < sc->ns; g++) {
    double x0, y0, x1, y1;
    to_xy(sc, sc->sg[g].u0, sc->sg[g].k, &x0, &y0);
    to_xy(sc, sc->sg[g].u1, sc->sg[g].k, &x1, &y1);
    double dx = x1 - x0, dy = y1 - y0;
    long ia = (long)floor((fmin(x0, x1) - ox) / s), ib = (long)floor((fmax(x0, x1) - ox) / s);
    long ja = (long)floor((fmin(y0, y1) - oy) / s), jb = (long)floor((fmax(y0, y1) - oy) / s);
    size_t nt = 0, need = (size_t)(ib - ia + jb - ja + 4);
    if (gr_grow(&ts, &tcap, need, sizeof *ts)) { free(ts); return gr_fail(e, GR_EMEM, "hatch: out of memory"); }
    ts[nt++] = 0;
    ts[nt++] = 1;
    if (fabs(dx) > 0)
      for (long i = ia + 1; i <= ib; i++) {
        double t = (ox + (double)i * s - x0) / dx;
        if (t > 0 && t < 1) ts[nt++] = t;
      }
    if (fabs(dy) > 0)
      for (long j = ja + 1; j <= jb; j++) {
        double t = (oy + (double)j * s - y0) / dy;
        if (t > 0 && t < 1) ts[nt++] = t;
      }
    qsort(ts, nt, sizeof *ts, cmp_double);
    for (size_t m = 0; m + 1 < nt; m++) {
      double ta = ts[m], tb = ts[m + 1];
      if (!(tb > ta)) continue;
      double tm = 0.5 * (ta + tb);
      long i = (long)floor((x0 + tm * dx - ox) / s), j = (long)floor((y0 + tm * dy - oy) / s);
      if (((i + j) & 1) != parity) continue;
      double len = (tb - ta) * hypot(dx, dy);
      if (len < o->min_length) { rep->dropped++; rep->dropped_length += len; continue; }
      if (gr_grow(pp, cap, *np + 1, sizeof **pp)) { free(ts); return gr_fail(e, GR_EMEM, "hatch: out of memory"); }
      (*pp)[(*np)++] = (piece){i, j, sc->sg[g].k, sc->sg[g].u0 + ta * (sc->sg[g].u1 - sc->sg[g].u0),
                               x0 + ta * dx, y0 + ta * dy, x0 + tb * dx, y0 + tb * dy};
    }
  }
  free(ts);
  return GR_OK;
}

static int hatch_islands(const gr_rings *region, const gr_hatch_opts *o, gr_layer *out,
                         gr_hatch_report *rep, gr_err *e) {
  piece *pc = NULL;
  size_t np = 0, cap = 0;
  int rc = GR_OK;
  for (int parity = 0; parity < 2 && !rc; parity++) {
    scan sc;
    rc = scan_build(&sc, region, o->angle + 90.0 * parity, o->spacing, 0, e);
    if (!rc) rc = island_pieces(&sc, o, parity, &pc, &np, &cap, rep, e);
    scan_free(&sc);
  }
  if (!rc && np) qsort(pc, np, sizeof *pc, cmp_piece);
  for (size_t m = 0; m < np && !rc; m++) {
    const piece *p = &pc[m];
    int rev = o->alternate && (p->k & 1);
    if (rev ? gr_layer_add_segment(out, GR_HATCH, o->laser, p->x1, p->y1, p->x0, p->y0)
            : gr_layer_add_segment(out, GR_HATCH, o->laser, p->x0, p->y0, p->x1, p->y1))
      rc = gr_fail(e, GR_EMEM, "hatch: out of memory");
    else
      rep->hatches++;
  }
  free(pc);
  return rc;
}

int gr_hatch_region(const gr_rings *region, const gr_hatch_opts *o, gr_layer *out,
                    gr_hatch_report *rep, gr_err *e) {
  gr_hatch_report dummy;
  if (!rep) { memset(&dummy, 0, sizeof dummy); rep = &dummy; }
  int rc = gr_hatch_check(o, e);
  if (rc) return rc;
  if (!region || !out) return gr_fail(e, GR_EARG, "hatch: region and layer must not be NULL");
  if (o->pattern == GR_ISLAND) return hatch_islands(region, o, out, rep, e);
  scan sc;
  rc = scan_build(&sc, region, o->angle, o->spacing, o->pattern == GR_ZIGZAG, e);
  if (!rc) rc = o->pattern == GR_ZIGZAG ? hatch_zigzag(&sc, o, out, rep, e)
                                        : hatch_parallel(&sc, o, out, rep, e);
  scan_free(&sc);
  return rc;
}
