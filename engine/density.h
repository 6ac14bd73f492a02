/* density.h: design by relative density. For a TPMS surface H (catalogue
 * name and level) the signed distance sd to H is sampled over one unit cell
 * (exact closest points, the offset field of distance.h); its distribution
 * gives the relative density of every offset solid of that surface:
 *   sheet            rho(T) = P(|sd| <= T)
 *   asymmetric sheet rho(T) = P(-r T <= sd <= T)   (inside thickness r T)
 *   network          rho(T) = P(sd <= T)            (side +1: P(sd >= -T))
 * rho depends on T / L only (distances scale with the cell), so one table per
 * (surface, level, side) serves every cell size. A gr_dtable is immutable
 * after construction (thread-safe); it maps density to half-thickness T by
 * monotone piecewise-linear inversion. */
#ifndef GR_DENSITY_H
#define GR_DENSITY_H
#include "common.h"

enum { GR_DENS_SHEET = 0, GR_DENS_NETWORK = 1 };

typedef struct gr_dtable_opts {
  const char *surface; /* catalogue name (field.h) */
  double level;        /* c */
  int kind;            /* GR_DENS_SHEET / GR_DENS_NETWORK */
  int side;            /* network: -1 (phi < c, default) or +1 */
  double ratio;        /* sheet: inside thickness / outside thickness (1) */
  double cell;         /* L, mm */
  double track;        /* melt track width, mm: thinnest wall and pore (> 0) */
  int res;             /* samples per cell edge for the calibration (128) */
  const char *cache;   /* directory for calibration files, NULL or "": none */
  int clamp;           /* 1: out-of-range targets are clamped, else refused */
} gr_dtable_opts;
gr_dtable_opts gr_dtable_defaults(void);

typedef struct gr_dtable gr_dtable;
/* Calibrate (or read the cached calibration of) the surface. Errors: unknown
 * surface, bad cell/track/res/ratio (GR_EARG naming the option), unreadable
 * cache (GR_EPARSE naming the file; a damaged cache file is recomputed). */
gr_dtable *gr_dtable_new(const gr_dtable_opts *o, gr_err *e);
gr_dtable *gr_dtable_ref(gr_dtable *t);
void gr_dtable_free(gr_dtable *t); /* drops one reference; NULL is fine */

/* Relative density of the offset solid with half-thickness T (mm). */
double gr_dtable_rho(const gr_dtable *t, double T);
/* Half-thickness T (mm) with density rho: monotone inverse of
 * gr_dtable_rho, clamped to [0, L/2]. */
double gr_dtable_thickness(const gr_dtable *t, double rho);
/* Reachable densities with walls and pores at least one track wide, and the
 * thickness range (mm) that gives them. */
void gr_dtable_range(const gr_dtable *t, double *rho_lo, double *rho_hi, double *t_lo, double *t_hi);
/* Check a target at point p: GR_OK when reachable (or the table clamps),
 * else GR_EARG "density 0.03 at x=.. y=.. z=..: gyroid sheet, L=2 mm,
 * reachable 0.08..0.86 with a 0.07 mm track". what = "density"/"porosity"
 * (for porosity the message gives 1 - rho and the reachable porosities). */
int gr_dtable_check(const gr_dtable *t, double rho, const double p[3], const char *what, gr_err *e);
/* In place: density values -> half-thickness (clamped to the reachable range
 * when clamping, else to [0, L/2]; NaN stays NaN). */
void gr_dtable_apply(const gr_dtable *t, size_t n, double *v);
/* Inside / outside thickness ratio of an asymmetric sheet (1 otherwise). */
double gr_dtable_ratio(const gr_dtable *t);
/* "gyroid sheet, level 0, L=2" plus the calibration: a key for signatures. */
const char *gr_dtable_key(const gr_dtable *t);
/* Largest signed distance on each side over the cell, as fractions of L:
 * sd ranges over [-lo, hi]. */
void gr_dtable_extent(const gr_dtable *t, double *lo, double *hi);

/* Achieved density per voxel from closed contours: the area of rings
 * (counter-clockwise positive, holes clockwise) inside the rectangle
 * [lo, hi] (mm^2), by clipping every ring to it. xy: 2n coordinates of a
 * closed ring (first point not repeated or repeated: both fine). */
double gr_ring_area_in_box(const double *xy, size_t n, const double lo[2], const double hi[2]);


/* Solid volume per voxel from the closed contours of a CLI file: for each
 * layer, the signed area of its contour rings inside each voxel's square
 * times the layer thickness; with a beam offset b > 0 the rings are grown
 * back by b (Steiner: area + b * perimeter + pi b^2 per outer ring, less per
 * hole). Needs one contour per boundary. vol: n[0]*n[1]*n[2] values (mm^3),
 * voxel (i,j,k) at i + n0*(j + n1*k). Errors name the file (gr_cli_read). */
typedef struct gr_achieved_opts {
  double origin[3];   /* voxel grid corner, mm */
  double cell;        /* voxel size L, mm */
  int n[3];           /* voxels per axis */
  double layer;       /* layer thickness t, mm */
  double beam_offset; /* contour offset b, mm */
} gr_achieved_opts;
int gr_density_achieved(const char *cli, const gr_achieved_opts *o, double *vol, gr_err *e);

#endif
