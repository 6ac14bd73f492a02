/* solid.h: a part given as a closed triangle mesh (an STL file) made a field:
 * the signed distance to the mesh, negative inside, in mm, so that the part
 * can be the design domain of a placement job (place.h) or be combined with
 * any other field.
 *
 * Sign: by angle-weighted pseudo-normals (Baerentzen and Aanaes, 2005): the
 * sign of (p - q) . n, q the closest point of the mesh to p and n the
 * pseudo-normal of the feature q lies on: the face normal inside a face, the
 * sum of the two face normals on an edge, the sum of the face normals
 * weighted by their angles at a vertex. This is exact for a closed,
 * consistently oriented mesh that does not intersect itself, which is why
 * those are checked first. */
#ifndef GR_SOLID_H
#define GR_SOLID_H
#include "field.h"
#include "mesh.h"
#include "bvh.h"

/* The solid bounded by m (copied: m may be freed afterwards). The field is
 * thread-safe, has the analytic gradient (p - q)/|p - q| (signed) and the
 * Lipschitz bound 1.
 * Errors (GR_EARG/GR_EGEOM), each with the count and one example (the
 * coordinates of an edge or of a face's first vertex, the faces' numbers
 * 0-based):
 *  - an empty mesh, a non-finite vertex, a face naming a missing vertex;
 *  - degenerate faces (a repeated vertex, or zero area);
 *  - open edges (used by one face), non-manifold edges (more than two faces),
 *    edges traversed the same way by both of their faces (inconsistent
 *    orientation);
 *  - two faces that share no vertex and intersect (touching counts);
 *  - a mesh that encloses no volume.
 * A mesh whose normals all point inward (negative volume) is accepted: the
 * sign is flipped. */
gr_field *gr_solid_field(const gr_mesh *m, gr_err *e);

/* The parts of a solid field, borrowed (valid while f lives): its mesh and
 * BVH, unit face normals (3 per face), each face's planar patch (faces
 * joined across edges where their normals agree to 1e-12 in 1 - cos: the
 * number of the patch's lowest face) and, per face, bit k set when its edge
 * k (vertex k to k+1) bounds its patch (a crease of the surface). */
typedef struct gr_solid_view {
  const gr_mesh *m;
  const gr_bvh *bvh;
  const double *fn;
  const uint32_t *patch;
  const unsigned char *bmask;
} gr_solid_view;

/* 1 and v filled if f was made by gr_solid_field, else 0. */
int gr_solid_view_of(const gr_field *f, gr_solid_view *v);

#endif
