/* cptab.c: shared closest points, see cptab.h. */
#include "cptab.h"
#include <limits.h>
#include <math.h>
#include <string.h>
#include <stdlib.h>
#include "distance.h"
#include "domain.h"
#include "march.h"

void gr_cptab_free(gr_cptab *t) {
  if (!t) return;
  free(t->q);
  free(t->sd);
  free(t->st);
  free(t->sq);
  free(t->ssd);
  free(t->ldmax);
  free(t);
}

int gr_cptab_period(double cell, double h) {
  double P = cell / h;
  /* P * P nodes are allocated per layer: beyond 2^15 a side the shared grid
   * is refused here (no int overflow in the cast, none in P * P later) */
  return P <= 32768 && fabs(P - round(P)) < 1e-9 * P && round(P) >= 2 ? (int)round(P) : 0;
}

int gr_cptab_periodic(const double cell[3], double h) {
  return gr_cptab_period(cell[0], h) && gr_cptab_period(cell[1], h);
}

gr_cptab *gr_cptab_new(const double cell[3], double h, double margin, const gr_field *ref, const double oref[3], double z0,
                       double t_layer, int nl, double dmax, gr_err *e) {
  gr_cptab *t = calloc(1, sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  for (int a = 0; a < 2; a++) t->P[a] = gr_cptab_period(cell[a], h);
  t->nl = nl;
  t->z0 = z0;
  t->t = t_layer;
  t->h = h;
  t->cell[0] = cell[0];
  t->cell[1] = cell[1];
  t->field = ref;
  for (int a = 0; a < 3; a++) t->oref[a] = oref[a];
  t->lo[0] = t->oref[0] - margin;
  t->lo[1] = t->oref[1] - margin;
  t->dmax = dmax;
  size_t np = (size_t)t->P[0] * t->P[1] * nl;
  t->q = malloc(3 * np * sizeof *t->q);
  t->sd = malloc(np * sizeof *t->sd);
  t->st = calloc(2 * np, 1);
  t->sq = malloc(6 * np * sizeof *t->sq);
  t->ssd = malloc(2 * np * sizeof *t->ssd);
  t->ldmax = calloc(nl, sizeof *t->ldmax);
  if (!t->q || !t->sd || !t->st || !t->sq || !t->ssd || !t->ldmax) {
    gr_cptab_free(t);
    return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  }
  return t;
}

/* Layer q's nodes filled before to a smaller reach (ldmax) whose closest
 * points were beyond it and may lie within dmax now: their closest points
 * found (the others' stay). */
static int layer_grow(gr_cptab *t, int q, gr_err *e) {
  size_t n = (size_t)t->P[0] * t->P[1], m = 0;
  double *tq = t->q + 3 * n * q, *tsd = t->sd + n * q;
  for (size_t k = 0; k < n; k++) m += isnan(tq[3 * k]) && fabs(tsd[k]) <= t->dmax;
  if (!m) return GR_OK;
  double *x = malloc(7 * m * sizeof *x);
  size_t *id = malloc(m * sizeof *id);
  if (!x || !id) {
    free(x);
    free(id);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  double *y = x + m, *z = x + 2 * m, *qq = x + 3 * m, *sd = x + 6 * m;
  m = 0;
  for (size_t k = 0; k < n; k++) {
    if (!(isnan(tq[3 * k]) && fabs(tsd[k]) <= t->dmax)) continue;
    x[m] = t->lo[0] + (double)(k % t->P[0]) * t->h;
    y[m] = t->lo[1] + (double)(k / t->P[0]) * t->h;
    z[m] = t->z0 + q * t->t;
    id[m++] = k;
  }
  int rc = gr_offset_closest(t->field, m, x, y, z, t->dmax, qq, sd, e);
  for (size_t i = 0; i < m && !rc; i++) {
    memcpy(tq + 3 * id[i], qq + 3 * i, 3 * sizeof *qq);
    tsd[id[i]] = sd[i];
  }
  free(x);
  free(id);
  return rc;
}

int gr_cptab_layer(gr_cptab *t, int q, gr_err *e) {
  if (t->ldmax[q] >= t->dmax) return GR_OK;
  int rc = GR_OK;
  size_t n = (size_t)t->P[0] * t->P[1];
  if (t->ldmax[q] > 0) {
    rc = layer_grow(t, q, e);
  } else {
    double *x = malloc(3 * n * sizeof *x);
    if (!x) return gr_fail(e, GR_EMEM, "out of memory");
    double *y = x + n, *z = x + 2 * n, zq = t->z0 + q * t->t;
    for (int b = 0; b < t->P[1]; b++)
      for (int a = 0; a < t->P[0]; a++) {
        x[a + (size_t)t->P[0] * b] = t->lo[0] + a * t->h;
        y[a + (size_t)t->P[0] * b] = t->lo[1] + b * t->h;
        z[a + (size_t)t->P[0] * b] = zq;
      }
    rc = gr_offset_closest_rows(t->field, n, (size_t)t->P[0], x, y, z, t->dmax, t->q + 3 * n * q, t->sd + n * q, e);
    free(x);
  }
  if (!rc) t->ldmax[q] = t->dmax;
  return rc;
}

/* Refinement on the true field from the closest points of the nearest nodes. */
typedef struct node_models {
  double *c;
  size_t n, cap; /* models made; room, in doubles */
} node_models;

typedef struct near_ud {
  const gr_field *f;
  double z, lo[2], h;
  int nx, ny;
  const double *q; /* 3 per window node */
  /* node_predict's stencil per window node, made when a point first needs
   * it (refined points crowd round the contours: most nodes serve several):
   * pix 0 not made, 1 no model there, k >= 2 model k - 2 of pm (NCO each,
   * packed in the order made: the nodes by the contours only, a few
   * hundred kB less to keep in cache than one slot per node) */
  unsigned *pix;
  struct node_models *pm;
  /* the nodes' signed distances and the thickness their values imply (NaN
   * where a value is only a bound): T's slope along the section from them
   * (NULL: none) */
  const double *sd, *T;
  double ih; /* 1 / h: grid positions without a division per point */
} near_ud;


/* Hints for the point (x, y): the closest points of the four nodes around
 * it, each moved along its tangent plane by the point's offset from the node,
 * nearest node first, those on distinct patches of H only (across the medial
 * surface the nearer patch decides, and with it the thickness there). NH
 * hints (3 each) written, NaN past the last; returns how many. */
enum { NH = 4 };
static int node_hints(const near_ud *u, double x, double y, double *hi) {
  double fx = (x - u->lo[0]) * u->ih, fy = (y - u->lo[1]) * u->ih;
  int a = (int)floor(fx), b = (int)floor(fy), nh = 0, order[4] = {0, 1, 2, 3};
  double d2[4];
  for (int c = 0; c < 4; c++) d2[c] = (fx - a - (c & 1)) * (fx - a - (c & 1)) + (fy - b - (c >> 1)) * (fy - b - (c >> 1));
  for (int c = 1; c < 4; c++) /* nearest node first */
    for (int k = c; k > 0 && d2[order[k]] < d2[order[k - 1]]; k--) {
      int t = order[k];
      order[k] = order[k - 1];
      order[k - 1] = t;
    }
  for (int r = 0; r < 4; r++) {
    int c = order[r], ia = a + (c & 1), ib = b + (c >> 1);
    if (ia < 0 || ib < 0 || ia >= u->nx || ib >= u->ny) continue;
    const double *q = u->q + 3 * (ia + (size_t)u->nx * ib);
    if (isnan(q[0])) continue;
    double c3[3] = {u->lo[0] + ia * u->h, u->lo[1] + ib * u->h, u->z};
    double nv[3] = {c3[0] - q[0], c3[1] - q[1], c3[2] - q[2]}, dp[3] = {x - c3[0], y - c3[1], 0};
    double nn = nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2];
    double dn = nn > 1e-18 ? (dp[0] * nv[0] + dp[1] * nv[1]) / nn : 0, hk[3];
    for (int k = 0; k < 3; k++) hk[k] = q[k] + dp[k] - dn * nv[k];
    /* a hint within two grid cells of one already taken: the same patch */
    int same = 0;
    for (int k = 0; k < nh && !same; k++) {
      const double *o = hi + 3 * k;
      same = (o[0] - hk[0]) * (o[0] - hk[0]) + (o[1] - hk[1]) * (o[1] - hk[1]) + (o[2] - hk[2]) * (o[2] - hk[2]) <
             4 * u->h * u->h;
    }
    if (!same) memcpy(hi + 3 * nh++, hk, sizeof hk);
  }
  for (int k = nh; k < NH; k++) hi[3 * k] = hi[3 * k + 1] = hi[3 * k + 2] = NAN;
  return nh;
}

/* Per node of the stencil's model: the foot map's derivatives (dx, dy, dxx,
 * dyy, dxy, each 3), then T's (node_tslope). */
enum { NCO = 20 };

/* The thickness at the foot points of node (i, j)'s 3 x 3 stencil (the
 * distance part less the value, u->T), its derivatives dx, dy, dxx, dyy, dxy
 * in c (per node step); NaN when a node's value is only a bound (beyond the
 * band) or the stencil has nodes on both sides of H (a sheet's inside
 * thickness may differ). The value's slope is the distance's less
 * T's along the section: without T's, Newton steps on a graded sheet
 * converge only linearly (by the ratio of the slopes, 1-2 % a step). */
static void node_tslope(const near_ud *u, int i, int j, double c[5]) {
  double T[3][3];
  for (int k = 0; k < 5; k++) c[k] = NAN;
  if (!u->T) return;
  size_t n0 = (size_t)i + (size_t)u->nx * (size_t)j;
  for (int a = -1; a <= 1; a++)
    for (int b = -1; b <= 1; b++) {
      size_t n = n0 + a + (ptrdiff_t)u->nx * b;
      if (isnan(u->T[n]) || !(u->sd[n] * u->sd[n0] > 0)) return;
      T[a + 1][b + 1] = u->T[n];
    }
  double t0 = T[1][1];
  c[0] = 0.5 * (T[2][1] - T[0][1]);
  c[1] = 0.5 * (T[1][2] - T[1][0]);
  c[2] = T[2][1] - 2 * t0 + T[0][1];
  c[3] = T[1][2] - 2 * t0 + T[1][0];
  c[4] = 0.25 * (T[2][2] - T[2][0] - T[0][2] + T[0][0]);
}

/* The derivatives of node (i, j) into c (NCO); 0 when it has no model. */
static int node_model(const near_ud *u, int i, int j, double c[NCO]) {
  const double *q[3][3]; /* q[a + 1][b + 1]: node (i + a, j + b) */
  for (int a = -1; a <= 1; a++)
    for (int b = -1; b <= 1; b++) {
      q[a + 1][b + 1] = u->q + 3 * ((size_t)(i + a) + (size_t)u->nx * (size_t)(j + b));
      if (isnan(q[a + 1][b + 1][0])) return 0;
    }
  for (int k = 0; k < 3; k++) {
    double q0 = q[1][1][k], dx = 0.5 * (q[2][1][k] - q[0][1][k]), dy = 0.5 * (q[1][2][k] - q[1][0][k]);
    double dxx = q[2][1][k] - 2 * q0 + q[0][1][k], dyy = q[1][2][k] - 2 * q0 + q[1][0][k];
    double dxy = 0.25 * (q[2][2][k] - q[2][0][k] - q[0][2][k] + q[0][0][k]);
    if (!(fabs(dxx) < u->h && fabs(dyy) < u->h && fabs(dxy) < u->h)) return 0;
    c[k] = dx;
    c[3 + k] = dy;
    c[6 + k] = dxx;
    c[9 + k] = dyy;
    c[12 + k] = dxy;
  }
  node_tslope(u, i, j, c + 15);
  return 1;
}

/* Node (i, j)'s model made into the next slot of u->pm: its pix, 1 when
 * it has none (or no room could be had: the point is then solved from the
 * nodes' hints, as where there is no model). */
static unsigned model_add(const near_ud *u, int i, int j) {
  node_models *m = u->pm;
  if (m->n + 1 >= UINT_MAX - 2 || gr_grow(&m->c, &m->cap, NCO * (m->n + 1), sizeof *m->c)) return 1;
  if (!node_model(u, i, j, m->c + NCO * m->n)) return 1;
  return (unsigned)(2 + m->n++);
}

/* The closest point of (x, y) predicted from the nearest node's and its eight
 * neighbours' closest points: the foot map's second-order Taylor expansion
 * there, its derivatives by central differences (error of order h^3 times
 * the map's third derivative: tens of nanometres at h = 0.025 mm). NaN when a
 * node of the 3 x 3 stencil has none or when the stencil's closest points
 * jump (they lie on more than one patch of H). The stencil comes from
 * node_model, once per node (u->pix, u->pm); the sum is the same. ts: T's
 * slope along the section there (per mm; NaN when unknown). */
/* The stencil of the node nearest (x, y) (its index in *n, (x, y)'s offset
 * from it in node steps in st), or NULL when it has none (a node of its
 * 3 x 3 has no closest point, or they jump). */
static const double *node_stencil(const near_ud *u, double x, double y, size_t *n, double st[2]) {
  double fx = (x - u->lo[0]) * u->ih, fy = (y - u->lo[1]) * u->ih;
  /* the nearest node (i, j) must have all eight neighbours */
  if (!(fx >= 0.5 && fy >= 0.5 && fx < u->nx - 1.5 && fy < u->ny - 1.5)) return NULL;
  int i = (int)(fx + 0.5), j = (int)(fy + 0.5);
  st[0] = fx - i;
  st[1] = fy - j;
  *n = (size_t)i + (size_t)u->nx * (size_t)j;
  unsigned k = u->pix[*n];
  if (!k) k = u->pix[*n] = model_add(u, i, j);
  return k >= 2 ? u->pm->c + NCO * (size_t)(k - 2) : NULL;
}

static void node_predict(const near_ud *u, double x, double y, double pr[3], double ts[2]) {
  size_t n;
  double st[2];
  pr[0] = pr[1] = pr[2] = ts[0] = ts[1] = NAN;
  const double *c = node_stencil(u, x, y, &n, st);
  if (!c) return;
  double s = st[0], t = st[1];
  for (int k = 0; k < 3; k++) {
    double q0 = u->q[3 * n + k], dx = c[k], dy = c[3 + k], dxx = c[6 + k], dyy = c[9 + k], dxy = c[12 + k];
    pr[k] = q0 + s * dx + t * dy + 0.5 * s * s * dxx + s * t * dxy + 0.5 * t * t * dyy;
  }
  const double *T = c + 15;
  ts[0] = (T[0] + s * T[2] + t * T[4]) * u->ih;
  ts[1] = (T[1] + t * T[3] + s * T[4]) * u->ih;
}

/* Whether the section is smooth between its points a and b
 * (gr_slice_smooth_fn, given only where the thickness is): the stencils of the nodes
 * nearest a and b (3 x 3 nodes each, about a chord's length around it) have
 * closest points on one patch of H, so that no medial surface (where a thick
 * sheet's walls meet at a corner) passes between. */
static int near_smooth(void *ud, const double a[2], const double b[2]) {
  const near_ud *u = ud;
  size_t n;
  double st[2];
  return node_stencil(u, a[0], a[1], &n, st) && node_stencil(u, b[0], b[1], &n, st);
}

/* Value (and in-plane gradient when gx != NULL) at n points: from the
 * closest point predicted by the table's nodes, checked and polished on the
 * surface (gr_offset_eval_model); where that is not accepted, solved from
 * the hints of the four nodes around the point (gr_offset_eval_near). */
static int near_eval(void *ud_, size_t n, const double *x, const double *y, double *out,
                     double *gx, double *gy, gr_err *e) {
  const near_ud *u = ud_;
  enum { B = 256 };
  double hint[3 * NH * B], zb[B], g[3 * B], pr[3 * B], fx[B], fy[B], fo[B], fg[3 * B], ts[2 * B];
  size_t id[B];
  char hinted[B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B, k = 0;
    for (size_t i = 0; i < m; i++) {
      node_predict(u, x[s + i], y[s + i], pr + 3 * i, ts + 2 * i);
      zb[i] = u->z;
      /* no prediction: the four nodes' hints (kept in slot i for the exact
       * solve below), the nearest node's as the model's start */
      hinted[i] = isnan(pr[3 * i]);
      if (hinted[i] && node_hints(u, x[s + i], y[s + i], hint + 3 * NH * i) > 0)
        memcpy(pr + 3 * i, hint + 3 * NH * i, 3 * sizeof *pr);
    }
    int rc = gr_offset_eval_model(u->f, m, x + s, y + s, zb, pr, out + s, gx ? g : NULL, e);
    if (rc) return rc;
    for (size_t i = 0; i < m && gx; i++) /* the model's foot: on the stencil's patch, T's slope from it */
      if (!isnan(out[s + i]) && !isnan(ts[2 * i])) {
        g[3 * i] -= ts[2 * i];
        g[3 * i + 1] -= ts[2 * i + 1];
      }
    for (size_t i = 0; i < m; i++) /* not accepted: solved from the hints */
      if (isnan(out[s + i])) {
        fx[k] = x[s + i];
        fy[k] = y[s + i];
        double *hk = hint + 3 * NH * k;
        if (hinted[i]) {
          /* slot i to slot k <= i: later points' slots are above i, untouched */
          memmove(hk, hint + 3 * NH * i, 3 * NH * sizeof *hk);
        } else {
          /* a prediction: the stencil's closest points lie on one patch, and
           * it is a nearer start than any node's */
          memcpy(hk, pr + 3 * i, 3 * sizeof *hk);
          for (int r = 3; r < 3 * NH; r++) hk[r] = NAN;
        }
        id[k++] = i;
      }
    if (k && (rc = gr_offset_eval_near(u->f, k, fx, fy, zb, hint, NH, fo, gx ? fg : NULL, e))) return rc;
    for (size_t r = 0; r < k; r++) {
      out[s + id[r]] = fo[r];
      if (gx) memcpy(g + 3 * id[r], fg + 3 * r, 3 * sizeof *g);
    }
    if (gx)
      for (size_t i = 0; i < m; i++) {
        gx[s + i] = g[3 * i];
        gy[s + i] = g[3 * i + 1];
      }
  }
  return GR_OK;
}
static int near_fn(void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  return near_eval(ud, n, x, y, out, NULL, NULL, e);
}

/* A trimmed member (domain.h): the lattice part through the table, cut by
 * the domain d with its skin. No gradient: crossings and chords are
 * refined by bracketing, as they were when trimmed fields were sliced on
 * their own (with Newton steps the contours moved by up to 12 um where the
 * skin meets the lattice). */
typedef struct cut_ud {
  near_ud n;
  const gr_field *d;
  double skin, hy;
  const double *dv;        /* the domain at the grid nodes (gr_domain_grid) */
  const unsigned char *far; /* nodes farther than skin + 3h from its boundary */
  const double *sd;        /* the lattice's signed distance at the grid nodes (the table's) */
  double herr;             /* H's error bound: the table's distances are at most 2 herr too long */
} cut_ud;

/* A lower bound of the lattice value g at (x, y): the distance to the
 * surface is at least each of the four nodes' around it (the table's, less
 * 2 herr) less its distance from the point (1-Lipschitz), and g at least
 * that less the thickness's bound (gr_offset_value_floor). -INFINITY
 * outside the grid. */
static double lattice_floor(const cut_ud *u, double x, double y) {
  double fx = (x - u->n.lo[0]) / u->n.h, fy = (y - u->n.lo[1]) / u->hy, dlb = -INFINITY;
  if (!(fx >= 0 && fy >= 0 && fx < u->n.nx - 1 && fy < u->n.ny - 1)) return -INFINITY;
  int a = (int)fx, b = (int)fy;
  for (int c = 0; c < 4; c++) {
    int ia = a + (c & 1), ib = b + (c >> 1);
    double r = hypot(x - (u->n.lo[0] + ia * u->n.h), y - (u->n.lo[1] + ib * u->hy));
    dlb = fmax(dlb, fabs(u->sd[ia + (size_t)u->n.nx * ib]) - 2 * u->herr - r);
  }
  return gr_offset_value_floor(u->n.f, dlb);
}

/* Whether p lies in a grid cell with four far corners, wholly inside: d <=
 * -A there, A = skin + 1.5h (domain.h). */
static int far_inside(const cut_ud *u, double x, double y) {
  double fx = (x - u->n.lo[0]) / u->n.h, fy = (y - u->n.lo[1]) / u->hy;
  if (!(fx >= 0 && fy >= 0 && fx < u->n.nx - 1 && fy < u->n.ny - 1)) return 0;
  size_t k = (size_t)fx + (size_t)u->n.nx * (size_t)fy, nx = (size_t)u->n.nx;
  return u->far[k] && u->far[k + 1] && u->far[k + nx] && u->far[k + nx + 1] && u->dv[k] < 0;
}

/* The trimmed value at refined points, d evaluated only where it may
 * decide: with a skin, wherever d >= -skin/2 the value is d whatever the
 * lattice (min(g, -d - skin) <= d there), so g is not needed, nor where g is
 * certainly above -d - skin (lattice_floor, with CUT_ROOM to spare: the
 * value is then max(d, -d - skin), the same as from g itself); deep inside
 * (d <= -A) it is g wherever -A <= g <= A - skin, so d is not needed. */
#define CUT_ROOM 1e-4 /* mm: far above the closest points' tolerance */
static int cut_fn(void *ud_, size_t n, const double *x, const double *y, double *out, gr_err *e) {
  cut_ud *u = ud_;
  enum { B = 256 };
  double zb[B], dv[B], px[B], py[B], g[B], A = u->skin + 1.5 * fmax(u->n.h, u->hy);
  size_t id[B];
  unsigned char st[B]; /* 1: deep inside, 2: d known, 4: g known */
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B, k = 0;
    for (size_t i = 0; i < m; i++) zb[i] = u->n.z;
    for (size_t i = 0; i < m; i++) {
      st[i] = far_inside(u, x[s + i], y[s + i]) ? 1 : 2;
      if (st[i] == 2) id[k] = i, px[k] = x[s + i], py[k] = y[s + i], k++;
    }
    if (k && gr_field_eval(u->d, k, px, py, zb, g, e)) return e->code;
    for (size_t q = 0; q < k; q++) dv[id[q]] = g[q];
    /* the lattice where it may decide */
    k = 0;
    for (size_t i = 0; i < m; i++) {
      if (st[i] == 2 && u->skin > 0) {
        if (dv[i] >= -0.5 * u->skin) continue;
        if (lattice_floor(u, x[s + i], y[s + i]) > -dv[i] - u->skin + CUT_ROOM) {
          st[i] |= 4, out[s + i] = -dv[i] - u->skin; /* min(g, -d - skin) */
          continue;
        }
      }
      st[i] |= 4, id[k] = i, px[k] = x[s + i], py[k] = y[s + i], k++;
    }
    int rc = k ? near_eval(&u->n, k, px, py, g, NULL, NULL, e) : GR_OK;
    if (rc) return rc;
    for (size_t q = 0; q < k; q++) out[s + id[q]] = g[q];
    /* deep inside with g beyond [-A, A - skin]: d after all */
    k = 0;
    for (size_t i = 0; i < m; i++)
      if (st[i] == 5 && !(out[s + i] >= -A && out[s + i] <= A - u->skin))
        st[i] |= 2, id[k] = i, px[k] = x[s + i], py[k] = y[s + i], k++;
    if (k && gr_field_eval(u->d, k, px, py, zb, g, e)) return e->code;
    for (size_t q = 0; q < k; q++) dv[id[q]] = g[q];
    for (size_t i = 0; i < m; i++) {
      if (!(st[i] & 2)) continue; /* deep inside: the value is g */
      if (!(st[i] & 4)) out[s + i] = dv[i];
      gr_domain_trim_apply(1, out + s + i, dv + i, u->skin, NULL);
    }
  }
  return GR_OK;
}

/* The strict check of table node k of layer q (gr_offset_strict, in the
 * table's own frame, so that every member gets the same answer whichever
 * asks first): made once and kept; a member that finds it being made by
 * another thread makes it too, without keeping it. With `local` (a member
 * that uses H's local reach) the check may use it, and is kept apart. */
static int strict_node(const gr_cptab *t, int q, size_t k, int local, double qk[3], double *sdk, gr_err *e) {
  size_t np = (size_t)t->P[0] * t->P[1], i = np * q + k + (local ? np * t->nl : 0), j = np * q + k;
  if (__atomic_load_n(&t->st[i], __ATOMIC_ACQUIRE) == 2) {
    memcpy(qk, t->sq + 3 * i, 3 * sizeof *qk);
    *sdk = t->ssd[i];
    return GR_OK;
  }
  unsigned char zero = 0;
  int mine = __atomic_compare_exchange_n(&t->st[i], &zero, 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE);
  double p[3] = {t->lo[0] + (double)(k % t->P[0]) * t->h, t->lo[1] + (double)(k / t->P[0]) * t->h, t->z0 + q * t->t};
  memcpy(qk, t->q + 3 * j, 3 * sizeof *qk);
  *sdk = t->sd[j];
  int rc = gr_offset_strict(t->field, p, qk, sdk, local, e);
  if (rc || !mine) return rc;
  memcpy(t->sq + 3 * i, qk, 3 * sizeof *qk);
  t->ssd[i] = *sdk;
  __atomic_store_n(&t->st[i], 2, __ATOMIC_RELEASE);
  return GR_OK;
}

/* The field's values at the slice grid's nodes (nx a row; window node n is
 * table node k of node_shift, its closest point shifted by off there) from
 * the window's closest points Q and signed distances sd
 * (gr_offset_values_band: the far nodes need no copy of Q), nodes whose
 * value is within twice H's error bound of zero through the strict check
 * (strict_node). T is evaluated only at nodes within tmax + FAR_CELLS grid
 * cells + 2 herr of H (the table's sd may be up to 2 herr too long before the
 * strict check): beyond, |value| >= |sd| - tmax is more than FAR_CELLS cells,
 * and so is every node within two cells of it, farther from zero than
 * anything marching squares or the hidden-boundary search (which looks at
 * nodes within HID_GUARD cell diagonals of zero and their neighbours,
 * hidden.c) reads as more than a sign: those get the bound (the value with
 * T = tmax). Not for a trimmed field (the domain's cut takes the lattice
 * value's size). */
#define FAR_CELLS 6
/* Window node n's closest point shifted from the table's (node k of its
 * period): by sh plus the whole periods before it. */
static void node_shift(const gr_cptab *t, int nx, const double sh[3], size_t n, size_t *k, double off[3]) {
  int a = (int)(n % (size_t)nx), b = (int)(n / (size_t)nx);
  *k = a % t->P[0] + (size_t)t->P[0] * (b % t->P[1]);
  off[0] = sh[0] + (a / t->P[0]) * t->cell[0];
  off[1] = sh[1] + (b / t->P[1]) * t->cell[1];
  off[2] = sh[2];
}

/* How far from H (|sd|, mm) the nodes' values are exact (the band above;
 * everywhere for a trimmed field); grid spacing h. node_values takes it. */
static double band_for(double tmax, double herr, double h) { return tmax + FAR_CELLS * h + 2 * herr; }
static double value_band(const gr_field *f, int cut, double h) {
  double tmax = gr_offset_max_thickness(f);
  return !cut && tmax >= 0 ? band_for(tmax, gr_offset_herr(f), h) : INFINITY;
}

/* The chord search's farthest points from the section, grid cells (march.c:
 * the corner search, at most four cells). */
#define CHORD_CELLS 4

double gr_cptab_reach(const gr_field *f, double h) {
  const gr_field *g = f, *d = NULL;
  double skin = 0;
  int cut = gr_domain_trim_parts(f, &g, &d, &skin);
  return value_band(g, cut, h) + CHORD_CELLS * h;
}

double gr_cptab_reach_est(const gr_field *ref, double tmax, double h) {
  return band_for(tmax, gr_offset_herr(ref), h) + CHORD_CELLS * h;
}

static int node_values(const gr_cptab *t, int q, const gr_field *f, double band, int nx, size_t nn,
                       const double sh[3], double *Q, double *sd, double *v, gr_err *e) {
  double herr = gr_offset_herr(f);
  int local = gr_offset_uses_local_reach(f);
  int rc = gr_offset_values_band(f, nn, Q, sd, band, v, e);
  /* the table's closest points may be up to 2 herr too far (its tolerance,
   * H's error): where that could decide the sign, the strict check. (A
   * graded T can differ between the two patches and flip the sign of larger
   * |g| too; checking |g| < 2 herr + the spread of T as well cost 40 % more
   * template time on eq. (8) sheets and changed no layer of the iwp sheet's
   * measurement, doc/quality.md: not done.) */
  double lim = 2 * herr;
  /* a node nearer to H than its reach keeps its closest point under the
   * check (gr_offset_strict returns at once): not looked up (the checks'
   * cache is shared by the group and large: its reads missed the cache) */
  double reach = gr_offset_reach(t->field);
  /* the nodes to check marked for all at once (a loop without branches: on
   * a thin sheet none is, every node near zero lies within the reach), then
   * checked in order, eight unmarked ones skipped at a time */
  unsigned char *need = rc ? NULL : malloc(nn + 8);
  if (!rc && !need) rc = gr_fail(e, GR_EMEM, "out of memory");
  for (size_t n = 0; n < nn && !rc; n++) {
    double a = fabs(sd[n]);
    need[n] = (unsigned char)((fabs(v[n]) < lim) & !(a > band) & !(a < reach));
  }
  if (need) memset(need + nn, 0, 8);
  for (size_t n = 0; n < nn && !rc; n++) {
    if (!gr_ms_word(need + n)) {
      n += 7;
      continue;
    }
    if (!need[n] || isnan(Q[3 * n])) continue;
    double qk[3], sdk, off[3];
    size_t k;
    node_shift(t, nx, sh, n, &k, off);
    if ((rc = strict_node(t, q, k, local, qk, &sdk, e))) break;
    if (sdk == sd[n]) continue;
    for (int a = 0; a < 3; a++) Q[3 * n + a] = qk[a] + off[a];
    sd[n] = sdk;
    rc = gr_offset_values(f, 1, Q + 3 * n, sd + n, v + n, e);
  }
  free(need);
  return rc;
}

/* The table's closest points and signed distances of the window's nodes
 * (nx a row; sh: the member's voxel corner less the reference's), shifted by
 * whole periods (node_shift, without its divisions). */
static void window_nodes(const gr_cptab *t, int q, int nx, int ny, const double sh[3], double *Q, double *sd) {
  size_t np = (size_t)t->P[0] * t->P[1];
  const double *tq = t->q + 3 * np * q, *tsd = t->sd + np * q;
  for (int b = 0; b < ny; b++) {
    size_t kb = (size_t)t->P[0] * (b % t->P[1]);
    double oy = sh[1] + (b / t->P[1]) * t->cell[1];
    for (int a = 0, ka = 0, ia = 0; a < nx; a++) {
      size_t n = a + (size_t)nx * b, k = ka + kb;
      double ox = sh[0] + ia * t->cell[0];
      Q[3 * n] = tq[3 * k] + ox;
      Q[3 * n + 1] = tq[3 * k + 1] + oy;
      Q[3 * n + 2] = tq[3 * k + 2] + sh[2];
      sd[n] = tsd[k];
      if (++ka == t->P[0]) ka = 0, ia++;
    }
  }
}

/* Section of class c's layer at z (template layer q) through the table; a
 * trimmed field's lattice part through the table, then cut by its domain,
 * evaluated near the domain's boundary only (gr_domain_grid). */
int gr_cptab_slice(const gr_cptab *t, const gr_field *f, const double o[3], int q,
                   double z, const gr_slice_opts *so, gr_rings *out, gr_err *e) {
  int nx, ny;
  double hx, hy, skin = 0;
  const gr_field *d = NULL;
  int cut = gr_domain_trim_parts(f, &f, &d, &skin);
  gr_slice_grid_size(so, &nx, &ny, &hx, &hy);
  size_t nn = (size_t)nx * ny;
  double *Q = malloc((6 + (cut ? 1 : 0)) * nn * sizeof *Q);
  unsigned *pix = calloc(nn, sizeof *pix);
  node_models pm = {NULL, 0, 0};
  if (!Q || !pix) {
    free(Q);
    free(pix);
    return gr_fail(e, GR_EMEM, "out of memory");
  }
  double *sd = Q + 3 * nn, *v = Q + 4 * nn;
  double sh[3] = {o[0] - t->oref[0], o[1] - t->oref[1], o[2] - t->oref[2]};
  window_nodes(t, q, nx, ny, sh, Q, sd);
  double band = value_band(f, cut, fmax(hx, hy));
  int rc = node_values(t, q, f, band, nx, nn, sh, Q, sd, v, e);
  double *dv = Q + 6 * nn, *T = Q + 5 * nn;
  if (!rc && !cut) gr_offset_implied_thickness(f, nn, sd, v, band, T);
  unsigned char *far = cut ? malloc(nn) : NULL;
  if (!rc && cut && !far) rc = gr_fail(e, GR_EMEM, "out of memory");
  if (!rc && cut) {
    rc = gr_domain_grid(d, skin, z, so->lo[0], so->lo[1], hx, hy, nx, ny, dv, far, e);
    if (!rc) gr_domain_trim_apply(nn, v, dv, skin, NULL);
  }
  cut_ud u = {{f, z, {so->lo[0], so->lo[1]}, hx, nx, ny, Q, pix, &pm, cut ? NULL : sd, cut ? NULL : T, 1 / hx},
              d, skin, hy, dv, far, sd, gr_offset_herr(f)};
  gr_slice_opts sm = *so; /* chords judged by their neighbours where the section is smooth */
  sm.smooth = !cut && gr_offset_smooth_thickness(f) ? near_smooth : NULL;
  /* where the section is smooth, crossings from the nodes' cubic
   * (gr_ms_grid.exact): a node's value below FAR_CELLS - 1 cells is its own,
   * not the bound beyond the band (value_band) */
  sm.exact = sm.smooth ? (FAR_CELLS - 1) * fmax(hx, hy) : 0;
  if (!rc)
    rc = cut ? gr_slice_grid(v, so, cut_fn, NULL, &u, out, e) : gr_slice_grid(v, &sm, near_fn, near_eval, &u.n, out, e);
  free(far);
  free(pix);
  free(pm.c);
  free(Q);
  return rc;
}
