/* distance.c: BVH closest points and graded offset fields, see distance.h. */
#include "distance.h"
#include <pthread.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include "expr.h"
#include "grid.h"
#include "mc.h"
#include "reach.h"

/* ---- offset field ---- */
gr_offset_opts gr_offset_defaults(void) {
  gr_offset_opts o;
  memset(&o, 0, sizeof o);
  o.cell[0] = o.cell[1] = o.cell[2] = 2;
  o.res = 40;
  o.thickness = 0.1;
  o.kind = GR_OFFSET_SHEET;
  o.side = -1;
  o.mode = GR_DIST_EXACT;
  return o;
}

typedef struct lreach_slot lreach_slot;

typedef struct offset {
  gr_field *phi;
  gr_mesh *own;       /* H when meshed here */
  const gr_mesh *h;
  gr_bvh *bvh;
  gr_expr *t, *tin;
  gr_field *tfield;   /* T as a field of q, when given so */
  double tconst;
  double L, o[3];     /* L: the smallest cell length (tolerances' scale) */
  double Lv[3];       /* Lx, Ly, Lz */
  int vfix;           /* u, v, w relative to the own voxel (centre vc) */
  double vc[3];
  double maxt;        /* max T over H's vertices (with a 20 % reserve) */
  double tmax;        /* max T over H's vertices */
  double herr;        /* bound on the distance between H's mesh and phi = 0 */
  double reach;       /* below this distance a local closest point is the closest (mm) */
  lreach_slot *lrs;   /* H's local reach, made when first needed (periodic H), or NULL;
                         owned unless `like` */
  int lreach_on;      /* whether this field uses lrs (lreach_wanted) */
  double mdev;        /* measured: how far H's mesh lies off phi = 0 (mm, exact mode) */
  gr_field *like;     /* the offset field whose H and BVH are shared, or NULL */
  gr_dtable *dens;    /* density -> T table, or NULL */
  double shift[3];    /* H = the shared mesh translated by this, mm */
  double lip;         /* Lipschitz bound of phi */
  gr_field_step hstep; /* exact_newton's Hessian step (1e-6 L), its phases made once */
  int kind, side, mode;
  double tnear;       /* typical T, centre of the refinement band */
  double refine_band; /* refine q where | d - tnear | < this */
  long npts, nquery, nrefine, ncalls; /* statistics (GRADUS_DEBUG) */
  char warning[256];  /* offsets of neighbouring sheet parts touch (where), or "" */
} offset;

/* H's local reach (reach.h), made when first needed: by the first point
 * beyond the global reach that a field sharing H and using the table
 * (lreach_wanted: thin sheets do not) evaluates. Made once, under the
 * mutex, always from the same H and options: the same table whichever
 * thread or voxel asks first. */
struct lreach_slot {
  pthread_mutex_t mu;
  int state;           /* 0: not made; 1: made (r NULL when that failed: the reach serves) */
  gr_reach *r;
  const struct offset *owner; /* the field whose H it is (shift 0) */
  double lo[3], period[3];    /* one period of H */
  int threads;
  /* the group's members check their thickness on H's vertices near their
   * box (offset_vertices): every member's box lies on the same part of H
   * (their shifts are whole periods), so the first member keeps the
   * vertices of that part, in H's frame, grown by VNEAR_PAD (vmade 1;
   * -1: no room), and the others test those only */
  int vmade;
  size_t *vid, nvid;
  double vlo[3], vhi[3];
};

static void lreach_free(lreach_slot *s) {
  if (!s) return;
  pthread_mutex_destroy(&s->mu);
  gr_reach_free(s->r);
  free(s->vid);
  free(s);
}

static void offset_free(void *ud) {
  offset *f = ud;
  if (!f) return;
  if (getenv("GRADUS_DEBUG"))
    fprintf(stderr, "offset field: %ld calls, %ld points, %ld BVH queries, %ld refinements, reach %.4g mm\n", f->ncalls, f->npts, f->nquery, f->nrefine, f->reach);
  gr_field_free(f->phi);
  gr_mesh_free(f->own);
  if (!f->like) gr_bvh_free(f->bvh);
  if (!f->like) lreach_free(f->lrs);
  gr_field_free(f->like);
  gr_expr_free(f->t);
  gr_expr_free(f->tin);
  gr_field_free(f->tfield);
  gr_dtable_free(f->dens);
  free(f);
}

/* The centre of the voxel that owns point p (voxel-owned grading): the
 * field's own voxel when it has one, else the voxel of the cell grid that
 * holds p (a point on a face belongs to the voxel above it). */
static void owner_centre(const offset *f, const double p[3], double c[3]) {
  for (int a = 0; a < 3; a++)
    c[a] = f->vfix ? f->vc[a] : f->o[a] + (floor((p[a] - f->o[a]) / f->Lv[a]) + 0.5) * f->Lv[a];
}

/* q's coordinates relative to the voxel with centre c, normalised so that the
 * voxel spans [-1, 1] and clamped to it (voxel-owned grading). */
void gr_offset_uvw(const double q[3], const double c[3], const double L[3], double uvw[3]) {
  for (int a = 0; a < 3; a++) {
    double t = 2 * (q[a] - c[a]) / L[a];
    uvw[a] = t < -1 ? -1 : t > 1 ? 1 : t;
  }
}

/* T at n foot points q (global, mm) of the points p (NULL: q itself locates
 * the owning voxel when the field has none of its own), before any density
 * table. */
/* u, v, w of the feet q (points s .. s + m - 1) relative to the voxels that
 * own the points p (NULL: q). */
static void feet_uvw(const offset *f, const double *const p[3], const double *qx, const double *qy, const double *qz,
                     size_t s, size_t m, double *u, double *v, double *w) {
  for (size_t i = 0; i < m; i++) {
    double q[3] = {qx[s + i], qy[s + i], qz[s + i]}, c[3], r[3];
    double pp[3] = {p ? p[0][s + i] : q[0], p ? p[1][s + i] : q[1], p ? p[2][s + i] : q[2]};
    owner_centre(f, pp, c);
    gr_offset_uvw(q, c, f->Lv, r);
    u[i] = r[0];
    v[i] = r[1];
    w[i] = r[2];
  }
}

static int thick_value(const offset *f, const gr_expr *x, size_t n, const double *const p[3], const double *qx,
                 const double *qy, const double *qz, double *out, gr_err *e) {
  if (!x && f->tfield) return gr_field_eval(f->tfield, n, qx, qy, qz, out, e);
  if (!x) {
    for (size_t i = 0; i < n; i++) out[i] = f->tconst;
    return GR_OK;
  }
  double u[256], v[256], w[256];
  /* u, v, w only when T reads them (or for an error message, which names all six) */
  int uvw = gr_expr_uses(x, 3) || gr_expr_uses(x, 4) || gr_expr_uses(x, 5);
  for (size_t s = 0; s < n; s += 256) {
    size_t m = n - s < 256 ? n - s : 256;
    if (uvw) feet_uvw(f, p, qx, qy, qz, s, m, u, v, w);
    const double *vars[6] = {qx + s, qy + s, qz + s, u, v, w};
    int rc = gr_expr_eval(x, m, vars, out + s, e);
    if (rc && !uvw) {
      feet_uvw(f, p, qx, qy, qz, s, m, u, v, w);
      rc = gr_expr_eval(x, m, vars, out + s, e);
    }
    if (rc) return rc;
  }
  return GR_OK;
}

/* T at n points q: thick_value, then the density table when there is one. */
static int thick(const offset *f, const gr_expr *x, size_t n, const double *const p[3], const double *qx,
                 const double *qy, const double *qz, double *out, gr_err *e) {
  int rc = thick_value(f, x, n, p, qx, qy, qz, out, e);
  if (rc || !f->dens) return rc;
  gr_dtable_apply(f->dens, n, out);
  if (x && x == f->tin) for (size_t i = 0; i < n; i++) out[i] *= gr_dtable_ratio(f->dens);
  return GR_OK;
}

static int exact_newton(const offset *f, const double p[3], double q[3]);

/* Newton projection of x onto phi = 0 (a few steps); 0 if it fails. */
static int project(const offset *f, double x[3]) {
  gr_err e;
  for (int k = 0; k < 8; k++) {
    double v, gx, gy, gz;
    if (gr_field_eval_grad(f->phi, 1, &x[0], &x[1], &x[2], &v, &gx, &gy, &gz, &e)) return 0;
    double g2 = gx * gx + gy * gy + gz * gz;
    if (!(g2 > 1e-300)) return 0;
    if (fabs(v) < 1e-14) return 1;
    x[0] -= v * gx / g2;
    x[1] -= v * gy / g2;
    x[2] -= v * gz / g2;
  }
  return 1;
}

/* The alternation below did not settle (p near a centre of curvature, or
 * on a mirror plane between two feet: it can stop off the surface, which
 * made d too short by micrometres on thick iwp sheets). End on the surface,
 * and take the constrained Newton answer from the mesh point q0 instead when
 * it is nearer. */
static int settle(const offset *f, const double p[3], const double q0[3], double x[3]) {
  if (!project(f, x)) return 0;
  double y[3] = {q0[0], q0[1], q0[2]};
  if (exact_newton(f, p, y) && project(f, y)) {
    double dx = (p[0] - x[0]) * (p[0] - x[0]) + (p[1] - x[1]) * (p[1] - x[1]) + (p[2] - x[2]) * (p[2] - x[2]);
    double dy = (p[0] - y[0]) * (p[0] - y[0]) + (p[1] - y[1]) * (p[1] - y[1]) + (p[2] - y[2]) * (p[2] - y[2]);
    if (dy < dx) memcpy(x, y, 3 * sizeof *x);
  }
  return 1;
}

/* Refine q onto phi = 0 as the closest point to p: alternate a Newton
 * projection onto the surface with a move to the foot of p on the tangent
 * plane. Keeps the mesh point when it does not converge. The alternation
 * converges linearly, slowly where d times the curvature nears 1 (P
 * necks): 12 rounds left 1e-5 mm there, 40 reach 1e-9 mm (most points stop
 * after a few rounds). Where the surface curves away from p more sharply
 * than 1/d a full move overshoots (each round's error grows by d kappa:
 * thick iwp sheets, p near the mirror planes), so a move that leaves the
 * projected point farther from p than the last one is taken back and
 * halved: every round then brings the point nearer, towards a local
 * minimum of the distance (without it, a point 3 um too far ended the
 * search there). */
static int exact_refine(const offset *f, const double p[3], double q[3]) {
  double x[3] = {q[0], q[1], q[2]}, xb[3] = {q[0], q[1], q[2]}, tb[3] = {0, 0, 0}, db = INFINITY, alpha = 1;
  int conv = 0;
  for (int it = 0; it < 60; it++) {
    double v, gx, gy, gz;
    gr_err e;
    for (int k = 0; k < 3; k++) {
      if (gr_field_eval_grad(f->phi, 1, &x[0], &x[1], &x[2], &v, &gx, &gy, &gz, &e)) return 0;
      double g2 = gx * gx + gy * gy + gz * gz;
      if (!(g2 > 1e-300)) return 0;
      x[0] -= v * gx / g2;
      x[1] -= v * gy / g2;
      x[2] -= v * gz / g2;
      if (fabs(v) < 1e-14) break;
    }
    double d = gr_dist3(p, x);
    if (d > db) { /* overshot: back to the best point, half the move */
      if (alpha < 1e-3) break;
      alpha *= 0.5;
      for (int a = 0; a < 3; a++) x[a] = xb[a] + alpha * tb[a];
      continue;
    }
    if (gr_field_grad(f->phi, 1, &x[0], &x[1], &x[2], &gx, &gy, &gz, &e)) return 0;
    double gn = sqrt(gx * gx + gy * gy + gz * gz);
    if (!(gn > 0)) return 0;
    double n[3] = {gx / gn, gy / gn, gz / gn};
    double r[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
    double rn = gr_dot3(r, n);
    double t[3] = {r[0] - rn * n[0], r[1] - rn * n[1], r[2] - rn * n[2]};
    double tl = sqrt(gr_dot3(t, t));
    if (tl < 1e-12) { conv = 1; break; }
    memcpy(xb, x, sizeof x);
    memcpy(tb, t, sizeof t);
    db = d;
    alpha = fmin(1, 2 * alpha);
    for (int a = 0; a < 3; a++) x[a] += alpha * t[a];
  }
  if (!conv) memcpy(x, xb, sizeof x);
  if (!conv && !settle(f, p, q, x)) return 0;
  double dq = gr_dist3(x, q);
  if (!(isfinite(dq) && dq < 0.25 * f->L)) return 0;
  memcpy(q, x, sizeof x);
  return 1;
}

/* Solve the 4x4 system A x = b in place (partial pivoting); 0 if singular. */
static int solve4(double A[4][4], double b[4]) {
  for (int c = 0; c < 4; c++) {
    int piv = c;
    for (int r = c + 1; r < 4; r++)
      if (fabs(A[r][c]) > fabs(A[piv][c])) piv = r;
    if (!(fabs(A[piv][c]) > 1e-300)) return 0;
    if (piv != c) {
      for (int k = 0; k < 4; k++) { double t = A[c][k]; A[c][k] = A[piv][k]; A[piv][k] = t; }
      double t = b[c]; b[c] = b[piv]; b[piv] = t;
    }
    for (int r = c + 1; r < 4; r++) {
      double m = A[r][c] / A[c][c];
      for (int k = c; k < 4; k++) A[r][k] -= m * A[c][k];
      b[r] -= m * b[c];
    }
  }
  for (int c = 3; c >= 0; c--) {
    for (int k = c + 1; k < 4; k++) b[c] -= A[c][k] * b[k];
    b[c] /= A[c][c];
  }
  return 1;
}

/* The bordered system [M g; g^T 0] [x; l] = b (M symmetric 3 x 3, b four
 * long, solved in place) through M's adjugate A: l = (g.Ab - b3 det) / g.Ag,
 * x = A (b - g l) / det. Two divisions instead of solve4's elimination; 0
 * (b untouched) when M or the system is near singular (solve_lagrange then
 * takes solve4). */
static int solve_bordered(const double M[3][3], const double g[3], double b[4]) {
  double A[3][3];
  A[0][0] = M[1][1] * M[2][2] - M[1][2] * M[1][2];
  A[0][1] = A[1][0] = M[0][2] * M[1][2] - M[0][1] * M[2][2];
  A[0][2] = A[2][0] = M[0][1] * M[1][2] - M[0][2] * M[1][1];
  A[1][1] = M[0][0] * M[2][2] - M[0][2] * M[0][2];
  A[1][2] = A[2][1] = M[0][1] * M[0][2] - M[0][0] * M[1][2];
  A[2][2] = M[0][0] * M[1][1] - M[0][1] * M[0][1];
  double det = M[0][0] * A[0][0] + M[0][1] * A[0][1] + M[0][2] * A[0][2], u[3], w[3];
  for (int r = 0; r < 3; r++) {
    u[r] = A[r][0] * b[0] + A[r][1] * b[1] + A[r][2] * b[2];
    w[r] = A[r][0] * g[0] + A[r][1] * g[1] + A[r][2] * g[2];
  }
  double gw = gr_dot3(g, w);
  /* M's eigenvalues are 1 - d kappa along the surface: det below 1e-3
   * only near a centre of curvature, where elimination is the safer way */
  if (!(fabs(det) > 1e-3) || !(fabs(gw) > 1e-9 * gr_dot3(g, g) * fabs(det))) return 0;
  double l = (gr_dot3(g, u) - b[3] * det) / gw;
  for (int r = 0; r < 3; r++) b[r] = (u[r] - w[r] * l) / det;
  b[3] = l;
  return 1;
}

/* The bordered system by solve_bordered, or where that declines by solve4
 * (its 4 x 4 matrix made only then; b is left as it was on a decline). */
static int solve_lagrange(const double M[3][3], const double g[3], double b[4]) {
  if (solve_bordered(M, g, b)) return 1;
  double A[4][4];
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) A[r][c] = M[r][c];
    A[r][3] = A[3][r] = g[r];
  }
  A[3][3] = 0;
  return solve4(A, b);
}

/* Closest point of phi = 0 to p from a nearby start, the point *at (its
 * value v and gradient g0 there, made by gr_field_grad_at or followed by
 * gr_field_move_grad): Newton on the Lagrange conditions
 * x - p + lambda grad phi(x) = 0, phi(x) = 0 (Hessian of phi by differences
 * of gradients, from at's sines and cosines). Converges quadratically from a
 * start near the answer (a neighbour's closest point); done when the foot
 * is within tol L; the answer into q (1), or 0 (q unchanged) when it does
 * not converge, so the caller can fall back. */
static int newton_from(const offset *f, const double p[3], gr_field_at *at, double v, const double g0[3], double tol,
                       double q[3]) {
  double x[3] = {at->p[0], at->p[1], at->p[2]}, x0[3] = {at->p[0], at->p[1], at->p[2]}, lam = 0, prev = INFINITY;
  double gs[3][3], dp[3] = {0, 0, 0}, g[3] = {g0[0], g0[1], g0[2]};
  gr_err e;
  /* the Hessian once: the start is near, so it barely changes; the steps
   * after it move the start's sines and cosines */
  if (gr_field_hess_fd_moved(f->phi, at, &f->hstep, g, gs, &e)) return 0;
  for (int it = 0; it < 20; it++) {
    if (it > 0 && gr_field_move_grad(f->phi, at, dp, &v, g, &e)) return 0;
    double g2 = gr_dot3(g, g);
    if (!(g2 > 1e-300)) return 0;
    if (it == 0) lam = ((p[0] - x[0]) * g[0] + (p[1] - x[1]) * g[1] + (p[2] - x[2]) * g[2]) / g2;
    double b[4], M[3][3];
    for (int r = 0; r < 3; r++) {
      for (int c = 0; c < 3; c++) M[r][c] = (r == c) + lam * 0.5 * (gs[c][r] + gs[r][c]);
      b[r] = -(x[r] - p[r] + lam * g[r]);
    }
    b[3] = -v;
    if (!solve_lagrange(M, g, b)) return 0;
    for (int a = 0; a < 3; a++) x[a] += dp[a] = b[a];
    lam += b[3];
    double dx = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    if (!isfinite(dx)) return 0;
    /* the Hessian is frozen at the start, so convergence is linear with a
     * tiny rate rho (the start is within a grid cell): the error left after
     * a step dx is about rho dx, rho measured as the ratio of the last two
     * steps. Done when that is below tol L (or the step itself below
     * 10 tol L: then the error left is below tol L / 100) */
    /* (rho < 0.1 and rho dx < tol L (1 - rho), times prev: no division) */
    int settled = dx < 10 * tol * f->L || (it > 0 && dx < 0.1 * prev && dx * dx < tol * f->L * (prev - dx));
    prev = dx;
    if (settled) {
      if (!(gr_dist3(x, x0) < 0.25 * f->L)) return 0;
      memcpy(q, x, sizeof x);
      return 1;
    }
  }
  return 0;
}

/* newton_from the point q. */
static int exact_newton_tol(const offset *f, const double p[3], double q[3], double tol) {
  gr_field_at at;
  double v, g[3];
  gr_err e;
  if (gr_field_grad_at(f->phi, q, &v, g, &at, &e)) return 0;
  return newton_from(f, p, &at, v, g, tol, q);
}

/* exact_newton_tol to 1e-7 L. */
static int exact_newton(const offset *f, const double p[3], double q[3]) { return exact_newton_tol(f, p, q, 1e-7); }

/* q (a point of H's mesh, or near H) polished into p's closest point on
 * phi = 0: Newton's method (quadratic, a few steps), the alternating
 * refinement where that does not settle (it moves only towards a local
 * minimum of the distance, slowly where d kappa nears 1). */
static int exact_polish(const offset *f, const double p[3], double q[3]) {
  return exact_newton(f, p, q) || exact_refine(f, p, q);
}

static double reach_for(const offset *f, const double q[3], double d);
static double reach_local(const offset *f, const double q[3]);

/* Closest point of H to p within maxd, H being the (shared) mesh translated by f->shift. */
static void closest_h(const offset *f, const double p[3], double maxd, gr_hit *h) {
  double pp[3] = {p[0] - f->shift[0], p[1] - f->shift[1], p[2] - f->shift[2]};
  gr_bvh_closest(f->bvh, pp, maxd, h);
  for (int a = 0; a < 3; a++) h->q[a] += f->shift[a];
}

/* A local search for the closest point (Newton from a neighbour's or a
 * node's closest point) stays on its patch of the surface even where another
 * patch has come nearer: across the medial surface, which thick sheets and
 * networks reach (iwp, neovius). Accepting it while no part of H is nearer
 * by more than H's error bound herr left the distance up to herr (25 um at
 * res 40) too long there, enough to move the sharp tips of the pores
 * between thick walls by tens of micrometres. PATCH_TOL (mm) is the strict
 * tolerance: H nearer than the local answer by more than this is refined
 * and taken when it is nearer. */
#define PATCH_TOL 1e-4

/* The nearer of q and c's candidate (a point of H's mesh, refined onto
 * phi = 0); returns |p - q|. */
static double take_nearer(const offset *f, const double p[3], double q[3], gr_hit *c) {
  double d = gr_dist3(p, q);
  if (c->tri < 0 || !exact_polish(f, p, c->q)) return d;
  double d2 = gr_dist3(p, c->q);
  if (d2 < d) {
    memcpy(q, c->q, sizeof c->q);
    return d2;
  }
  return d;
}

/* q: a local closest point of p on phi = 0. Searches H for anything nearer
 * than q by more than tol; the nearest part found, refined onto phi = 0,
 * replaces q when it is nearer. With `away` (the strict check) another
 * patch is also looked for where its mesh is up to twice
 * the mesh's measured deviation (mdev) farther than q: the nearest point of
 * the mesh away from q's own patch (which lies within sqrt((d + m)^2 - d^2)
 * of q there), refined and taken when nearer. Near the medial surface two
 * patches are within the mesh's error of each other, and the mesh alone
 * would pick either. With `local`, the local reach at q may serve instead
 * of H's reach (it is made when first needed). Returns the distance |p - q|. */
static double nearest_patch(const offset *f, const double p[3], double q[3], double tol, int away, int local) {
  double d = gr_dist3(p, q);
  /* within the reach: no other patch can be nearer */
  if (d < f->reach || (local && f->lrs && d < reach_local(f, q))) return d;
  gr_hit c;
  closest_h(f, p, d - tol, &c);
  d = take_nearer(f, p, q, &c);
  if (!away) return d;
  double R = d + 2 * f->mdev, sp[3] = {p[0] - f->shift[0], p[1] - f->shift[1], p[2] - f->shift[2]};
  double sq[3] = {q[0] - f->shift[0], q[1] - f->shift[1], q[2] - f->shift[2]};
  gr_bvh_closest_away(f->bvh, sp, R, sq, sqrt(R * R - d * d) + 2 * f->mdev, &c);
  for (int a = 0; a < 3 && c.tri >= 0; a++) c.q[a] += f->shift[a];
  return take_nearer(f, p, q, &c);
}

/* The gradient g of the distance part of the value at p, from its closest
 * point q and signed distance sd (T's own slope along H neglected; NaN on
 * H). */
static void dist_grad(const offset *f, const double p[3], const double q[3], double sd, double g[3]) {
  double d = fabs(sd), sg = f->kind == GR_OFFSET_SHEET ? 1 : (f->side > 0 ? -1 : 1) * (sd < 0 ? -1 : 1);
  for (int a = 0; a < 3; a++) g[a] = d > 1e-9 ? sg * (p[a] - q[a]) / d : NAN;
}

/* The field's value from a closest point's signed distance sd (+ where
 * phi > 0) and the thickness T there (Tin: inside thickness, for sd < 0). */
static double offset_value(const offset *f, double sd, double T, double Tin) {
  if (f->kind == GR_OFFSET_SHEET) return fabs(sd) - (f->tin && sd < 0 ? Tin : T);
  return (f->side > 0 ? -sd : sd) - T;
}

static int offset_eval(void *ud, size_t n, const double *x, const double *y, const double *z,
                       double *out, gr_err *e) {
  offset *f = ud;
  __atomic_fetch_add(&f->ncalls, 1, __ATOMIC_RELAXED);
  __atomic_fetch_add(&f->npts, (long)n, __ATOMIC_RELAXED);
  enum { B = 256 };
  double ph[B], qx[B], qy[B], qz[B], dd[B], tt[B], ti[B], px[B], py[B], pz[B];
  const double *pk[3] = {px, py, pz};
  size_t idx[B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B;
    int rc = gr_field_eval(f->phi, m, x + s, y + s, z + s, ph, e);
    if (rc) return rc;
    double band = f->maxt + f->refine_band;
    size_t k = 0;
    for (size_t i = 0; i < m; i++) {
      double lb = isfinite(f->lip) ? fabs(ph[i]) / f->lip : 0;
      if (lb > band) {
        /* certainly far from H: only the sign matters, keep a lower bound */
        int in = f->side > 0 ? ph[i] > 0 : ph[i] < 0; /* inside the grown network */
        out[s + i] = (f->kind == GR_OFFSET_NETWORK && in) ? -lb : lb - f->maxt;
        continue;
      }
      double p[3] = {x[s + i], y[s + i], z[s + i]};
      gr_hit h;
      __atomic_fetch_add(&f->nquery, 1, __ATOMIC_RELAXED);
      closest_h(f, p, band, &h);
      if (h.tri < 0) { /* nothing within the band: only the sign matters */
        int in = f->side > 0 ? ph[i] > 0 : ph[i] < 0;
        out[s + i] = (f->kind == GR_OFFSET_NETWORK && in) ? -band : band - f->maxt;
        continue;
      }
      qx[k] = h.q[0];
      qy[k] = h.q[1];
      qz[k] = h.q[2];
      px[k] = p[0];
      py[k] = p[1];
      pz[k] = p[2];
      dd[k] = sqrt((p[0] - h.q[0]) * (p[0] - h.q[0]) + (p[1] - h.q[1]) * (p[1] - h.q[1]) + (p[2] - h.q[2]) * (p[2] - h.q[2]));
      idx[k++] = i;
    }
    if (k == 0) continue;
    if ((rc = thick(f, f->t, k, pk, qx, qy, qz, tt, e))) return rc;
    if (f->tin && (rc = thick(f, f->tin, k, pk, qx, qy, qz, ti, e))) return rc;
    if (f->mode == GR_DIST_EXACT) {
      /* refine q onto the analytic surface where g is small: there the
       * value matters; elsewhere the mesh value has the right sign */
      size_t nr = 0;
      double rx[B], ry[B], rz[B], rt[B], rti[B], rpx[B], rpy[B], rpz[B];
      const double *rp[3] = {rpx, rpy, rpz};
      size_t ri[B];
      for (size_t q = 0; q < k; q++) {
        size_t i = idx[q];
        double T = (f->tin && ph[i] < 0) ? ti[q] : tt[q];
        double g = (f->kind == GR_OFFSET_SHEET) ? dd[q] - T : fabs(dd[q] - T);
        if (g > f->refine_band && (f->kind == GR_OFFSET_SHEET || dd[q] + T > f->refine_band)) continue;
        double p[3] = {x[s + i], y[s + i], z[s + i]}, qq[3] = {qx[q], qy[q], qz[q]};
        __atomic_fetch_add(&f->nrefine, 1, __ATOMIC_RELAXED);
        exact_polish(f, p, qq);
        dd[q] = nearest_patch(f, p, qq, PATCH_TOL, 1, f->lreach_on); /* the mesh may pick the farther of two patches */
        qx[q] = qq[0]; qy[q] = qq[1]; qz[q] = qq[2];
        rx[nr] = qq[0]; ry[nr] = qq[1]; rz[nr] = qq[2];
        rpx[nr] = p[0]; rpy[nr] = p[1]; rpz[nr] = p[2];
        ri[nr++] = q;
      }
      if (nr) {
        if ((rc = thick(f, f->t, nr, rp, rx, ry, rz, rt, e))) return rc;
        if (f->tin && (rc = thick(f, f->tin, nr, rp, rx, ry, rz, rti, e))) return rc;
        for (size_t r = 0; r < nr; r++) {
          tt[ri[r]] = rt[r];
          if (f->tin) ti[ri[r]] = rti[r];
        }
      }
    }
    for (size_t q = 0; q < k; q++) {
      size_t i = idx[q];
      out[s + i] = offset_value(f, ph[i] > 0 ? dd[q] : -dd[q], tt[q], ti[q]);
    }
  }
  return GR_OK;
}

/* Gradient of g: the unit vector from q to p (times the sign of sd for
 * networks), i.e. the gradient of the distance; T's own variation along the
 * surface is neglected (it changes g's slope by |grad T| << 1, which only
 * slows root finding slightly, never moves a root). */
static int offset_grad(void *ud, size_t n, const double *x, const double *y, const double *z,
                       double *gx, double *gy, double *gz, gr_err *e) {
  offset *f = ud;
  for (size_t i = 0; i < n; i++) {
    double p[3] = {x[i], y[i], z[i]}, ph;
    if (gr_field_eval(f->phi, 1, &p[0], &p[1], &p[2], &ph, e)) return e->code;
    gr_hit h;
    closest_h(f, p, INFINITY, &h);
    double v[3] = {0, 0, 0}, dd = 0;
    if (h.tri >= 0) {
      if (f->mode == GR_DIST_EXACT) exact_polish(f, p, h.q);
      for (int a = 0; a < 3; a++) v[a] = p[a] - h.q[a];
      dd = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    }
    if (dd < 1e-9) { /* on H: the surface normal, oriented to phi > 0 */
      double g[3];
      if (gr_field_grad(f->phi, 1, &p[0], &p[1], &p[2], &g[0], &g[1], &g[2], e)) return e->code;
      double gn = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
      for (int a = 0; a < 3; a++) v[a] = gn > 0 ? g[a] / gn : 0;
      if (f->kind == GR_OFFSET_SHEET) { gx[i] = gy[i] = gz[i] = 0; continue; }
    } else {
      for (int a = 0; a < 3; a++) v[a] /= dd;
      if (f->kind == GR_OFFSET_NETWORK && ph < 0) for (int a = 0; a < 3; a++) v[a] = -v[a];
    }
    double sgn = (f->kind == GR_OFFSET_NETWORK && f->side > 0) ? -1 : 1;
    gx[i] = sgn * v[0];
    gy[i] = sgn * v[1];
    gz[i] = sgn * v[2];
  }
  return GR_OK;
}

double gr_offset_max_thickness(const gr_field *f) {
  const offset *o = gr_field_callback_data(f, offset_eval);
  return o ? o->tmax : -1;
}

/* The earlier point (the one before k, else the one a row before) whose
 * closest point may start k's local search: it has one and lies within
 * 0.1 L of k; -1 when none does. */
static long closest_hint(const offset *f, size_t k, size_t row, const double *x, const double *y, const double *z,
                         const double *q) {
  size_t c[2] = {k - 1, k - row};
  for (int a = 0; a < 2; a++) {
    if ((a == 0 && k == 0) || (a == 1 && (row == 0 || k < row)) || isnan(q[3 * c[a]])) continue;
    double dx = x[k] - x[c[a]], dy = y[k] - y[c[a]], dz = z[k] - z[c[a]];
    if (dx * dx + dy * dy + dz * dz < 0.01 * f->L * f->L) return (long)c[a];
  }
  return -1;
}

int gr_offset_closest(const gr_field *f_, size_t n, const double *x, const double *y,
                      const double *z, double dmax, double *q, double *sd, gr_err *e) {
  return gr_offset_closest_rows(f_, n, 0, x, y, z, dmax, q, sd, e);
}

int gr_offset_closest_rows(const gr_field *f_, size_t n, size_t row, const double *x, const double *y,
                           const double *z, double dmax, double *q, double *sd, gr_err *e) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return gr_fail(e, GR_EARG, "closest points need an offset field");
  enum { B = 256 };
  double ph[B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B;
    int rc = gr_field_eval(f->phi, m, x + s, y + s, z + s, ph, e);
    if (rc) return rc;
    for (size_t i = 0; i < m; i++) {
      double sg = ph[i] > 0 ? 1 : -1, *qi = q + 3 * (s + i);
      double lb = isfinite(f->lip) ? fabs(ph[i]) / f->lip : 0;
      gr_hit h;
      double p[3] = {x[s + i], y[s + i], z[s + i]};
      if (lb > dmax) {
        qi[0] = qi[1] = qi[2] = NAN;
        sd[s + i] = sg * lb;
        continue;
      }
      /* from the previous point's closest point when it is near (points
       * come in grid order; after a point without one, the point a row
       * before), checked against the mesh: no part of H may be nearer than
       * the answer less H's error bound herr (the answer may be up to 2 herr
       * too long: gr_offset_values checks strictly where that matters) */
      long hk = f->mode == GR_DIST_EXACT ? closest_hint(f, s + i, row, x, y, z, q) : -1;
      if (hk >= 0) {
        double qq[3] = {q[3 * hk], q[3 * hk + 1], q[3 * hk + 2]};
        if (exact_newton(f, p, qq)) {
          double d = nearest_patch(f, p, qq, f->herr, 0, 0);
          if (d <= dmax) {
            memcpy(qi, qq, sizeof qq);
            sd[s + i] = sg * d;
            continue;
          }
        }
      }
      if (closest_h(f, p, dmax, &h), h.tri < 0) {
        qi[0] = qi[1] = qi[2] = NAN;
        sd[s + i] = sg * fmax(lb, dmax);
        continue;
      }
      if (f->mode == GR_DIST_EXACT) exact_polish(f, p, h.q);
      memcpy(qi, h.q, sizeof h.q);
      sd[s + i] = sg * sqrt((p[0] - h.q[0]) * (p[0] - h.q[0]) + (p[1] - h.q[1]) * (p[1] - h.q[1]) + (p[2] - h.q[2]) * (p[2] - h.q[2]));
    }
  }
  return GR_OK;
}

/* Values from closest points q and signed distances sd; p (NULL: q) the
 * points themselves, for the owning voxel. Points farther than band from H
 * (|sd| > band) are taken as far, as those without a closest point are. */
static int values_at(const offset *f, size_t n, const double *p, const double *q, const double *sd, double band,
                     double *out, gr_err *e) {
  enum { B = 256 };
  double qx[B], qy[B], qz[B], tt[B], ti[B], px[B], py[B], pz[B];
  /* the points themselves, or (p NULL) the feet: no second copy */
  const double *pk[3] = {p ? px : qx, p ? py : qy, p ? pz : qz};
  size_t idx[B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B, k = 0;
    for (size_t i = 0; i < m; i++) {
      const double *qi = q + 3 * (s + i);
      if (isnan(qi[0]) || fabs(sd[s + i]) > band) { /* far from H: a bound with the right sign */
        out[s + i] = offset_value(f, sd[s + i], f->tmax, f->tmax);
        continue;
      }
      qx[k] = qi[0]; qy[k] = qi[1]; qz[k] = qi[2];
      if (p) { px[k] = p[3 * (s + i)]; py[k] = p[3 * (s + i) + 1]; pz[k] = p[3 * (s + i) + 2]; }
      idx[k++] = i;
    }
    if (k == 0) continue;
    int rc = thick(f, f->t, k, pk, qx, qy, qz, tt, e);
    if (!rc && f->tin) rc = thick(f, f->tin, k, pk, qx, qy, qz, ti, e);
    if (rc) return rc;
    for (size_t r = 0; r < k; r++) out[s + idx[r]] = offset_value(f, sd[s + idx[r]], tt[r], f->tin ? ti[r] : tt[r]);
  }
  return GR_OK;
}

int gr_offset_values(const gr_field *f, size_t n, double *q, double *sd, double *out, gr_err *e) {
  return gr_offset_values_band(f, n, q, sd, INFINITY, out, e);
}

int gr_offset_values_band(const gr_field *f_, size_t n, const double *q, const double *sd, double band, double *out,
                          gr_err *e) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return gr_fail(e, GR_EARG, "offset values need an offset field");
  return values_at(f, n, NULL, q, sd, band, out, e);
}

double gr_offset_keeps_foot(const gr_field *f_, const double q[3]) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return -1;
  return f->lrs ? reach_local(f, q) : f->reach; /* the table whatever the field's thickness */
}

int gr_offset_uses_local_reach(const gr_field *f_) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  return f && f->lreach_on;
}

void gr_offset_implied_thickness(const gr_field *f_, size_t n, const double *sd, const double *v, double band,
                                 double *T) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  /* offset_value(f, sd, 0, 0): |sd| for a sheet, sd or -sd for a network
   * (the side chosen once, so that the loop vectorises) */
  double sg = f && f->side > 0 ? -1 : 1;
  if (!f)
    for (size_t i = 0; i < n; i++) T[i] = NAN;
  else if (f->kind == GR_OFFSET_SHEET)
    for (size_t i = 0; i < n; i++) T[i] = fabs(sd[i]) <= band ? fabs(sd[i]) - v[i] : NAN;
  else
    for (size_t i = 0; i < n; i++) T[i] = fabs(sd[i]) <= band ? sg * sd[i] - v[i] : NAN;
}

double gr_offset_herr(const gr_field *f_) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  return f ? f->herr : -1;
}

double gr_offset_reach(const gr_field *f_) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  return f && f->mode == GR_DIST_EXACT ? f->reach : 0;
}

/* Whether a thickness expression (NULL: none) uses none of x, y, z, u, v, w:
 * T is then the same everywhere (the density table maps it to one value). */
static int expr_constant(const gr_expr *x) {
  for (int i = 0; x && i < 6; i++)
    if (gr_expr_uses(x, i)) return 0;
  return 1;
}

/* Whether T is smooth (twice differentiable) along H: a smooth expression
 * of x, y, z only (u, v, w are clamped to the voxel: T kinks where a foot
 * crosses its face), no field or density table (interpolated). */
static int expr_smooth_xyz(const gr_expr *x) {
  return !x || (gr_expr_smooth(x) && !gr_expr_uses(x, 3) && !gr_expr_uses(x, 4) && !gr_expr_uses(x, 5));
}

int gr_offset_smooth_thickness(const gr_field *f_) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  return f && f->mode == GR_DIST_EXACT && !f->tfield && !f->dens && expr_smooth_xyz(f->t) && expr_smooth_xyz(f->tin);
}

double gr_offset_value_floor(const gr_field *f_, double dlb) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f || f->kind != GR_OFFSET_SHEET) return -INFINITY;
  return dlb - (expr_constant(f->t) && expr_constant(f->tin) && !f->tfield ? f->tmax : f->maxt);
}

int gr_offset_strict(const gr_field *f_, const double p[3], double q[3], double *sd, int local, gr_err *e) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return gr_fail(e, GR_EARG, "closest points need an offset field");
  if (f->mode != GR_DIST_EXACT || isnan(q[0])) return GR_OK;
  double d = fabs(*sd), d2 = nearest_patch(f, p, q, PATCH_TOL, 1, local);
  if (d2 < d) *sd = *sd < 0 ? -d2 : d2;
  return GR_OK;
}

int gr_offset_eval_near(const gr_field *f_, size_t n, const double *x, const double *y,
                        const double *z, const double *hint, int nh, double *out, double *grad, gr_err *e) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return gr_fail(e, GR_EARG, "offset evaluation needs an offset field");
  if (nh < 1) return gr_fail(e, GR_EARG, "offset evaluation needs at least one hint per point");
  enum { B = 256 };
  double q[3 * B], sd[B], ph[B], pb[3 * B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B;
    /* the side of H: a sheet of one thickness does not depend on it */
    int rc = GR_OK;
    if (f->kind == GR_OFFSET_SHEET && !f->tin)
      for (size_t i = 0; i < m; i++) ph[i] = 1;
    else
      rc = gr_field_eval(f->phi, m, x + s, y + s, z + s, ph, e);
    if (rc) return rc;
    for (size_t i = 0; i < m; i++) {
      double p[3] = {x[s + i], y[s + i], z[s + i]}, *qi = q + 3 * i, d = INFINITY;
      memcpy(pb + 3 * i, p, sizeof p);
      /* every hint refined on its own patch; the nearest answer wins (hints
       * from nodes across the medial surface lie on different patches) */
      for (int k = 0; k < nh && f->mode == GR_DIST_EXACT; k++) {
        const double *hk = hint + 3 * ((s + i) * nh + k);
        double qk[3] = {hk[0], hk[1], hk[2]};
        if (isnan(qk[0]) || !exact_newton(f, p, qk)) continue;
        double dk = gr_dist3(p, qk);
        if (dk < d) {
          d = dk;
          memcpy(qi, qk, sizeof qk);
        }
      }
      if (d < INFINITY) {
        /* the hints come from grid nodes whose own closest points were
         * checked strictly near zero (gr_offset_values): across the medial
         * surface they lie on both patches, so no search away from them */
        d = nearest_patch(f, p, qi, PATCH_TOL, 0, f->lreach_on);
      } else {
        /* no usable hint: search the mesh */
        gr_hit h;
        closest_h(f, p, INFINITY, &h);
        if (h.tri < 0) return gr_fail(e, GR_EGEOM, "no closest point of H to (%g, %g, %g)", p[0], p[1], p[2]);
        if (f->mode == GR_DIST_EXACT) exact_polish(f, p, h.q);
        memcpy(qi, h.q, sizeof h.q);
        d = gr_dist3(p, qi);
      }
      sd[i] = ph[i] > 0 ? d : -d;
      if (grad) dist_grad(f, p, qi, sd[i], grad + 3 * (s + i));
    }
    if ((rc = values_at(f, m, pb, q, sd, INFINITY, out + s, e))) return rc;
  }
  return GR_OK;
}

/* A predicted closest point x of p (near the true one, on its patch)
 * polished by projections of p onto phi's tangent plane, the first from phi's
 * value v and gradient g0 at x (at: x's sines and cosines, made for a batch
 * of points at once), the gradients after it moved from those
 * (gr_field_move_grad): q and the
 * signed distance sd (+ on the gradient's side); 1 when accepted, 0 when not
 * (solve exactly), -1 on error.
 * Each projection moves the foot by D; it converges linearly, the ratio rho
 * of successive moves about d kappa, so the foot is left within
 * rho D / (1 - rho): stopped when that is below 1e-6 L (T there is then off
 * by 1e-6 L |grad T|, below 1e-7 L for any grading with |grad T| < 0.1; a
 * tighter 1e-7 L, as exact_newton stops, left seven times more points to
 * the exact solve on the continuous P job).
 * The distance is then off by about D^2 / 2 times the larger of
 * kappa / (1 - d kappa) (along the surface; kappa <= 1 / reach, the local
 * reach at q where it serves: it holds cut distances, at most the focal
 * distances 1 / kappa) and
 * |phi_nn| / |grad phi| (across it; estimated from the last two gradients):
 * accepted when that is below MODEL_ERR L and the distance is within the
 * reach (then no other patch is nearer). */
#define MODEL_ERR 1e-8
#define MODEL_ROUNDS 4

/* The projections did not settle in MODEL_ROUNDS (d kappa near 1: thick
 * sheets, points near a centre of curvature): finish by Newton's method with
 * phi's Hessian (quadratic from a start this near) from the last foot they
 * evaluated (*at, its value v and gradient g: no new sines), to the
 * projections' own tolerance (a foot within 1e-6 L), the answer into q; then
 * the reach at the foot decides as for an accepted projection (a foot within
 * it is the closest point). sd keeps its side. */
static int newton_finish(const offset *f, const double p[3], gr_field_at *at, double v, const double g[3],
                         double q[3], double *sd) {
  if (!newton_from(f, p, at, v, g, 1e-6, q)) return 0;
  double d = gr_dist3(p, q);
  if (!(d < reach_for(f, q, d))) return 0;
  *sd = *sd < 0 ? -d : d;
  return 1;
}
static int model_foot(const offset *f, const double p[3], const double x[3], gr_field_at at, double v,
                      const double g0[3], double q[3], double *sd, gr_err *e) {
  double g[3] = {g0[0], g0[1], g0[2]}, gp[3], o[3] = {x[0], x[1], x[2]}, prev = INFINITY, prev2 = 0;
  for (int r = 0; r < MODEL_ROUNDS; r++) {
    if (r) {
      double dp[3] = {q[0] - o[0], q[1] - o[1], q[2] - o[2]};
      memcpy(gp, g, sizeof g);
      memcpy(o, q, sizeof o);
      if (gr_field_move_grad(f->phi, &at, dp, &v, g, e)) return -1;
    }
    double g2 = gr_dot3(g, g), s = v, D2 = 0;
    if (!(g2 > 1e-300)) return 0;
    for (int a = 0; a < 3; a++) s += g[a] * (p[a] - o[a]);
    s /= g2;
    for (int a = 0; a < 3; a++) {
      q[a] = p[a] - s * g[a];
      D2 += (q[a] - o[a]) * (q[a] - o[a]);
    }
    *sd = s * sqrt(g2);
    /* settled: the step's ratio to the last, rho = D / prev, below 1/2 and
     * the error left, rho D / (1 - rho), below 1e-6 L (times prev: no division) */
    double d = fabs(*sd), D = sqrt(D2);
    if (r > 0 && (D == 0 || (D < 0.5 * prev && D * D < 1e-6 * f->L * (prev - D)))) {
      /* the reach at the last foot only: the earlier ones do not decide */
      double R = reach_for(f, q, d);
      if (!(d < R)) return 0;
      double dg[3] = {g[0] - gp[0], g[1] - gp[1], g[2] - gp[2]};
      double K = fmax(1 / (R - d), sqrt(gr_dot3(dg, dg) / (gr_dot3(gp, gp) * prev2)));
      return K * D2 <= 2 * MODEL_ERR * f->L;
    }
    if (r > 0 && D >= 0.5 * prev) break; /* too slow to settle in the rounds left */
    prev = D;
    prev2 = D2;
  }
  return newton_finish(f, p, &at, v, g, q, sd);
}

int gr_offset_eval_model(const gr_field *f_, size_t n, const double *x, const double *y, const double *z,
                         const double *pred, double *out, double *grad, gr_err *e) {
  const offset *f = gr_field_callback_data(f_, offset_eval);
  if (!f) return gr_fail(e, GR_EARG, "offset evaluation needs an offset field");
  enum { B = 256 };
  double pb[3 * B], sd[B], q[3 * B], vk[B], cv[B], cg[3 * B], cp[3 * B];
  size_t id[B], ic[B];
  gr_field_at at[B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B, k = 0, nc = 0;
    /* the points whose prediction may serve; the field's gradient at all
     * their predictions at once */
    for (size_t i = 0; i < m; i++) {
      const double *c = pred + 3 * (s + i);
      double P[3] = {x[s + i], y[s + i], z[s + i]};
      out[s + i] = NAN;
      if (f->mode != GR_DIST_EXACT || isnan(c[0])) continue;
      double dc = gr_dist3(P, c);
      if (!(dc < reach_for(f, c, dc))) continue;
      memcpy(cp + 3 * nc, c, 3 * sizeof *c);
      ic[nc++] = i;
    }
    if (nc && gr_field_grad_at_n(f->phi, nc, cp, cv, cg, at, e)) return e->code;
    for (size_t j = 0; j < nc; j++) {
      size_t i = ic[j];
      double P[3] = {x[s + i], y[s + i], z[s + i]};
      int ok = model_foot(f, P, cp + 3 * j, at[j], cv[j], cg + 3 * j, q + 3 * k, sd + k, e);
      if (ok < 0) return e->code;
      if (!ok) continue;
      memcpy(pb + 3 * k, P, sizeof P);
      id[k++] = i;
    }
    int rc = values_at(f, k, pb, q, sd, INFINITY, vk, e);
    if (rc) return rc;
    for (size_t i = 0; i < k; i++) {
      size_t o = s + id[i];
      out[o] = vk[i];
      if (grad) dist_grad(f, pb + 3 * i, q + 3 * i, sd[i], grad + 3 * o);
    }
  }
  return GR_OK;
}

const char *gr_offset_warning(const gr_field *f) {
  const offset *o = gr_field_callback_data(f, offset_eval);
  return o ? o->warning : "";
}

/* The thickness expressions of o compiled into f (errors name the option). */
gr_expr *gr_offset_thickness_expr(const char *src, const double cell[3], gr_err *e) {
  static const char *const vars[] = {"x", "y", "z", "u", "v", "w"};
  static const char *const cn[] = {"L", "Lx", "Ly", "Lz"};
  double cv[] = {gr_cell_min(cell), cell[0], cell[1], cell[2]};
  return gr_expr_compile(src, 6, vars, 4, cn, cv, e);
}

/* The thickness expressions of o compiled into f (errors name the option). */
static int offset_compile(offset *f, const gr_offset_opts *o, gr_err *e) {
  double L = gr_cell_min(o->cell);
  if (o->thickness_expr && !(f->t = gr_offset_thickness_expr(o->thickness_expr, o->cell, e))) {
    char m[512];
    snprintf(m, sizeof m, "%s", e->msg);
    return gr_fail(e, GR_EARG, "bad option 'thickness' (%s)", m);
  }
  if (o->inside_expr && !(f->tin = gr_offset_thickness_expr(o->inside_expr, o->cell, e))) {
    char m[512];
    snprintf(m, sizeof m, "%s", e->msg);
    return gr_fail(e, GR_EARG, "bad option 'inside' (%s)", m);
  }
  if (!o->thickness_expr && !f->tfield && !f->dens && !(o->thickness >= 0 && o->thickness <= L / 2))
    return gr_fail(e, GR_EARG, "bad option 'thickness' (must be in [0, L/2 = %g], got %g)", L / 2, o->thickness);
  return GR_OK;
}

/* The largest thickness, estimated from 8^3 samples over the box grown by
 * the margin and half a cell (at most L/2). */
static double offset_tmax_estimate(const offset *f, const gr_offset_opts *o) {
  double tmax_est = f->tconst, L = gr_cell_min(o->cell);
  if (!(f->t || f->tin || f->tfield)) return tmax_est;
  enum { S = 8 };
  double sx[S * S * S], sy[S * S * S], sz[S * S * S], st[S * S * S];
  int n = 0;
  for (int a = 0; a < S; a++)
    for (int b = 0; b < S; b++)
      for (int c = 0; c < S; c++, n++) {
        double m = o->margin + 0.5 * L;
        sx[n] = o->box_lo[0] - m + (o->box_hi[0] - o->box_lo[0] + 2 * m) * a / (S - 1);
        sy[n] = o->box_lo[1] - m + (o->box_hi[1] - o->box_lo[1] + 2 * m) * b / (S - 1);
        sz[n] = o->box_lo[2] - m + (o->box_hi[2] - o->box_lo[2] + 2 * m) * c / (S - 1);
      }
  tmax_est = 0;
  for (int pass = 0; pass < 2; pass++) {
    const gr_expr *x = pass ? f->tin : f->t;
    if (!x && !(pass == 0 && f->tfield)) continue;
    gr_err e2;
    const double *sp[3] = {sx, sy, sz};
    if (thick(f, x, (size_t)n, sp, sx, sy, sz, st, &e2) == GR_OK) {
      for (int q = 0; q < n; q++)
        if (st[q] > tmax_est) tmax_est = st[q];
    } else {
      tmax_est = 0.5 * L;
    }
  }
  if (tmax_est > 0.5 * L) tmax_est = 0.5 * L;
  return tmax_est;
}

/* H: shared with o->like (lk, shifted, with its BVH), given (o->mesh), or
 * meshed by marching cubes over the box grown by reach. */
static int offset_mesh(offset *f, const gr_offset_opts *o, const offset *lk, double reach, gr_err *e) {
  if (lk) {
    f->like = gr_field_ref(o->like);
    f->h = lk->h;
    f->bvh = lk->bvh;
    for (int a = 0; a < 3; a++) f->shift[a] = lk->shift[a] + o->like_shift[a];
  } else if (o->mesh) {
    f->h = o->mesh;
  } else {
    double lo[3], hi[3];
    int n[3];
    for (int a = 0; a < 3; a++) {
      lo[a] = o->box_lo[a] - reach;
      hi[a] = o->box_hi[a] + reach;
      if (!(hi[a] > lo[a])) return gr_fail(e, GR_EARG, "bad option 'box' (empty along axis %d)", a);
      n[a] = (int)ceil((hi[a] - lo[a]) / o->cell[a] * o->res) + 1;
    }
    f->own = gr_mc_field_mt(o->surface, lo, hi, n, 1, o->threads, e);
    if (!f->own) return e->code ? e->code : GR_EMEM;
    f->h = f->own;
  }
  return GR_OK;
}

/* Margin (mm) of the vertices a group keeps for its members' checks: far
 * above the rounding of box - shift (1e-15 mm), far below a mesh spacing. */
#define VNEAR_PAD 1e-6

/* Whether p lies in the box [lo, hi] (NaN does not). */
static int in_box3(const double p[3], const double lo[3], const double hi[3]) {
  int in = 1;
  for (int a = 0; a < 3; a++) in &= p[a] >= lo[a] && p[a] <= hi[a];
  return in;
}

/* The vertices of H (its own frame) within [lo, hi], kept in s by the
 * first member that asks, under s's lock; the list when it covers [lo, hi]
 * (the rounding of another member's box), else NULL: search all. */
static const size_t *near_vertices(lreach_slot *s, const gr_mesh *h, const double lo[3], const double hi[3],
                                   size_t *n) {
  pthread_mutex_lock(&s->mu);
  if (!s->vmade) {
    s->vmade = -1;
    size_t *id = malloc((h->nv + 1) * sizeof *id), m = 0;
    for (int a = 0; a < 3; a++) s->vlo[a] = lo[a] - VNEAR_PAD, s->vhi[a] = hi[a] + VNEAR_PAD;
    for (size_t i = 0; id && i < h->nv; i++)
      if (in_box3(h->v + 3 * i, s->vlo, s->vhi)) id[m++] = i;
    if (id) s->vid = id, s->nvid = m, s->vmade = 1;
  }
  int cover = s->vmade == 1;
  for (int a = 0; a < 3 && cover; a++) cover = s->vlo[a] + 0.5 * VNEAR_PAD <= lo[a] && hi[a] <= s->vhi[a] - 0.5 * VNEAR_PAD;
  pthread_mutex_unlock(&s->mu);
  *n = cover ? s->nvid : 0;
  return cover ? s->vid : NULL;
}

/* H's vertices (shifted) into vx, vy, vz, those within reach of the box
 * only when H is shared (`lrs`: the group's slot, whose kept vertices
 * spare the search over all of H, whose count grows with the group); the
 * count. */
static size_t offset_vertices(const offset *f, const gr_offset_opts *o, int shared, lreach_slot *lrs, double reach,
                              double *vx, double *vy, double *vz) {
  size_t m = 0, nc = f->h->nv;
  const size_t *cand = NULL;
  double blo[3], bhi[3]; /* the box grown by the reach */
  for (int a = 0; a < 3; a++) blo[a] = o->box_lo[a] - reach, bhi[a] = o->box_hi[a] + reach;
  if (shared && lrs) {
    double lo[3], hi[3];
    for (int a = 0; a < 3; a++) lo[a] = blo[a] - f->shift[a], hi[a] = bhi[a] - f->shift[a];
    cand = near_vertices(lrs, f->h, lo, hi, &nc);
    if (!cand) nc = f->h->nv;
  }
  for (size_t c = 0; c < nc; c++) {
    size_t i = cand ? cand[c] : c;
    double p[3] = {f->h->v[3 * i] + f->shift[0], f->h->v[3 * i + 1] + f->shift[1], f->h->v[3 * i + 2] + f->shift[2]};
    if (shared && !in_box3(p, blo, bhi)) continue;
    vx[m] = p[0]; vy[m] = p[1]; vz[m] = p[2];
    m++;
  }
  return m;
}

/* The thickness over H's nv vertices into t (the inside thickness's last
 * when given), validated to [0, L/2]; *maxt: the largest. */
static int offset_check_thickness(offset *f, const gr_offset_opts *o, size_t nv, const double *vx, const double *vy,
                                  const double *vz, double *t, double *maxt, gr_err *e) {
  *maxt = f->tconst;
  double L = gr_cell_min(o->cell);
  for (int pass = 0; pass < (f->tin ? 2 : 1) && (f->t || f->tin || f->tfield); pass++) {
    const gr_expr *x = pass ? f->tin : f->t;
    if (!x && !(pass == 0 && f->tfield)) continue;
    const double *vp[3] = {vx, vy, vz};
    if (thick(f, x, nv, vp, vx, vy, vz, t, e)) {
      char m[512];
      snprintf(m, sizeof m, "%s", e->msg);
      return gr_fail(e, e->code, "bad option '%s' (%s)", pass ? "inside" : "thickness", m);
    }
    if (pass == 0) *maxt = 0;
    for (size_t i = 0; i < nv; i++) {
      if (!(t[i] >= 0) || t[i] > L / 2) {
        int out = 0;
        double pv[3] = {vx[i], vy[i], vz[i]};
        for (int a = 0; a < 3; a++) out |= pv[a] < o->box_lo[a] || pv[a] > o->box_hi[a];
        return gr_fail(e, GR_EARG, "bad option '%s' (must be in [0, L/2 = %g], got %g at x=%g, y=%g, z=%g%s)",
                       pass ? "inside" : "thickness", L / 2, t[i], vx[i], vy[i], vz[i],
                       out ? ", outside the cell's box: the thickness is evaluated on the surface up to a margin beyond"
                             " the part, so it must stay valid there too, e.g. clamp with min(max(z, z0), z1)" : "");
      }
      if (t[i] > *maxt) *maxt = t[i];
    }
  }
  return GR_OK;
}

/* Touching offsets: from each vertex v of H, step along the normal to the
 * offset surface (distance T(v)); if that point is as close to another part
 * of H (one whose closest point is more than 2 T(v) from v), the offset
 * sheets of the two parts meet there: f->warning. Sheets only. A vertex
 * whose T is below H's reach, or its local reach when the field uses the
 * table (`local`), keeps its point's foot: no other part can be nearer, and
 * it is not searched. */
static void offset_touch_warning(offset *f, const gr_offset_opts *o, int shared, size_t nv, const double *vx,
                                 const double *vy, const double *vz, const double *t, int local) {
  if (f->kind != GR_OFFSET_SHEET) return;
  for (size_t i = 0; i < nv && !f->warning[0]; i += 7) {
    double tv = (f->t || f->tin || f->tfield) ? t[i] : f->tconst;
    double v[3] = {vx[i], vy[i], vz[i]}, g[3];
    int in = 1; /* a shared H: only this field's box */
    for (int a = 0; a < 3 && shared; a++) in &= v[a] >= o->box_lo[a] && v[a] <= o->box_hi[a];
    if (!in || tv < f->reach || (local && tv < reach_local(f, v))) continue;
    gr_err e2;
    if (gr_field_grad(f->phi, 1, &v[0], &v[1], &v[2], &g[0], &g[1], &g[2], &e2)) continue;
    double gn = sqrt(gr_dot3(g, g));
    if (!(gn > 0) || !(tv > 0)) continue;
    for (int sgn = -1; sgn <= 1 && !f->warning[0]; sgn += 2) {
      double p[3];
      for (int a = 0; a < 3; a++) p[a] = v[a] + sgn * tv * g[a] / gn;
      gr_hit h;
      closest_h(f, p, 0.95 * tv, &h);
      double dq = sqrt((h.q[0] - v[0]) * (h.q[0] - v[0]) + (h.q[1] - v[1]) * (h.q[1] - v[1]) + (h.q[2] - v[2]) * (h.q[2] - v[2]));
      if (h.tri >= 0 && dq > tv && h.dist < 0.95 * tv)
        snprintf(f->warning, sizeof f->warning,
                 "thickness %.4g mm: offset sheets of neighbouring parts touch near x=%.4g, y=%.4g, z=%.4g", tv, p[0], p[1], p[2]);
    }
  }
}

/* The exact closest point of p (H's nearest part polished), or 0 (the cut
 * distances of the reach measure points near centres of curvature, where
 * the alternating refinement alone took up to 60 rounds). */
static int exact_foot(const offset *f, const double p[3], double q[3]) {
  gr_hit h;
  closest_h(f, p, INFINITY, &h);
  if (h.tri < 0 || !exact_polish(f, p, h.q)) return 0;
  memcpy(q, h.q, sizeof h.q);
  return 1;
}

/* The vertex v of H's mesh moved onto phi = 0 (s) with its unit normal n
 * there; 0 when that fails. */
static int on_surface(const offset *f, const double v[3], double s[3], double n[3]) {
  gr_err e;
  memcpy(s, v, 3 * sizeof *s);
  for (int it = 0; it < 6; it++) { /* onto phi = 0 */
    double val;
    if (gr_field_eval_grad(f->phi, 1, &s[0], &s[1], &s[2], &val, &n[0], &n[1], &n[2], &e)) break;
    double g2 = gr_dot3(n, n);
    if (!(g2 > 1e-300)) break;
    for (int a = 0; a < 3; a++) s[a] -= val * n[a] / g2;
  }
  if (gr_field_grad(f->phi, 1, &s[0], &s[1], &s[2], &n[0], &n[1], &n[2], &e)) return 0;
  double gn = sqrt(gr_dot3(n, n));
  if (!(gn > 0)) return 0;
  for (int a = 0; a < 3; a++) n[a] /= gn;
  return 1;
}

static int foot_cb(void *ud, const double p[3], double q[3]) { return exact_foot(ud, p, q); }

/* A lower estimate of the surface's reach (mm): the cut distance
 * (reach.h) of a sample of H's vertices (every 29th, both sides, by
 * bisection to 1e-3 L) times REACH_SAFETY. A point nearer to the surface
 * than the reach has one closest point, and a local closest point (Newton
 * from a hint) nearer than it is that one: thin walls skip the nearer-patch
 * search. */
#define REACH_SAFETY 0.6
static double reach_estimate(const offset *f, const gr_offset_opts *o, size_t nv, const double *vx, const double *vy,
                             const double *vz) {
  double L = gr_cell_min(o->cell), best = 0.5 * L, eps = 0.2 * f->herr;
  size_t used = 0;
  for (size_t i = 0; i < nv; i += 29) {
    double v[3] = {vx[i], vy[i], vz[i]}, s[3], n[3];
    int inbox = 1;
    for (int a = 0; a < 3; a++) inbox &= v[a] >= o->box_lo[a] && v[a] <= o->box_hi[a];
    if (!inbox || !on_surface(f, v, s, n)) continue;
    used++;
    for (int sg = -1; sg <= 1; sg += 2)
      best = fmin(best, gr_reach_bisect(foot_cb, (void *)f, s, n, sg, best, 1e-3 * L, 12, eps));
  }
  return used ? REACH_SAFETY * best : 0;
}

/* The table of H's local reach over one period (slot s), from H's vertices
 * in the period box moved onto phi = 0; NULL when that fails. Cut distances
 * are measured up to LREACH_CAP L: sheets up to about a quarter of the cell
 * thick are served (thicker ones search H as before); a larger cap costs
 * more, the largest empty balls of the common TPMS being some 0.4 L. */
#define LREACH_CAP 0.3
static gr_reach *lreach_make(const lreach_slot *s) {
  const offset *f = s->owner;
  size_t nv = f->h->nv, m = 0;
  double *sn = malloc((6 * nv + 1) * sizeof *sn);
  if (!sn) return NULL;
  for (size_t i = 0; i < nv; i++) {
    const double *v = f->h->v + 3 * i;
    int in = 1;
    for (int a = 0; a < 3; a++) in &= v[a] >= s->lo[a] && v[a] < s->lo[a] + s->period[a];
    if (in && on_surface(f, v, sn + 3 * m, sn + 3 * nv + 3 * m)) m++;
  }
  gr_err e;
  /* a point of H lies within mdev of the mesh (measured), a point of a
   * triangle within its longest edge / sqrt 3 of a vertex (a triangle of
   * marching cubes lies in one cube of the mesh spacing 2 herr: edges up to
   * sqrt 3 times that), and the vertices moved by up to mdev onto phi = 0 */
  double spacing = 2 * f->herr + 2 * f->mdev;
  gr_reach *r = gr_reach_new(s->lo, s->period, LREACH_CAP * f->L, 0.2 * f->herr, spacing, m, sn, sn + 3 * nv, foot_cb,
                             (void *)f, s->threads, &e);
  free(sn);
  return r;
}

/* The slot's table, made by the first caller (the others wait). */
static const gr_reach *lreach_get(lreach_slot *s) {
  if (__atomic_load_n(&s->state, __ATOMIC_ACQUIRE)) return s->r;
  pthread_mutex_lock(&s->mu);
  if (!s->state) {
    s->r = lreach_make(s);
    __atomic_store_n(&s->state, 1, __ATOMIC_RELEASE);
  }
  pthread_mutex_unlock(&s->mu);
  return s->r;
}

/* Whether field f uses H's local reach: only when its thickness reaches
 * H's reach somewhere (tmax >= reach). Thinner walls put few points beyond
 * the reach (grid nodes and probes near the thickest wall): searching H for
 * those costs less than making the table (1-1.5 s of CPU per group).
 * Decided per field from its own thickness, so its values are the same
 * whoever else made the table; the strict checks of the group's shared
 * closest points follow the asking member's choice (cptab.c keeps the two
 * kinds apart). */
static int lreach_wanted(const offset *f) { return f->lrs && f->tmax >= f->reach; }

/* The larger of H's reach and its local reach at q (reach.h; the table made
 * now when it is not yet). */
static double reach_local(const offset *f, const double q[3]) {
  const gr_reach *r = lreach_get(f->lrs);
  if (!r) return f->reach;
  double c[3] = {q[0] - f->shift[0], q[1] - f->shift[1], q[2] - f->shift[2]};
  return fmax(f->reach, gr_reach_at(r, c));
}

/* Below what distance from its foot q (a point of H) a point at distance d
 * keeps q as its closest point: H's reach, or beyond it (for a field that
 * uses the table) the local reach at q when larger. */
static double reach_for(const offset *f, const double q[3], double d) {
  return d < f->reach || !f->lreach_on ? f->reach : reach_local(f, q);
}

/* A slot for H's local reach (made later, when needed). */
static int lreach_slot_new(offset *f, const gr_offset_opts *o, gr_err *e) {
  lreach_slot *s = calloc(1, sizeof *s);
  if (!s) return gr_fail(e, GR_EMEM, "out of memory");
  pthread_mutex_init(&s->mu, NULL);
  s->owner = f;
  memcpy(s->lo, o->box_lo, sizeof s->lo);
  memcpy(s->period, o->cell, sizeof s->period);
  s->threads = gr_field_threadsafe(f->phi) ? o->threads : 1;
  f->lrs = s;
  return GR_OK;
}

/* How far H's mesh lies off phi = 0: |phi| / |grad phi| at each triangle's
 * centroid and edge midpoints (where a flat triangle strays farthest from
 * the surface), the largest times 1.5, at most herr. */
static double mesh_deviation(const offset *f) {
  enum { B = 256 };
  double x[B], y[B], z[B], v[B], gx[B], gy[B], gz[B], worst = 0;
  const gr_mesh *m = f->h;
  size_t n = 0;
  gr_err e;
  for (size_t t = 0; t <= m->nf; t++) {
    if (n + 4 > B || (t == m->nf && n)) {
      if (gr_field_eval_grad(f->phi, n, x, y, z, v, gx, gy, gz, &e)) return f->herr;
      for (size_t k = 0; k < n; k++) {
        double g = sqrt(gx[k] * gx[k] + gy[k] * gy[k] + gz[k] * gz[k]);
        worst = g > 0 ? fmax(worst, fabs(v[k]) / g) : f->herr;
      }
      n = 0;
    }
    if (t == m->nf) break;
    const double *a = m->v + 3 * m->f[3 * t], *b = m->v + 3 * m->f[3 * t + 1], *c = m->v + 3 * m->f[3 * t + 2];
    const double w[4][3] = {{1. / 3, 1. / 3, 1. / 3}, {0.5, 0.5, 0}, {0, 0.5, 0.5}, {0.5, 0, 0.5}};
    for (int k = 0; k < 4; k++, n++) {
      x[n] = w[k][0] * a[0] + w[k][1] * b[0] + w[k][2] * c[0] + f->shift[0];
      y[n] = w[k][0] * a[1] + w[k][1] * b[1] + w[k][2] * c[1] + f->shift[1];
      z[n] = w[k][0] * a[2] + w[k][1] * b[2] + w[k][2] * c[2] + f->shift[2];
    }
  }
  return fmin(1.5 * worst, f->herr);
}

/* mesh_deviation on a thread of its own */
typedef struct dev_job {
  const offset *f;
  double out;
  pthread_t th;
} dev_job;
static void *dev_main(void *a) {
  dev_job *d = a;
  d->out = mesh_deviation(d->f);
  return NULL;
}

/* After meshing: H's BVH, the thickness over H's vertices (validation,
 * *maxt its largest, the touch warning) and the reach. */
static int offset_checks(offset *f, const gr_offset_opts *o, const offset *lk, double reach, double *maxt, gr_err *e) {
  if (!f->bvh && !(f->bvh = gr_bvh_new(f->h, e))) return e->code ? e->code : GR_EMEM;
  size_t nv = f->h->nv;
  double *buf = malloc((4 * nv + 1) * sizeof *buf);
  if (!buf) return gr_fail(e, GR_EMEM, "out of memory");
  double *vx = buf, *vy = buf + nv, *vz = buf + 2 * nv, *t = buf + 3 * nv;
  nv = offset_vertices(f, o, lk != NULL, lk ? lk->lrs : NULL, reach, vx, vy, vz);
  int rc = offset_check_thickness(f, o, nv, vx, vy, vz, t, maxt, e);
  if (rc == GR_OK) {
    f->tmax = *maxt;
    f->reach = lk ? lk->reach : (o->mode == GR_DIST_EXACT ? reach_estimate(f, o, nv, vx, vy, vz) : 0);
    f->lrs = lk ? lk->lrs : NULL;
    if (!lk && o->periodic && o->mode == GR_DIST_EXACT) rc = lreach_slot_new(f, o, e);
    /* the local reach only where the field will use it anyway and its owner
     * is complete (a member of a group: the table needs the owner's measured
     * mesh deviation, set after these checks) */
    if (rc == GR_OK) offset_touch_warning(f, o, lk != NULL, nv, vx, vy, vz, t, lk && lreach_wanted(f));
  }
  free(buf);
  return rc;
}

gr_field *gr_offset_field_new(const gr_offset_opts *o, gr_err *e) {
  if (!o->surface) return gr_fail(e, GR_EARG, "bad option 'surface' (a field is needed)"), NULL;
  for (int a = 0; a < 3; a++)
    if (!(o->cell[a] > 0)) return gr_fail(e, GR_EARG, "bad option 'cell' (must be > 0, got %g)", o->cell[a]), NULL;
  double L = gr_cell_min(o->cell);
  if (o->res < 2) return gr_fail(e, GR_EARG, "bad option 'res' (must be >= 2, got %d)", o->res), NULL;
  offset *f = calloc(1, sizeof *f);
  if (!f) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  f->phi = gr_field_ref(o->surface);
  f->L = L;
  gr_field_step_init(f->phi, 1e-6 * L, &f->hstep);
  memcpy(f->Lv, o->cell, sizeof f->Lv);
  memcpy(f->o, o->origin, sizeof f->o);
  f->kind = o->kind;
  f->side = o->side >= 0 ? 1 : -1;
  f->mode = o->mode;
  f->tconst = o->thickness;
  f->tfield = (!o->thickness_expr && o->thickness_field) ? gr_field_ref(o->thickness_field) : NULL;
  f->lip = gr_field_lipschitz(o->surface);
  f->dens = gr_dtable_ref(o->density);
  f->vfix = o->voxel != 0;
  for (int a = 0; a < 3; a++) f->vc[a] = o->box_lo[a] + 0.5 * o->cell[a];
  if (offset_compile(f, o, e)) { offset_free(f); return NULL; }
  /* H over the box grown by a reach: margin + the largest thickness (from
   * samples over the grown box) + two mesh spacings */
  double reach = o->margin + 1.5 * offset_tmax_estimate(f, o) + 3 * L / o->res;
  const offset *lk = o->like ? gr_field_callback_data(o->like, offset_eval) : NULL;
  if (o->like && !lk) { offset_free(f); return gr_fail(e, GR_EARG, "bad option 'like' (an offset field is needed)"), NULL; }
  double hmesh = fmax(o->cell[0], fmax(o->cell[1], o->cell[2])) / o->res; /* the coarsest mesh spacing */
  f->herr = 0.5 * hmesh;
  if (offset_mesh(f, o, lk, reach, e)) { offset_free(f); return NULL; }
  /* H's deviation (it needs the mesh only) on a thread of its own beside
   * the BVH, the thickness checks and the reach, when threads allow */
  dev_job dj = {.f = f, .out = f->herr};
  int dev = !lk && o->mode == GR_DIST_EXACT;
  int dev_th = dev && o->threads > 1 && gr_field_threadsafe(f->phi);
  dev_th = dev_th && pthread_create(&dj.th, NULL, dev_main, &dj) == 0;
  double maxt = 0;
  int rc = offset_checks(f, o, lk, reach, &maxt, e);
  if (dev_th) pthread_join(dj.th, NULL);
  else if (dev && rc == GR_OK) dj.out = mesh_deviation(f);
  if (rc) { offset_free(f); return NULL; }
  f->mdev = lk ? lk->mdev : dj.out;
  f->lreach_on = lreach_wanted(f);
  f->maxt = 1.2 * maxt + 2 * hmesh;
  f->tnear = 0.5 * maxt;
  f->refine_band = 0.25 * hmesh; /* a quarter mesh spacing: far above H's error */
  gr_field *g = gr_field_callback(offset_eval, offset_grad, f, offset_free, f->tfield ? gr_field_threadsafe(f->tfield) : 1, o->kind == GR_OFFSET_SHEET ? "sheet offset" : "network offset");
  if (!g) { offset_free(f); return gr_fail(e, GR_EMEM, "out of memory"), NULL; }
  return g;
}
