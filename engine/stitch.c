/* stitch.c: closed loops per laser, stitching between lasers, see stitch.h. */
#include "stitch.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "clip.h"
#include "lasers.h"

typedef struct buf { double *p; size_t n, cap; } buf;

static int put(buf *b, double x, double y) {
  if (gr_grow(&b->p, &b->cap, b->n + 1, 2 * sizeof(double))) return GR_EMEM;
  b->p[2 * b->n] = x;
  b->p[2 * b->n + 1] = y;
  b->n++;
  return GR_OK;
}

static double seg_len(const double *p, size_t a) {
  return gr_len2d(p[2 * a + 2] - p[2 * a], p[2 * a + 3] - p[2 * a + 1]);
}

/* Length of piece k of the chain, mm. */
static double piece_len(const gr_stitch_chain *c, size_t k) {
  double s = 0;
  for (size_t a = c->ps[k]; a < c->ps[k + 1]; a++) s += seg_len(c->p, a);
  return s;
}

/* The laser that scans the chain whole: the largest share of its length
 * among the lasers whose field holds the chain's bounding box; -1: none. */
static int pick_laser(const gr_machine *m, const gr_stitch_chain *c) {
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t q = 0; q < c->m; q++)
    for (int a = 0; a < 2; a++) {
      if (c->p[2 * q + a] < lo[a]) lo[a] = c->p[2 * q + a];
      if (c->p[2 * q + a] > hi[a]) hi[a] = c->p[2 * q + a];
    }
  double vote[GR_MAX_LASERS] = {0};
  for (size_t k = 0; k < c->np; k++)
    if (c->pl[k] >= 0 && c->pl[k] < GR_MAX_LASERS) vote[c->pl[k]] += piece_len(c, k);
  int best = -1;
  for (int l = 0; l < m->n; l++)
    if (gr_lasers_reach_box(m, l, lo, hi) && (best < 0 || vote[l] > vote[best])) best = l;
  return best;
}

static int emit_whole(gr_stitch_chain *c, int laser, gr_layer *out) {
  double *p = c->p;
  size_t m = c->m;
  if (c->closed && c->dir != GR_DIR_THIN) {
    p[0] = 0.5 * (p[0] + p[2 * (m - 1)]);
    p[1] = 0.5 * (p[1] + p[2 * (m - 1) + 1]);
    p[2 * (m - 1)] = p[0];
    p[2 * (m - 1) + 1] = p[1];
    double a = 0;
    for (size_t k = 0; k + 1 < m; k++) a += p[2 * k] * p[2 * k + 3] - p[2 * k + 2] * p[2 * k + 1];
    return gr_layer_add(out, GR_CLOSED, c->kind, laser, a > 0 ? 1 : 0, p, m);
  }
  if (m < 2) return GR_OK;
  int dir = c->closed ? GR_DIR_THIN : gr_clip_open_dir(c->dir);
  return gr_layer_add(out, GR_OPEN, c->kind, laser, dir, p, m);
}

/* Next / previous point index along the chain (closed: p[m-1] is p[0]);
 * -1 at an open chain's end. */
static long step(const gr_stitch_chain *c, long q, int fwd) {
  long last = (long)c->m - 1;
  if (fwd) return q < last ? q + 1 : (c->closed ? 1 : -1);
  return q > 0 ? q - 1 : (c->closed ? last - 1 : -1);
}

/* Walk from point q along the chain (forward or back) for at most len mm,
 * staying inside laser l's field; the points passed go to b (not q). */
static int walk(const gr_machine *m, int l, const gr_stitch_chain *c, long q, int fwd, double len, buf *b) {
  while (len > 1e-12) {
    long r = step(c, q, fwd);
    if (r < 0) break;
    double x0 = c->p[2 * q], y0 = c->p[2 * q + 1], x1 = c->p[2 * r], y1 = c->p[2 * r + 1];
    double d = gr_len2d(x1 - x0, y1 - y0), t0, t1, t = d > len ? len / d : 1;
    if (!gr_clip_seg(x0, y0, x1, y1, m->lo[l], m->hi[l], &t0, &t1) || t0 > 0) break;
    if (t1 < t) t = t1;
    if (put(b, x0 + t * (x1 - x0), y0 + t * (y1 - y0))) return GR_EMEM;
    if (t < 1) break;
    len -= d;
    q = r;
  }
  return GR_OK;
}

/* Runs of equal lasers over the pieces: run r starts at piece rk[r]
 * (mod np) and has rn[r] pieces; for a closed chain the first run starts
 * where the laser changes. Returns the number of runs. */
static size_t make_runs(const gr_stitch_chain *c, size_t *rk, size_t *rn) {
  size_t np = c->np, k0 = 0, nr = 0;
  if (c->closed) {
    while (k0 < np && c->pl[k0] == c->pl[(k0 + np - 1) % np]) k0++;
    if (k0 == np) k0 = 0;
  }
  for (size_t i = 0; i < np; i++) {
    size_t k = (k0 + i) % np;
    if (nr > 0 && c->pl[k] == c->pl[rk[nr - 1]]) { rn[nr - 1]++; continue; }
    rk[nr] = k;
    rn[nr++] = 1;
  }
  return nr;
}

/* One run: back extension, its pieces, forward extension, as one open line. */
static int emit_run(const gr_machine *m, const gr_stitch_chain *c, size_t k, size_t n, double back,
                    double fwd, buf *b, buf *tmp, gr_layer *out) {
  int l = c->pl[k];
  size_t np = c->np;
  b->n = tmp->n = 0;
  if (back > 0 && walk(m, l, c, (long)c->ps[k], 0, back, tmp)) return GR_EMEM;
  for (size_t i = tmp->n; i-- > 0;)
    if (put(b, tmp->p[2 * i], tmp->p[2 * i + 1])) return GR_EMEM;
  for (size_t i = 0; i < n; i++) {
    size_t kk = (k + i) % np;
    for (size_t q = c->ps[kk] + (i > 0); q <= c->ps[kk + 1]; q++)
      if (put(b, c->p[2 * q], c->p[2 * q + 1])) return GR_EMEM;
  }
  size_t e = c->ps[(k + n - 1) % np + 1];
  if (fwd > 0 && walk(m, l, c, (long)e, 1, fwd, b)) return GR_EMEM;
  if (b->n < 2) return GR_OK;
  return gr_layer_add(out, GR_OPEN, c->kind, l, c->dir == GR_DIR_THIN ? GR_DIR_THIN : 2, b->p, b->n);
}

/* Length of run r (pieces rk[r], rn[r]), mm. */
static double run_len(const gr_stitch_chain *c, size_t k, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++) s += piece_len(c, (k + i) % c->np);
  return s;
}

static int emit_split(const gr_machine *m, const gr_stitch_chain *c, gr_layer *out) {
  size_t np = c->np, *rk = malloc(2 * np * sizeof *rk);
  if (!rk) return GR_EMEM;
  size_t *rn = rk + np, nr = make_runs(c, rk, rn);
  buf b = {0}, tmp = {0};
  int rc = GR_OK;
  double h = 0.5 * m->stitch;
  for (size_t r = 0; r < nr && rc == GR_OK; r++) {
    int has_prev = c->closed || r > 0, has_next = c->closed || r + 1 < nr;
    size_t rp = (r + nr - 1) % nr, rx = (r + 1) % nr;
    double back = has_prev ? fmin(h, run_len(c, rk[rp], rn[rp])) : 0;
    double fwd = has_next ? fmin(h, run_len(c, rk[rx], rn[rx])) : 0;
    rc = emit_run(m, c, rk[r], rn[r], back, fwd, &b, &tmp, out);
  }
  free(b.p);
  free(tmp.p);
  free(rk);
  return rc;
}

int gr_stitch_chain_emit(const gr_machine *m, gr_stitch_chain *c, gr_layer *out, long *split) {
  if (c->m == 0 || c->np == 0) return GR_OK;
  int l = pick_laser(m, c);
  if (l >= 0) return emit_whole(c, l, out);
  if (c->closed) {
    c->p[2 * (c->m - 1)] = c->p[0];
    c->p[2 * (c->m - 1) + 1] = c->p[1];
    if (c->dir != GR_DIR_THIN) (*split)++;
  }
  return emit_split(m, c, out);
}

/* ---- hatches ---- */

typedef struct hkey { long line; double s0; size_t i; } hkey;

static int hkey_cmp(const void *a, const void *b) {
  const hkey *p = a, *q = b;
  if (p->line != q->line) return p->line < q->line ? -1 : 1;
  return (p->s0 > q->s0) - (p->s0 < q->s0);
}

/* Move segment end (end = 1) or start forward/back by d mm along the line,
 * at most to the edge of laser l's field. */
static void extend(const gr_machine *m, gr_hseg *g, int end, double d) {
  double len = g->s1 - g->s0;
  if (d <= 0 || len <= 0) return;
  double ux = (g->x1 - g->x0) / len, uy = (g->y1 - g->y0) / len, sg = end ? 1 : -1;
  double px = end ? g->x1 : g->x0, py = end ? g->y1 : g->y0;
  double qx = px + sg * d * ux, qy = py + sg * d * uy, t0, t1;
  if (!gr_clip_seg(px, py, qx, qy, m->lo[g->laser], m->hi[g->laser], &t0, &t1) || t0 > 0) return;
  d *= t1;
  if (end) { g->x1 = px + d * ux; g->y1 = py + d * uy; g->s1 += d; }
  else { g->x0 = px - d * ux; g->y0 = py - d * uy; g->s0 -= d; }
}

int gr_stitch_hatches(const gr_machine *m, gr_hseg *s, size_t n) {
  if (m->n < 2 || n < 2 || !(m->stitch > 0)) return GR_OK;
  hkey *k = malloc(n * sizeof *k);
  double *ext = malloc(2 * n * sizeof *ext); /* per segment: start, end */
  if (!k || !ext) { free(k); free(ext); return GR_EMEM; }
  for (size_t i = 0; i < n; i++) {
    k[i] = (hkey){s[i].line, s[i].s0, i};
    ext[2 * i] = ext[2 * i + 1] = 0;
  }
  qsort(k, n, sizeof *k, hkey_cmp);
  double h = 0.5 * m->stitch, tol = 1e-7;
  for (size_t r = 0; r + 1 < n; r++) {
    const gr_hseg *a = &s[k[r].i], *b = &s[k[r + 1].i];
    if (a->line != b->line || a->laser == b->laser || fabs(b->s0 - a->s1) > tol) continue;
    ext[2 * k[r].i + 1] = fmin(h, b->s1 - b->s0);
    ext[2 * k[r + 1].i] = fmin(h, a->s1 - a->s0);
  }
  for (size_t i = 0; i < n; i++) {
    extend(m, &s[i], 0, ext[2 * i]);
    extend(m, &s[i], 1, ext[2 * i + 1]);
  }
  free(k);
  free(ext);
  return GR_OK;
}
