/* regions.h: regions of a part with their own build styles (skin, thin-wall
 * centre lines, down-skin, up-skin; the rest is the lattice core).
 *
 * Takes: the job (templates of every layer, domain and skin), the regions
 * asked for, n layers below (down-skin) and above (up-skin), and the scan
 * speed of each region (time estimates). Gives, while a layer is assembled
 * (assemble.h): each hatch segment of a voxel cut where it enters or leaves
 * a region, every piece tagged with its region (gr_block.region, paths.h);
 * thin-wall centre lines tagged GR_THIN. The CLI id of a block is
 * region * 48 + laser * 3 + kind + 1 (paths.h gr_style_id), so a job
 * without regions writes exactly what it wrote before.
 *
 * Definitions (doc/api/regions.md): the "solid" of layer k inside voxel
 * column (i, j) is the hatch region of its template layer (the section
 * inset by the contour band: what is hatched). A hatch point p of layer g
 *  - is down-skin when p is outside the solid of one of layers g-1 .. g-n
 *    (below layer 1 is the build plate: solid);
 *  - else up-skin when p is outside the solid of one of layers g+1 .. g+n
 *    (above the last layer: void);
 *  - else skin when the design domain has a skin and domain(p) >= -skin
 *    (the solid band along the domain, build.c's definition);
 *  - else core.
 * A region not asked for falls through to the next rule. Contours are cut
 * into down-skin, up-skin and core pieces by facing.h (against the
 * neighbours' sections); thin-wall lines get their own region. */
#ifndef GR_REGIONS_H
#define GR_REGIONS_H
#include <pthread.h>
#include "place.h"
#include "stitch.h"
struct gr_skinring;

struct gr_regions;

typedef struct gr_regions_opts {
  int mask;                  /* bit r set: region r (GR_SKIN..GR_UPSKIN) has its own style */
  int down, up;              /* layers looked at below / above, 1..64 */
  double speed[GR_NREGIONS]; /* scan speed per region, mm/s (index 0 unused: the machine's) */
  double hatch[GR_NREGIONS]; /* hatch spacing of a hatched region (skin, downskin, upskin), mm;
                                0: the job's. Index 0 (core) must be 0 or the job's. */
  int skin_contours;         /* contours along the skin's outer surface (skinring.h); 0: the job's */
} gr_regions_opts;

/* Give job j its regions (copied). Errors (GR_EARG): an unknown region bit,
 * layers outside 1..64, a speed not finite and > 0 for a region asked for,
 * a hatch spacing on a region without hatches, not finite and > 0, or with
 * no common line spacing with the job's (below).
 *
 * Hatch spacings per region: every hatch line of a layer lies on one global
 * family k * d0 (contract s.5); d0 is the largest job hatch / n (n = 1..16)
 * of which every region's spacing is a whole multiple m_r <= 64 (0.05 and
 * 0.025: d0 0.025; 0.05 and 0.075: d0 0.025). Voxels are hatched at d0 and a
 * piece of region r is kept only on lines k with k mod m_r = 0, so each
 * region's lines are exactly its spacing apart, on the same global family
 * in every voxel, and joined across voxels as before.
 * Call after the machine is set (gr_job_set_machine resets the speeds). */
int gr_job_set_regions(gr_job *j, const gr_regions_opts *o, gr_err *e);
/* The spacing d0 of the line family the voxels are hatched on, mm (the
 * job's hatch spacing without regions of their own spacing). */
double gr_regions_line(const gr_job *j);
/* The hatch spacing of region r's lines, mm (d0 times its step). */
double gr_regions_hatch(const gr_job *j, int r);
/* The skin's contour count (the job's when it has none of its own). */
int gr_regions_skin_contours(const gr_job *j);
/* The margin of the job's template windows (gr_tmpl_window): deep enough
 * for the skin's contours. */
double gr_job_window(const gr_job *j);
/* The lock around domain evaluations (NULL when the domain is thread-safe). */
pthread_mutex_t *gr_regions_mutex(gr_job *j);
/* The regions asked for (bit mask, 0 = none). */
int gr_regions_mask(const gr_job *j);
/* Layers below and above the layer range [ga, gb] that the down- and
 * up-skin tests read (0 without those regions). */
void gr_regions_margin(const gr_job *j, int *below, int *above);
void gr_regions_free(struct gr_regions *r);
/* Cut the hatch segments (*segs)[a .. *n) of voxel v (row slot order kept,
 * each segment replaced by its pieces in order) in global layer g by
 * region; pieces tagged in gr_hseg.region, those off their region's lines
 * (k mod m_r != 0) dropped, and with sr (skinring.h, may be NULL) those
 * within the skin's contour band dropped. No-op without regions. */
int gr_regions_split(gr_job *j, int g, int v, struct gr_skinring *sr, gr_hseg **segs, size_t *n, size_t *cap,
                     size_t a, gr_err *e);
/* Layer g2's solid in the column of voxel v into *state: GR_SOLID_PLATE
 * below layer 1, GR_SOLID_NONE above the part or where the column is empty,
 * else GR_SOLID_RINGS with *r the template layer's section (section = 1) or
 * hatch region (0), voxel-local. GR_EARG when the template is missing. */
enum { GR_SOLID_PLATE = 0, GR_SOLID_NONE = 1, GR_SOLID_RINGS = 2 };
int gr_regions_solid(const gr_job *j, int v, int g2, int section, int *state, const gr_rings **r, gr_err *e);
/* Tag the thin-wall centre lines of an assembled layer GR_THIN (when asked). */
void gr_regions_tag_thin(const gr_job *j, gr_layer *l);

#endif
