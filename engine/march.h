/* march.h: marching squares with refined crossings, the primitive under
 * field sections (slice.h) and 2-D offsets of sections (polydist.c).
 * Internal to the engine.
 *
 * Takes: values of a function sampled on a regular grid (inside: < 0) and
 * the function itself. Gives: the closed rings of {f < 0}, inside on the
 * left, with crossings refined on the function (Illinois or Newton) and
 * chords refined until they deviate less than chord_tol from the curve. */
#ifndef GR_MARCH_H
#define GR_MARCH_H
#include "slice.h"
#include <stdint.h>
#include <string.h>

#define MS_CHUNK 65536
#define MS_MAX_NODES ((size_t)1 << 27)

/* A grid of nx*ny samples v[i + nx*j] at (x0 + i*hx, y0 + j*hy); inside is
 * v < 0. The grid is padded (conceptually) by one ring of outside nodes
 * placed at the positions of the border nodes, so that regions touching the
 * window are closed along its border with no extra code. */
typedef struct gr_ms_grid {
  int nx, ny;
  double x0, y0, hx, hy;
  const double *v;
  /* > 0: the values smaller than this in magnitude are fn's own (not
   * bounds or blends), and fn is smooth enough along grid lines that a
   * crossing whose six nodes along its line are all such may be taken from
   * their cubic (gr_ms_contour); 0: every crossing is refined on fn */
  double exact;
} gr_ms_grid;

/* The chord pass's window: with `on`, a segment along the window border
 * [lo, hi] is exact; reach (mm, 0: none) bounds how far from a chord a
 * corner it cut off is looked for (four cells of the grid contoured), and
 * how far a tip is followed; tips = 1: tips of slivers are followed along
 * the field's crest to their end (tips.c; field sections, not offsets). */
typedef struct gr_ms_win {
  int on;
  double lo[2], hi[2], reach;
  int tips;
  gr_slice_smooth_fn smooth; /* or NULL: gr_slice_opts.smooth, with fn's ud */
} gr_ms_win;

/* Where the line through p0, a meets the line through b, p1 (NaN when they
 * are near parallel): the corner a chord a-b may have cut off. */
void gr_ms_chord_corner(const double *p0, const double *a, const double *b, const double *p1, double c[2]);
/* Parts of the zero set hidden between nodes of one sign (hidden.c): where
 * probes of suspect edges find the other sign by more than 1 um, g is
 * sampled again 2x finer near the zero set (up to twice); *g then describes
 * the finer grid, whose values *owned holds (the caller frees it; NULL when
 * g was not refined). lip > 0: a bound on fn's slope (1 for distances:
 * fewer edges are suspect), 0: none. box (x0 y0 x1 y1, or NULL: all): only
 * edges within a cell of it are probed. */
int gr_ms_unhide(gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, double **owned, gr_err *e);
/* Only the probes of gr_ms_unhide's first level: *hidden = 1 where they
 * find a part of the zero set hidden between nodes (g left as it is). */
int gr_ms_hidden(const gr_ms_grid *g, double lip, const double *box, gr_slice_fn fn, void *ud, int *hidden, gr_err *e);
/* Evaluate fn at n points in chunks (keeps scratch buffers of callers small). */
int gr_ms_eval(gr_slice_fn fn, void *ud, size_t n, const double *x, const double *y, double *out, gr_err *e);
/* Contour {fn < 0} from the sampled grid: crossings on grid edges refined on
 * fn, saddles decided by fn at the cell centre, segments oriented with the
 * inside on the left and chained by edge id into closed rings (appended to
 * out, not nested). */
int gr_ms_contour(const gr_ms_grid *g, gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, int refine,
                  double tol, gr_rings *out, gr_err *e);
/* Chord accuracy pass over the rings of r (rewritten); w: the window whose
 * border segments are exact; with w->tips, tips of slivers are then followed
 * to their end (gr_ms_follow_tips) and the new chords checked. */
int gr_ms_chord_refine(gr_rings *r, gr_slice_fn fn, gr_slice_grad_fn gfn, void *ud, double tol,
                       double chord_tol, const gr_ms_win *w, gr_err *e);
/* Tips of slivers narrower than the chords, grown along the crest of the
 * field to where it closes them (tips.c): run after the chord pass; *okp
 * (the chord pass's checked-chord marks, one per point) is replaced, new
 * chords unchecked; *grown counts the tips that grew. */
int gr_ms_follow_tips(gr_rings *r, unsigned char **okp, gr_slice_fn fn, void *ud, double tol, const gr_ms_win *w,
                      size_t *grown, gr_err *e);
/* Whether segments a-b and c-d cross at a point inside both. */
int gr_ms_seg_cross(const double *a, const double *b, const double *c, const double *d);
/* Append the ring xy (n points; consecutive duplicates removed) to out if it
 * keeps >= 3 points and nonzero area. */
int gr_ms_emit_ring(gr_rings *out, double *xy, size_t n);
/* A slice window [lo, hi] with grid spacing cell and tolerance tol: errors
 * name the bad value; too many nodes is GR_EMEM. */
int gr_ms_check_window(const double lo[2], const double hi[2], double cell, double tol, gr_err *e);

/* Eight bytes of per-node flags from p as one word (any alignment), for
 * the scans that test eight nodes at once (march.c, hidden.c, cptab.c). */
static inline uint64_t gr_ms_word(const unsigned char *p) {
  uint64_t w;
  memcpy(&w, p, sizeof w);
  return w;
}

#endif
