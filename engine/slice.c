/* slice.c: marching squares with refined crossings (field sections and 2-D
 * offsets of sections), and mesh/plane intersection. See slice.h. */
#include "slice.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef gr_slice_fn ms_fn;

#define MS_CHUNK 65536
#define MS_MAX_NODES ((size_t)1 << 27)

gr_slice_opts gr_slice_defaults(void) {
  gr_slice_opts o;
  memset(&o, 0, sizeof o);
  o.lo[0] = o.lo[1] = 0;
  o.hi[0] = o.hi[1] = 1;
  o.cell = 0.0125;
  o.refine = 1;
  o.tol = 1e-6;
  o.chord_tol = 0;
  return o;
}

double gr_slice_max_cell(double hatch) { return hatch / 2; }

int gr_slice_check_res(double cell, double hatch, gr_err *e) {
  if (!(hatch > 0) || !isfinite(hatch))
    return gr_fail(e, GR_EARG, "hatch spacing must be > 0, got %g", hatch);
  if (!(cell > 0) || !isfinite(cell))
    return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (cell > hatch / 2 * (1 + 1e-12))
    return gr_fail(e, GR_EARG,
                   "resolution too coarse: cell %g mm > hatch/2 = %g mm (eq. 7, L <= n*d/2)",
                   cell, hatch / 2);
  return GR_OK;
}

/* Evaluate fn at n points in chunks (keeps scratch buffers of callers small). */
static int eval_pts(ms_fn fn, void *ud, size_t n, const double *x,
                    const double *y, double *out, gr_err *e) {
  for (size_t s = 0; s < n; s += MS_CHUNK) {
    size_t m = n - s < MS_CHUNK ? n - s : MS_CHUNK;
    int rc = fn(ud, m, x + s, y + s, out + s, e);
    if (rc) return rc;
  }
  return GR_OK;
}

/* Batched root finding on n segments P_k + t (Q_k - P_k), t in [0,1], with
 * fp < 0 <= fq given. Each pass evaluates once on all unconverged segments.
 * Without gfn: Illinois (modified regula falsi), stopping when the bracket is
 * shorter than tol (mm), so the returned point is within tol of a root. With
 * gfn (value and gradient): Newton steps kept inside the bracket (Illinois
 * where a step leaves it), stopping when the Newton step is below tol.
 * P, Q: 2n coordinates; out: 2n coordinates. */
static int roots_batch(ms_fn fn, gr_slice_grad_fn gfn, void *ud, size_t n, const double *P,
                       const double *Q, const double *fp, const double *fq,
                       int refine, double tol, double *out, gr_err *e) {
  if (n == 0) return GR_OK;
  double *ta = malloc(n * sizeof *ta), *tb = malloc(n * sizeof *tb);
  double *fa = malloc(n * sizeof *fa), *fb = malloc(n * sizeof *fb);
  double *len = malloc(n * sizeof *len), *tn = malloc(n * sizeof *tn);
  int *side = calloc(n, sizeof *side);
  size_t *act = malloc(n * sizeof *act);
  double *qx = malloc(n * sizeof *qx), *qy = malloc(n * sizeof *qy);
  double *qt = malloc(n * sizeof *qt), *qf = malloc(n * sizeof *qf);
  double *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy);
  int rc = GR_OK;
  if (!ta || !tb || !fa || !fb || !len || !tn || !side || !act || !qx || !qy || !qt || !qf || !gx || !gy) {
    rc = gr_fail(e, GR_EMEM, "out of memory refining %zu crossings", n);
    goto done;
  }
  size_t na = 0;
  for (size_t k = 0; k < n; k++) {
    ta[k] = 0; tb[k] = 1; fa[k] = fp[k]; fb[k] = fq[k];
    tn[k] = NAN;
    len[k] = hypot(Q[2 * k] - P[2 * k], Q[2 * k + 1] - P[2 * k + 1]);
    if (refine && len[k] > tol && fb[k] != 0) act[na++] = k;
  }
  for (int it = 0; it < 200 && na > 0; it++) {
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double t = tn[k];
      if (!(t > ta[k] && t < tb[k])) t = (ta[k] * fb[k] - tb[k] * fa[k]) / (fb[k] - fa[k]);
      if (!(t > ta[k] && t < tb[k]) || !isfinite(t)) t = 0.5 * (ta[k] + tb[k]);
      if (it > 100) t = 0.5 * (ta[k] + tb[k]); /* safety net: plain bisection */
      qt[i] = t;
      qx[i] = P[2 * k] + t * (Q[2 * k] - P[2 * k]);
      qy[i] = P[2 * k + 1] + t * (Q[2 * k + 1] - P[2 * k + 1]);
    }
    if (gfn) {
      for (size_t s = 0; s < na && !rc; s += MS_CHUNK) {
        size_t m = na - s < MS_CHUNK ? na - s : MS_CHUNK;
        rc = gfn(ud, m, qx + s, qy + s, qf + s, gx + s, gy + s, e);
      }
    } else {
      rc = eval_pts(fn, ud, na, qx, qy, qf, e);
    }
    if (rc) goto done;
    size_t keep = 0;
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double f = qf[i], t = qt[i];
      if (f < 0) {
        ta[k] = t; fa[k] = f;
        if (side[k] == -1) fb[k] *= 0.5;
        side[k] = -1;
      } else {
        tb[k] = t; fb[k] = f;
        if (side[k] == 1) fa[k] *= 0.5;
        side[k] = 1;
      }
      if (f == 0) { ta[k] = tb[k] = t; continue; }
      if (gfn) {
        double dt = gx[i] * (Q[2 * k] - P[2 * k]) + gy[i] * (Q[2 * k + 1] - P[2 * k + 1]);
        double step = dt > 0 ? -f / dt : NAN;
        tn[k] = t + step;
        if (fabs(step) * len[k] < tol && tn[k] >= ta[k] && tn[k] <= tb[k]) { ta[k] = tb[k] = tn[k]; continue; }
      }
      if ((tb[k] - ta[k]) * len[k] > tol) act[keep++] = k;
    }
    na = keep;
  }
  for (size_t k = 0; k < n; k++) {
    double t;
    if (ta[k] == tb[k]) t = ta[k];
    else if (fb[k] == 0) t = tb[k];
    else {
      /* final linear estimate inside the (tiny) bracket; with the original
       * values this is plain linear interpolation when refine is off */
      double A = refine ? fa[k] : fp[k], B = refine ? fb[k] : fq[k];
      t = ta[k] + (tb[k] - ta[k]) * (A / (A - B));
      if (!(t >= ta[k] && t <= tb[k])) t = 0.5 * (ta[k] + tb[k]);
    }
    out[2 * k] = P[2 * k] + t * (Q[2 * k] - P[2 * k]);
    out[2 * k + 1] = P[2 * k + 1] + t * (Q[2 * k + 1] - P[2 * k + 1]);
  }
done:
  free(ta); free(tb); free(fa); free(fb); free(len); free(tn); free(side); free(act);
  free(qx); free(qy); free(qt); free(qf); free(gx); free(gy);
  return rc;
}

/* ---- marching squares ---- */

/* A grid of nx*ny samples v[i + nx*j] at (x0 + i*hx, y0 + j*hy); inside is
 * v < 0. The grid is padded (conceptually) by one ring of outside nodes
 * placed at the positions of the border nodes, so that regions touching the
 * window are closed along its border with no extra code. */
typedef struct ms_grid {
  int nx, ny;
  double x0, y0, hx, hy;
  const double *v;
} ms_grid;

static double node_x(const ms_grid *g, int I) {
  int i = I - 1;
  if (i < 0) i = 0;
  if (i > g->nx - 1) i = g->nx - 1;
  return i == g->nx - 1 ? g->x0 + (g->nx - 1) * g->hx : g->x0 + i * g->hx;
}
static double node_y(const ms_grid *g, int J) {
  int j = J - 1;
  if (j < 0) j = 0;
  if (j > g->ny - 1) j = g->ny - 1;
  return g->y0 + j * g->hy;
}
/* Value at padded node (I, J): pad nodes are outside (+1). */
static double node_v(const ms_grid *g, int I, int J) {
  if (I < 1 || J < 1 || I > g->nx || J > g->ny) return 1.0;
  return g->v[(I - 1) + (size_t)g->nx * (J - 1)];
}

/* Remove consecutive duplicates of the ring being built in `tmp` (xy, n
 * points) and append it to out if it keeps >= 3 points and nonzero area. */
static int emit_ring(gr_rings *out, double *xy, size_t n) {
  size_t m = 0;
  for (size_t k = 0; k < n; k++) {
    if (m > 0 && xy[2 * k] == xy[2 * (m - 1)] && xy[2 * k + 1] == xy[2 * (m - 1) + 1]) continue;
    xy[2 * m] = xy[2 * k];
    xy[2 * m + 1] = xy[2 * k + 1];
    m++;
  }
  while (m > 1 && xy[0] == xy[2 * (m - 1)] && xy[1] == xy[2 * (m - 1) + 1]) m--;
  if (m < 3) return GR_OK;
  double a = 0;
  for (size_t k = 0, j = m - 1; k < m; j = k++)
    a += (xy[2 * j] - xy[0]) * (xy[2 * k + 1] - xy[1]) - (xy[2 * k] - xy[0]) * (xy[2 * j + 1] - xy[1]);
  if (a == 0) return GR_OK;
  return gr_rings_add(out, xy, m);
}

/* Contour {fn < 0} from the sampled grid: crossings on grid edges refined on
 * fn, saddles decided by fn at the cell centre, segments oriented with the
 * inside on the left and chained by edge id into closed rings (appended to
 * out, not nested). */
static int ms_contour(const ms_grid *g, ms_fn fn, gr_slice_grad_fn gfn, void *ud, int refine,
                      double tol, gr_rings *out, gr_err *e) {
  int NX = g->nx + 2, NY = g->ny + 2;
  size_t nedge = 2 * (size_t)NX * NY;
  int rc = GR_OK;
  int *cross = malloc(nedge * sizeof *cross);
  double *P = NULL, *Q = NULL, *fp = NULL, *fq = NULL, *pt = NULL;
  int *next = NULL, *sad = NULL;
  double *cx = NULL, *cy = NULL, *cv = NULL, *ring = NULL;
  size_t ncr = 0, capcr = 0, nsad = 0, capsad = 0;
  if (!cross) return gr_fail(e, GR_EMEM, "out of memory: marching squares on %dx%d nodes", g->nx, g->ny);
  /* 1. crossing edges: H(I,J) = (I,J)-(I+1,J) id 2*(I+NX*J); V(I,J) = (I,J)-(I,J+1) id +1 */
  for (int J = 0; J < NY; J++)
    for (int I = 0; I < NX; I++) {
      double v0 = node_v(g, I, J);
      for (int dir = 0; dir < 2; dir++) {
        size_t id = 2 * ((size_t)I + (size_t)NX * J) + dir;
        cross[id] = -1;
        int I1 = I + (dir == 0), J1 = J + (dir == 1);
        if (I1 >= NX || J1 >= NY) continue;
        double v1 = node_v(g, I1, J1);
        if ((v0 < 0) == (v1 < 0)) continue;
        if (ncr + 1 > capcr) {
          size_t c = capcr;
          if (gr_grow(&P, &c, ncr + 1, 2 * sizeof(double)) || (c = capcr, gr_grow(&Q, &c, ncr + 1, 2 * sizeof(double))) ||
              (c = capcr, gr_grow(&fp, &c, ncr + 1, sizeof(double))) || (c = capcr, gr_grow(&fq, &c, ncr + 1, sizeof(double)))) {
            rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", ncr);
            goto done;
          }
          capcr = c;
        }
        /* inside end first */
        int inI = v0 < 0 ? I : I1, inJ = v0 < 0 ? J : J1;
        int ouI = v0 < 0 ? I1 : I, ouJ = v0 < 0 ? J1 : J;
        P[2 * ncr] = node_x(g, inI); P[2 * ncr + 1] = node_y(g, inJ);
        Q[2 * ncr] = node_x(g, ouI); Q[2 * ncr + 1] = node_y(g, ouJ);
        fp[ncr] = v0 < 0 ? v0 : v1;
        fq[ncr] = v0 < 0 ? v1 : v0;
        cross[id] = (int)ncr++;
      }
    }
  if (ncr == 0) goto done;
  pt = malloc(2 * ncr * sizeof *pt);
  next = malloc(ncr * sizeof *next);
  if (!pt || !next) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", ncr); goto done; }
  rc = roots_batch(fn, gfn, ud, ncr, P, Q, fp, fq, refine, tol, pt, e);
  if (rc) goto done;
  /* 2. saddle cells: centre value on the true function */
  for (int J = 0; J + 1 < NY; J++)
    for (int I = 0; I + 1 < NX; I++) {
      int a = node_v(g, I, J) < 0, b = node_v(g, I + 1, J) < 0;
      int c = node_v(g, I + 1, J + 1) < 0, d = node_v(g, I, J + 1) < 0;
      if (!((a && c && !b && !d) || (b && d && !a && !c))) continue;
      if (nsad + 1 > capsad) {
        size_t cc = capsad;
        if (gr_grow(&sad, &cc, nsad + 1, 2 * sizeof(int)) || (cc = capsad, gr_grow(&cx, &cc, nsad + 1, sizeof(double))) ||
            (cc = capsad, gr_grow(&cy, &cc, nsad + 1, sizeof(double))) || (cc = capsad, gr_grow(&cv, &cc, nsad + 1, sizeof(double)))) {
          rc = gr_fail(e, GR_EMEM, "out of memory: %zu saddles", nsad);
          goto done;
        }
        capsad = cc;
      }
      sad[2 * nsad] = I; sad[2 * nsad + 1] = J;
      cx[nsad] = 0.5 * (node_x(g, I) + node_x(g, I + 1));
      cy[nsad] = 0.5 * (node_y(g, J) + node_y(g, J + 1));
      nsad++;
    }
  if (nsad) {
    rc = eval_pts(fn, ud, nsad, cx, cy, cv, e);
    if (rc) goto done;
  }
  /* 3. segments: walk the cell boundary CCW (edges e0 bottom, e1 right,
   * e2 top, e3 left); an in->out crossing X is joined to the out->in
   * crossing Y that follows it (centre inside) or precedes it (outside). */
  for (size_t k = 0; k < ncr; k++) next[k] = -1;
  size_t s = 0;
  for (int J = 0; J + 1 < NY; J++)
    for (int I = 0; I + 1 < NX; I++) {
      int ins[4] = {node_v(g, I, J) < 0, node_v(g, I + 1, J) < 0,
                    node_v(g, I + 1, J + 1) < 0, node_v(g, I, J + 1) < 0};
      int m = ins[0] | ins[1] << 1 | ins[2] << 2 | ins[3] << 3;
      if (m == 0 || m == 15) continue;
      size_t ids[4] = {2 * ((size_t)I + (size_t)NX * J), 2 * ((size_t)I + 1 + (size_t)NX * J) + 1,
                       2 * ((size_t)I + (size_t)NX * (J + 1)), 2 * ((size_t)I + (size_t)NX * J) + 1};
      int centre_in = 0;
      if (m == 5 || m == 10) {
        while (s < nsad && (sad[2 * s + 1] < J || (sad[2 * s + 1] == J && sad[2 * s] < I))) s++;
        centre_in = s < nsad && sad[2 * s] == I && sad[2 * s + 1] == J && cv[s] < 0;
      }
      for (int k = 0; k < 4; k++) {
        if (!(ins[k] && !ins[(k + 1) & 3])) continue; /* X at edge k */
        int y = -1;
        if (centre_in) {
          for (int q = 1; q < 4; q++) { int kk = (k + q) & 3; if (!ins[kk] && ins[(kk + 1) & 3]) { y = kk; break; } }
        } else {
          for (int q = 1; q < 4; q++) { int kk = (k - q + 4) & 3; if (!ins[kk] && ins[(kk + 1) & 3]) { y = kk; break; } }
        }
        if (y < 0) continue;
        next[cross[ids[k]]] = cross[ids[y]];
      }
    }
  /* 4. chain */
  ring = malloc(2 * (ncr + 1) * sizeof *ring);
  if (!ring) { rc = gr_fail(e, GR_EMEM, "out of memory: %zu crossings", ncr); goto done; }
  for (size_t k = 0; k < ncr; k++) {
    if (next[k] < 0) continue;
    size_t n = 0;
    int c = (int)k;
    while (c >= 0 && next[c] >= 0) {
      ring[2 * n] = pt[2 * c];
      ring[2 * n + 1] = pt[2 * c + 1];
      n++;
      int nc = next[c];
      next[c] = -1;
      c = nc;
    }
    rc = emit_ring(out, ring, n);
    if (rc) { rc = gr_fail(e, GR_EMEM, "out of memory storing rings"); goto done; }
  }
done:
  free(cross); free(P); free(Q); free(fp); free(fq); free(pt); free(next);
  free(sad); free(cx); free(cy); free(cv); free(ring);
  return rc;
}

/* Chords by Newton along the normal from the midpoint (value and gradient):
 * one evaluation settles chords whose zero set is well inside chord_tol; the
 * others converge in one or two more, and a converged root more than
 * chord_tol from the midpoint becomes an insertion (ins[seg] = 1 + index into
 * ipt). Chords Newton cannot settle (flat gradient, a step leaving the
 * bracket) stay in the candidate arrays (compacted, *m updated) for
 * bracketing. */
static int chord_newton(gr_slice_grad_fn gfn, void *ud, double tol, double chord_tol,
                        double *ax, double *ay, double *bx, double *by, size_t *seg, size_t *m,
                        int *ins, double *ipt, size_t *nins, gr_err *e) {
  size_t n = *m;
  double *mx = malloc(n * sizeof *mx), *my = malloc(n * sizeof *my), *t = calloc(n, sizeof *t);
  double *qx = malloc(n * sizeof *qx), *qy = malloc(n * sizeof *qy), *f = malloc(n * sizeof *f);
  double *gx = malloc(n * sizeof *gx), *gy = malloc(n * sizeof *gy);
  size_t *act = malloc(n * sizeof *act);
  unsigned char *left = calloc(n, 1); /* 1: bracket it */
  int rc = GR_OK;
  if (!mx || !my || !t || !qx || !qy || !f || !gx || !gy || !act || !left) {
    rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
    goto done;
  }
  size_t na = n;
  for (size_t k = 0; k < n; k++) {
    mx[k] = 0.5 * (ax[k] + bx[k]);
    my[k] = 0.5 * (ay[k] + by[k]);
    act[k] = k;
  }
  for (int it = 0; it < 6 && na > 0; it++) {
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double h = hypot(bx[k] - mx[k], by[k] - my[k]);
      qx[i] = mx[k] + t[k] * (bx[k] - mx[k]) / h;
      qy[i] = my[k] + t[k] * (by[k] - my[k]) / h;
    }
    for (size_t s = 0; s < na && !rc; s += MS_CHUNK) {
      size_t c = na - s < MS_CHUNK ? na - s : MS_CHUNK;
      rc = gfn(ud, c, qx + s, qy + s, f + s, gx + s, gy + s, e);
    }
    if (rc) goto done;
    size_t keep = 0;
    for (size_t i = 0; i < na; i++) {
      size_t k = act[i];
      double h = hypot(bx[k] - mx[k], by[k] - my[k]);
      double dn = (gx[i] * (bx[k] - mx[k]) + gy[i] * (by[k] - my[k])) / h;
      double step = dn > 0.5 ? -f[i] / dn : NAN;
      if (!isfinite(step) || fabs(t[k] + step) > h) { left[k] = 1; continue; }
      t[k] += step;
      if (it == 0 && fabs(t[k]) < 0.9 * chord_tol) continue; /* the chord is fine */
      if (fabs(step) < tol) {                                 /* converged */
        if (fabs(t[k]) > chord_tol) {
          ipt[2 * *nins] = mx[k] + t[k] * (bx[k] - mx[k]) / h;
          ipt[2 * *nins + 1] = my[k] + t[k] * (by[k] - my[k]) / h;
          ins[seg[k]] = (int)++*nins;
        }
        continue;
      }
      act[keep++] = k;
    }
    na = keep;
  }
  for (size_t i = 0; i < na; i++) left[act[i]] = 1; /* not converged */
  size_t q = 0;
  for (size_t k = 0; k < n; k++) {
    if (!left[k]) continue;
    ax[q] = ax[k]; ay[q] = ay[k]; bx[q] = bx[k]; by[q] = by[k]; seg[q] = seg[k];
    q++;
  }
  *m = q;
done:
  free(mx); free(my); free(t); free(qx); free(qy); free(f); free(gx); free(gy); free(act); free(left);
  return rc;
}

/* Window test for the chord pass: a segment along the window border is exact. */
typedef struct win { int on; double lo[2], hi[2]; } win;
static int on_border(const win *w, const double *a, const double *b) {
  if (!w->on) return 0;
  for (int c = 0; c < 2; c++)
    if ((a[c] == w->lo[c] && b[c] == w->lo[c]) || (a[c] == w->hi[c] && b[c] == w->hi[c])) return 1;
  return 0;
}

/* Chord accuracy pass: for each ring segment, find the zero of fn on the
 * normal line through the chord midpoint (bracket +-half the chord); where
 * it lies more than chord_tol from the midpoint, insert it. Repeats until no
 * insertion (at most 12 passes). Rings in `r` are rewritten. */
static int chord_refine(gr_rings *r, ms_fn fn, gr_slice_grad_fn gfn, void *ud, double tol,
                        double chord_tol, const win *w, gr_err *e) {
  int rc = GR_OK;
  gr_rings *nr = gr_rings_new();
  /* ok[i]: the chord from point i was checked (only new chords are checked
   * in later passes) */
  unsigned char *ok = calloc(r->npts + 1, 1);
  if (!nr || !ok) { gr_rings_free(nr); free(ok); return gr_fail(e, GR_EMEM, "out of memory refining chords"); }
  for (int pass = 0; pass < 12; pass++) {
    size_t n = r->npts;
    /* per candidate chord: bracket ends a, b (+-half the chord along the
     * outward normal through the midpoint) and its first point's index */
    double *ax = malloc(n * sizeof *ax + 1), *ay = malloc(n * sizeof *ay + 1);
    double *bx = malloc(n * sizeof *bx + 1), *by = malloc(n * sizeof *by + 1);
    double *fa = malloc(n * sizeof *fa + 1), *fb = malloc(n * sizeof *fb + 1);
    double *A = malloc(2 * n * sizeof *A + 1), *B = malloc(2 * n * sizeof *B + 1);
    double *root = malloc(2 * n * sizeof *root + 1), *ipt = malloc(2 * n * sizeof *ipt + 1);
    int *ins = calloc(n + 1, sizeof *ins);
    size_t *seg = malloc(n * sizeof *seg + 1);
    unsigned char *ok2 = NULL;
    size_t nins = 0;
    if (!ax || !ay || !bx || !by || !fa || !fb || !A || !B || !root || !ipt || !ins || !seg) {
      rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
      goto pass_done;
    }
    size_t m = 0;
    for (size_t i = 0; i < r->nrings; i++) {
      size_t len = gr_ring_len(r, i), st = r->start[i];
      const double *p = gr_ring_xy(r, i);
      for (size_t k = 0; k < len; k++) {
        if (ok[st + k]) continue;
        const double *a = p + 2 * k, *b = p + 2 * ((k + 1) % len);
        if (on_border(w, a, b)) continue;
        double dx = b[0] - a[0], dy = b[1] - a[1], L = hypot(dx, dy);
        if (L <= 2 * chord_tol) continue;
        double mx = 0.5 * (a[0] + b[0]), my = 0.5 * (a[1] + b[1]);
        double nx = dy / L, ny = -dx / L, h = 0.5 * L; /* right normal: outside */
        ax[m] = mx - h * nx; ay[m] = my - h * ny;
        bx[m] = mx + h * nx; by[m] = my + h * ny;
        seg[m] = st + k;
        m++;
      }
    }
    if (m == 0) goto pass_done;
    if (gfn && (rc = chord_newton(gfn, ud, tol, chord_tol, ax, ay, bx, by, seg, &m, ins, ipt, &nins, e)))
      goto pass_done;
    if ((rc = eval_pts(fn, ud, m, ax, ay, fa, e)) || (rc = eval_pts(fn, ud, m, bx, by, fb, e))) goto pass_done;
    size_t q = 0;
    for (size_t k = 0; k < m; k++) {
      if (!(fa[k] < 0 && fb[k] >= 0)) continue;
      A[2 * q] = ax[k]; A[2 * q + 1] = ay[k];
      B[2 * q] = bx[k]; B[2 * q + 1] = by[k];
      fa[q] = fa[k]; fb[q] = fb[k]; seg[q] = seg[k];
      q++;
    }
    rc = roots_batch(fn, gfn, ud, q, A, B, fa, fb, 1, tol, root, e);
    if (rc) goto pass_done;
    /* mark insertions: ins[global point index] = 1 + index into ipt */
    for (size_t k = 0; k < q; k++) {
      double mx = 0.5 * (A[2 * k] + B[2 * k]), my = 0.5 * (A[2 * k + 1] + B[2 * k + 1]);
      if (hypot(root[2 * k] - mx, root[2 * k + 1] - my) > chord_tol) {
        ipt[2 * nins] = root[2 * k];
        ipt[2 * nins + 1] = root[2 * k + 1];
        ins[seg[k]] = (int)++nins;
      }
    }
    if (nins) {
      ok2 = calloc(n + nins + 1, 1);
      if (!ok2) { rc = gr_fail(e, GR_EMEM, "out of memory refining chords"); goto pass_done; }
      gr_rings_clear(nr);
      size_t np = 0;
      for (size_t i = 0; i < r->nrings && !rc; i++) {
        size_t len = gr_ring_len(r, i), st = r->start[i];
        const double *p = gr_ring_xy(r, i);
        for (size_t k = 0; k < len && !rc; k++) {
          rc = gr_rings_point(nr, p[2 * k], p[2 * k + 1]);
          ok2[np++] = !ins[st + k];
          if (!rc && ins[st + k]) {
            size_t c = (size_t)ins[st + k] - 1;
            rc = gr_rings_point(nr, ipt[2 * c], ipt[2 * c + 1]);
            ok2[np++] = 0;
          }
        }
        if (!rc) rc = gr_rings_close(nr);
      }
      if (rc) rc = gr_fail(e, GR_EMEM, "out of memory refining chords");
      else rc = gr_rings_copy(r, nr) ? gr_fail(e, GR_EMEM, "out of memory refining chords") : GR_OK;
      if (!rc) { free(ok); ok = ok2; ok2 = NULL; }
    }
  pass_done:
    free(ax); free(ay); free(bx); free(by); free(fa); free(fb); free(A); free(B);
    free(root); free(ipt); free(ins); free(seg); free(ok2);
    if (rc || nins == 0) break;
  }
  gr_rings_free(nr);
  free(ok);
  return rc;
}

/* ---- field sections ---- */

typedef struct field_ud {
  const gr_field *f;
  double z;
  double *zb; /* MS_CHUNK copies of z */
} field_ud;

static int field_fn(void *ud, size_t n, const double *x, const double *y,
                    double *out, gr_err *e) {
  field_ud *u = ud;
  return gr_field_eval(u->f, n, x, y, u->zb, out, e);
}

static int check_window(const double lo[2], const double hi[2], double cell,
                        double tol, gr_err *e) {
  for (int c = 0; c < 2; c++) {
    if (!isfinite(lo[c]) || !isfinite(hi[c]) || !(hi[c] > lo[c]))
      return gr_fail(e, GR_EARG, "window must have hi > lo, got %s lo %g, hi %g",
                     c ? "y" : "x", lo[c], hi[c]);
  }
  if (!(cell > 0) || !isfinite(cell)) return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (!(tol > 0) || !isfinite(tol)) return gr_fail(e, GR_EARG, "tol must be > 0, got %g", tol);
  double nx = ceil((hi[0] - lo[0]) / cell) + 1, ny = ceil((hi[1] - lo[1]) / cell) + 1;
  if (nx * ny > (double)MS_MAX_NODES)
    return gr_fail(e, GR_EMEM, "slice grid too large: %.0f x %.0f nodes for cell %g mm (limit %zu nodes)",
                   nx, ny, cell, MS_MAX_NODES);
  return GR_OK;
}

/* The grid over the window: nodes at most `cell` apart. A width that is a
 * whole number of cells up to rounding (a window [o - m, o + L + m] far from
 * the origin, say) keeps exactly that number: one node more would shrink
 * every spacing and misalign the grid with grids of equal windows elsewhere
 * (the shared closest-point tables rely on that alignment). */
static ms_grid window_grid(const gr_slice_opts *o) {
  int nx = (int)ceil((o->hi[0] - o->lo[0]) / o->cell - 1e-9) + 1;
  int ny = (int)ceil((o->hi[1] - o->lo[1]) / o->cell - 1e-9) + 1;
  ms_grid g = {nx, ny, o->lo[0], o->lo[1], (o->hi[0] - o->lo[0]) / (nx - 1),
               (o->hi[1] - o->lo[1]) / (ny - 1), NULL};
  return g;
}

static int check_opts(const gr_slice_opts *o, gr_err *e) {
  int rc = check_window(o->lo, o->hi, o->cell, o->tol, e);
  if (rc) return rc;
  if (o->chord_tol < 0 || !isfinite(o->chord_tol))
    return gr_fail(e, GR_EARG, "chord_tol must be >= 0, got %g", o->chord_tol);
  return GR_OK;
}

void gr_slice_grid_size(const gr_slice_opts *o, int *nx, int *ny, double *hx, double *hy) {
  ms_grid g = window_grid(o);
  *nx = g.nx;
  *ny = g.ny;
  *hx = g.hx;
  *hy = g.hy;
}

/* Contour the sampled grid g (values set) with fn for refinement, chords and nesting. */
static int slice_sampled(ms_grid *g, const gr_slice_opts *o, ms_fn fn, gr_slice_grad_fn gfn,
                         void *ud, gr_rings *out, gr_err *e) {
  gr_rings_clear(out);
  int rc = ms_contour(g, fn, gfn, ud, o->refine, o->tol, out, e);
  if (!rc && o->chord_tol > 0) {
    win w = {1, {o->lo[0], o->lo[1]}, {o->hi[0], o->hi[1]}};
    rc = chord_refine(out, fn, gfn, ud, o->tol, o->chord_tol, &w, e);
  }
  if (!rc) rc = gr_rings_nest(out, e);
  return rc;
}

int gr_slice_grid(const double *v, const gr_slice_opts *o, gr_slice_fn fn,
                  gr_slice_grad_fn gfn, void *ud, gr_rings *out, gr_err *e) {
  if (!o || !v || !fn) return gr_fail(e, GR_EARG, "slice grid: options, values and function are needed");
  int rc = check_opts(o, e);
  if (rc) return rc;
  ms_grid g = window_grid(o);
  g.v = v;
  return slice_sampled(&g, o, fn, gfn, ud, out, e);
}

int gr_slice_field(const gr_field *f, double z, const gr_slice_opts *o,
                   gr_rings *out, gr_err *e) {
  gr_slice_opts d = gr_slice_defaults();
  if (!o) o = &d;
  if (!f) return gr_fail(e, GR_EARG, "field must not be NULL");
  if (!isfinite(z)) return gr_fail(e, GR_EARG, "z must be finite, got %g", z);
  int rc = check_opts(o, e);
  if (rc) return rc;
  ms_grid g = window_grid(o);
  int nx = g.nx, ny = g.ny;
  size_t nn = (size_t)nx * ny;
  field_ud u = {f, z, malloc(MS_CHUNK * sizeof(double))};
  double *v = malloc(nn * sizeof *v);
  double *xs = malloc((size_t)nx * sizeof *xs), *ys = malloc((size_t)nx * sizeof *ys);
  if (!u.zb || !v || !xs || !ys) {
    rc = gr_fail(e, GR_EMEM, "out of memory: slice grid %d x %d", nx, ny);
    goto done;
  }
  for (size_t k = 0; k < MS_CHUNK; k++) u.zb[k] = z;
  for (int i = 0; i < nx; i++) xs[i] = i == nx - 1 ? o->hi[0] : o->lo[0] + i * g.hx;
  for (int j = 0; j < ny && !rc; j++) {
    double y = j == ny - 1 ? o->hi[1] : o->lo[1] + j * g.hy;
    for (int i = 0; i < nx; i++) ys[i] = y;
    rc = eval_pts(field_fn, &u, (size_t)nx, xs, ys, v + (size_t)nx * j, e);
  }
  if (rc) goto done;
  g.v = v;
  rc = slice_sampled(&g, o, field_fn, NULL, &u, out, e);
done:
  free(u.zb); free(v); free(xs); free(ys);
  return rc;
}

/* ---- 2-D distance to a polygon set (for offsets) ---- */

typedef struct poly_dist {
  size_t ne;            /* edges */
  double *ab;           /* 4 per edge: ax ay bx by */
  size_t *prv, *nxt;    /* neighbouring edges in the ring */
  double lo[2];         /* bucket grid origin, mm */
  double bs;            /* bucket size, mm */
  int bx, by;           /* buckets per axis */
  size_t *bstart, *bedge; /* CSR: edges of bucket k are bedge[bstart[k]..bstart[k+1]) */
  double b;             /* offset distance, mm: fn returns sd + b */
} poly_dist;

static void pd_free(poly_dist *d) {
  free(d->ab); free(d->prv); free(d->nxt); free(d->bstart); free(d->bedge);
}

static int left_of(const double *e4, double x, double y) {
  return (e4[2] - e4[0]) * (y - e4[1]) - (e4[3] - e4[1]) * (x - e4[0]) > 0;
}

/* Nearest edge to (x, y) among edges within rmax (searching rings of buckets
 * outward). Returns the squared distance (INFINITY if none within rmax) and
 * the edge and parameter. */
static double pd_nearest(const poly_dist *d, double x, double y, double rmax,
                         size_t *edge, double *tpar) {
  double best = INFINITY;
  int ci = (int)floor((x - d->lo[0]) / d->bs), cj = (int)floor((y - d->lo[1]) / d->bs);
  int kmax = (int)ceil(rmax / d->bs) + 1;
  int lim = (d->bx > d->by ? d->bx : d->by) + 2;
  if (kmax > lim + abs(ci) + abs(cj)) kmax = lim + abs(ci) + abs(cj);
  for (int k = 0; k <= kmax; k++) {
    for (int j = cj - k; j <= cj + k; j++) {
      if (j < 0 || j >= d->by) continue;
      int step = (j == cj - k || j == cj + k) ? 1 : 2 * k;
      for (int i = ci - k; i <= ci + k; i += step ? step : 1) {
        if (i >= 0 && i < d->bx) {
          size_t bk = (size_t)i + (size_t)d->bx * j;
          for (size_t q = d->bstart[bk]; q < d->bstart[bk + 1]; q++) {
            size_t ed = d->bedge[q];
            const double *p = d->ab + 4 * ed;
            double ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
            double t = L2 > 0 ? ((x - p[0]) * ex + (y - p[1]) * ey) / L2 : 0;
            if (t < 0) t = 0;
            if (t > 1) t = 1;
            double qx = p[0] + t * ex - x, qy = p[1] + t * ey - y, d2 = qx * qx + qy * qy;
            if (d2 < best) { best = d2; *edge = ed; *tpar = t; }
          }
        }
        if (step == 0) break;
      }
    }
    /* everything not yet searched is farther than k*bs from (x, y) when the
     * point is inside bucket (ci, cj) */
    double safe = k * d->bs;
    if (best <= safe * safe) break;
    if (safe > rmax) break;
  }
  if (best > rmax * rmax) return INFINITY;
  return best;
}

/* Inside test from the nearest feature: rings are oriented (inside on the
 * left of every edge); at a vertex, the point is inside the interior angle. */
static int pd_inside(const poly_dist *d, size_t ed, double t, double x, double y) {
  const double *p = d->ab + 4 * ed;
  if (t > 0 && t < 1) return left_of(p, x, y);
  const double *e1, *e2; /* incoming, outgoing edge at the vertex */
  if (t <= 0) { e1 = d->ab + 4 * d->prv[ed]; e2 = p; }
  else { e1 = p; e2 = d->ab + 4 * d->nxt[ed]; }
  double turn = (e1[2] - e1[0]) * (e2[3] - e2[1]) - (e1[3] - e1[1]) * (e2[2] - e2[0]);
  int l1 = left_of(e1, x, y), l2 = left_of(e2, x, y);
  return turn > 0 ? (l1 && l2) : (l1 || l2);
}

/* Exact signed distance (negative inside) of (x, y) to the edges; q (may be
 * NULL) receives the nearest boundary point. +INFINITY without edges. */
static double pd_signed(const poly_dist *d, double x, double y, double q[2]) {
  if (d->ne == 0) return INFINITY;
  size_t ed = 0;
  double t = 0, d2 = INFINITY;
  for (double r = 2 * d->bs; !isfinite(d2); r *= 4) d2 = pd_nearest(d, x, y, r, &ed, &t);
  const double *a = d->ab + 4 * ed;
  if (q) { q[0] = a[0] + t * (a[2] - a[0]); q[1] = a[1] + t * (a[3] - a[1]); }
  return pd_inside(d, ed, t, x, y) ? -sqrt(d2) : sqrt(d2);
}

/* Signed distance (negative inside) + b, exact. */
static int pd_fn(void *ud, size_t n, const double *x, const double *y,
                 double *out, gr_err *e) {
  (void)e;
  const poly_dist *d = ud;
  for (size_t k = 0; k < n; k++) out[k] = pd_signed(d, x[k], y[k], NULL) + d->b;
  return GR_OK;
}

/* Build edges and the bucket grid (bucket size about bs) of nested rings r. */
static int pd_build(poly_dist *d, const gr_rings *r, double bs, gr_err *e) {
  memset(d, 0, sizeof *d);
  d->ne = r->npts;
  d->ab = malloc(4 * d->ne * sizeof *d->ab + 1);
  d->prv = malloc(d->ne * sizeof *d->prv + 1);
  d->nxt = malloc(d->ne * sizeof *d->nxt + 1);
  if (!d->ab || !d->prv || !d->nxt) return gr_fail(e, GR_EMEM, "out of memory: %zu edges", d->ne);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t i = 0; i < r->nrings; i++) {
    size_t n = gr_ring_len(r, i), st = r->start[i];
    const double *p = gr_ring_xy(r, i);
    for (size_t k = 0; k < n; k++) {
      size_t k1 = (k + 1) % n;
      double *a = d->ab + 4 * (st + k);
      a[0] = p[2 * k]; a[1] = p[2 * k + 1]; a[2] = p[2 * k1]; a[3] = p[2 * k1 + 1];
      d->prv[st + k] = st + (k + n - 1) % n;
      d->nxt[st + k] = st + k1;
      for (int c = 0; c < 2; c++) { lo[c] = fmin(lo[c], a[c]); hi[c] = fmax(hi[c], a[c]); }
    }
  }
  double w = fmax(hi[0] - lo[0], hi[1] - lo[1]);
  if (!(bs > 0)) bs = w / 16;
  /* at most ~4 buckets per edge and 4M buckets */
  double maxb = fmin(4.0 * (double)d->ne + 16, 4e6);
  while (((hi[0] - lo[0]) / bs + 1) * ((hi[1] - lo[1]) / bs + 1) > maxb) bs *= 1.5;
  if (!(bs > 0)) bs = 1;
  d->bs = bs;
  d->lo[0] = lo[0]; d->lo[1] = lo[1];
  d->bx = (int)floor((hi[0] - lo[0]) / bs) + 1;
  d->by = (int)floor((hi[1] - lo[1]) / bs) + 1;
  size_t nb = (size_t)d->bx * d->by;
  d->bstart = calloc(nb + 1, sizeof *d->bstart);
  if (!d->bstart) return gr_fail(e, GR_EMEM, "out of memory: %zu buckets", nb);
  for (int pass = 0; pass < 2; pass++) {
    for (size_t ed = 0; ed < d->ne; ed++) {
      const double *a = d->ab + 4 * ed;
      int i0 = (int)floor((fmin(a[0], a[2]) - lo[0]) / bs), i1 = (int)floor((fmax(a[0], a[2]) - lo[0]) / bs);
      int j0 = (int)floor((fmin(a[1], a[3]) - lo[1]) / bs), j1 = (int)floor((fmax(a[1], a[3]) - lo[1]) / bs);
      if (i1 >= d->bx) i1 = d->bx - 1;
      if (j1 >= d->by) j1 = d->by - 1;
      for (int j = j0; j <= j1; j++)
        for (int i = i0; i <= i1; i++) {
          size_t bk = (size_t)i + (size_t)d->bx * j;
          if (pass == 0) d->bstart[bk + 1]++;
          else d->bedge[d->bstart[bk]++] = ed;
        }
    }
    if (pass == 0) {
      for (size_t k = 0; k < nb; k++) d->bstart[k + 1] += d->bstart[k];
      d->bedge = malloc(d->bstart[nb] * sizeof *d->bedge + 1);
      if (!d->bedge) return gr_fail(e, GR_EMEM, "out of memory: %zu bucket entries", d->bstart[nb]);
    } else {
      for (size_t k = nb; k > 0; k--) d->bstart[k] = d->bstart[k - 1];
      d->bstart[0] = 0;
    }
  }
  return GR_OK;
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Sample sd + b on the grid g (v allocated by the caller): the sign by the
 * even-odd rule along each row (exact), the distance from the buckets
 * within rmax (clamped to rmax farther away). */
static int pd_sample(const poly_dist *d, const ms_grid *g, double *v,
                     double rmax, gr_err *e) {
  double *xs = malloc((d->ne + 1) * sizeof *xs);
  if (!xs) return gr_fail(e, GR_EMEM, "out of memory: %zu edges", d->ne);
  /* squared distances: each edge updates the nodes within rmax of it */
  size_t nn = (size_t)g->nx * g->ny;
  for (size_t k = 0; k < nn; k++) v[k] = INFINITY;
  for (size_t ed = 0; ed < d->ne; ed++) {
    const double *p = d->ab + 4 * ed;
    double ex = p[2] - p[0], ey = p[3] - p[1], L2 = ex * ex + ey * ey;
    int i0 = (int)floor((fmin(p[0], p[2]) - rmax - g->x0) / g->hx), i1 = (int)ceil((fmax(p[0], p[2]) + rmax - g->x0) / g->hx);
    int j0 = (int)floor((fmin(p[1], p[3]) - rmax - g->y0) / g->hy), j1 = (int)ceil((fmax(p[1], p[3]) + rmax - g->y0) / g->hy);
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 > g->nx - 1) i1 = g->nx - 1;
    if (j1 > g->ny - 1) j1 = g->ny - 1;
    for (int j = j0; j <= j1; j++) {
      double y = g->y0 + j * g->hy;
      double *row = v + (size_t)g->nx * j;
      for (int i = i0; i <= i1; i++) {
        double x = g->x0 + i * g->hx;
        double t = L2 > 0 ? ((x - p[0]) * ex + (y - p[1]) * ey) / L2 : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        double qx = p[0] + t * ex - x, qy = p[1] + t * ey - y, d2 = qx * qx + qy * qy;
        if (d2 < row[i]) row[i] = d2;
      }
    }
  }
  /* signs by scan-line parity */
  for (int j = 0; j < g->ny; j++) {
    double y = g->y0 + j * g->hy;
    size_t nc = 0;
    for (size_t ed = 0; ed < d->ne; ed++) {
      const double *a = d->ab + 4 * ed;
      if ((a[1] > y) != (a[3] > y)) xs[nc++] = a[0] + (y - a[1]) * (a[2] - a[0]) / (a[3] - a[1]);
    }
    qsort(xs, nc, sizeof *xs, cmp_double);
    size_t c = 0;
    for (int i = 0; i < g->nx; i++) {
      double x = g->x0 + i * g->hx;
      while (c < nc && xs[c] <= x) c++;
      int in = c & 1;
      double *vv = v + i + (size_t)g->nx * j;
      double dist = *vv <= rmax * rmax ? sqrt(*vv) : rmax;
      *vv = (in ? -dist : dist) + d->b;
    }
  }
  free(xs);
  return GR_OK;
}

/* Grid over the bounding box of r with cell <= cell; fails if too large. */
static int bbox_grid(const gr_rings *r, double cell, ms_grid *g, gr_err *e) {
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t k = 0; k < r->npts; k++)
    for (int c = 0; c < 2; c++) { lo[c] = fmin(lo[c], r->xy[2 * k + c]); hi[c] = fmax(hi[c], r->xy[2 * k + c]); }
  for (int c = 0; c < 2; c++)
    if (!isfinite(lo[c]) || !isfinite(hi[c])) return gr_fail(e, GR_ENUM, "rings have a non-finite coordinate");
  for (int c = 0; c < 2; c++) if (hi[c] - lo[c] < cell) { double m = 0.5 * (lo[c] + hi[c]); lo[c] = m - cell / 2; hi[c] = m + cell / 2; }
  int rc = check_window(lo, hi, cell, 1, e);
  if (rc) return rc;
  g->nx = (int)ceil((hi[0] - lo[0]) / cell) + 1;
  g->ny = (int)ceil((hi[1] - lo[1]) / cell) + 1;
  g->x0 = lo[0]; g->y0 = lo[1];
  g->hx = (hi[0] - lo[0]) / (g->nx - 1);
  g->hy = (hi[1] - lo[1]) / (g->ny - 1);
  return GR_OK;
}

int gr_offset_rings_opt(const gr_rings *in, double b, double cell, double tol,
                        double chord_tol, gr_rings *out, gr_err *e) {
  if (!(b >= 0) || !isfinite(b)) return gr_fail(e, GR_EARG, "offset distance b must be >= 0, got %g", b);
  if (!(cell > 0) || !isfinite(cell)) return gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell);
  if (!(tol > 0) || !isfinite(tol)) return gr_fail(e, GR_EARG, "tol must be > 0, got %g", tol);
  if (!(chord_tol >= 0) || !isfinite(chord_tol)) return gr_fail(e, GR_EARG, "chord_tol must be >= 0, got %g", chord_tol);
  gr_rings *src = gr_rings_new();
  if (!src) return gr_fail(e, GR_EMEM, "out of memory copying rings");
  int rc = gr_rings_copy(src, in) ? gr_fail(e, GR_EMEM, "out of memory copying rings") : GR_OK;
  if (!rc) rc = gr_rings_nest(src, e);
  if (rc || b == 0 || src->nrings == 0) {
    if (!rc) rc = gr_rings_copy(out, src) ? gr_fail(e, GR_EMEM, "out of memory copying rings") : GR_OK;
    if (!rc) rc = gr_rings_nest(out, e);
    gr_rings_free(src);
    return rc;
  }
  poly_dist d;
  ms_grid g;
  double *v = NULL;
  rc = bbox_grid(src, cell, &g, e);
  if (rc) { gr_rings_free(src); return rc; }
  double rmax = b + 2 * fmax(g.hx, g.hy);
  rc = pd_build(&d, src, rmax, e);
  d.b = b;
  if (!rc) {
    v = malloc((size_t)g.nx * g.ny * sizeof *v);
    if (!v) rc = gr_fail(e, GR_EMEM, "out of memory: offset grid %d x %d", g.nx, g.ny);
  }
  if (!rc) rc = pd_sample(&d, &g, v, rmax, e);
  if (!rc) {
    g.v = v;
    gr_rings_clear(out);
    rc = ms_contour(&g, pd_fn, NULL, &d, 1, tol, out, e);
  }
  if (!rc && chord_tol > 0) {
    win w = {0, {0, 0}, {0, 0}};
    rc = chord_refine(out, pd_fn, NULL, &d, tol, chord_tol, &w, e);
  }
  if (!rc) rc = gr_rings_nest(out, e);
  free(v);
  pd_free(&d);
  gr_rings_free(src);
  return rc;
}

int gr_offset_rings(const gr_rings *in, double b, double cell, gr_rings *out,
                    gr_err *e) {
  return gr_offset_rings_opt(in, b, cell, 1e-6, 0, out, e);
}

double gr_rings_max_inner_distance(const gr_rings *in, double cell, gr_err *e) {
  if (!(cell > 0) || !isfinite(cell)) { gr_fail(e, GR_EARG, "cell must be > 0, got %g", cell); return -1; }
  if (!in || in->nrings == 0) return 0;
  gr_rings *src = gr_rings_new();
  if (!src || gr_rings_copy(src, in)) { gr_rings_free(src); gr_fail(e, GR_EMEM, "out of memory copying rings"); return -1; }
  poly_dist d;
  ms_grid g;
  double *v = NULL, best = 0;
  int rc = gr_rings_nest(src, e);
  if (!rc) rc = bbox_grid(src, cell, &g, e);
  if (rc) { gr_rings_free(src); return -1; }
  double w = fmax((g.nx - 1) * g.hx, (g.ny - 1) * g.hy);
  rc = pd_build(&d, src, fmax(4 * cell, w / 64), e);
  d.b = 0;
  if (!rc) {
    v = malloc((size_t)g.nx * g.ny * sizeof *v);
    if (!v) rc = gr_fail(e, GR_EMEM, "out of memory: grid %d x %d", g.nx, g.ny);
  }
  if (!rc) rc = pd_sample(&d, &g, v, 2 * w + 1, e);
  if (!rc)
    for (size_t k = 0; k < (size_t)g.nx * g.ny; k++) best = fmax(best, -v[k]);
  free(v);
  pd_free(&d);
  gr_rings_free(src);
  return rc ? -1 : best;
}

struct gr_polydist { poly_dist d; };

gr_polydist *gr_polydist_new(const gr_rings *r, double bucket, gr_err *e) {
  gr_polydist *p = calloc(1, sizeof *p);
  if (!p) { gr_fail(e, GR_EMEM, "out of memory"); return NULL; }
  if (pd_build(&p->d, r, bucket, e)) { pd_free(&p->d); free(p); return NULL; }
  return p;
}

void gr_polydist_free(gr_polydist *p) {
  if (!p) return;
  pd_free(&p->d);
  free(p);
}

double gr_polydist_at(const gr_polydist *p, double x, double y, double q[2]) { return pd_signed(&p->d, x, y, q); }

int gr_polydist_grid(const gr_polydist *p, double x0, double y0, double h, int nx, int ny,
                     double rmax, double *v, gr_err *e) {
  ms_grid g = {nx, ny, x0, y0, h, h, NULL};
  return pd_sample(&p->d, &g, v, rmax, e);
}

/* ---- mesh / plane ---- */

typedef struct mkey { uint64_t key; size_t idx; } mkey;
static int cmp_key(const void *a, const void *b) {
  uint64_t x = ((const mkey *)a)->key, y = ((const mkey *)b)->key;
  return x < y ? -1 : x > y;
}
static long find_key(const uint64_t *keys, size_t n, uint64_t k) {
  size_t lo = 0, hi = n;
  while (lo < hi) {
    size_t m = (lo + hi) / 2;
    if (keys[m] < k) lo = m + 1;
    else hi = m;
  }
  return lo < n && keys[lo] == k ? (long)lo : -1;
}

int gr_slice_mesh(const gr_mesh *m, double z, gr_rings *closed,
                  gr_layer *open, gr_err *e) {
  if (!m) return gr_fail(e, GR_EARG, "mesh must not be NULL");
  if (!isfinite(z)) return gr_fail(e, GR_EARG, "z must be finite, got %g", z);
  if (closed) gr_rings_clear(closed);
  if (open) gr_layer_clear(open, z);
  /* segments: two crossing-edge keys each, oriented so that the inside is
   * on the left: direction along z x n */
  size_t nseg = 0, cap = 0;
  uint64_t *seg = NULL;
  int rc = GR_OK;
  uint64_t nv = m->nv;
  for (size_t f = 0; f < m->nf; f++) {
    const uint32_t *t = m->f + 3 * f;
    if (t[0] >= nv || t[1] >= nv || t[2] >= nv)
      { rc = gr_fail(e, GR_EGEOM, "face %zu has a vertex index out of range", f); goto fail; }
    const double *p[3] = {m->v + 3 * t[0], m->v + 3 * t[1], m->v + 3 * t[2]};
    int above[3] = {p[0][2] >= z, p[1][2] >= z, p[2][2] >= z};
    int na = above[0] + above[1] + above[2];
    if (na == 0 || na == 3) continue;
    uint64_t k[2];
    double q[2][2];
    int c = 0;
    for (int a = 0; a < 3; a++) {
      int b = (a + 1) % 3;
      if (above[a] == above[b]) continue;
      uint32_t u = t[a] < t[b] ? t[a] : t[b], w = t[a] < t[b] ? t[b] : t[a];
      k[c] = (uint64_t)u * nv + w;
      const double *pu = m->v + 3 * (size_t)u, *pw = m->v + 3 * (size_t)w;
      double s = (z - pu[2]) / (pw[2] - pu[2]);
      q[c][0] = pu[0] + s * (pw[0] - pu[0]);
      q[c][1] = pu[1] + s * (pw[1] - pu[1]);
      c++;
    }
    double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    double e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    double nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2];
    /* z x n = (-ny, nx) */
    if ((q[1][0] - q[0][0]) * -ny + (q[1][1] - q[0][1]) * nx < 0) { uint64_t tk = k[0]; k[0] = k[1]; k[1] = tk; }
    if (k[0] == k[1]) continue;
    if (gr_grow(&seg, &cap, nseg + 1, 2 * sizeof *seg)) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    seg[2 * nseg] = k[0];
    seg[2 * nseg + 1] = k[1];
    nseg++;
  }
  {
    size_t nk = 2 * nseg;
    uint64_t *keys = malloc(nk * sizeof *keys + 1);
    long *nxt = NULL;
    int *hasin = NULL, *used = NULL;
    double *pt = NULL, *buf = NULL;
    if (!keys) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    memcpy(keys, seg, nk * sizeof *keys);
    mkey *tmp = malloc(nk * sizeof *tmp + 1);
    if (!tmp) { free(keys); rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fail; }
    for (size_t i = 0; i < nk; i++) { tmp[i].key = keys[i]; tmp[i].idx = i; }
    qsort(tmp, nk, sizeof *tmp, cmp_key);
    size_t nu = 0;
    for (size_t i = 0; i < nk; i++) if (nu == 0 || keys[nu - 1] != tmp[i].key) keys[nu++] = tmp[i].key;
    free(tmp);
    nxt = malloc(nu * sizeof *nxt + 1);
    hasin = calloc(nu + 1, sizeof *hasin);
    used = calloc(nu + 1, sizeof *used);
    pt = malloc(2 * nu * sizeof *pt + 1);
    buf = malloc(2 * (nu + 1) * sizeof *buf);
    if (!nxt || !hasin || !used || !pt || !buf) { rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin; }
    for (size_t i = 0; i < nu; i++) {
      nxt[i] = -1;
      uint64_t u = keys[i] / nv, w = keys[i] % nv;
      const double *pu = m->v + 3 * u, *pw = m->v + 3 * w;
      double s = (z - pu[2]) / (pw[2] - pu[2]);
      pt[2 * i] = pu[0] + s * (pw[0] - pu[0]);
      pt[2 * i + 1] = pu[1] + s * (pw[1] - pu[1]);
    }
    for (size_t s = 0; s < nseg; s++) {
      long a = find_key(keys, nu, seg[2 * s]), b = find_key(keys, nu, seg[2 * s + 1]);
      nxt[a] = b; /* non-manifold input: last one wins */
      hasin[b] = 1;
    }
    /* open chains first (start where nothing comes in), then loops */
    for (int pass = 0; pass < 2; pass++)
      for (size_t i = 0; i < nu; i++) {
        if (used[i] || nxt[i] < 0 || (pass == 0 && hasin[i])) continue;
        size_t n = 0;
        long c = (long)i;
        int loop = 0;
        while (c >= 0 && !used[c]) {
          used[c] = 1;
          buf[2 * n] = pt[2 * c]; buf[2 * n + 1] = pt[2 * c + 1]; n++;
          c = nxt[c];
          if (c == (long)i) { loop = 1; break; }
        }
        if (pass == 0 || !loop) {
          if (c >= 0 && !loop) { buf[2 * n] = pt[2 * c]; buf[2 * n + 1] = pt[2 * c + 1]; n++; }
          if (open && n >= 2 && gr_layer_add(open, GR_OPEN, GR_CONTOUR, 0, 2, buf, n)) {
            rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin;
          }
        } else if (closed && emit_ring(closed, buf, n)) {
          rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin;
        }
      }
    if (closed) {
      /* keep the orientation found from the normals; nest for parents only */
      gr_rings *tmpr = gr_rings_new();
      if (!tmpr || gr_rings_copy(tmpr, closed)) { gr_rings_free(tmpr); rc = gr_fail(e, GR_EMEM, "out of memory slicing mesh"); goto fin; }
      rc = gr_rings_nest(tmpr, e);
      if (!rc) {
        free(closed->parent);
        closed->parent = tmpr->parent;
        tmpr->parent = NULL;
      }
      gr_rings_free(tmpr);
    }
  fin:
    free(keys); free(nxt); free(hasin); free(used); free(pt); free(buf);
  }
fail:
  free(seg);
  return rc;
}
