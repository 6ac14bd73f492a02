/* field.h: scalar fields phi(p) over 3-D space, evaluated over batches of
 * points (structure of arrays). The zero set of a field is its surface; a
 * field is negative on its "inside". Fields are reference counted and
 * immutable after construction, so combinations can share children.
 * Thread safety: gr_field_eval may run from several threads at once on one
 * field unless gr_field_threadsafe() says 0 (Lua-function fields). */
#ifndef GR_FIELD_H
#define GR_FIELD_H
#include "common.h"

typedef struct gr_field gr_field;

/* Callback kinds, for fields computed elsewhere (Lua functions, distance
 * fields). Return GR_OK or an error code after filling e. */
typedef int (*gr_field_fn)(void *ud, size_t n, const double *x,
                           const double *y, const double *z, double *out,
                           gr_err *e);
typedef int (*gr_field_gradfn)(void *ud, size_t n, const double *x,
                               const double *y, const double *z, double *gx,
                               double *gy, double *gz, gr_err *e);

/* ---- TPMS catalogue (doc/contract.md section 2) ---- */
int gr_tpms_count(void);
const char *gr_tpms_name(int i);
int gr_tpms_lookup(const char *name); /* index, or -1 */
/* "primitive, gyroid, ..." for error messages. */
const char *gr_tpms_names(void);
/* phi(p) - level for the named surface, cell size `cell` (mm, > 0), cells
 * tiled from `origin` (the domain min corner; NULL = 0,0,0), so that
 * X = 2*pi/cell*(x - origin_x - cell/2). Analytic gradient. Unknown name:
 * GR_EARG listing the valid names. */
gr_field *gr_field_tpms(const char *name, double cell, const double *origin,
                        double level, gr_err *e);
/* The same surface stretched: cell lengths Lx, Ly, Lz (mm, each > 0), so that
 * X = 2*pi/Lx*(x - origin_x - Lx/2), Y and Z likewise with Ly, Lz. Equal
 * lengths give exactly gr_field_tpms. */
gr_field *gr_field_tpms3(const char *name, const double cell[3], const double *origin,
                         double level, gr_err *e);

/* Information about a TPMS field (for the voxel signature and exact mode);
 * returns 0 if f is not a plain TPMS field. */
typedef struct gr_tpms_info {
  int surface;       /* catalogue index */
  double cell;       /* L (a stretched cell: Lx), mm */
  double lengths[3]; /* Lx, Ly, Lz, mm */
  double origin[3];  /* mm */
  double level;      /* c */
} gr_tpms_info;
int gr_field_tpms_info(const gr_field *f, gr_tpms_info *info);

/* ---- other kinds ---- */
/* Expression in x, y, z (mm) with pi, see expr.h. */
gr_field *gr_field_expr(const char *src, gr_err *e);
/* Constant field c everywhere (gradient 0). */
gr_field *gr_field_constant(double c);
/* Callback field. grad may be NULL: central differences are used then.
 * free_ud (may be NULL) is called on ud when the field is released. */
gr_field *gr_field_callback(gr_field_fn fn, gr_field_gradfn grad, void *ud,
                            void (*free_ud)(void *), int threadsafe,
                            const char *describe);
/* Combinations take new references to their arguments. */
gr_field *gr_field_min(gr_field *a, gr_field *b);       /* union */
gr_field *gr_field_max(gr_field *a, gr_field *b);       /* intersection */
gr_field *gr_field_negate(gr_field *a);                 /* complement */
/* (1-w) a + w b, w a field clamped to [0,1] (hybrid lattices). */
gr_field *gr_field_blend(gr_field *a, gr_field *b, gr_field *w);
gr_field *gr_field_translate(gr_field *a, const double d[3]); /* a(p - d) */
gr_field *gr_field_scale(gr_field *a, double s);              /* s*a(p/s) */

gr_field *gr_field_ref(gr_field *f);   /* returns f */
void gr_field_free(gr_field *f);       /* drops one reference; NULL is fine */
int gr_field_threadsafe(const gr_field *f);
/* The user data of a callback field made with `fn`, or NULL (lets the
 * owner of a callback kind reach its own state, e.g. offset warnings). */
void *gr_field_callback_data(const gr_field *f, gr_field_fn fn);
/* Upper bound on |grad phi| (INFINITY if unknown): d(p) >= |phi(p)|/K. */
double gr_field_lipschitz(const gr_field *f);
/* Set that bound (a callback field's maker, right after gr_field_callback,
 * before the field is shared; e.g. 1 for a signed distance). */
void gr_field_set_lipschitz(gr_field *f, double k);
/* Short text such as "primitive(L=2, level=0)". */
const char *gr_field_describe(const gr_field *f);

/* Evaluate at n points. NaN/inf results fail with GR_ENUM naming the point. */
int gr_field_eval(const gr_field *f, size_t n, const double *x,
                  const double *y, const double *z, double *out, gr_err *e);
int gr_field_grad(const gr_field *f, size_t n, const double *x,
                  const double *y, const double *z, double *gx, double *gy,
                  double *gz, gr_err *e);
/* Value and gradient together (TPMS fields share their sines and cosines). */
int gr_field_eval_grad(const gr_field *f, size_t n, const double *x, const double *y,
                       const double *z, double *out, double *gx, double *gy, double *gz, gr_err *e);
/* Value, gradient and Hessian at one point p, the Hessian by forward
 * differences of the gradient with step h (mm) along each axis: hs[a][c] =
 * (d_c f(p + h e_a) - d_c f(p)) / h. A TPMS takes the shifted sines and
 * cosines from p's by the angle-addition rule (one set of trigonometric calls
 * for all four gradients); other fields evaluate the gradient four times.
 * Errors as gr_field_eval_grad. */
int gr_field_hess_fd(const gr_field *f, const double p[3], double h, double *v, double g[3], double hs[3][3],
                     gr_err *e);
/* A point followed through small moves (closest-point Newton steps): a TPMS
 * keeps the sines and cosines of its phases and moves them by the
 * angle-addition rule instead of calling sin and cos again. */
typedef struct gr_field_at {
  double p[3];         /* the point, mm */
  double sn[3], cs[3]; /* sines and cosines of its phases (trig = 1) */
  int trig;            /* 1: a plain TPMS whose sn, cs are valid */
} gr_field_at;
/* gr_field_eval_grad at one point p, remembering p in *at. */
int gr_field_grad_at(const gr_field *f, const double p[3], double *v, double g[3], gr_field_at *at, gr_err *e);
/* The same at n points p (3 each) into v, g (3 each) and at (n): a TPMS's
 * sines and cosines of all of them at once (vecmath.h). */
int gr_field_grad_at_n(const gr_field *f, size_t n, const double *p, double *v, double *g, gr_field_at *at,
                       gr_err *e);
/* gr_field_hess_fd at p, remembering p in *at. */
int gr_field_hess_fd_at(const gr_field *f, const double p[3], double h, double *v, double g[3], double hs[3][3],
                        gr_field_at *at, gr_err *e);
/* A difference step h with, for a TPMS, the sines and cosines of its phase
 * per axis (the angle-addition factors gr_field_hess_fd_at takes): made
 * once for many Hessians with the same step. */
typedef struct gr_field_step {
  double h;
  double sn[3], cs[3];
} gr_field_step;
/* The step h of f (h > 0 and finite is checked when used). */
void gr_field_step_init(const gr_field *f, double h, gr_field_step *st);
/* gr_field_hess_fd_at with the step st (gr_field_step_init): the same values. */
int gr_field_hess_fd_step(const gr_field *f, const double p[3], const gr_field_step *st, double *v, double g[3],
                          double hs[3][3], gr_field_at *at, gr_err *e);
/* The Hessian at at->p (a point followed by gr_field_grad_at and
 * gr_field_move_grad), g the gradient there: the differences of
 * gr_field_hess_fd_step from the point's own sines and cosines (a TPMS: no
 * trigonometric call); other fields evaluate three gradients. */
int gr_field_hess_fd_moved(const gr_field *f, const gr_field_at *at, const gr_field_step *st, const double g[3],
                           double hs[3][3], gr_err *e);
/* Move *at (filled by gr_field_grad_at or gr_field_hess_fd_at) by dp (mm) and give the value
 * and gradient there (as gr_field_eval_grad at at->p + dp, to rounding). */
int gr_field_move_grad(const gr_field *f, gr_field_at *at, const double dp[3], double *v, double g[3], gr_err *e);

/* ---- sampling ---- */
/* Samples v[i + nx*(j + ny*k)] at (x0 + i*hx, y0 + j*hy, z0 + k*hz). */
typedef struct gr_grid3 {
  int nx, ny, nz;
  double x0, y0, z0, hx, hy, hz; /* mm */
  double *v;
} gr_grid3;
typedef struct gr_grid2 {
  int nx, ny;
  double x0, y0, hx, hy, z; /* mm; z is the plane's height */
  double *v;                /* v[i + nx*j] */
} gr_grid2;
/* n samples per axis (>= 2) spanning lo..hi inclusive. A grid too large for
 * memory is refused before allocating, with the estimate in the message. */
gr_grid3 *gr_grid3_sample(const gr_field *f, const double lo[3],
                          const double hi[3], const int n[3], gr_err *e);
gr_grid2 *gr_grid2_sample(const gr_field *f, double z, const double lo[2],
                          const double hi[2], const int n[2], gr_err *e);
void gr_grid3_free(gr_grid3 *g);
void gr_grid2_free(gr_grid2 *g);
/* The n[0] x n[1] samples of the plane at height z at (lo[0] + i*h[0],
 * lo[1] + j*h[1]) into out[i + n[0]*j] (caller's memory): the values
 * gr_field_eval gives at those points, bit for bit; a TPMS from one sine and
 * cosine per axis sample instead of three pairs per point. */
int gr_field_plane(const gr_field *f, double z, const double lo[2], const double h[2], const int n[2], double *out,
                   gr_err *e);

#endif
