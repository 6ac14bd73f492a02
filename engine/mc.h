/* mc.h: marching cubes from a sampled grid to an indexed triangle mesh. */
#ifndef GR_MC_H
#define GR_MC_H
#include "field.h"
#include "mesh.h"

/* Extract {v = iso}. Shared vertices (one per crossed grid edge, none
 * duplicated), crack-free (ambiguous faces decided by a rule that depends on
 * the face alone, so neighbouring cubes agree), faces oriented so normals
 * point to v > iso; open where the surface leaves the grid. A sample equal to
 * iso counts as positive. */
gr_mesh *gr_mc(const gr_grid3 *g, double iso, gr_err *e);

/* Sample f over lo..hi with n[i] samples per axis and extract its zero set,
 * refining each edge crossing on the field itself (secant/bisection) when
 * refine != 0 instead of linear interpolation only. */
gr_mesh *gr_mc_field(const gr_field *f, const double lo[3], const double hi[3],
                     const int n[3], int refine, gr_err *e);
/* The same, the samples taken on `threads` threads when f is thread-safe
 * (gr_field_threadsafe; else on the calling thread): the same mesh as
 * gr_mc_field's. */
gr_mesh *gr_mc_field_mt(const gr_field *f, const double lo[3], const double hi[3],
                        const int n[3], int refine, int threads, gr_err *e);

#endif
