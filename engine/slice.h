/* slice.h: direct slicing of a field at a height into closed rings (marching
 * squares with crossings refined on the true field), slicing a mesh by a
 * plane, and the in-plane inward offset of a section (2-D distance field of
 * the section, marching squares at level -b: the paper's Fig. 8). */
#ifndef GR_SLICE_H
#define GR_SLICE_H
#include "field.h"
#include "mesh.h"
#include "paths.h"

/* Whether the zero set is smooth (its curvature continuous) between its
 * points a and b: no corner, no second branch (see gr_slice_opts). */
typedef int (*gr_slice_smooth_fn)(void *ud, const double a[2], const double b[2]);

typedef struct gr_slice_opts {
  double lo[2], hi[2]; /* window in the plane, mm */
  double cell;         /* marching-squares cell size, mm (> 0) */
  int refine;          /* 1: refine each edge crossing on the true field */
  double tol;          /* crossing tolerance, mm (default 1e-6) */
  double chord_tol;    /* > 0: insert refined midpoints where a chord is more
                          than chord_tol (mm) from the true zero set; 0 = off */
  /* gr_slice_grid only (NULL: every chord is checked on fn): where it says
   * the zero set is smooth between a chord's ends, a chord whose neighbours'
   * circles put it within chord_tol / 2 of the curve is not checked */
  gr_slice_smooth_fn smooth;
  /* gr_slice_grid only (0: off): values smaller than this (mm) in magnitude
   * are exact, so crossings may come from the nodes' cubic where its error
   * estimate is within tol (gr_ms_grid.exact) */
  double exact;
} gr_slice_opts;
gr_slice_opts gr_slice_defaults(void);

/* Eq. (7) of the paper, L <= n*d/2: the grid cell may be at most d/2 for
 * hatch spacing d. Returns that bound, mm. */
double gr_slice_max_cell(double hatch);
/* GR_OK if cell <= hatch/2 (eq. 7), else GR_EARG with the reason. */
int gr_slice_check_res(double cell, double hatch, gr_err *e);

/* Section {f < 0} of the plane z: closed, non-crossing rings, nested and
 * oriented (outer CCW, holes CW). Parts of the section touching the window
 * border are closed along the border. `out` is cleared first. */
int gr_slice_field(const gr_field *f, double z, const gr_slice_opts *o,
                   gr_rings *out, gr_err *e);

/* A scalar function of the plane at n points (negative = inside). */
typedef int (*gr_slice_fn)(void *ud, size_t n, const double *x, const double *y,
                           double *out, gr_err *e);
/* Value and in-plane gradient of such a function at n points. */
typedef int (*gr_slice_grad_fn)(void *ud, size_t n, const double *x, const double *y,
                                double *out, double *gx, double *gy, gr_err *e);
/* The window's grid: nx x ny nodes at (lo[0] + i*hx, lo[1] + j*hy), the last
 * ones exactly at hi. */
void gr_slice_grid_size(const gr_slice_opts *o, int *nx, int *ny, double *hx, double *hy);
/* As gr_slice_field from values already sampled at the window's grid nodes
 * (v[i + nx*j]); fn, the true function, refines crossings, saddles and chords;
 * gfn (optional: value and gradient) lets the refinement take Newton steps.
 * For callers that sample faster than point by point (shared closest points). */
int gr_slice_grid(const double *v, const gr_slice_opts *o, gr_slice_fn fn,
                  gr_slice_grad_fn gfn, void *ud, gr_rings *out, gr_err *e);

/* Mesh/plane intersection (the paper's Fig. 12 route): closed loops go to
 * `closed`, open polylines (the mesh boundary) to `open` as GR_OPEN blocks
 * (either may be NULL). Loops are oriented with the inside (the side the
 * normals point away from) on the left. */
int gr_slice_mesh(const gr_mesh *m, double z, gr_rings *closed,
                  gr_layer *open, gr_err *e);

/* Inward in-plane offset of the region bounded by `in` by distance b >= 0
 * (mm): every point of the result lies at distance b from the boundary of
 * `in`, inside it. cell is the grid cell of the 2-D distance field (mm).
 * Components narrower than 2b vanish; parts of the offset narrower than the
 * grid (walls just over 2b wide) are found and sampled finer. `out` is
 * cleared first. Crossings are refined on the exact polygon distance to
 * 1e-6 mm. */
int gr_offset_rings(const gr_rings *in, double b, double cell, gr_rings *out,
                    gr_err *e);
/* The chord tolerance of the engine's sections (mm): a chord deviates from
 * the true curve by at most this; refined midpoints are inserted where it
 * would not. */
#define GR_CHORD_TOL 2e-4
/* The crossing tolerance of the engine's sections (mm): a crossing on a
 * grid edge is refined (or taken from the nodes' cubic, whose error
 * estimate must be within it) to 10 nm, a twentieth of GR_CHORD_TOL. At
 * 1 nm (the slices' default) the cubic's estimate refused half the
 * crossings of a graded sheet's section, each then solved on the surface:
 * 4.5 % of a thin voxel-layer's instructions, for contours that moved by
 * under 10 nm. */
#define GR_CROSS_TOL 1e-5
/* The chord tolerance of in-plane offsets (contours, hatch regions; mm):
 * their vertices lie on the offset of the section's polygon, itself within
 * GR_CHORD_TOL of the true section, so a contour's chords lie within
 * GR_CHORD_TOL + GR_OFFSET_CHORD_TOL = 0.7 um of the true offset, inside
 * the contract's 1 um (measured: 0.66 um at most with points inside the
 * chords, doc/quality.md). 0.2 um here cost a sixth of a continuously graded
 * voxel-layer and an eighth of the periodic cube's time for 0.3 um. */
#define GR_OFFSET_CHORD_TOL 5e-4
/* The same with the crossing tolerance tol (mm, > 0), the chord option
 * chord_tol (mm, 0 = off) of gr_slice_opts, and box (x0 y0 x1 y1, mm, or
 * NULL: everywhere): parts narrower than the grid are looked for only
 * there (a template's window beyond its voxel needs no such care). */
int gr_offset_rings_opt(const gr_rings *in, double b, double cell, double tol,
                        double chord_tol, const double *box, gr_rings *out, gr_err *e);
/* The same, sampled first on a grid of coarse (>= 1) cells: where its
 * probes find a strip hidden between nodes, the grid is sampled again at
 * cell and refined from there as gr_offset_rings_opt's is. */
int gr_offset_rings_coarse(const gr_rings *in, double b, double cell, double coarse, double tol,
                           double chord_tol, const double *box, const double *cut, gr_rings *out, gr_err *e);
/* gr_offset_rings_opt and _coarse (chord_tol > 0) first try the offset
 * straight from the edges (gr_offset_rings_direct below: _opt keeps every
 * point, _coarse, the templates', simplifies and takes the cut) and sample
 * the grid only where it declines; this one always samples the grid (the
 * reference the tests compare the direct offset with). */
int gr_offset_rings_grid(const gr_rings *in, double b, double cell, double coarse, double tol,
                         double chord_tol, const double *box, gr_rings *out, gr_err *e);

/* The same straight from the edges of nested rings `in` (offsetdirect.c):
 * each edge moved by b, convex corners mitred, arcs around reflex vertices
 * as chords within chord_tol (> 0). box (x0 y0 x1 y1, or NULL): where the
 * offset is needed; rings lying wholly farther than 2b outside it, whose
 * offsets cannot reach it, are left out. cut (x0 y0 x1 y1, or NULL): the
 * rectangle a window's section was cut to; its edges along the rectangle
 * are no walls (the part goes on beyond) and move out by 2b (the offset
 * differs from the grid's only beyond the window's sides). Where no
 * two raw segments meet (tested in buckets of `bucket` mm), the rings of
 * positive winding number are the offset: into out (not nested), *done =
 * 1; simplify: 1 to drop the points not needed (arcs' chords to 0.4 and
 * the rings' simplification to 0.6 of chord_tol; 0: every point kept, on
 * the offset of every vertex of `in`, arcs to chord_tol, as a caller
 * sorting points by their nearest boundary point needs). Otherwise (a wall narrower than 2b, an offset closing over a tip)
 * *done = 0 and out is untouched. */
int gr_offset_rings_direct(const gr_rings *in, double b, double chord_tol, double bucket, const double *box,
                           const double *cut, int simplify, gr_rings *out, int *done, gr_err *e);

/* Largest in-plane distance from a point of the region to its boundary
 * (the inradius of the widest component), sampled on a grid of `cell` mm,
 * so exact to within about cell. A region with value < b is a thin wall for
 * beam offset b (its offset by b is empty). Returns -1 on error (e filled). */
double gr_rings_max_inner_distance(const gr_rings *in, double cell, gr_err *e);

/* Exact in-plane distance to the edges of nested, oriented rings (bucketed;
 * the same distance the offsets use). */
typedef struct gr_polydist gr_polydist;
/* NULL on error (e filled). rings must be nested (gr_rings_nest); bucket is
 * the edge bucket size, mm (0: a sixteenth of the rings' extent). */
gr_polydist *gr_polydist_new(const gr_rings *nested, double bucket, gr_err *e);
void gr_polydist_free(gr_polydist *d); /* NULL is fine */
/* Signed distance of (x, y) to the boundary (negative inside); q (may be
 * NULL) receives the nearest boundary point. +INFINITY without edges. */
double gr_polydist_at(const gr_polydist *d, double x, double y, double q[2]);
/* 1 if some boundary point is within r of (x, y), i.e. |gr_polydist_at| <= r,
 * else 0; stops at the first edge found (cheaper than the distance). hint
 * (or NULL): an edge index tried first, set to the edge found (queries along
 * a curve mostly find the previous query's edge). */
int gr_polydist_within(const gr_polydist *d, double x, double y, double r, size_t *hint);
/* Signed distances at the nodes (x0 + i h, y0 + j h), i < nx, j < ny, into
 * v[i + nx j]; |values| beyond rmax are clamped to rmax (sign exact). */
int gr_polydist_grid(const gr_polydist *d, double x0, double y0, double h, int nx, int ny,
                     double rmax, double *v, gr_err *e);

#endif
