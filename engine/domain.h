/* domain.h: a design domain's field made a signed distance in mm (a primitive
 * of the placement job, place.h).
 *
 * Takes: a domain field f (negative inside, any scale: an expression such as
 * (x-5)^2+(y-5)^2-16 is fine), the band (mm) within which distances must be
 * exact (the skin and the contour margin), and the cell edge L (mm, the scale
 * of tolerances). Gives: a field whose value is the signed distance to the
 * zero set of f (mm, the sign of f) within the band, so that skin depths and
 * inside/outside tests are in millimetres whatever the expression's scale.
 *
 * How: the first-order estimate f/|grad f| filters the points; those below
 * the band are projected onto f = 0 by iterating q <- p - ((f(q) + grad
 * f(q).(p - q)) / |grad f(q)|^2) grad f(q) (Newton's step onto the surface
 * and the move to p's foot on the tangent plane in one: at the fixed point
 * f(q) = 0 and p - q is parallel to grad f(q)), all points of a batch
 * together; the distance is |p - q| with the sign of f(p). Farther points
 * keep the estimate (at least the band): only their sign matters. The
 * gradient is the field's own (central differences for an expression).
 * Given the part's box, a field that is not a distance also gets its zero
 * set meshed (marching cubes over the box grown by the band): the mesh says
 * whether the boundary is within the band and seeds a second projection
 * from its closest point, which finds the nearest branch where f is the max
 * or min of terms of different scales; the mesh distance stands where no
 * projection lands near it (edges and corners of the zero set). */
#ifndef GR_DOMAIN_H
#define GR_DOMAIN_H
#include "field.h"

/* The true-distance field of domain f (a new reference). A field that is a
 * distance already (Lipschitz bound <= 1, e.g. an STL solid or a sphere; or,
 * when box = {x0, y0, z0, x1, y1, z1} mm is given, a gradient of length 1 at
 * 99 % of 1000 probes spread over the box, as for planes and spheres joined
 * by min, max and abs) is returned as it is (a new reference): wrapping such
 * a field would gain nothing and its creases defeat the projection. box may
 * be NULL. band > 0, L > 0 (mm). Errors of f
 * (NaN, a point where it is not finite) are reported by evaluation with
 * "domain" in the message. NULL and GR_EMEM in e when out of memory. */
gr_field *gr_domain_distance(gr_field *f, double band, double L, const double *box, gr_err *e);

/* The part of a trimmed voxel: its lattice field g cut by the domain d
 * (negative inside), with a solid skin of depth `skin` (mm, 0: none) along
 * d's boundary: max(d, min(g, -d - skin)), or max(g, d) without a skin; g
 * and d evaluated once per point (new references taken). NULL and GR_EMEM in
 * e when out of memory. */
gr_field *gr_domain_trim(gr_field *g, gr_field *d, double skin, gr_err *e);

/* 1 if d is such a true-distance wrapper. */
int gr_domain_is_distance(const gr_field *d);

/* 1 and g, d and skin (borrowed) if f was made by gr_domain_trim, else 0. */
int gr_domain_trim_parts(const gr_field *f, const gr_field **g, const gr_field **d, double *skin);

/* Trim n values of the lattice field in place, given the domain's values dv:
 * v <- max(d, min(v, -d - skin)) (skin > 0) or max(v, d), as gr_domain_trim
 * does; sel (may be NULL) gets 0 where v decides, 1 where d does, 2 where
 * -d - skin does. */
void gr_domain_trim_apply(size_t n, double *v, const double *dv, double skin, unsigned char *sel);

/* The domain d at the nodes (x0 + i hx, y0 + j hy, z), i < nx, j < ny, into
 * dv[i + nx j] (mm), evaluated only near its boundary: one sample at the
 * centre of each block of 4 x 4 nodes (not evaluated either where the last
 * one evaluated in its row bounds it) and d's Lipschitz bound K (known: 1
 * for an STL solid; 1 for gr_domain_distance's wrapper, whose values hold to
 * its band, when it has its zero-set mesh (without: every node evaluated);
 * else the largest gradient at the samples x 1.5, as the classification
 * takes it; a sample d refuses: every node evaluated, the error then
 * coming from a node, if any) prove which blocks lie wholly farther than
 * skin + 3 K max(hx, hy) from the boundary; their nodes get d's sign and a
 * magnitude below |d| but beyond that distance (trimming with it keeps the
 * trimmed value's sign everywhere, its value wherever it is within 3 K h of
 * zero). The other blocks' nodes are evaluated exactly. far (nx ny, or
 * NULL) gets 1 at the nodes not evaluated: at any point of a grid cell whose
 * four corners are such, |d| > skin + 1.5 max(hx, hy), with the corners'
 * sign. Errors of d as gr_field_eval gives them; GR_EMEM. */
int gr_domain_grid(const gr_field *d, double skin, double z, double x0, double y0, double hx, double hy, int nx,
                   int ny, double *dv, unsigned char *far, gr_err *e);

/* A key of d's boundary within the box lo..hi (mm, relative to the point
 * o): boxes whose keys match hold the same boundary, translated by their o,
 * to 1e-7 mm, and so the same values of d wherever |d| is below the
 * distance from the box's faces to the region that matters, and the same
 * sign wherever that region is connected to such points (what a trimmed
 * voxel's template needs: place.h). The boundary is described by its planar
 * patches, not its triangles (domkey.c). Made for an STL solid (solid.h)
 * with at most GR_BVH_NEAR_MAX faces near the box: 1 and key (64 hex
 * digits); 0 for any other domain (no key: the voxel keeps a template of
 * its own); -1 on an error of d (its message in e) or GR_EMEM. */
int gr_domain_local_key(const gr_field *d, const double lo[3], const double hi[3], const double o[3], char key[65],
                        gr_err *e);

#endif
