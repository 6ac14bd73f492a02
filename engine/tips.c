/* tips.c: tips of slivers followed along a crease of the field, after the
 * chord pass (see march.h, gr_ms_follow_tips).
 *
 * Why: a graded sheet's distance has creases (and jumps) along the medial
 * surface where the field stays within a fraction of a micrometre of zero
 * over tens of micrometres. A void sliver runs along such a crease, under
 * 1 um wide, its depth changing by about 0.1 um every 4 um along it. The
 * marching squares and the chord pass bracket the boundary on the scale of
 * the chords: as the sliver narrows below the chord tolerance they stop,
 * and the ring's tip is left micrometres short of where the field closes
 * the sliver. The same happens where a jump of f (the closest point
 * changing sides of the medial surface) bounds a void on one side: the
 * void's corner between the jump and the zero set of f is a wedge of a
 * few degrees that the chords cut. A short tip moves the contour at b
 * around it by as much.
 *
 * How: a ring vertex whose two chords leave it within 45 degrees of each
 * other is a tip. Beyond it, the sliver is the crest of s f across the
 * tip's direction (s = 1 for a void sliver, -1 for a solid one): each step
 * searches the crest on a short segment across the direction, and the
 * sliver goes on while the crest's value is above zero and both ends of
 * the segment are on the ring's side (the segment spans the sliver). Where
 * the crest drops to zero, the end is bisected along the crest. The sides
 * at every crest point (the roots between the crest and the segment's
 * ends) and the end are put into the ring in place of the old tip; the
 * chord pass then checks the new chords. A tip already within TIP_FIRST of
 * its end is left as it is (the first probe finds no crest above zero). */
#include "march.h"
#include <math.h>
#include <stdlib.h>

#define TIP_COS 0.7071   /* cos 45 degrees */
#define TIP_FIRST 2.5e-4 /* first probe beyond the tip (mm) */
#define TIP_STEP 1e-3    /* then steps along the crest (mm) */
#define TIP_HALF 2e-3    /* half the segment searched across the crest (mm) */
#define TIP_SAMPLES 9    /* samples per round of the crest search */
#define TIP_BISECT 12    /* halvings of the last step (to 0.25 nm) */
#define TIP_MAXPTS 512   /* side points kept per tip (two per step) */

typedef struct tip_ctx {
  gr_slice_fn fn;
  void *ud;
  double s;   /* 1: a void sliver (follow f > 0), -1: a solid one */
  double tol; /* crest and roots located to this (mm) */
  const gr_ms_win *w;
} tip_ctx;

/* The crest of s f on the segment q + t n, |t| <= TIP_HALF: *t where, *h its
 * value; *span = 1 when s f < 0 at both ends (the segment crosses the whole
 * sliver) and the crest lies inside. Sampled TIP_SAMPLES times, the bracket
 * narrowed to the best sample's neighbours, until shorter than tol: a crest
 * that is a kink or a jump of f (the medial surface) is found as well as a
 * smooth one, which a gradient would not. */
static int crest(const tip_ctx *c, const double q[2], const double n[2], double *t, double *h, int *span,
                 gr_err *e) {
  double xs[TIP_SAMPLES], ys[TIP_SAMPLES], v[TIP_SAMPLES], lo = -TIP_HALF, hi = TIP_HALF;
  *h = -INFINITY;
  *t = 0;
  *span = 0;
  for (int round = 0; hi - lo > c->tol; round++) {
    double dt = (hi - lo) / (TIP_SAMPLES - 1);
    for (int k = 0; k < TIP_SAMPLES; k++) {
      xs[k] = q[0] + (lo + k * dt) * n[0];
      ys[k] = q[1] + (lo + k * dt) * n[1];
    }
    int rc = c->fn(c->ud, TIP_SAMPLES, xs, ys, v, e);
    if (rc) return rc;
    int best = 0;
    for (int k = 1; k < TIP_SAMPLES; k++)
      if (c->s * v[k] > c->s * v[best]) best = k;
    if (c->s * v[best] > *h) { *h = c->s * v[best]; *t = lo + best * dt; }
    if (round == 0) {
      *span = c->s * v[0] < 0 && c->s * v[TIP_SAMPLES - 1] < 0;
      /* every sample below zero by more than 1.5 spacings: the field's slope
       * (about 1, a distance) keeps the crest below zero between them, and
       * below it on either side of a jump; most tips stop here */
      if (!*span || *h < -1.5 * dt) return GR_OK;
    }
    double nlo = lo + (best - 1) * dt, nhi = lo + (best + 1) * dt;
    lo = fmax(nlo, lo);
    hi = fmin(nhi, hi);
  }
  return GR_OK;
}

/* The two sides of the sliver on the segment q + t n, |t| <= TIP_HALF,
 * across its crest at t = tc (s f > 0 there, < 0 at both ends, as crest
 * found): the root in (tc, TIP_HALF) into side[0..1], the one in
 * (-TIP_HALF, tc) into side[2..3], bisected together. */
static int sides(const tip_ctx *c, const double q[2], const double n[2], double tc, double side[4], gr_err *e) {
  double in[2] = {tc, tc}, out[2] = {TIP_HALF, -TIP_HALF}, xs[2], ys[2], v[2];
  while (fabs(out[0] - in[0]) > c->tol || fabs(out[1] - in[1]) > c->tol) {
    for (int k = 0; k < 2; k++) {
      double m = 0.5 * (in[k] + out[k]);
      xs[k] = q[0] + m * n[0];
      ys[k] = q[1] + m * n[1];
    }
    int rc = c->fn(c->ud, 2, xs, ys, v, e);
    if (rc) return rc;
    for (int k = 0; k < 2; k++) {
      double m = 0.5 * (in[k] + out[k]);
      if (c->s * v[k] > 0) in[k] = m; else out[k] = m;
    }
  }
  for (int k = 0; k < 2; k++) {
    side[2 * k] = q[0] + out[k] * n[0];
    side[2 * k + 1] = q[1] + out[k] * n[1];
  }
  return GR_OK;
}

static int in_window(const gr_ms_win *w, const double p[2]) {
  return !w->on || (p[0] >= w->lo[0] && p[0] <= w->hi[0] && p[1] >= w->lo[1] && p[1] <= w->hi[1]);
}

/* A tip's growth: the sides on the left and on the right of the direction
 * of travel (both in the order found, outward) and the end. */
typedef struct tip_path {
  double left[2 * TIP_MAXPTS], right[2 * TIP_MAXPTS], end[2];
  size_t nl, nr;
} tip_path;

/* The end of the crest between crest point a (above zero) and the line
 * across at a + step u (not above zero; its crest at t1 along n), bisected;
 * the crest point of the last line not above zero goes to p->end. */
static int bisect_end(const tip_ctx *c, const double a[2], const double u[2], const double n[2], double step,
                      double t1, tip_path *p, gr_err *e) {
  double lo = 0, hi = 1, q[2], t, h;
  int span;
  p->end[0] = a[0] + step * u[0] + t1 * n[0];
  p->end[1] = a[1] + step * u[1] + t1 * n[1];
  for (int k = 0; k < TIP_BISECT; k++) {
    double m = 0.5 * (lo + hi);
    q[0] = a[0] + m * step * u[0];
    q[1] = a[1] + m * step * u[1];
    int rc = crest(c, q, n, &t, &h, &span, e);
    if (rc) return rc;
    if (span && h > 0) { lo = m; continue; }
    hi = m;
    p->end[0] = q[0] + (span ? t : 0) * n[0];
    p->end[1] = q[1] + (span ? t : 0) * n[1];
  }
  return GR_OK;
}

/* Follow the sliver from tip vertex T in direction u (unit) for at most
 * reach: *grown = 1 with p filled where it goes on beyond TIP_FIRST and
 * ends within reach and the window; 0 otherwise (leave the tip). */
static int follow(const tip_ctx *c, const double T[2], const double u0[2], double reach, tip_path *p, int *grown,
                  gr_err *e) {
  double a[2] = {T[0], T[1]}, u[2] = {u0[0], u0[1]}, step = TIP_FIRST, gone = 0;
  p->nl = p->nr = 0;
  *grown = 0;
  for (;;) {
    double n[2] = {-u[1], u[0]}, q[2] = {a[0] + step * u[0], a[1] + step * u[1]}, t, h;
    int span, rc;
    if (gone > reach || !in_window(c->w, q) || p->nl >= TIP_MAXPTS) return GR_OK;
    if ((rc = crest(c, q, n, &t, &h, &span, e))) return rc;
    if (!span) return GR_OK; /* not a thin sliver here: leave it */
    if (!(h > 0)) {
      if (gone == 0) return GR_OK; /* the tip is within TIP_FIRST of its end */
      *grown = 1;
      return bisect_end(c, a, u, n, step, t, p, e);
    }
    double b[2] = {q[0] + t * n[0], q[1] + t * n[1]}, sd[4];
    if ((rc = sides(c, q, n, t, sd, e))) return rc;
    p->left[2 * p->nl] = sd[0]; p->left[2 * p->nl + 1] = sd[1]; p->nl++;
    p->right[2 * p->nr] = sd[2]; p->right[2 * p->nr + 1] = sd[3]; p->nr++;
    /* the direction from one crest point to the next: the tip vertex itself
     * lies on a side, not on the crest, so the first step keeps u */
    double du = hypot(b[0] - a[0], b[1] - a[1]);
    if (gone > 0 && du > 0) {
      u[0] = (b[0] - a[0]) / du;
      u[1] = (b[1] - a[1]) / du;
    }
    a[0] = b[0];
    a[1] = b[1];
    gone += du;
    step = TIP_STEP;
  }
}

/* Does the chain P, seq[0..m), N cross a chord of r (other than those of
 * the tip vertices tg, tg2, which it replaces)? A grown tip that ran into
 * another part of the boundary would fold the ring: it is left as it was. */
static int chain_crosses(const gr_rings *r, size_t tg, size_t tg2, const double *P, const double *seq, size_t m,
                         const double *N) {
  double lo[2] = {fmin(P[0], N[0]), fmin(P[1], N[1])}, hi[2] = {fmax(P[0], N[0]), fmax(P[1], N[1])};
  for (size_t k = 0; k < m; k++)
    for (int c = 0; c < 2; c++) { lo[c] = fmin(lo[c], seq[2 * k + c]); hi[c] = fmax(hi[c], seq[2 * k + c]); }
  for (size_t i = 0; i < r->nrings; i++) {
    size_t len = gr_ring_len(r, i), st = r->start[i];
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < len; k++) {
      size_t k1 = gr_ring_next(k, len);
      if (st + k == tg || st + k1 == tg || st + k == tg2 || st + k1 == tg2) continue;
      const double *a = p + 2 * k, *b = p + 2 * k1;
      if (fmax(a[0], b[0]) < lo[0] || fmin(a[0], b[0]) > hi[0] || fmax(a[1], b[1]) < lo[1] || fmin(a[1], b[1]) > hi[1])
        continue;
      const double *prev = P;
      for (size_t j = 0; j <= m; j++) {
        const double *cur = j < m ? seq + 2 * j : N;
        if (gr_ms_seg_cross(prev, cur, a, b)) return 1;
        prev = cur;
      }
    }
  }
  return 0;
}

/* Tip at vertex k of ring i, or (ncap = 2) at the short chord from k to
 * k + 1 across a sliver the chord pass stopped in (no shorter than two
 * chord tolerances, so not split): follow it; on growth, *seq (malloc'd, *m
 * points) holds the points that replace vertex k (and k + 1, dropped). */
#define TIP_CAP 2e-3
static int grow_tip(const gr_rings *r, size_t i, size_t k, int ncap, gr_slice_fn fn, void *ud, double tol,
                    const gr_ms_win *w, double **seq, size_t *m, gr_err *e) {
  size_t len = gr_ring_len(r, i), st = r->start[i];
  const double *p = gr_ring_xy(r, i), *P = p + 2 * gr_ring_prev(k, len), *T1 = p + 2 * k;
  const double *T2 = p + 2 * gr_ring_at(k, (size_t)ncap - 1, len), *N = p + 2 * gr_ring_at(k, (size_t)ncap, len);
  *seq = NULL;
  *m = 0;
  double T[2] = {0.5 * (T1[0] + T2[0]), 0.5 * (T1[1] + T2[1])};
  double ax = P[0] - T1[0], ay = P[1] - T1[1], cx = N[0] - T2[0], cy = N[1] - T2[1];
  /* a tip turns back: its neighbours lie on one side (the test below needs
   * a positive dot product; most vertices fail it here, without the roots) */
  if (!(ax * cx + ay * cy > 0)) return GR_OK;
  double la = hypot(ax, ay), lc = hypot(cx, cy), cap = hypot(T2[0] - T1[0], T2[1] - T1[1]);
  if (!(la > tol && lc > tol) || (ax * cx + ay * cy) < TIP_COS * la * lc || !in_window(w, T)) return GR_OK;
  if (ncap == 2 && !(cap > 0 && cap <= TIP_CAP && len >= 4)) return GR_OK;
  double u[2] = {-(ax / la + cx / lc), -(ay / la + cy / lc)}, lu = hypot(u[0], u[1]);
  if (!(lu > 0)) return GR_OK;
  u[0] /= lu;
  u[1] /= lu;
  /* the ring turns right at a void tip (the solid is on its left) */
  tip_ctx c = {fn, ud, (-ax) * (N[1] - T1[1]) - (-ay) * (N[0] - T1[0]) < 0 ? 1 : -1, tol, w};
  tip_path *tp = malloc(sizeof *tp);
  if (!tp) return gr_fail(e, GR_EMEM, "out of memory following a tip");
  int grown = 0, rc = follow(&c, T, u, w->reach, tp, &grown, e);
  if (!rc && grown) {
    size_t n = tp->nl + tp->nr + 1, q = 0;
    int p_left = u[0] * (P[1] - T[1]) - u[1] * (P[0] - T[0]) > 0;
    const double *out = p_left ? tp->left : tp->right, *back = p_left ? tp->right : tp->left;
    size_t nout = p_left ? tp->nl : tp->nr, nback = p_left ? tp->nr : tp->nl;
    double *s = malloc(2 * n * sizeof *s);
    if (!s) rc = gr_fail(e, GR_EMEM, "out of memory following a tip");
    for (size_t j = 0; !rc && j < nout; j++, q++) { s[2 * q] = out[2 * j]; s[2 * q + 1] = out[2 * j + 1]; }
    if (!rc) { s[2 * q] = tp->end[0]; s[2 * q + 1] = tp->end[1]; q++; }
    for (size_t j = nback; !rc && j-- > 0; q++) { s[2 * q] = back[2 * j]; s[2 * q + 1] = back[2 * j + 1]; }
    if (!rc && chain_crosses(r, st + k, st + gr_ring_at(k, (size_t)ncap - 1, len), P, s, q, N)) { free(s); s = NULL; q = 0; }
    *seq = s;
    *m = q;
  }
  free(tp);
  return rc;
}

/* The rings rebuilt with the tips that grew: tip vertex g replaced by
 * seq[g], vertices marked in drop left out; the chords from new points and from each tip's predecessor are
 * marked unchecked in the new *okp. */
static int rebuild(gr_rings *r, unsigned char **okp, double **seq, const size_t *m, const unsigned char *drop,
                   size_t added, gr_err *e) {
  gr_rings *nr = gr_rings_new();
  unsigned char *ok = *okp, *ok2 = calloc(r->npts + added + 1, 1);
  int rc = nr && ok2 ? GR_OK : gr_fail(e, GR_EMEM, "out of memory following tips");
  size_t np = 0;
  for (size_t i = 0; i < r->nrings && !rc; i++) {
    size_t len = gr_ring_len(r, i), st = r->start[i];
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < len && !rc; k++) {
      size_t g = st + k, gn = st + gr_ring_next(k, len);
      if (drop[g]) continue;
      if (seq[g]) {
        for (size_t j = 0; j < m[g] && !rc; j++) {
          rc = gr_rings_point(nr, seq[g][2 * j], seq[g][2 * j + 1]);
          ok2[np++] = 0;
        }
        continue;
      }
      rc = gr_rings_point(nr, p[2 * k], p[2 * k + 1]);
      ok2[np++] = ok[g] && !seq[gn];
    }
    if (!rc) rc = gr_rings_close(nr);
  }
  if (!rc && gr_rings_copy(r, nr)) rc = gr_fail(e, GR_EMEM, "out of memory following tips");
  gr_rings_free(nr);
  if (rc) { free(ok2); return rc; }
  free(ok);
  *okp = ok2;
  return GR_OK;
}

int gr_ms_follow_tips(gr_rings *r, unsigned char **okp, gr_slice_fn fn, void *ud, double tol, const gr_ms_win *w,
                      size_t *grown, gr_err *e) {
  *grown = 0;
  size_t n0 = r->npts;
  double **seq = calloc(n0 + 1, sizeof *seq);
  size_t *m = calloc(n0 + 1, sizeof *m), added = 0;
  unsigned char *busy = calloc(n0 + 1, 1), *drop = calloc(n0 + 1, 1);
  int rc = seq && m && busy && drop ? GR_OK : gr_fail(e, GR_EMEM, "out of memory following tips");
  for (size_t i = 0; i < r->nrings && !rc; i++) {
    size_t len = gr_ring_len(r, i), st = r->start[i];
    for (size_t k = 0; k < len && !rc && len >= 3; k++) {
      size_t kp = gr_ring_prev(k, len); /* the tip's first vertex's neighbour before it */
      for (int ncap = 1; ncap <= 2 && !rc && !seq[st + k]; ncap++) {
        /* the vertices of a grown tip and its neighbours keep their place */
        int free_ = 1;
        for (size_t j = 0; j < (size_t)ncap + 2; j++) free_ &= !busy[st + gr_ring_at(kp, j, len)];
        if (!free_) break;
        rc = grow_tip(r, i, k, ncap, fn, ud, tol, w, &seq[st + k], &m[st + k], e);
        if (rc || !seq[st + k]) continue;
        ++*grown;
        added += m[st + k];
        for (size_t j = 0; j < (size_t)ncap + 2; j++) busy[st + gr_ring_at(kp, j, len)] = 1;
        if (ncap == 2) drop[st + gr_ring_next(k, len)] = 1;
      }
    }
  }
  if (!rc && *grown) rc = rebuild(r, okp, seq, m, drop, added, e);
  for (size_t g = 0; seq && g < n0; g++) free(seq[g]);
  free(seq);
  free(m);
  free(busy);
  free(drop);
  return rc;
}
