/* slice.h: direct slicing of a field at a height into closed rings (marching
 * squares with crossings refined on the true field), slicing a mesh by a
 * plane, and the in-plane inward offset of a section (2-D distance field of
 * the section, marching squares at level -b: the paper's Fig. 8). */
#ifndef GR_SLICE_H
#define GR_SLICE_H
#include "field.h"
#include "mesh.h"
#include "paths.h"

typedef struct gr_slice_opts {
  double lo[2], hi[2]; /* window in the plane, mm */
  double cell;         /* marching-squares cell size, mm (> 0) */
  int refine;          /* 1: refine each edge crossing on the true field */
  double tol;          /* crossing tolerance, mm (default 1e-6) */
} gr_slice_opts;
gr_slice_opts gr_slice_defaults(void);

/* Eq. (7) of the paper, L <= n*d/2: the grid cell may be at most d/2 for
 * hatch spacing d. Returns that bound, mm. */
double gr_slice_max_cell(double hatch);

/* Section {f < 0} of the plane z: closed, non-crossing rings, nested and
 * oriented (outer CCW, holes CW). Parts of the section touching the window
 * border are closed along the border. `out` is cleared first. */
int gr_slice_field(const gr_field *f, double z, const gr_slice_opts *o,
                   gr_rings *out, gr_err *e);

/* Mesh/plane intersection (the paper's Fig. 12 route): closed loops go to
 * `closed`, open polylines (the mesh boundary) to `open` as GR_OPEN blocks. */
int gr_slice_mesh(const gr_mesh *m, double z, gr_rings *closed,
                  gr_layer *open, gr_err *e);

/* Inward in-plane offset of the region bounded by `in` by distance b >= 0
 * (mm): every point of the result lies at distance b from the boundary of
 * `in`, inside it. cell is the grid cell of the 2-D distance field (mm).
 * Components narrower than 2b vanish. `out` is cleared first. */
int gr_offset_rings(const gr_rings *in, double b, double cell, gr_rings *out,
                    gr_err *e);

#endif
