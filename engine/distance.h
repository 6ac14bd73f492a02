/* distance.h: the graded offset field of the paper's section 3.3
 * (doc/contract.md s.3), over closest points on H (bvh.h):
 *   sheet:   g(p) = d(p) - T(q(p))      network: g(p) = sd(p) - T(q(p))
 * q(p) the closest point of H (the marching-cubes mesh of phi = 0), d its
 * distance, sd = +d where phi > 0 and -d elsewhere, T the graded
 * half-thickness at q. Mode `mesh` uses the mesh closest point (the paper);
 * mode `exact` refines it onto the analytic surface phi = 0 by constrained
 * Newton steps. Thread-safe after construction. */
#ifndef GR_DISTANCE_H
#define GR_DISTANCE_H
#include "field.h"
#include "bvh.h"
#include "mesh.h"
#include "density.h"

enum { GR_OFFSET_SHEET = 0, GR_OFFSET_NETWORK = 1 };
enum { GR_DIST_MESH = 0, GR_DIST_EXACT = 1 };

typedef struct gr_offset_opts {
  gr_field *surface;          /* phi, zero set H (a reference is taken) */
  double cell[3];             /* Lx, Ly, Lz, mm (for u, v, w; the thickness bound is
                                 half the smallest) */
  double origin[3];           /* cell grid origin, mm */
  double box_lo[3], box_hi[3];/* where the field will be evaluated, mm */
  double margin;              /* extra evaluation margin around the box, mm */
  int res;                    /* marching-cubes samples per cell edge for H */
  int voxel;                  /* 1: the field is the voxel [box_lo, box_lo + cell] (a template):
                                 u, v, w relative to it; 0: relative to the voxel of the
                                 cell grid (origin, cell) that holds the point p */
  double thickness;           /* constant T (used when thickness_expr is NULL) */
  const char *thickness_expr; /* T in x,y,z,u,v,w,L,Lx,Ly,Lz (copied) */
  const char *inside_expr;    /* inside T for asymmetric sheets, or NULL */
  gr_field *thickness_field;  /* T as a field of q's global x, y, z (e.g. a Lua
                                 function), used when thickness_expr is NULL */
  int kind;                   /* GR_OFFSET_SHEET / GR_OFFSET_NETWORK */
  int side;                   /* network: -1 grows phi < 0 (default), +1 phi > 0 */
  int mode;                   /* GR_DIST_MESH / GR_DIST_EXACT */
  const gr_mesh *mesh;        /* use this H instead of meshing (must outlive the field) */
  gr_field *like;             /* share H and its BVH with this offset field of the same
                                 surface (a reference is taken), translated by like_shift
                                 (a lattice vector, mm); its box must cover this one's */
  double like_shift[3];
  gr_dtable *density;         /* or NULL; else the thickness values above are relative
                                 densities, turned into T by this table (a reference is
                                 taken; the inside pass gets ratio * T) */
  int threads;                /* threads for meshing H and its checks (<= 1: the calling
                                 thread only); the field is the same either way */
  int periodic;               /* 1: phi repeats with period cell along each axis (a TPMS):
                                 exact mode keeps a table of H's local reach over one
                                 period (reach.h), shared with fields made `like` this */
} gr_offset_opts;
gr_offset_opts gr_offset_defaults(void);

/* The foot point q relative to the voxel with centre c (mm) and lengths
 * L[3], each axis normalised to [-1, 1] and clamped: the u, v, w of
 * voxel-owned grading. */
void gr_offset_uvw(const double q[3], const double c[3], const double L[3], double uvw[3]);

/* A thickness expression in x, y, z, u, v, w with the constants L (the
 * smallest cell length), Lx, Ly, Lz (mm); NULL + e when it does not compile. */
struct gr_expr *gr_offset_thickness_expr(const char *src, const double cell[3], gr_err *e);

/* The offset field (a gr_field usable everywhere). Thickness errors
 * (negative, NaN, over half the cell) are GR_EARG naming the value and the
 * point. */
gr_field *gr_offset_field_new(const gr_offset_opts *o, gr_err *e);

/* Warning text of an offset field ("" when none, or when f is not one): the
 * thickness is large enough that offset sheets of neighbouring parts touch,
 * with where. */
const char *gr_offset_warning(const gr_field *f);

/* Largest T over H's vertices (mm), or -1 when f is not an offset field. */
double gr_offset_max_thickness(const gr_field *f);

/* Closest points of H to n points within dmax (mm) of H, refined onto phi = 0
 * in exact mode: q (3n, mm) and the signed distance sd (n, + where phi > 0).
 * Points farther than dmax get q = NaN and sd = +-(a lower bound >= dmax).
 * With gr_offset_values, these give the field's value for any thickness of
 * the same surface: closest points are shared by fields differing only in T. */
int gr_offset_closest(const gr_field *f, size_t n, const double *x, const double *y,
                      const double *z, double dmax, double *q, double *sd, gr_err *e);
/* The same for points in rows of `row` points (a grid, row by row): a
 * point whose predecessor has no closest point starts from the one a row
 * before (0: no rows). */
int gr_offset_closest_rows(const gr_field *f, size_t n, size_t row, const double *x, const double *y,
                           const double *z, double dmax, double *q, double *sd, gr_err *e);
/* Values of offset field f from closest points and signed distances (from
 * gr_offset_closest of any offset field of the same surface): g = d - T(q)
 * (sheet) or sd - T(q) (network); q = NaN gives a bound of the right sign.
 * gr_offset_closest accepts local answers up to twice H's error bound
 * (gr_offset_herr) too long: where |g| is within that, the caller checks q
 * with gr_offset_strict and evaluates again. */
int gr_offset_values(const gr_field *f, size_t n, double *q, double *sd, double *out, gr_err *e);
/* The same, points with |sd| > band (mm) taken as far (a bound of the right
 * sign, as for q = NaN) without evaluating T there: the caller's nodes whose
 * value is read only for its sign, without copying q. */
int gr_offset_values_band(const gr_field *f, size_t n, const double *q, const double *sd, double band, double *out,
                          gr_err *e);
/* The thickness T[i] that makes offset field f's value v[i] at a point of
 * signed distance sd[i] (the distance part less the value), n points; NaN
 * where |sd| > band (mm: the values there are bounds, as
 * gr_offset_values_band takes them) or when f is not an offset field. */
void gr_offset_implied_thickness(const gr_field *f, size_t n, const double *sd, const double *v, double band,
                                 double *T);
/* H's error bound of offset field f (half a mesh spacing, mm), or -1 when
 * f is not one. */
double gr_offset_herr(const gr_field *f);
/* H's reach (mm): a point nearer to H than this has one closest point, and
 * the strict check (gr_offset_strict) keeps it. 0 in mesh mode or when f is
 * not an offset field. */
double gr_offset_reach(const gr_field *f);
/* Below what distance from q (a point of H) a point along q's normal (either
 * side) keeps q as its closest point (mm): H's reach, or the larger local
 * reach at q (fields made with `periodic`, and those sharing their H; the
 * table is made on first use). -1 when f is not an offset field. */
double gr_offset_keeps_foot(const gr_field *f, const double q[3]);
/* A lower bound of offset field f's value at a point at least dlb (mm) from
 * its surface, for a sheet: dlb less its thickness when that is constant
 * (its value at H's vertices), or less the graded thickness's bound (the largest T over H's vertices with a 20 %
 * reserve and two mesh spacings, as the field's own far values take it);
 * -INFINITY for a network (or not an offset field), whose value inside is
 * negative however far. */
double gr_offset_value_floor(const gr_field *f, double dlb);
/* Whether offset field f's thickness is smooth along H (exact mode; a
 * thickness expression of x, y, z without abs, min, max or floor, or a
 * constant): its sections' boundaries then turn without corners wherever
 * the closest points do not jump. 0 when f is not an offset field. */
int gr_offset_smooth_thickness(const gr_field *f);
/* The strict check for one point p with closest point q (in place) and
 * signed distance sd (in place): where a patch of H is
 * nearer than q by more than 0.1 um (also one within twice the mesh's
 * measured error, away from q's own patch), it is refined and taken when
 * nearer. Depends on p, q and the surface only, not on T. Exact mode (a
 * no-op in mesh mode or for q = NaN). With `local`, H's local reach may
 * spare the search where it holds (the table made when first needed;
 * gr_offset_uses_local_reach); the answer can differ from one without it in
 * the last bits. */
int gr_offset_strict(const gr_field *f, const double p[3], double q[3], double *sd, int local, gr_err *e);
/* Whether offset field f uses H's local reach (its thickness reaches H's
 * reach somewhere); 0 when f is not an offset field. */
int gr_offset_uses_local_reach(const gr_field *f);
/* f at n points, each closest point found by refining hints (nh per point,
 * 3 nh n values, mm; closest points of nearby points, e.g. the grid
 * neighbours) instead of searching the mesh: each hint is refined on its own
 * patch and the nearest answer taken; NaN or non-converging hints are
 * skipped, and with none left the mesh is searched. The answer's patch is
 * checked: where H comes nearer than it (by more than 0.1 um), that part is
 * refined and taken when nearer (so hints from across the medial surface do
 * no harm).
 * grad (3n, or NULL): the gradient of the distance part (NaN on H). */
int gr_offset_eval_near(const gr_field *f, size_t n, const double *x, const double *y,
                        const double *z, const double *hint, int nh, double *out, double *grad, gr_err *e);
/* f at n points from predicted closest points pred (3n, mm; NaN: none),
 * exact mode: each prediction is projected onto phi's tangent plane (twice
 * at most) and accepted where the projection's move bounds the distance's
 * error below 1e-8 L and the distance is within H's reach (no other patch
 * can be nearer). out[i] = NaN where not accepted: solve those with
 * gr_offset_eval_near. grad as there. */
int gr_offset_eval_model(const gr_field *f, size_t n, const double *x, const double *y, const double *z,
                         const double *pred, double *out, double *grad, gr_err *e);

#endif
