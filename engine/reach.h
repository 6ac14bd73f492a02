/* reach.h: the local reach of a periodic surface (a primitive under the
 * offset field, distance.h).
 *
 * A point p whose local closest point q on H (found by Newton from a hint,
 * on q's own patch) lies nearer than the cut distance t*(q) -- how far along
 * q's normal a point keeps q as its closest point -- has q as its closest
 * point: no other patch of H can be nearer. The surface's reach is the
 * smallest t* over all of H; thick sheets lie beyond it, yet far from the
 * necks t* is several times larger. This table holds a lower estimate of t*
 * near each point of one period of H, so that a point beyond the reach but
 * within its local value skips the search of H for a nearer patch.
 *
 * Takes: points of H (on the exact surface) with unit normals, the closest
 * point of H to any point (a callback), one period box. Gives: per cell of a
 * grid over the period (cells of the points' spacing, at least 1/64 of the
 * period), the smallest t* (either side, capped) of the points in
 * the cell and its 26 neighbours (wrapped) less a margin for what t* may
 * lose between samples (reach.c), 0 where no point is near. */
#ifndef GR_REACH_H
#define GR_REACH_H
#include "common.h"

/* The closest point q of H to p (1), or 0 when none was found. Called from
 * several threads at once when threads > 1. */
typedef int (*gr_reach_foot)(void *ud, const double p[3], double q[3]);

typedef struct gr_reach gr_reach;

/* The table over the period box [lo, lo + period) from nv points s (3 each,
 * on H) with unit normals nrm (3 each), every point of H within `spacing`
 * (mm) of one of them; t* measured up to cap (mm); a foot counts as s itself
 * when within eps (mm). Errors: out of memory, a non-positive period, cap
 * or spacing. */
gr_reach *gr_reach_new(const double lo[3], const double period[3], double cap, double eps, double spacing, size_t nv,
                       const double *s, const double *nrm, gr_reach_foot foot, void *ud, int threads, gr_err *e);
/* The lower estimate of t* at a point q of H, either side (mm; 0: none
 * known). */
double gr_reach_at(const gr_reach *r, const double q[3]);
/* The cut distance t* of the point s of H with unit normal n, on the side
 * sg (+1 along n, -1 against), up to cap: the largest r (within 1 % or
 * eps) for which s is the closest point of s + sg r n. 0 when unknown. */
double gr_reach_cut(gr_reach_foot foot, void *ud, const double s[3], const double n[3], int sg, double cap,
                    double eps);
/* The same by bisection over [0, top] (steps halvings, or until the
 * interval is below tol): the largest r found for which s keeps its foot,
 * top itself when it keeps it at top. */
double gr_reach_bisect(gr_reach_foot foot, void *ud, const double s[3], const double n[3], int sg, double top,
                       double tol, int steps, double eps);
void gr_reach_free(gr_reach *r);

#endif
