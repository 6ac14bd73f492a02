/* bvh.h: closest points on triangle meshes (a bounding-volume hierarchy),
 * the primitive under the offset field (distance.h) and the STL domain
 * (solid.h). Takes a mesh; gives the closest point of the mesh to any point. */
#ifndef GR_BVH_H
#define GR_BVH_H
#include "mesh.h"

static inline double gr_dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

typedef struct gr_bvh gr_bvh;
/* Build over m (which must outlive the BVH). Empty meshes and NaN vertices
 * are GR_EARG/GR_EGEOM errors naming the vertex. */
gr_bvh *gr_bvh_new(const gr_mesh *m, gr_err *e);
void gr_bvh_free(gr_bvh *b);
typedef struct gr_hit {
  double q[3];   /* closest point, mm */
  double dist;   /* unsigned distance, mm */
  long tri;      /* triangle index, -1 when nothing within the cut-off */
} gr_hit;
/* Closest point of the mesh to p within maxdist (INFINITY: no cut-off). */
int gr_bvh_closest(const gr_bvh *b, const double p[3], double maxdist, gr_hit *h);
/* The same among the mesh's points at least r from c (another patch of the
 * surface than the one around c). */
int gr_bvh_closest_away(const gr_bvh *b, const double p[3], double maxdist, const double c[3], double r, gr_hit *h);
/* The triangles holding a point within r of p, at most cap, into out[]:
 * nearest to p first; their count, or -1 when there are more than cap
 * (at most GR_BVH_NEAR_MAX). A point whose closest
 * point lies within r - |p - x| of x has it on one of these, so
 * gr_bvh_closest_among over them answers for every point x of a small
 * group about p. */
#define GR_BVH_NEAR_MAX 64
int gr_bvh_near(const gr_bvh *b, const double p[3], double r, uint32_t *out, int cap);
/* Closest point of the mesh to p among the n triangles tri[] (the same
 * arithmetic as gr_bvh_closest: the same point when they hold it). */
void gr_bvh_closest_among(const gr_bvh *b, const uint32_t *tri, int n, const double p[3], gr_hit *h);
/* Exact closest point of triangle abc to p. */
void gr_closest_on_triangle(const double p[3], const double a[3], const double b[3],
                            const double c[3], double q[3]);

#endif
